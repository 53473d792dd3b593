"""The mean conveying speed of the general model (issue 11), for any parameters.

Kostek's model (normal excitation, level track, one friction coefficient,
Pa below the load) has the exact closed-form map of
:mod:`friction_sim.core.meanspeed.urelation`; :func:`mean_speed` returns that value,
bit for bit, whenever it applies (``exact`` is then True).  Everywhere else
(an inclined vibration, a slope, mu_s > mu, a hopping slider) there is no
closed form for the mean speed, but there is an exact motion: the slider
core (:class:`~friction_sim.core.engine.single.Slider`) follows it event by event.
The mean speed is read off it like this:

* Start at rest at phase 0 and look at the state at every period start
  n/f: mode, tangential speed v, height z and normal speed vz.  That state
  decides the whole future motion (x only shifts it), so once it repeats
  after k periods the motion is periodic with k periods from there on.
* A repeat is a match of v, z and vz to :data:`STATE_TOLERANCE` of the
  plant's own scales (acceleration scale A over omega, over omega^2) and an
  equal mode, held for a whole repeat (k consecutive period starts, two at
  least).  k runs up to :data:`MAX_PERIOD_MULTIPLE`: 1 is the ordinary
  periodic motion, 2 a period-doubled one, and so on.  The check runs from
  the start, so a motion that settles after three periods costs five, not
  ``settle_periods``; ``settle_periods`` is the most it may take.
* The mean speed of a periodic motion is its travel over the last k periods
  divided by k/f: exact to rounding, like the core.
* A motion that does not repeat within ``settle_periods`` (irregular, or
  still settling) is averaged over ``periods`` more, and the record says so
  (``periodic`` False, ``period_multiple`` 0).  A slider that accelerates
  without bound (the period-start speed keeps growing by steady steps and it
  never sticks: the drive beats the friction on average; see
  :func:`_runs_away`) has ``runaway`` True and an infinite U, as the closed
  form has beyond phi = 1.

U is nondimensional, U = V*f/(g*mu) with the plant's own g (not an effective
one), so it depends on the force ratios, the angles, mu, mu_s/mu, e and the
landing rule only: :func:`u_general` evaluates it over arrays of the
paper's groups phi = Fd/(mu*m*g) and a = Pa/(m*g).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.urelation import kostek_prediction, moves, stop_phase_advance, u_map
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import (
    TWO_PI,
    amplitude_for,
    drive_force_for,
    nondimensional_speed,
)
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.model.records import share
from friction_sim.core.physics.plant import closed_form_applies, kostek_applies
from friction_sim.errors import ParameterError

#: The most periods a simulated motion may take to settle before it is averaged as it is.
DEFAULT_SETTLE_PERIODS = int(spec.SETTLE_PERIODS.default)
#: The periods an irregular (non-repeating) motion is averaged over after settling.
DEFAULT_PERIODS = int(spec.PERIODS.default)
#: The longest repeat looked for, in excitation periods.
MAX_PERIOD_MULTIPLE = 16
#: Period-start states match when v, z and vz agree to this fraction of the
#: plant's speed scale A/omega and height scale A/omega^2 (A: the largest
#: acceleration the forces can give).  The core repeats a periodic state to
#: rounding (1e-16); a motion converging geometrically passes it once its
#: remaining transient is this small, which moves the mean speed by as little.
STATE_TOLERANCE = 1e-11
#: The frequency [Hz] :func:`u_general` simulates at (U does not depend on it).
REFERENCE_FREQUENCY = float(spec.EXCITATION_FREQUENCY.default)


@dataclass(frozen=True)
class MeanSpeed:
    """The long-run mean conveying speed of one plant under constant inputs.

    u: nondimensional mean speed U = V*f/(g*mu) (g the plant's gravity);
    mean_velocity: V [m/s] (+-inf for a runaway);
    periodic: the motion repeats (then the mean is exact to rounding);
    period_multiple: its period in excitation periods (1, 2, ...; 0 if not periodic);
    settle_periods: excitation periods before the averaging window;
    periods: excitation periods averaged over;
    flight_fraction, stick_fraction: time off the track, time stuck, over the window;
    exact: True when the value comes from the closed-form Kostek map (no simulation);
    runaway: the slider accelerates without bound (U = +-inf).
    """

    u: float
    mean_velocity: float
    periodic: bool
    period_multiple: int
    settle_periods: int
    periods: int
    flight_fraction: float
    stick_fraction: float
    exact: bool
    runaway: bool = False


def mean_speed(params: SliderParams, inputs: Inputs, *, settle_periods: int = DEFAULT_SETTLE_PERIODS,
               periods: int = DEFAULT_PERIODS, max_multiple: int = MAX_PERIOD_MULTIPLE,
               simulate: bool = False) -> MeanSpeed:
    """The mean speed of ``params`` under constant ``inputs`` (see the module doc).

    The closed form where it applies (unless ``simulate`` forces the
    simulation, for checks); otherwise the exact motion from rest at phase 0,
    periodic within ``settle_periods`` (repeats up to ``max_multiple``
    periods), else averaged over ``periods`` after them.
    """
    settle_periods = int(spec.SETTLE_PERIODS.check(settle_periods))
    periods = int(spec.PERIODS.check(periods))
    max_multiple = _count("max_multiple", max_multiple, 1)
    if not simulate and closed_form_applies(params, inputs):
        return _closed_form(params, inputs)
    return _simulated(params, inputs, settle_periods, periods, max_multiple)


def _count(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ParameterError(name, value, f"must be an integer >= {low}")
    return int(value)


def _closed_form(params: SliderParams, inputs: Inputs) -> MeanSpeed:
    prediction = kostek_prediction(params, inputs)
    assert prediction is not None  # closed_form_applies said so
    runaway = math.isinf(prediction.u)
    # U with the plant's g: the map's U uses the effective gravity g - Fz/m (exactly g when Fz = 0)
    u = prediction.u if inputs.external_force_z == 0.0 else prediction.u * prediction.effective_gravity / params.gravity
    return MeanSpeed(u=u, mean_velocity=prediction.mean_velocity, periodic=not runaway,
                     period_multiple=0 if runaway else 1, settle_periods=0, periods=1, flight_fraction=0.0,
                     stick_fraction=_closed_form_stick(prediction.effective_phi, prediction.effective_amplitude_ratio),
                     exact=True, runaway=runaway)


def _closed_form_stick(phi: float, a: float) -> float:
    """The stuck fraction of the closed-form motion: 1 - psi_C/(2*pi)."""
    if not moves(phi, a):
        return 1.0
    if abs(phi) >= 1.0:
        return 0.0
    return 1.0 - float(stop_phase_advance(phi, a)) / TWO_PI


class _Start:
    """What is kept of the state at one period start."""

    __slots__ = ("x", "v", "z", "vz", "mode", "stuck", "flight")

    def __init__(self, slider: Slider) -> None:
        state = slider.state()
        self.x, self.v, self.z, self.vz, self.mode = state.x, state.v, state.z, state.vz, state.mode
        self.stuck = slider.stuck_time
        self.flight = slider.flight_time


def _scales(params: SliderParams, inputs: Inputs) -> tuple[float, float]:
    """The tolerances on speed and height at which two period-start states match."""
    amplitude = inputs.excitation_amplitude
    forces = (params.weight + amplitude * (1.0 + abs(params.tangential_ratio)) + abs(inputs.tangential_force)
              + abs(inputs.external_force_z))
    omega = TWO_PI * inputs.excitation_frequency
    speed = forces / params.mass / omega
    return STATE_TOLERANCE * speed, STATE_TOLERANCE * speed / omega


def _same(p: _Start, q: _Start, tol_v: float, tol_z: float) -> bool:
    return (p.mode == q.mode and abs(p.v - q.v) <= tol_v and abs(p.z - q.z) <= tol_z
            and abs(p.vz - q.vz) <= tol_v)


def _simulated(params: SliderParams, inputs: Inputs, settle_periods: int, periods: int,
               max_multiple: int) -> MeanSpeed:
    frequency = inputs.excitation_frequency
    slider = Slider(params, inputs, event_log_size=0)
    tol_v, tol_z = _scales(params, inputs)
    starts = [_Start(slider)]
    runs = [0] * (max_multiple + 1)  # runs[k]: consecutive period starts matching the one k before
    for n in range(1, settle_periods + 1):
        slider.advance_to(n / frequency)
        now = _Start(slider)
        starts.append(now)
        for k in range(1, min(max_multiple, n) + 1):
            runs[k] = runs[k] + 1 if _same(now, starts[n - k], tol_v, tol_z) else 0
            if runs[k] >= max(k, 2):
                return _window(params, inputs, starts, n - k, k, periodic=True)
    for n in range(settle_periods + 1, settle_periods + periods + 1):
        slider.advance_to(n / frequency)
        starts.append(_Start(slider))
    return _window(params, inputs, starts, settle_periods, periods, periodic=False)


def _window(params: SliderParams, inputs: Inputs, starts: list[_Start], first: int, count: int,
            *, periodic: bool) -> MeanSpeed:
    """The means over period starts ``first`` .. ``first + count``."""
    frequency = inputs.excitation_frequency
    begin, end = starts[first], starts[first + count]
    duration = count / frequency
    velocity = (end.x - begin.x) / duration
    runaway = not periodic and _runs_away(starts[first:first + count + 1])
    if runaway:
        velocity = math.copysign(math.inf, end.v)
    return MeanSpeed(
        u=nondimensional_speed(velocity, frequency, params.gravity, params.mu), mean_velocity=velocity,
        periodic=periodic,
        period_multiple=count if periodic else 0, settle_periods=first, periods=count,
        flight_fraction=share(end.flight - begin.flight, duration),
        stick_fraction=share(end.stuck - begin.stuck, duration),
        exact=False, runaway=runaway,
    )


def _runs_away(window: list[_Start]) -> bool:
    """True when the speed grows without bound over the window: the slider
    never sticks in it, and the mean speeds of its four quarters grow
    steadily in the direction of motion (each step at least half the first,
    all together at least a quarter of the last), as they do under a
    constant mean acceleration; an irregular but bounded motion, or one
    still settling, does not do that."""
    count = len(window) - 1
    if count < 4 or window[-1].stuck != window[0].stuck:
        return False
    cuts = [window[round(count * k / 4)] for k in range(5)]
    means = [(q.x - p.x) / (round(count * (k + 1) / 4) - round(count * k / 4))
             for k, (p, q) in enumerate(itertools.pairwise(cuts))]
    steps = [b - a for a, b in itertools.pairwise(means)]
    sign = math.copysign(1.0, means[-1])
    return (means[-1] != 0.0 and all(sign * step > 0.0 for step in steps)
            and all(abs(step) >= 0.5 * abs(steps[0]) for step in steps)
            and abs(means[-1] - means[0]) >= 0.25 * abs(means[-1]))


@dataclass(frozen=True)
class MeanSpeedGrid:
    """:func:`u_general` with ``details``: per point, U and what kind of motion gave it."""

    u: NDArray[np.float64]
    period_multiple: NDArray[np.int64]
    flight_fraction: NDArray[np.float64]
    exact: NDArray[np.bool_]
    runaway: NDArray[np.bool_]
    stick_fraction: NDArray[np.float64]

    @property
    def periodic(self) -> NDArray[np.bool_]:
        """Where the motion repeats (and the mean is exact to rounding)."""
        result: NDArray[np.bool_] = self.period_multiple > 0
        return result

    @staticmethod
    def of(results: Sequence[MeanSpeed]) -> MeanSpeedGrid:
        """The grid of mean speeds computed one by one (:func:`mean_speed`), in their order."""
        return MeanSpeedGrid(u=np.array([r.u for r in results]),
                             period_multiple=np.array([r.period_multiple for r in results], dtype=np.int64),
                             flight_fraction=np.array([r.flight_fraction for r in results]),
                             exact=np.array([r.exact for r in results], dtype=bool),
                             runaway=np.array([r.runaway for r in results], dtype=bool),
                             stick_fraction=np.array([r.stick_fraction for r in results]))


def u_general(phi: ArrayLike, a: ArrayLike, model: SliderParams | None = None, *,
              frequency: float = REFERENCE_FREQUENCY, settle_periods: int = DEFAULT_SETTLE_PERIODS,
              periods: int = DEFAULT_PERIODS, details: bool = False) -> Any:
    """U(phi, a) for the plant ``model`` (default: Kostek's), over arrays.

    phi = Fd/(mu*m*g) and a = Pa/(m*g) broadcast together; U = V*f/(g*mu).
    Where the closed form applies (:func:`closed_form_applies`) the values
    are :func:`~friction_sim.core.meanspeed.urelation.u_map`'s, bit for bit and in one
    call; elsewhere each point is a :func:`mean_speed`.  Returns a float for
    scalars, else an array; with ``details`` a :class:`MeanSpeedGrid`.
    """
    params = model if model is not None else SliderParams()
    phi_arr, a_arr = np.broadcast_arrays(np.asarray(phi, float), np.asarray(a, float))
    bad = ~(np.isfinite(phi_arr) & np.isfinite(a_arr) & (a_arr >= 0.0))
    if np.any(bad):
        where = np.argwhere(bad)[0]
        field, value = ("phi", phi_arr) if not np.isfinite(phi_arr[tuple(where)]) else ("amplitude_ratio", a_arr)
        raise ParameterError(field, float(value[tuple(where)]), "must be finite (and the ratio >= 0)")
    u = np.empty(phi_arr.shape)
    multiple = np.ones(phi_arr.shape, dtype=np.int64)
    flight = np.zeros(phi_arr.shape)
    stick = np.zeros(phi_arr.shape)
    runaway = np.zeros(phi_arr.shape, dtype=bool)
    # the closed form's rule, for these amplitudes (no external force)
    exact = np.asarray(kostek_applies(params.excitation_angle, params.track_inclination, params.static_ratio,
                                      amplitude_for(a_arr, params.weight), params.weight, 0.0))
    if np.any(exact):
        u[exact] = u_map(phi_arr[exact], a_arr[exact])
        runaway[exact] = np.isinf(u[exact])
        multiple[exact] = np.where(runaway[exact], 0, 1)
        if details:
            for index in zip(*np.nonzero(exact)):
                stick[index] = _closed_form_stick(float(phi_arr[index]), float(a_arr[index]))
    weight = params.weight
    for index in np.ndindex(phi_arr.shape):
        if exact[index]:
            continue
        inputs = Inputs(drive_force=drive_force_for(float(phi_arr[index]), params.mu, weight),
                        excitation_amplitude=amplitude_for(float(a_arr[index]), weight), excitation_frequency=frequency)
        result = mean_speed(params, inputs, settle_periods=settle_periods, periods=periods)
        u[index], multiple[index], flight[index] = result.u, result.period_multiple, result.flight_fraction
        runaway[index], stick[index] = result.runaway, result.stick_fraction
    if details:
        return MeanSpeedGrid(u=u, period_multiple=multiple, flight_fraction=flight, exact=exact, runaway=runaway,
                             stick_fraction=stick)
    if np.ndim(phi) == 0 and np.ndim(a) == 0:
        return float(u)
    return u


__all__ = [
    "DEFAULT_PERIODS", "DEFAULT_SETTLE_PERIODS", "MAX_PERIOD_MULTIPLE", "MeanSpeed", "MeanSpeedGrid",
    "STATE_TOLERANCE", "mean_speed", "u_general",
]
