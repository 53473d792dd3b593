"""The friction-reduction curve (``friction-sim reduction``): the paper's title
claim, that normal vibration reduces the friction force through stick-slip alone.

A tribologist measures the force it takes to slide a body at a steady mean
speed V over a vibrating track and calls Fd/(m g) the apparent friction
coefficient mu_app.  On Kostek's model that force is phi*mu*m*g, where phi =
Fd/(mu*m*g) is the drive ratio at which U(phi, a) = V*f/(g*mu): so
mu_app/mu = phi, read exactly from the inverse of U in phi
(:func:`~friction_sim.core.meanspeed.urelation.drive_ratio_for`).  At V -> 0 it
is 1 - a (breakaway under the vibration); at the fastest a periodic stick-slip
reaches, U = a/(2 pi), it is 1 (the full Coulomb friction).

The paper's Fig. 4 compares that reduction with Lomakin's 1955 measurements
(mu = 0.156, m = 1 kg, g = 10 m/s^2, f = 100 Hz: :data:`LOMAKIN`); our copy of
the text has neither the figure's axes nor the data, so the measured points
are not reproduced here.

Beyond Kostek's model (a vibration inclined to the track, a slope, mu_s > mu,
or a hop) there is no closed form: the drive ratio is found by bisection on
the general mean speed, for every point at once on the population engine
(:func:`~friction_sim.core.engine.population.run_batch`), each mean exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from friction_sim.core.engine.population import run_batch
from friction_sim.core.meanspeed.general import DEFAULT_PERIODS, DEFAULT_SETTLE_PERIODS
from friction_sim.core.meanspeed.urelation import drive_ratio_for
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import (
    TWO_PI,
    amplitude_for,
    dimensional_speed,
    drive_force_for,
    drive_ratio,
    nondimensional_speed,
)
from friction_sim.core.model.params import Inputs, SliderParams, field_values
from friction_sim.core.physics.plant import kostek_applies
from friction_sim.errors import ParameterError

Floats = NDArray[np.float64]

#: Lomakin's conditions in the paper's Fig. 4: mu 0.156, m 1 kg, g 10 m/s^2 ...
LOMAKIN = SliderParams(mass=1.0, mu=0.156, gravity=10.0)
#: ... at f = 100 Hz.
LOMAKIN_FREQUENCY = 100.0
#: Bisection halvings on the general model: the bracket's width times 2**-52, rounding.
BISECTIONS = 52


@dataclass(frozen=True)
class ReductionCurves:
    """mu_app/mu (the drive ratio phi) needed to slide at a mean speed, two ways:
    ``by_speed[i, j]`` at amplitude ratio ``ratios[i]`` (a = Pa/Q, Q = m g) and
    mean speed ``speeds[i, j]`` [m/s] (each curve its own speeds: see
    :func:`reduction_curves`); ``by_amplitude[i, j]`` at mean speed
    ``marked_speeds[i]`` and amplitude ratio ``amplitudes[i, j]`` (each curve its own ratios).  NaN where no
    steady stick-slip reaches that speed (only a slider that runs away would go
    faster).  ``closed_form``: Kostek's exact inverse (else the general mean speed's)."""

    params: SliderParams
    frequency: float
    ratios: Floats
    speeds: Floats
    by_speed: Floats
    marked_speeds: Floats
    amplitudes: Floats
    by_amplitude: Floats
    closed_form: bool


def apparent_friction_ratio(speed: ArrayLike, ratio: ArrayLike, params: SliderParams, frequency: float, *,
                            simulated: bool = False) -> Floats:
    """mu_app/mu: the drive ratio phi at which ``params`` moves at mean ``speed``
    [m/s] under the amplitude ratio ``ratio`` at ``frequency`` [Hz] (arrays,
    broadcast).  Kostek's closed form where it holds, unless ``simulated``: then
    (and beyond his model) bisection on the general mean speed."""
    spec.EXCITATION_FREQUENCY.check(frequency)
    v, a = np.broadcast_arrays(np.asarray(speed, float), np.asarray(ratio, float))
    if not (np.all(np.isfinite(v)) and np.all(np.isfinite(a)) and np.all(a >= 0.0)):
        raise ParameterError("mean_speed", float(v.flat[0]), "speeds and amplitude ratios must be finite, ratios >= 0")
    if not simulated and _closed_form(params, a):
        u = nondimensional_speed(v, frequency, params.gravity, params.mu)
        return np.asarray(drive_ratio_for(u, a), dtype=float)
    return _bisected(v, a, params, frequency)


def _closed_form(params: SliderParams, a: Floats) -> bool:
    """Whether every amplitude ratio lies in Kostek's model for ``params`` (no hop)."""
    return not params.resonant and bool(np.all(kostek_applies(
        params.excitation_angle, params.track_inclination, params.static_ratio, amplitude_for(a, params.weight),
        params.weight, 0.0)))


def runaway_ratio(params: SliderParams) -> float:
    """The drive ratio beyond which the slider slides away uphill whatever the
    vibration: Fd - m g sin(alpha) = mu m g cos(alpha), over mu m g (the
    boundary of :func:`~friction_sim.core.model.dimensionless.beats_friction`, where
    the slider itself still moves at a bounded speed)."""
    return drive_ratio(params.downhill_weight + params.mu * params.normal_weight, params.mu, params.weight)


