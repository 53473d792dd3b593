"""The inner loop of a controller that works through a resonant exciter: the
drive level that brings the slideway's vibration to the amplitude the outer
loop asks for, and optionally the drive frequency that holds it at resonance
(numpy only, no ROS).

The outer loop is today's mean-speed law (:mod:`friction_sim.core.control.law`):
the mean speed asked for gives, through U's inverse, the excitation force Pa,
so the slideway's normal acceleration amplitude Pa/m.  A drive level cannot
set that amplitude at once: the slideway is a lightly damped oscillator, its
envelope follows a change of drive over 1/(zeta*omega_n) (7.7 periods at f_n =
52 Hz, zeta = 0.02, 50 Hz), and off resonance it beats at |f_d - f|, so a step
of the drive overshoots the envelope by up to exp(-zeta*omega_n*pi/|omega_d -
omega|) (about 27 % of the mean-speed step in that case).

So the loop predicts the slideway exactly with the controller's model of the
exciter (f_n, zeta, A, through the core's own exciter functions,
:mod:`friction_sim.core.physics.exciter`): at each period boundary (drive phase
a whole turn, the slider's mean_velocity stamp) it knows the slideway's state
(q, q') from the drive levels it applied.  It plans the next two periods'
levels so that the slideway comes near the steady motion of a reference level
two periods on (two real unknowns: least squares on the state, pulled toward
the reference's own level by :data:`REGULARIZATION`), applies the first and
plans again at the next boundary.  The reference moves from the level in
force toward the one asked for by ``smoothing`` of the way per period, so the
envelope rises with hardly any overshoot (0.3: a step of the target settles
within 2 % in about 12 periods on that plant, overshooting 2 %).

A window whose level stepped by more than :data:`LEARNING_STEP` at its start
is not learnt from (when the level took effect the model cannot know), and
:attr:`DriveLoop.steady` tells the outer law when a mean speed measured
answers the amplitude it asked for.  The boundaries are the slider's
mean_velocity stamps, every ``cycles`` drive periods (its mean window).

What the model gets wrong the accelerometer corrects.  Each period's lock-in
reading (:mod:`friction_sim.core.control.lockin`) is compared with the model's
own reading of the motion it predicted for that period, at the same sample
times, so with the model right the two agree to rounding and nothing moves.
Otherwise the measured over the predicted amplitude scales the model's gain
(``gain_ratio``: a wrong A; the model's motion is scaled with it, so the gain
learnt is not mistaken for a transient), and the difference of lag moves the
model's steady lag, whose natural frequency (tan(lag) = 2 zeta r/(1 - r**2),
r = f/f_n, for the model's zeta) the model takes at a rate
:data:`LAG_LEARNING` times :func:`lag_sensitivity`: near resonance the lag
tells f_n sharply, far from it hardly at all, and a noisy reading must not
move f_n far.  Each reading moves the gain and f_n by a bounded amount.
With ``tracking`` the drive frequency moves to the model's natural frequency
by at most :data:`MAX_FREQUENCY_STEP` of itself per period: at resonance the
lag is 90 degrees and the amplitude per unit drive the largest, A, whatever
the load on the slideway.

Each reading is judged against the model the window was planned with (its
f_n and gain, kept with the plan): readings arrive a window or two after the
window they read, and a correction added to what earlier readings had already
moved counted the same error twice (on ROS the drive frequency then swung
+-0.7 Hz around resonance for seconds after a load change).

Figures (test/core/control/test_drive.py, the exact resonant slider in the
loop, drive levels taken at period boundaries): the mean-speed steps of
acceptance case 1 on f_n = 52 Hz, zeta = 0.02 at 50 Hz settle within 2 % in
12 and 12 periods with 1.8 % and 1.4 % overshoot (19 periods, 5 %, with the
levels taking effect half a period late), against 28 and 29 periods and 27 %
and 19 % overshoot for the drive stepped through the steady gain.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from friction_sim.core.control.lockin import MIN_SAMPLES, Vibration, fit_period
from friction_sim.core.engine.transient_kernel import normal_accelerations
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.model.params import SliderParams
from friction_sim.core.physics.exciter import (
    Slideway,
    eigenvalue,
    rebased,
    response,
    slideway_state,
    steady_acceleration,
    steady_slideway,
)
from friction_sim.core.physics.numerics import solve_positive_definite

#: The plan's pull toward the reference's level, relative to its authority over the state: as
#: strong as the state's own pull, so the levels do not swing far from the reference's; a level
#: that takes effect later than planned (a message's way, the plant's tick) then leaves little
#: transient behind (on ROS at 1 kHz ticks 1e-2 rang for 40 periods, 1.0 settles in 13).
REGULARIZATION = 1.0
#: Tracking moves the drive frequency by at most this fraction per period.
MAX_FREQUENCY_STEP = 0.005


def natural_frequency_from_lag(frequency: float, lag: float, damping_ratio: float) -> float:
    """The natural frequency whose steady lag at ``frequency`` is ``lag`` (0 < lag < pi),
    for the damping ratio: r = f/f_n solves r**2 + 2 zeta cot(lag) r - 1 = 0."""
    cot = math.cos(lag) / math.sin(lag)
    r = math.hypot(damping_ratio * cot, 1.0) - damping_ratio * cot
    return frequency / r


#: A reading moves the model's gain by at most this (logarithmic) fraction ...
MAX_GAIN_CORRECTION = 0.05
#: ... and the steady lag it infers by at most this many radians from the model's.
MAX_LAG_CORRECTION = 0.3
#: The fraction of the way to the natural frequency a reading's lag shows that the model goes.
LAG_LEARNING = 0.3
#: A window whose level stepped by more than this fraction at its start is not learnt from.
LEARNING_STEP = 0.05
#: A reading whose lag is further than this [rad] from the model's teaches f_n, not the gain.
LAG_FIRST = 0.05
#: A reading further than this from the model's own (relative amplitude) means the slideway is not steady yet.
AGREEMENT = 0.02


def lag_sensitivity(ratio: float, damping_ratio: float) -> float:
    """How strongly the steady lag tells the natural frequency at r = f/f_n,
    relative to at resonance: zeta*d(lag)/dr = 2 zeta**2 (1 + r**2)/((1 - r**2)**2
    + (2 zeta r)**2), 1 at r = 1.  Off resonance the lag hardly moves with f_n,
    so a reading's noise would move the model's f_n far: it learns slower."""
    detune, quadrature = (1.0 - ratio) * (1.0 + ratio), 2.0 * damping_ratio * ratio
    return 2.0 * damping_ratio * damping_ratio * (1.0 + ratio * ratio) / (detune * detune + quadrature * quadrature)


@dataclass(frozen=True)
class _Planned:
    """A window this loop drove: its start, drive frequency and level, the
    model's slideway over it, and the model's natural frequency and gain ratio
    it was planned with (a reading corrects those, not what later readings
    have made of them already)."""

    t_start: float
    frequency: float
    level: float
    way: Slideway
    natural_frequency: float
    gain_ratio: float


def saturated_level(level: float) -> float:
    """``level`` within the exciter's drive range (:data:`spec.DRIVE_LEVEL`'s bounds,
    [0, 1]): the saturation of a level a controller worked out, the least and the most
    the actuator can be driven at; not a check of an input (those are refused at the
    edge, as the slider's drive_level command and parameter are)."""
    return min(max(level, _LEAST_LEVEL), _MOST_LEVEL)


def _drive_range() -> tuple[float, float]:
    low, high = spec.DRIVE_LEVEL.low, spec.DRIVE_LEVEL.high
    assert low is not None and high is not None, "a drive level is bounded both ways"
    return float(low), float(high)


_LEAST_LEVEL, _MOST_LEVEL = _drive_range()


def _limited(value: float, limit: float) -> float:
    """``value`` within +-``limit``."""
    return min(max(value, -limit), limit)


def _close(a: float, b: float) -> bool:
    """Equal to a few parts in 1e9 (times and levels computed the same way twice)."""
    return abs(a - b) <= 1e-9 * max(1.0, abs(a), abs(b))


class DriveLoop:
    """Drive level (and frequency, with tracking) per period, from the amplitude
    wanted and the lock-in's readings (see the module doc).  ``model`` is the
    controller's model of the plant, as the outer law's: its natural_frequency,
    damping_ratio and full_drive_acceleration are the exciter's data sheet."""

    def __init__(self, model: SliderParams, frequency: float, drive_level: float, *, smoothing: float = 0.3,
                 correction_gain: float = 0.1, tracking: bool = False, cycles: int = 1) -> None:
        self.model = model
        #: Drive periods between two boundaries (the slider's mean_window_periods).
        self.cycles = int(spec.MEAN_WINDOW_PERIODS.check(cycles))
        self.frequency = float(spec.EXCITATION_FREQUENCY.check(frequency))
        #: The level in force: ``drive_level`` (a level in the drive range: one this runtime
        #: saturated, or the plant's, checked where it was read), then each boundary's.
        self.drive_level = drive_level
        self.smoothing, self.correction_gain, self.tracking = smoothing, correction_gain, tracking
        #: Measured over modelled amplitude per unit drive (1: the model is right).
        self.gain_ratio = 1.0
        #: The natural frequency the readings show (the model's until a steady period is read).
        self.natural_frequency = model.natural_frequency
        self._response_key: tuple[float, float, float] | None = None
        self._response_value = (math.nan, math.nan)
        self._reference = self._amplitude(self.drive_level)  # [m/s^2]: a frequency move keeps its meaning
        self._way = steady_slideway(self._amplitude(self.drive_level), self._lag(), self._omega(), self._lam())
        self._planned: list[_Planned] = []
        self._last_boundary: float | None = None
        #: Boundaries in a row with the same amplitude asked for and the reference on it (see :attr:`steady`).
        self._steady_boundaries = 0
        self._asked = math.nan

    # -- the model in force -----------------------------------------------------------

    def _response(self) -> tuple[float, float]:
        """The model's resonance curve at the frequency in force (kept while neither frequency
        moves: a boundary's plan asks for it a dozen times, and it costs an exact hypot)."""
        key = (self.frequency, self.natural_frequency, self.model.damping_ratio)
        if key != self._response_key:
            self._response_key, self._response_value = key, response(*key)
        return self._response_value

    def _lag(self) -> float:
        return self._response()[1]

    def _omega(self) -> float:
        return TWO_PI * self.frequency

    def _lam(self) -> complex:
        return eigenvalue(self.natural_frequency, self.model.damping_ratio)

    def _amplitude(self, level: float) -> float:
        """The steady normal acceleration amplitude [m/s^2] the model gives at drive ``level``."""
        return steady_acceleration(level, self.model.full_drive_acceleration, self._response()[0]) * self.gain_ratio

    @property
    def full_drive_amplitude(self) -> float:
        """The steady amplitude [m/s^2] at full drive (level 1) by the model in force,
        its gain and f_n as the accelerometer taught them: the most the actuator gives."""
        return self._amplitude(1.0)

    def level_for(self, amplitude: float) -> float:
        """The drive level whose steady amplitude is ``amplitude`` [m/s^2] (unclamped)."""
        return amplitude / self._amplitude(1.0)

    # -- one period boundary ----------------------------------------------------------

    def boundary(self, t: float, wanted_amplitude: float, readings: list[Vibration]) -> tuple[float, float]:
        """At the boundary ``t`` (drive phase a whole turn, the end of a window of
        :attr:`cycles` periods): take the readings of windows that have ended,
        then decide the (drive level, frequency) for the coming window, the
        level in [0, 1].  The time since the previous boundary is what the
        level in force drove (a boundary missed, a lost sample, is one long window)."""
        for reading in readings:
            self._correct(reading)
        span = self.cycles / self.frequency
        elapsed = t - self._last_boundary if self._last_boundary is not None and t > self._last_boundary else span
        self._last_boundary = t
        if self.tracking:
            self._track()
        reachable = min(max(wanted_amplitude, 0.0), self.full_drive_amplitude)
        self._reference += self.smoothing * (reachable - self._reference)
        near = abs(reachable - self._reference) <= 1e-2 * max(reachable, 1e-12)
        asked_before, self._asked = self._asked, wanted_amplitude
        self._steady_boundaries = self._steady_boundaries + 1 if near and wanted_amplitude == asked_before else 0
        level = saturated_level(self._plan(elapsed, self.cycles / self.frequency))
        self._way = self._driven(self._way, elapsed, level)
        self.drive_level = level
        if self._planned and t < self._planned[-1].t_start:  # (time went back: those windows are of no reading now)
            self._planned = []
        self._planned = [*self._planned[-63:], _Planned(t, self.frequency, level, self._way, self.natural_frequency,
                                                        self.gain_ratio)]
        return level, self.frequency

    @property
    def steady(self) -> bool:
        """Whether the slideway's amplitude is where the outer loop asked: the same
        amplitude has been asked for, the reference within 1 % of it and the
        readings within :data:`AGREEMENT` of the model's, since two windows (the
        plan's horizon) and one
        time constant 1/(zeta omega_n) of the slideway ago (what the plan leaves
        of a transient, from a level that took effect later than planned, has
        decayed by e then).  Until then a mean speed measured is not yet the
        answer to the amplitude asked for."""
        decay = self.frequency / (TWO_PI * self.model.damping_ratio * self.natural_frequency)
        return self._steady_boundaries > 2 + math.ceil(decay / self.cycles)

    def set_frequency(self, frequency: float) -> None:
        """The drive frequency was set from outside (a command, the plant's
        parameter): the coming windows are planned at it.  The model's motion in
        the window under way keeps the frequency it was planned at; what that
        misses, the next readings correct."""
        self.frequency = float(spec.EXCITATION_FREQUENCY.check(frequency))

    def _driven(self, way: Slideway, tau: float, level: float) -> Slideway:
        """The slideway ``tau`` into ``way``, from then on driven at ``level`` (model in force)."""
        return rebased(way, 0.0, tau, self._amplitude(level), self._lag(), self._omega(), self._lam())

    def _state(self, way: Slideway, tau: float) -> tuple[float, float]:
        """(omega*q, q') at a boundary: both in m/s, so neither dominates the plan's least squares."""
        q, velocity, _ = slideway_state(way, 0.0, tau)
        return self._omega() * q, velocity

    def _plan(self, elapsed: float, period: float) -> float:
        """The first of two drive levels that put the slideway into the reference's
        steady motion two periods on (an affine map of the two levels, solved);
        ``elapsed`` is the period that just ended, ``period`` the coming ones."""
        def after(ended: Slideway, second: float) -> tuple[float, float]:
            return self._state(self._driven(ended, period, second), period)

        at_rest = self._driven(self._way, elapsed, 0.0)  # (the first period at level 0, for two of the three)
        origin = after(at_rest, 0.0)
        by_first, by_second = after(self._driven(self._way, elapsed, 1.0), 0.0), after(at_rest, 1.0)
        a0, a1 = by_first[0] - origin[0], by_first[1] - origin[1]  # the map's columns: what each level moves
        b0, b1 = by_second[0] - origin[0], by_second[1] - origin[1]
        goal = self._state(steady_slideway(self._reference, self._lag(), self._omega(), self._lam()), 0.0)
        r0, r1 = goal[0] - origin[0], goal[1] - origin[1]
        level = self.level_for(self._reference)
        # Least squares with a small pull toward the reference's level: near resonance the two
        # levels push the state along nearly one direction, and the other (a phase error) is
        # left to decay by itself rather than chased with levels of opposite extremes.  The
        # 2x2 normal equations are solved in plain floats: the same levels on every CPU.
        fsum = math.fsum
        weight = REGULARIZATION * fsum((a0 * a0, a1 * a1, b0 * b0, b1 * b1))
        normal = ((fsum((a0 * a0, a1 * a1)) + weight,), (fsum((a0 * b0, a1 * b1)), fsum((b0 * b0, b1 * b1)) + weight))
        rhs = (fsum((a0 * r0, a1 * r1)) + weight * level, fsum((b0 * r0, b1 * r1)) + weight * level)
        solution = solve_positive_definite(normal, rhs)
        if solution is None:  # no authority over the state (a zero gain)
            return level
        return solution[0] if math.isfinite(solution[0]) else level

    # -- what the accelerometer says ----------------------------------------------------

    def _correct(self, reading: Vibration) -> None:
        """A reading of a period this loop drove, against the model's own reading
        of that period at the same sample times (its predicted motion, transient
        included): the measured over the predicted amplitude shows the gain ratio,
        and the difference of lag the steady lag, so the natural frequency, of
        the plant (each against the model the window was planned with); the
        model moves toward them (see the module doc), by at most
        :data:`MAX_GAIN_CORRECTION` and :data:`MAX_LAG_CORRECTION` per reading.
        With the model right the two readings agree to rounding and nothing moves."""
        index = self._planned_index(reading)
        if index is None or len(reading.times) < MIN_SAMPLES or not reading.amplitude > 0.0 or self._stepped(index):
            return
        planned = self._planned[index]
        normal = normal_accelerations(planned.way, planned.frequency, planned.t_start, reading.times)
        expected = fit_period(reading.times, normal, reading.t_start, reading.t_end, reading.cycles)
        if not expected.amplitude > 0.0:
            return
        if abs(reading.amplitude / expected.amplitude - 1.0) > AGREEMENT:
            self._steady_boundaries = 0  # the plant is not where the model put it (a load, a wrong model)
        driven = planned.frequency
        lag_error = math.remainder(reading.lag - expected.lag, TWO_PI)
        steady_lag = response(driven, planned.natural_frequency, self.model.damping_ratio).lag + _limited(
            lag_error, MAX_LAG_CORRECTION)
        if 0.0 < steady_lag < math.pi:
            natural = natural_frequency_from_lag(driven, steady_lag, self.model.damping_ratio)
            rate = LAG_LEARNING * lag_sensitivity(driven / self.natural_frequency, self.model.damping_ratio)
            self.natural_frequency += _limited(rate * (natural - self.natural_frequency),
                                               MAX_FREQUENCY_STEP * self.natural_frequency)
        if abs(lag_error) > LAG_FIRST:
            return  # f_n is off: the amplitude's error is mostly the resonance curve's, not the gain's
        shown = planned.gain_ratio * reading.amplitude / expected.amplitude  # the gain ratio the reading shows
        factor = math.exp(_limited(self.correction_gain * math.log(shown / self.gain_ratio), MAX_GAIN_CORRECTION))
        self.gain_ratio *= factor
        # The motion of a linear slideway scales with its gain: the model's own motion, transient and all,
        # scales with it, so a gain learnt is not taken for a transient the plan would then chase.
        way = self._way
        self._way = way._replace(amplitude=way.amplitude * factor, d=way.d * factor)

    def _stepped(self, index: int) -> bool:
        """Whether the level stepped by more than :data:`LEARNING_STEP` at the start of
        the window ``self._planned[index]``: when exactly a level takes effect at the plant
        (a message's way, the plant's tick) the model cannot know, and the error of that
        moment, times the step, would be learnt as a wrong gain or f_n.  Such windows teach nothing."""
        if index == 0:
            return False
        level, before = self._planned[index].level, self._planned[index - 1].level
        return abs(level - before) > LEARNING_STEP * max(level, before)

    def level_of(self, reading: Vibration) -> float | None:
        """The drive level this loop drove ``reading``'s window at (None: not one of its last 64)."""
        index = self._planned_index(reading)
        return self._planned[index].level if index is not None else None

    def _planned_index(self, reading: Vibration) -> int | None:
        """Where in ``self._planned`` the period this loop drove that ``reading`` is of
        lies (the first such: a boundary taken twice plans twice), None: not one of the last 64.
        The boundaries come in time order (a stamp before the last restarts the loop), so the
        windows are searched from the newest back, down to the first that starts too early."""
        start = reading.t_start
        found = None
        for index in range(len(self._planned) - 1, -1, -1):
            planned_start = self._planned[index].t_start
            if _close(planned_start, start):
                found = index
            elif planned_start < start:
                break
        return found

    def _track(self) -> None:
        """Move the drive frequency toward the natural frequency (lag 90 degrees)."""
        target = self.frequency + _limited(self.natural_frequency - self.frequency,
                                           MAX_FREQUENCY_STEP * self.frequency)
        if target != self.frequency:
            self.frequency = float(spec.EXCITATION_FREQUENCY.check(target))


__all__ = [
    "AGREEMENT", "LAG_FIRST", "LAG_LEARNING", "LEARNING_STEP", "MAX_FREQUENCY_STEP", "MAX_GAIN_CORRECTION",
    "MAX_LAG_CORRECTION", "REGULARIZATION", "DriveLoop", "lag_sensitivity", "natural_frequency_from_lag",
    "saturated_level",
]
