"""The nondimensional mean-speed relation U(phi, a) and its inverses (numpy and math only).

With phi = Fd/(mu*m*g) and a = Pa/(m*g), Kostek's nondimensional mean speed
U = V*f/(g*mu) depends on (phi, a) alone.  It is exact here, not fitted:

* Nothing moves for phi <= 1 - a (the friction limit mu*R never drops below
  Fd), so U = 0 there.
* For 1 - a < phi < 1 every period has one slip.  It starts from rest at the
  phase theta_A = asin((1 - phi)/a), where mu*R falls below Fd, and in
  units of mu*g/omega its speed after a phase advance psi is

      w(psi) = (phi - 1)*psi + a*(cos(theta_A) - cos(theta_A + psi)).

  w rises until psi = pi - 2*theta_A (the peak velocity, point B) and falls
  until it is zero again at psi_C (point C) in (pi - 2*theta_A, 2*pi], because
  w(2*pi) = 2*pi*(phi - 1) <= 0.  The slip thus ends within the period, the
  motion is periodic with the excitation, and the displacement per period in
  units of mu*g/omega^2 is the integral of w up to psi_C:

      D = (phi - 1)*psi_C^2/2 + a*(psi_C*cos(theta_A) - sin(theta_A + psi_C) + sin(theta_A)),

  so U = V*f/(g*mu) = D/(4*pi^2).
* phi = 1 slides forever with a bounded oscillating speed (U = a/(2*pi), the
  limit of the above); phi > 1 accelerates without bound (U = inf).
* Negative phi mirrors: U(-phi, a) = -U(phi, a).

Near the motion boundary these textbook forms cancel catastrophically (the
slip is tiny, its terms are not), so they are evaluated in the same
cancellation-free form as the slider's closed form: with 1 - cos(psi),
psi - sin(psi) and psi^2/2 - (1 - cos(psi)) from
:func:`~friction_sim.core.physics.roots.remainders`, and because
phi - 1 + a*sin(theta_A) = 0,

    w(psi) = a*(cos(theta_A)*(1 - cos psi) - sin(theta_A)*(psi - sin psi))
    D      = a*(cos(theta_A)*(psi_C - sin psi_C) - sin(theta_A)*(psi_C^2/2 - 1 + cos psi_C)),

where cos(theta_A) comes from the distance to the boundary
phi - (1 - a), computed without rounding.  psi_C is found by Newton's method
kept inside the bracket [pi - 2*theta_A, 2*pi], where w is monotone.  The
inverses a(U, phi), which the controller uses once per period, and
phi(U, a) invert the monotone rise of U by Newton's method with the exact
slope, kept inside a shrinking bracket.

These formulas are written once, for one point, in
:mod:`friction_sim.core.meanspeed.kostek` (plain floats and ``math``, in the
subset Numba compiles, as the slider's physics): a call with scalars
evaluates them directly, a call with arrays applies them element by element.
So each element's value does not depend on its neighbours, and a point gets
the same bits alone as in any array.

All of this is Kostek's model below lift-off (normal excitation, level track,
mu_s = mu, a < 1).  The general model of issue 11 has no closed form: its
mean speed is :func:`friction_sim.core.meanspeed.general.mean_speed` (this module's
value, bit for bit, wherever this one applies) and its inverse lives in
:mod:`friction_sim.core.meanspeed.inverse`; :func:`~friction_sim.core.meanspeed.predict.predict` chooses between them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from friction_sim.core.meanspeed import kostek
from friction_sim.core.model.dimensionless import amplitude_ratio, dimensional_speed, drive_ratio
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import closed_form_applies
from friction_sim.errors import ParameterError


def _result(values: NDArray[np.float64], *inputs: Any) -> Any:
    """Return a Python float when every input was a scalar, else the array."""
    if all(np.ndim(value) == 0 for value in inputs):
        return float(values)
    return values


def _scalar(value: Any) -> bool:
    """Whether ``value`` is one number (a float, an int, a numpy scalar or a 0-d
    array): such calls evaluate :mod:`~friction_sim.core.meanspeed.kostek` directly,
    without the microseconds each numpy operation costs."""
    return type(value) is float or np.ndim(value) == 0


def _elementwise(function: Callable[..., Any], dtype: Any, *arrays: ArrayLike) -> NDArray[Any]:
    """``function`` of every element of ``arrays`` (broadcast together), each on
    its own and as Python floats: a scalar function of
    :mod:`~friction_sim.core.meanspeed.kostek` over arrays, giving every element the
    bits it gets alone."""
    broadcast = np.broadcast_arrays(*(np.asarray(array, float) for array in arrays))
    columns = [array.ravel().tolist() for array in broadcast]
    values = np.fromiter(map(function, *columns), dtype=dtype, count=broadcast[0].size)
    return values.reshape(broadcast[0].shape)


def slip_start_phase(phi: ArrayLike, a: ArrayLike) -> Any:
    """theta_A = asin((1 - |phi|)/a): where each period's slip starts (NaN where
    the slider never slips from rest)."""
    if _scalar(phi) and _scalar(a):
        return kostek.start_phase(float(phi), float(a))  # type: ignore[arg-type]
    return _elementwise(kostek.start_phase, float, phi, a)


def moves(phi: ArrayLike, a: ArrayLike) -> Any:
    """True where the slider moves at all: |phi| > 1 - a (the motion boundary),
    decided exactly on the given floats, as :func:`u_map` and the slider do."""
    if _scalar(phi) and _scalar(a):
        return kostek.moves(float(phi), float(a))  # type: ignore[arg-type]
    return _elementwise(kostek.moves, bool, phi, a)


def motion_boundary(phi: ArrayLike) -> Any:
    """The smallest amplitude ratio a = 1 - |phi| at which motion can start
    (exclusive: at a = 1 - |phi| exactly the slider still stands)."""
    boundary = np.clip(1.0 - np.abs(np.asarray(phi, float)), 0.0, None)
    return _result(boundary, phi)


def stop_phase_advance(phi: ArrayLike, a: ArrayLike) -> Any:
    """psi_C: the phase the slip lasts, from slip start (A) to stick (C): 2*pi
    at |phi| = 1 (it never sticks), NaN where there is no periodic slip."""
    if _scalar(phi) and _scalar(a):
        return kostek.stop_phase(float(phi), float(a))  # type: ignore[arg-type]
    return _elementwise(kostek.stop_phase, float, phi, a)


def u_map(phi: ArrayLike, a: ArrayLike) -> Any:
    """Exact nondimensional mean speed U(phi, a) = V*f/(g*mu).

    Accepts scalars or arrays (broadcast together); returns a float for
    scalars.  0 where nothing moves, inf beyond phi > 1, sign of phi.
    """
    if _scalar(phi) and _scalar(a):
        ratio = float(a)  # type: ignore[arg-type]
        _check_ratio(ratio)
        return kostek.u_of(float(phi), ratio)  # type: ignore[arg-type]
    phi_arr, a_arr = np.broadcast_arrays(np.asarray(phi, float), np.asarray(a, float))
    _check_ratio(a_arr)
    return _elementwise(kostek.u_of, float, phi_arr, a_arr)


def _check_ratio(a: float | NDArray[np.float64]) -> None:
    """Refuse an amplitude ratio outside [0, 1) (Kostek's model holds below
    lift-off); of an array, its first such element."""
    if isinstance(a, float):
        if not 0.0 <= a < 1.0:
            raise ParameterError("amplitude_ratio", a, "must be in [0, 1) (Pa < m*g)")
        return
    bad = ~((a >= 0.0) & (a < 1.0))
    if np.any(bad):
        value = float(np.asarray(a)[bad].flat[0])
        raise ParameterError("amplitude_ratio", value, "must be in [0, 1) (Pa < m*g)")


def amplitude_ratio_for(u: ArrayLike, phi: ArrayLike, max_ratio: float = 1.0) -> Any:
    """The inverse relation: the amplitude ratio a with U(phi, a) = u.

    U rises monotonically with a on (1 - phi, 1), so the answer is unique.
    Returns 0 for u == 0 (no excitation needed to stand still), and NaN where
    u cannot be reached with a < ``max_ratio`` (too fast, or the sign of u
    disagrees with phi, or |phi| > 1 where the slider runs away: at |phi| = 1
    it slides on at U = a/(2*pi), which the excitation sets).
    """
    if not 0.0 < max_ratio <= 1.0:
        raise ParameterError("max_ratio", max_ratio, "must be in (0, 1]")
    top = math.nextafter(max_ratio, 0.0) if max_ratio >= 1.0 else float(max_ratio)
    if _scalar(u) and _scalar(phi):
        return kostek.amplitude_ratio(float(u), float(phi), top)  # type: ignore[arg-type]
    return _elementwise(lambda u_, phi_: kostek.amplitude_ratio(u_, phi_, top), float, u, phi)


def drive_ratio_for(u: ArrayLike, a: ArrayLike) -> Any:
    """The inverse relation in phi: the drive ratio phi = Fd/(mu*m*g) with
    U(phi, a) = u, for 0 <= a < 1 (scalars or arrays, broadcast together).

    U rises monotonically with phi, from 0 at the motion boundary phi = 1 - a
    to a/(2*pi) at phi = 1 (dU/dphi = psi_C**2/(8*pi**2) > 0), so the answer
    is unique.  u = 0 gives the largest phi at which the slider still stands,
    1 - a: the apparent friction coefficient over mu at breakaway.  NaN where
    |u| > a/(2*pi) (only phi > 1 would go faster: it accelerates without
    bound).  Negative u mirrors: phi(-u, a) = -phi(u, a).  The friction that
    vibration leaves a slider moving at U is mu_app = phi*mu.
    """
    if _scalar(u) and _scalar(a):
        ratio = float(a)  # type: ignore[arg-type]
        _check_ratio(ratio)
        return kostek.drive_ratio(float(u), ratio)  # type: ignore[arg-type]
    u_arr, a_arr = np.broadcast_arrays(np.asarray(u, float), np.asarray(a, float))
    _check_ratio(a_arr)
    return _elementwise(kostek.drive_ratio, float, u_arr, a_arr)


@dataclass(frozen=True)
class UMap:
    """U over a grid: ``u[i, j]`` belongs to ``amplitude_ratio[i]`` and ``phi[j]``."""

    phi: NDArray[np.float64]
    amplitude_ratio: NDArray[np.float64]
    u: NDArray[np.float64]


def u_grid(points: int) -> UMap:
    """The whole map on ``points`` x ``points`` values of phi and a, evenly
    spaced strictly inside (0, 1) (a = 1 would lift the slider off)."""
    if isinstance(points, bool) or not isinstance(points, int) or points < 2:
        raise ParameterError("grid", points, "must be an integer >= 2")
    axis = np.arange(1, points + 1) / (points + 1.0)
    phi, a = np.meshgrid(axis, axis)
    return UMap(phi=axis, amplitude_ratio=axis.copy(), u=np.asarray(u_map(phi, a)))


@dataclass(frozen=True)
class Prediction:
    """What the U relation predicts for a plant and its present inputs.

    ``phi`` and ``amplitude_ratio`` are the paper's groups, Fd/(mu*m*g) and
    Pa/(m*g).  With an external force Kostek's relation still holds with the
    effective groups (Fd + Fx)/(mu*(m*g - Fz)) and Pa/(m*g - Fz) (Fz > 0
    lifts), and an effective gravity (m*g - Fz)/m; ``u`` and
    ``mean_velocity`` use those, and so must a U measured to be compared with
    ``u`` (the ``effective_*`` fields; equal to the paper's groups without an
    external force).  Beyond Kostek's model the effective gravity is g.
    """

    phi: float
    amplitude_ratio: float
    u: float
    mean_velocity: float
    effective_phi: float = math.nan
    effective_amplitude_ratio: float = math.nan
    effective_gravity: float = math.nan


#: No prediction (the plant has none, or it could not be made): NaN throughout.
NO_PREDICTION = Prediction(math.nan, math.nan, math.nan, math.nan)


def kostek_prediction(params: SliderParams, inputs: Inputs) -> Prediction | None:
    """The exact periodic mean speed of Kostek's model (normal excitation,
    level track, mu_s = mu) with Pa below the load m*g - Fz; None for any
    other plant, whose mean speed has no closed form."""
    if not closed_form_applies(params, inputs):
        return None
    load = params.weight - inputs.external_force_z
    # (m*g - Fz)/m as g - Fz/m: exactly g without an external force (Fz > 0 lifts)
    phi, ratio, gravity = (drive_ratio(inputs.tangential_force, params.mu, load),
                           amplitude_ratio(inputs.excitation_amplitude, load),
                           params.gravity - inputs.external_force_z / params.mass)
    u = u_map(phi, ratio)
    return Prediction(
        phi=drive_ratio(inputs.drive_force, params.mu, params.weight),
        amplitude_ratio=amplitude_ratio(inputs.excitation_amplitude, params.weight),
        u=u,
        mean_velocity=dimensional_speed(u, inputs.excitation_frequency, gravity, params.mu),
        effective_phi=phi, effective_amplitude_ratio=ratio, effective_gravity=gravity,
    )