def _bisected(v: Floats, a: Floats, params: SliderParams, frequency: float) -> Floats:
    """phi with V(phi) = v, for all points at once, on [-top, top) (top: the
    runaway ratio): V rises with the drive, so the crossing is bracketed where
    the ends straddle v; NaN where they do not."""
    top = runaway_ratio(params)
    lo, hi = np.full(v.shape, -top), np.full(v.shape, math.nextafter(top, 0.0))
    below_lo = _speed(lo, a, params, frequency) <= v
    above_hi = _speed(hi, a, params, frequency) > v
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        faster = _speed(mid, a, params, frequency) > v
        hi, lo = np.where(faster, mid, hi), np.where(faster, lo, mid)
    phi: Floats = np.where(below_lo & above_hi, lo, np.nan)
    return phi


def _speed(phi: Floats, a: Floats, params: SliderParams, frequency: float) -> Floats:
    """The exact mean speed [m/s] of ``params`` at each (phi, a), on the population engine."""
    values = {**field_values(params, Inputs()), "actuator": "force", "excitation_frequency": frequency,
              "drive_force": drive_force_for(phi, params.mu, params.weight).ravel(),
              "excitation_amplitude": amplitude_for(a, params.weight).ravel()}
    batch = run_batch(values, settle_periods=DEFAULT_SETTLE_PERIODS, periods=DEFAULT_PERIODS)
    return np.asarray(batch.mean_velocity, dtype=float).reshape(phi.shape)


def speed_fractions(points: int) -> Floats:
    """Where a curve's ``points`` lie, as fractions 0..1 of its speed range: squares
    of an even grid.  From breakaway phi rises as the square root of the speed
    (dphi/dV is infinite at V = 0), so an even grid in V draws that vertical rise as
    one straight segment; on this one phi steps about evenly there too."""
    fractions: Floats = np.linspace(0.0, 1.0, points) ** 2
    return fractions


def _against_speed(params: SliderParams, frequency: float, ratios: Floats, points: int,
                   closed: bool) -> tuple[Floats, Floats]:
    """(speeds[i, j], phi[i, j]) of each ratio's curve, up to U = a/(2 pi), where phi = 1
    (Kostek's model: its own ratio's; beyond it, the largest's).  On Kostek's model phi
    comes from U itself, so the end is exact (a round trip through V may overshoot it)."""
    top_u = (ratios if closed else np.full(ratios.shape, np.max(ratios))) / TWO_PI
    u = top_u[:, None] * speed_fractions(points)[None, :]
    speeds = dimensional_speed(u, frequency, params.gravity, params.mu)
    if closed:
        return speeds, np.asarray(drive_ratio_for(u, ratios[:, None]), dtype=float)
    return speeds, apparent_friction_ratio(speeds, ratios[:, None], params, frequency)


def _against_ratio(params: SliderParams, frequency: float, marked: Floats, amplitudes: Floats,
                   closed: bool) -> tuple[Floats, Floats]:
    """(ratios[i, j], phi[i, j]) of each marked speed's curve, up to the largest ratio.
    On Kostek's model from the least ratio that reaches the speed, a = 2 pi U, where
    phi = 1 exactly (taken from a itself, as above); beyond it over ``amplitudes``."""
    if not closed:
        ratios = np.broadcast_to(amplitudes, (marked.size, amplitudes.size)).copy()
        return ratios, apparent_friction_ratio(marked[:, None], ratios, params, frequency)
    top = float(amplitudes[-1])
    least = np.minimum(TWO_PI * nondimensional_speed(marked, frequency, params.gravity, params.mu), top)
    ratios = least[:, None] + (top - least)[:, None] * np.linspace(0.0, 1.0, amplitudes.size)[None, :]
    first = np.asarray(drive_ratio_for(least[:, None] / TWO_PI, least[:, None]), dtype=float)
    rest = apparent_friction_ratio(marked[:, None], ratios[:, 1:], params, frequency)
    return ratios, np.concatenate([first, rest], axis=1)


def reduction_curves(params: SliderParams = LOMAKIN, frequency: float = LOMAKIN_FREQUENCY, *,
                     ratios: ArrayLike = (0.2, 0.4, 0.6, 0.8), marked_speeds: ArrayLike = (2e-4, 5e-4, 1e-3),
                     points: int = 101) -> ReductionCurves:
    """Both views of the reduction: against the mean speed at each of ``ratios``,
    from 0 to that ratio's fastest periodic stick-slip on Kostek's model (U = a/(2
    pi), where phi = 1 exactly; beyond his model, to the largest ratio's), the
    points closer toward 0 (:func:`speed_fractions`); against the amplitude ratio at
    each of ``marked_speeds``, up to the largest of ``ratios`` (below 1: Kostek's
    model has no hop), from the least ratio that reaches that speed (a = 2 pi U,
    where phi = 1 exactly; beyond his model, from 0)."""
    ratios_ = np.asarray(ratios, dtype=float)
    marked = np.asarray(marked_speeds, dtype=float)
    if points < 2 or ratios_.size == 0 or marked.size == 0:
        raise ParameterError("points", points, "need at least 2 points, one ratio and one speed")
    amplitudes = np.linspace(0.0, float(np.max(ratios_)), points)
    closed = _closed_form(params, np.concatenate([ratios_, amplitudes]))
    speeds, by_speed = _against_speed(params, frequency, ratios_, points, closed)
    ratios_by_speed, by_amplitude = _against_ratio(params, frequency, marked, amplitudes, closed)
    return ReductionCurves(params, frequency, ratios_, speeds, by_speed, marked, ratios_by_speed, by_amplitude,
                           closed)


__all__ = ["BISECTIONS", "LOMAKIN", "LOMAKIN_FREQUENCY", "ReductionCurves", "apparent_friction_ratio",
           "reduction_curves", "runaway_ratio", "speed_fractions"]
