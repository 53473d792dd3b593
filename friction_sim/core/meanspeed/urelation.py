"""The nondimensional mean-speed relation U(phi, a) and its inverse (numpy only).

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
phi - (1 - a), computed without rounding.  psi_C is found for whole arrays
at once by Newton's method kept inside the bracket [pi - 2*theta_A, 2*pi],
where w is monotone; each element stops on its own, so a value does not
depend on the array it came in.  The inverse a(U, phi),
which the controller uses, inverts the monotone rise of U with a by
Newton's method with the exact slope dU/da, kept inside a shrinking
bracket, again on whole arrays.

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

from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import closed_form_applies
from friction_sim.core.physics.roots import remainders_many, two_sum
from friction_sim.errors import ParameterError

_TWO_PI = 2.0 * np.pi
_FOUR_PI2 = 4.0 * np.pi**2


def _result(values: NDArray[np.float64], *inputs: Any) -> Any:
    """Return a Python float when every input was a scalar, else the array."""
    if all(np.ndim(value) == 0 for value in inputs):
        return float(values)
    return values


def slip_start_phase(phi: ArrayLike, a: ArrayLike) -> Any:
    """theta_A = asin((1 - |phi|)/a): where each period's slip starts (NaN where
    the slider never slips from rest)."""
    phi_, a_ = np.broadcast_arrays(np.abs(np.asarray(phi, float)), np.asarray(a, float))
    with np.errstate(divide="ignore", invalid="ignore"):
        sin_a, cos_a = _start_sin_cos(phi_, a_)
        theta = np.where((sin_a < 1.0) & (sin_a >= -1.0) & (cos_a > 0.0), np.arctan2(sin_a, cos_a), np.nan)
    return _result(theta, phi, a)


def _beyond_boundary(phi: NDArray[np.float64], a: NDArray[np.float64]) -> NDArray[np.float64]:
    """phi - (1 - a), as exactly as its sign: > 0 where the slider moves.

    phi + a is split into its rounded sum and the exact rounding error
    (TwoSum), and the sum minus 1 is exact (Sterbenz) wherever it matters, so
    the distance keeps its full relative precision however small it is.
    """
    with np.errstate(invalid="ignore"):
        total, error = two_sum(phi, a)
        beyond: NDArray[np.float64] = (total - 1.0) + error
    return np.where(np.isfinite(total), beyond, total - 1.0)  # inf stays inf, NaN NaN


def _start_sin_cos(
    phi: NDArray[np.float64], a: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(sin, cos) of theta_A for phi >= 0: sin = (1 - phi)/a, and
    cos = sqrt(1 - sin^2) = sqrt(e*(2 - e)) with e = 1 - sin = (phi - (1 - a))/a,
    accurate to the last bits even where theta_A is within 1e-6 of pi/2.
    NaN where there is no slip start (e outside (0, 2])."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # tiny a: e overflows, no start
        e = _beyond_boundary(phi, a) / a
        cos_a = np.sqrt(e * (2.0 - e))
        return (1.0 - phi) / a, np.where((e > 0.0) & (e <= 2.0), cos_a, np.nan)


def moves(phi: ArrayLike, a: ArrayLike) -> Any:
    """True where the slider moves at all: |phi| > 1 - a (the motion boundary),
    decided exactly on the given floats, as :func:`u_map` and the slider do."""
    phi_, a_ = np.broadcast_arrays(np.abs(np.asarray(phi, float)), np.asarray(a, float))
    result = _beyond_boundary(phi_, a_) > 0.0
    return bool(result) if np.ndim(result) == 0 else result


def motion_boundary(phi: ArrayLike) -> Any:
    """The smallest amplitude ratio a = 1 - |phi| at which motion can start
    (exclusive: at a = 1 - |phi| exactly the slider still stands)."""
    boundary = np.clip(1.0 - np.abs(np.asarray(phi, float)), 0.0, None)
    return _result(boundary, phi)


def stop_phase_advance(phi: ArrayLike, a: ArrayLike) -> Any:
    """psi_C: the phase the slip lasts, from slip start (A) to stick (C)."""
    phi_, a_ = np.broadcast_arrays(np.abs(np.asarray(phi, float)), np.asarray(a, float))
    psi = _stop_phase(phi_.astype(float), a_.astype(float))
    return _result(psi, phi, a)


def _periodic_slip(
    phi: NDArray[np.float64], a: NDArray[np.float64]
) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """For phi >= 0: where there is one periodic slip per period (1 - a < phi < 1),
    and there sin(theta_A), cos(theta_A) and psi_C."""
    sin_all, cos_all = _start_sin_cos(phi, a)
    slipping = (cos_all > 0.0) & (phi < 1.0) & (a > 0.0)
    sin_a, cos_a = sin_all[slipping], cos_all[slipping]
    # w/a = cos_a*(1 - cos x) - sin_a*(x - sin x) rises on (0, pi - 2*theta_A) and
    # falls from there to below zero at 2*pi; near the boundary its root is
    # close to 3*(pi/2 - theta_A) (the cubic w ~ x^2*(delta/2 - x/6)).
    delta = np.arctan2(cos_a, sin_a)  # pi/2 - theta_A, without cancellation
    lo = 2.0 * delta
    hi = np.full_like(lo, _TWO_PI)
    x = np.clip(3.0 * delta, lo, hi)
    active = np.ones(x.shape, dtype=bool)
    for _ in range(100):
        c1, s2, _c2 = remainders_many(x)
        w = cos_a * c1 - sin_a * s2
        lo = np.where(w > 0.0, x, lo)
        hi = np.where(w < 0.0, x, hi)
        slope = cos_a * np.sin(x) - sin_a * c1
        with np.errstate(divide="ignore", invalid="ignore"):
            step = x - w / slope
        outside = ~((step > lo) & (step < hi)) | ~np.isfinite(step)
        step = np.where(outside, 0.5 * (lo + hi), step)
        step = np.where(w == 0.0, x, step)
        # Each element stops on its own: its value must not depend on its neighbours.
        done = np.abs(step - x) <= 4.0 * np.finfo(float).eps * np.abs(x)
        x = np.where(active, step, x)
        active &= ~done
        if not np.any(active):
            break
    return slipping, sin_a, cos_a, x


def _stop_phase(phi: NDArray[np.float64], a: NDArray[np.float64]) -> NDArray[np.float64]:
    """psi_C for phi >= 0 (NaN where there is no periodic slip)."""
    psi = np.full(phi.shape, np.nan)
    psi[(phi == 1.0) & (a > 0.0)] = _TWO_PI
    slipping, _, _, x = _periodic_slip(phi, a)
    psi[slipping] = x
    return psi


def _travel(a: NDArray[np.float64], sin_a: NDArray[np.float64], cos_a: NDArray[np.float64],
            psi: NDArray[np.float64]) -> NDArray[np.float64]:
    """D = a*(cos_a*(psi - sin psi) - sin_a*(psi^2/2 - 1 + cos psi)) >= 0: the
    travel of one periodic slip in units of mu*g/omega^2."""
    _, s2, c2 = remainders_many(psi)
    travel: NDArray[np.float64] = np.maximum(a * (cos_a * s2 - sin_a * c2), 0.0)
    return travel


def u_map(phi: ArrayLike, a: ArrayLike) -> Any:
    """Exact nondimensional mean speed U(phi, a) = V*f/(g*mu).

    Accepts scalars or arrays (broadcast together); returns a float for
    scalars.  0 where nothing moves, inf beyond phi > 1, sign of phi.
    """
    phi_arr, a_arr = np.broadcast_arrays(np.asarray(phi, float), np.asarray(a, float))
    _check_ratio(a_arr)
    mag = np.abs(phi_arr)
    u = np.zeros(phi_arr.shape)
    periodic, sin_a, cos_a, psi = _periodic_slip(mag, a_arr)
    if np.any(periodic):
        u[periodic] = _travel(a_arr[periodic], sin_a, cos_a, psi) / _FOUR_PI2
    u[mag == 1.0] = a_arr[mag == 1.0] / _TWO_PI
    u[mag > 1.0] = np.inf
    u[np.isnan(mag)] = np.nan
    return _result(np.sign(phi_arr) * u + 0.0, phi, a)  # + 0.0: no -0.0 where a backward drive stands still


def _check_ratio(a: NDArray[np.float64]) -> None:
    bad = ~((a >= 0.0) & (a < 1.0))
    if np.any(bad):
        value = float(np.asarray(a)[bad].flat[0])
        raise ParameterError("amplitude_ratio", value, "must be in [0, 1) (Pa < m*g)")


def amplitude_ratio_for(u: ArrayLike, phi: ArrayLike, max_ratio: float = 1.0) -> Any:
    """The inverse relation: the amplitude ratio a with U(phi, a) = u.

    U rises monotonically with a on (1 - phi, 1), so the answer is unique.
    Returns 0 for u == 0 (no excitation needed to stand still), and NaN where
    u cannot be reached with a < ``max_ratio`` (too fast, or the sign of u
    disagrees with phi, or |phi| >= 1 where excitation no longer steers).
    """
    if not 0.0 < max_ratio <= 1.0:
        raise ParameterError("max_ratio", max_ratio, "must be in (0, 1]")
    u_arr, phi_arr = np.broadcast_arrays(np.asarray(u, float), np.asarray(phi, float))
    target, mag = np.abs(u_arr), np.abs(phi_arr)
    a = np.full(u_arr.shape, np.nan)
    a[u_arr == 0.0] = 0.0
    lo = np.clip(1.0 - mag, 0.0, 1.0)
    top = np.nextafter(max_ratio, 0.0) if max_ratio >= 1.0 else max_ratio
    hi = np.full(lo.shape, top)
    same_sign = np.sign(u_arr) == np.sign(phi_arr)
    candidates = (u_arr != 0.0) & same_sign & (mag > 0.0) & (mag < 1.0) & (lo < hi)
    if np.any(candidates):
        u_top = np.where(candidates, u_map(np.where(candidates, mag, 0.5), np.where(candidates, hi, 0.5)), 0.0)
        reachable = candidates & (target <= u_top)
        if np.any(reachable):
            mag_r = mag[reachable]
            a[reachable] = _invert(target[reachable], lo[reachable], hi[reachable], u_top[reachable],
                                   lambda x, index: _u_and_slope(mag_r[index], x))
    return _result(a, u, phi)


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
    u_arr, a_arr = np.broadcast_arrays(np.asarray(u, float), np.asarray(a, float))
    _check_ratio(a_arr)
    target = np.abs(u_arr)
    phi = np.full(u_arr.shape, np.nan)
    boundary = 1.0 - a_arr
    phi[target == 0.0] = boundary[target == 0.0]
    u_top = a_arr / _TWO_PI
    phi[(target == u_top) & (target > 0.0)] = 1.0
    inside = (target > 0.0) & (target < u_top)
    if np.any(inside):
        a_in = a_arr[inside]
        phi[inside] = _invert(target[inside], boundary[inside], np.ones(a_in.shape), u_top[inside],
                              lambda x, index: _u_and_phi_slope(x, a_in[index]))
    return _result(np.where(u_arr < 0.0, -phi, phi), u, a)


def _invert(
    target: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64], f_hi: NDArray[np.float64],
    evaluate: Callable[[NDArray[np.float64], NDArray[np.intp]], tuple[NDArray[np.float64], NDArray[np.float64]]],
) -> NDArray[np.float64]:
    """Solve U(x) = target for x in [lo, hi] (U(lo) = 0 < target <= U(hi), U rising):
    ``evaluate(x, index)`` gives U and its exact slope at x for the elements
    ``index`` (x the amplitude ratio at a given phi, or phi at a given
    amplitude ratio).

    Newton's method with the exact slope, every iterate kept inside the
    shrinking bracket (bisection when Newton would leave it): a handful of
    iterations, which matters to a controller that inverts once per period.
    Each element stops on its own (its value does not depend on its
    neighbours): when U meets the target to rounding, the step or the bracket
    is a few ulps (near the motion boundary U's rounding noise exceeds the
    first test; the bracket still closes).
    """
    eps = np.finfo(float).eps
    lo, hi = lo.copy(), hi.copy()
    x = lo + (hi - lo) * np.sqrt(target / f_hi)  # U grows roughly like (x - lo)^2 near the boundary
    active = np.arange(x.size)
    for _ in range(100):
        xa = x[active]
        u, slope = evaluate(xa, active)
        f = u - target[active]
        high, low = np.where(f > 0.0, xa, hi[active]), np.where(f > 0.0, lo[active], xa)
        hi[active], lo[active] = high, low
        with np.errstate(divide="ignore", invalid="ignore"):
            step = xa - f / slope
        step = np.where(np.isfinite(step) & (step > low) & (step < high), step, 0.5 * (low + high))
        step = np.where(np.abs(f) <= 4.0 * eps * target[active], xa, step)
        done = (np.abs(step - xa) <= 4.0 * eps * xa) | (high - low <= 4.0 * eps * xa)
        x[active] = step
        active = active[~done]
        if active.size == 0:
            break
    return x


def _u_and_slope(phi: NDArray[np.float64], a: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """U and dU/da where 1 - a < phi < 1 (one periodic slip per period).

    With D(psi) the travel per period, U = D(psi_C)/(4 pi^2); psi_C moves with
    a, but dD/dpsi = w(psi_C) = 0, and so does dD/d(theta_A) (it equals
    w(psi_C) too, since phi - 1 + a*sin(theta_A) = 0), so only the explicit
    factor a remains: dD/da = sin_a*(1 - cos psi_C) + cos_a*(psi_C - sin psi_C).
    """
    travel = np.zeros(phi.shape)
    slope = np.full(phi.shape, np.nan)
    slipping, sin_a, cos_a, psi = _periodic_slip(phi, a)
    c1, s2, _ = remainders_many(psi)
    travel[slipping] = _travel(a[slipping], sin_a, cos_a, psi)
    slope[slipping] = sin_a * c1 + cos_a * s2
    return travel / _FOUR_PI2, slope / _FOUR_PI2


def _u_and_phi_slope(phi: NDArray[np.float64],
                     a: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """U and dU/dphi where 1 - a < phi < 1: as for :func:`_u_and_slope`, psi_C and
    theta_A move with phi but D is stationary in both, so only the explicit
    term of D = (phi - 1)*psi**2/2 + ... remains: dD/dphi = psi_C**2/2."""
    travel = np.zeros(phi.shape)
    slope = np.full(phi.shape, np.nan)
    slipping, sin_a, cos_a, psi = _periodic_slip(phi, a)
    travel[slipping] = _travel(a[slipping], sin_a, cos_a, psi)
    slope[slipping] = 0.5 * psi * psi
    return travel / _FOUR_PI2, slope / _FOUR_PI2


def nondimensional_speed(v: ArrayLike, frequency: float, gravity: float, mu: float) -> Any:
    """U = V*f/(g*mu) from a dimensional mean speed V [m/s]."""
    return _result(np.asarray(v, float) * frequency / (gravity * mu), v)


def dimensional_speed(u: ArrayLike, frequency: float, gravity: float, mu: float) -> Any:
    """V = U*g*mu/f [m/s] from a nondimensional mean speed U."""
    return _result(np.asarray(u, float) * gravity * mu / frequency, u)


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
    phi, ratio, gravity = (inputs.tangential_force / (params.mu * load), inputs.excitation_amplitude / load,
                           params.gravity - inputs.external_force_z / params.mass)
    u = u_map(phi, ratio)
    return Prediction(
        phi=inputs.drive_force / (params.mu * params.weight),
        amplitude_ratio=inputs.excitation_amplitude / params.weight,
        u=u,
        mean_velocity=dimensional_speed(u, inputs.excitation_frequency, gravity, params.mu),
        effective_phi=phi, effective_amplitude_ratio=ratio, effective_gravity=gravity,
    )
