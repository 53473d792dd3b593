"""The exact, event-driven core (no ROS, numpy only).

The slider follows the general model of :mod:`friction_sim.core.motion`
(flight, inclined vibration, a sloped track, static friction) on its general
segments, and Kostek's model, the default special case described below, on
the fast segments of :mod:`friction_sim.core.kostek`; it switches between
them whenever a change of parameters or inputs makes the other apply.

Model (R. Kostek): a rigid slider of mass m on a slideway with one Coulomb
friction coefficient mu, pushed by a tangential force Ft = Fd + Fx and unloaded
by a normal harmonic force, so that the normal reaction is

    R(t) = m*g - Fz - Pa*sin(theta(t)),   d(theta)/dt = 2*pi*f   (Fz > 0 lifts).

Stuck (v = 0) while |Ft| <= mu*R; slipping, m*dv/dt = Ft - mu*R*sign(v).

Between two events every quantity has a closed form, because the acceleration
is a constant plus a sinusoid.  Writing s = +-1 for the slip direction and
w = s*v >= 0 for the speed, over a slip that starts at (t0, x0, w0, theta0):

    w(tau)  = w0 + B0*tau + (B1/omega)*(cos(theta0) - cos(theta0 + omega*tau))
    B0 = (s*Ft - mu*(m*g - Fz)) / m,   B1 = mu*Pa/m >= 0

and x is its integral.  Events are the roots of simple equations:

* stick -> slip: |Ft| rises above mu*R, i.e. Pa*sin(theta) > m*g - Fz - |Ft|/mu,
  solved in closed form with asin;
* slip -> stick or reversal: w returns to 0.  w is monotone between the zeros
  of w' = B0 + B1*sin(theta), so the root is bracketed on the first falling
  stretch that ends at or below zero (found in closed form, because the minima
  of w grow by exactly B0*T from one period to the next) and polished with a
  Newton iteration guarded by bisection.

So there is no step size anywhere, a stuck slider does not creep (x is held,
not integrated), and because a segment is evaluated from its own start, how the
time axis is cut into :meth:`Slider.advance_to` calls does not change the
result.  Every slip from rest at the same phase with the same inputs is the same
slip, which is why the periodic regime is cheap: its stop time is cached.

The design follows scipy's ``_ivp`` solvers: one object owns the state and
advances it; detecting the next event (:func:`next_slip_start`,
:func:`slip_stop_delay`) is kept apart from acting on it
(:meth:`Slider._apply`); results come back as typed records
(:class:`SliderState`, :class:`Event`, :class:`Trajectory`).
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from friction_sim.core.events import MODES as _MODES
from friction_sim.core.events import CycleMark, Event, EventKind, Mode, SliderState, Trajectory
from friction_sim.core.kostek import KostekPlant, KostekSegment
from friction_sim.core.motion import FLIGHT, NEVER_STEP, STUCK, GeneralPlant, Motion, Step, next_step
from friction_sim.core.params import Inputs, SliderParams, require_finite
from friction_sim.core.roots import (
    NEVER,
    TWO_PI,
    can_ever_slip,
    next_slip_start,
    reduce_phase,
    slip_stop_delay,
    two_sum,
)
from friction_sim.errors import ParameterError, SimulationFault

#: Slip stops kept per slider (one per phase a slip from rest starts at).
_CACHE_LIMIT = 256
#: The latest time [s] a slider runs to (2**53 s, 285 million years, far beyond
#: the end of ROS 2 time at 2**31 s) and the largest |x0| [m]: together with the
#: ranges of core/spec.py they keep every state finite (the fastest accepted
#: slider, at 2e12 m/s^2, covers 1e44 m by then).
MAX_TIME = 2.0**53
#: More events than this at one instant means the general model made no
#: progress (a rounding case its guards missed): the slider raises a
#: SimulationFault instead of looping for ever.  A real instant has at most a
#: handful (a landing, a lift-off at once, a slip onset).
MAX_EVENTS_AT_ONE_INSTANT = 1000
MAX_POSITION = 1e100


class _Checkpoint:
    """A slider as it was (:meth:`Slider.checkpoint`), to put back if taking a change fails.

    The core's attributes are saved by reference (its records are immutable);
    its dicts are copied (a few entries); of its deques (the event and period
    logs, thousands of entries) only the last entry is remembered, and on
    restore whatever was appended after it is popped.  That costs about a
    microsecond, where copying the logs would cost twenty at every command.
    """

    __slots__ = ("attributes", "tails")

    def __init__(self, slider: Slider) -> None:
        self.attributes = dict(vars(slider))
        self.tails: dict[str, Any] = {}
        for name, value in self.attributes.items():
            if isinstance(value, (dict, list, set)):
                self.attributes[name] = value.copy()
            elif isinstance(value, deque):
                self.tails[name] = value[-1] if value else None

    def restore(self, slider: Slider) -> None:
        for name, tail in self.tails.items():
            log: deque[Any] = self.attributes[name]
            while log and log[-1] is not tail:
                log.pop()
        vars(slider).clear()
        vars(slider).update(self.attributes)


# --------------------------------------------------------------------------
# The slider: owns the state, advances it event by event.
# --------------------------------------------------------------------------


class Slider:
    """One slider, advanced exactly in time.

    >>> slider = Slider()                 # the paper's Fig. 2 case
    >>> events = slider.advance_to(0.1)   # five excitation periods
    >>> round(slider.state().x * 1e6, 2)  # micrometres travelled
    19.97

    Inputs and parameters may change between calls; the change takes effect at
    the current time (:attr:`t`).  ``event_log_size`` bounds :attr:`events`
    (``None``: unbounded) so a slider that runs for hours keeps constant memory;
    :attr:`event_counts` always counts every event.  With ``cycle_log_size``
    other than 0 the slider also keeps a :class:`CycleMark` at the start of every
    excitation period (``None``: all of them), for per-period mean speeds.

    Event times are anchored to the excitation phase: the slider keeps one
    anchor (time ``t_a`` at total phase 2*pi*cycles_a + phase_a), set at the
    start and whenever the frequency changes, and computes the time of every
    event and period start afresh from it, as
    t_a + (cycles - cycles_a)/f + (phase - phase_a)/omega (plus the slip's
    duration for a stop).  Rounding errors therefore do not add up from one
    event to the next: after a million periods a slip still starts within a
    few units in the last place of t of its exact time, wherever the run
    started.
    """

    def __init__(
        self,
        params: SliderParams | None = None,
        inputs: Inputs | None = None,
        *,
        t0: float = 0.0,
        x0: float = 0.0,
        phase0: float = 0.0,
        event_log_size: int | None = 100_000,
        cycle_log_size: int | None = 0,
    ) -> None:
        self._params = params if params is not None else SliderParams()
        self._inputs = inputs if inputs is not None else Inputs()
        self._t = require_finite("t0", t0)
        if abs(self._t) > MAX_TIME:
            raise ParameterError("t0", self._t, f"must be within +-{MAX_TIME:g} s")
        phase, _ = reduce_phase(require_finite("phase0", phase0), 0)  # -1e-300 % 2pi == 2pi
        if event_log_size is not None and not (isinstance(event_log_size, int) and event_log_size >= 0):
            raise ParameterError("event_log_size", event_log_size, "must be an integer >= 0 or None")
        if cycle_log_size is not None and not (isinstance(cycle_log_size, int) and cycle_log_size >= 0):
            raise ParameterError("cycle_log_size", cycle_log_size, "must be an integer >= 0 or None")
        self._events: deque[Event] = deque(maxlen=event_log_size)
        self._counts = {kind: 0 for kind in EventKind}
        self._stuck_time = self._flight_time = 0.0
        self._at_instant = 0
        self._cache: dict[tuple[float, float, float, float, int], tuple[float, Any]] = {}
        self._marks: deque[CycleMark] | None = None
        self._next_mark_n, self._next_mark_t, self._next_mark_s = 1, NEVER, NEVER
        x0 = require_finite("x0", x0)
        if abs(x0) > MAX_POSITION:
            raise ParameterError("x0", x0, f"must be within +-{MAX_POSITION:g} m")
        if cycle_log_size != 0:
            self._marks = deque(maxlen=cycle_log_size)
            if phase == 0.0:
                self._marks.append(CycleMark(0, self._t, x0, 0.0))
        self._seg: KostekSegment | Motion
        self._set_plant(self._params, self._inputs, in_flight=False)
        self._set_anchor(self._t, 0, phase)
        if self._general:
            self._start_motion(self._t, 0.0, x0, 0.0, 0.0, phase, 0, STUCK)
        else:
            self._start_stuck(self._t, 0.0, x0, 0.0, phase, 0)

    # -- read-only views -------------------------------------------------------

    @property
    def t(self) -> float:
        """Current simulation time [s]."""
        return self._t

    @property
    def params(self) -> SliderParams:
        return self._params

    @property
    def inputs(self) -> Inputs:
        return self._inputs

    @property
    def events(self) -> list[Event]:
        """The most recent events, oldest first (bounded by ``event_log_size``)."""
        return list(self._events)

    @property
    def event_counts(self) -> dict[EventKind, int]:
        """How many events of each kind happened since the start."""
        return dict(self._counts)

    @property
    def stuck_time(self) -> float:
        """Total time [s] spent stuck since the start, up to :attr:`t`."""
        seg = self._seg
        return self._stuck_time + (self._t - seg.t0 if seg.direction == 0 else 0.0)

    @property
    def flight_time(self) -> float:
        """Total time [s] spent off the track since the start, up to :attr:`t`."""
        seg = self._seg
        return self._flight_time + (self._t - seg.t0 if seg.direction == FLIGHT else 0.0)

    @property
    def cycle_marks(self) -> list[CycleMark]:
        """The most recent period starts, oldest first (empty unless enabled)."""
        return list(self._marks) if self._marks is not None else []

    def cycle_marks_after(self, n: int) -> list[CycleMark]:
        """The kept period starts with a number above ``n``, oldest first."""
        newer: list[CycleMark] = []
        for mark in reversed(self._marks or ()):
            if mark.n <= n:
                break
            newer.append(mark)
        newer.reverse()
        return newer

    @property
    def next_mark_time(self) -> float:
        """When the next excitation period starts (inf when marks are not kept)."""
        return self._next_mark_t if self._marks is not None else NEVER

    @property
    def next_event_time(self) -> float:
        """When the next event happens under the present inputs (inf: never)."""
        return self._next_t

    def state(self) -> SliderState:
        """The state at the current time :attr:`t`."""
        seg = self._seg
        x, v, acc, friction, normal, theta, *height = seg.evaluate(self._t)
        return SliderState(self._t, x, v, acc, friction, normal, theta % TWO_PI, _MODES[seg.direction], *height)

    # -- advancing -------------------------------------------------------------

    def advance_to(self, t: float) -> list[Event]:
        """Advance exactly to time ``t``; return the events that happened since the
        previous call (a slip that an input change starts at once belongs to
        the next call), up to and including ``t``."""
        if not (self._t <= t <= MAX_TIME):
            raise ParameterError("t", t, f"must be finite, >= the current time {self._t!r} s "
                                         f"and <= {MAX_TIME:g} s")
        happened: list[Event] = []
        while True:
            if self._next_mark_s <= self._next_s:  # by phase: a mark and an event may round to one t
                if self._next_mark_t > t:
                    break
                self._mark_cycle()
            elif self._next_t <= t:
                happened.append(self._apply())
            else:
                break
        self._t = float(t)
        return happened

    def sample(self, times: np.ndarray) -> Trajectory:
        """Advance through ascending ``times`` (>= :attr:`t`) and return the exact
        state at each, evaluated segment by segment with numpy."""
        times = np.asarray(times, dtype=float)
        if times.ndim != 1 or times.size == 0:
            raise ParameterError("times", times.shape, "must be a non-empty 1-d array")
        if times[0] < self._t or np.any(np.diff(times) < 0.0):
            raise ParameterError("times", float(times[0]), f"must ascend from >= {self._t!r} s")
        columns = [np.empty_like(times) for _ in range(7)]
        height: list[np.ndarray] = [np.zeros_like(times), np.zeros_like(times)]
        happened: list[Event] = []
        first = 0
        while first < times.size:
            last = int(np.searchsorted(times, self._next_t, side="left"))
            if last > first:
                seg = self._seg
                values = seg.evaluate(times[first:last], np)
                for column, value in zip(columns[:6] + height, values):
                    column[first:last] = value
                columns[5][first:last] %= TWO_PI
                columns[6][first:last] = seg.direction
                first = last
            if first < times.size:
                happened.extend(self.advance_to(self._next_t))
        happened.extend(self.advance_to(float(times[-1])))
        x, v, acc, friction, normal, phase, mode = columns
        return Trajectory(times, x, v, acc, friction, normal, phase, mode.astype(np.int8), tuple(happened),
                          height[0], height[1])

    # -- changing inputs and parameters ----------------------------------------

    def set_inputs(self, inputs: Inputs | None = None, **changes: Any) -> Inputs:
        """Change the inputs at the current time; the phase stays continuous.

        Pass a whole :class:`Inputs` or field changes (validated as a new
        :class:`Inputs`; a bad value is refused and nothing changes).  Every
        valid combination is followed, including one that lifts the slider off.
        """
        new = (inputs if inputs is not None else self._inputs).replace(**changes)
        self.set_plant(self._params, new)
        return new

    def set_params(self, params: SliderParams) -> None:
        """Change the plant's parameters at the current time."""
        self.set_plant(params, self._inputs)

    def set_plant(self, params: SliderParams, inputs: Inputs) -> None:
        """Change parameters and inputs together at the current time: one new
        segment from the present state (in the air, a flight goes on under
        the new forces).  No combination of valid values is refused."""
        self._rebase(params, inputs)

    def restart(self) -> None:
        """Start again from the initial state at the current time: at rest on
        the track at x = 0, the excitation at phase 0, under the plant and
        inputs in force (what a simulator's reset does; the ``~/reset``
        service).  Time goes on (it never runs backwards), so the motion from
        here is the motion from the start shifted by the current time.  The
        period count goes on too: the period in progress ends here, a new one
        starts (a :class:`CycleMark` at x = 0 when marks are kept), and the
        event counts and logs keep what happened before."""
        seg = self._seg
        tau = self._t - seg.t0
        if seg.direction == 0:
            self._stuck_time += tau
        elif seg.direction == FLIGHT:
            self._flight_time += tau
        cycles = reduce_phase(seg.phase0 + seg.omega * tau, seg.cycles)[1] + 1
        self._at_instant = 0
        self._set_plant(self._params, self._inputs, in_flight=False)
        self._next_mark_n = cycles
        if self._marks is not None:
            self._marks.append(CycleMark(cycles, self._t, 0.0, self._stuck_time, self._flight_time))
            self._next_mark_n = cycles + 1
        self._set_anchor(self._t, cycles, 0.0)
        if self._general:
            self._start_motion(self._t, 0.0, 0.0, 0.0, 0.0, 0.0, cycles, STUCK)
        else:
            self._start_stuck(self._t, 0.0, 0.0, 0.0, 0.0, cycles)

    def checkpoint(self) -> _Checkpoint:
        """The state as it is now, for :meth:`restore` (about a microsecond)."""
        return _Checkpoint(self)

    def restore(self, checkpoint: _Checkpoint) -> None:
        """Put back the state of ``checkpoint`` exactly (a change that failed
        half-way leaves no trace)."""
        checkpoint.restore(self)

    # -- internals: acting on events -------------------------------------------

    def _set_anchor(self, t: float, cycles: int, phase: float) -> None:
        """Tie time ``t`` to total phase 2*pi*cycles + phase under the present
        frequency; every later event time is computed from here."""
        self._origin, self._origin_cycles, self._origin_phase = t, cycles, phase
        self._frequency = self._inputs.excitation_frequency
        self._schedule_mark()

    def _offset(self, cycles: int, phase: float) -> float:
        """When (after the anchor) the total phase reaches 2*pi*cycles + phase."""
        return (cycles - self._origin_cycles) / self._frequency + (phase - self._origin_phase) / self._plant.omega

    def _set_plant(self, params: SliderParams, inputs: Inputs, in_flight: bool) -> None:
        """Take new parameters and inputs: Kostek's model (normal excitation,
        level track, one friction coefficient, never leaving the track) runs
        on its own fast segments, everything else on the general ones."""
        self._params, self._inputs = params, inputs
        self._general = in_flight or not (
            params.is_kostek and inputs.excitation_amplitude < params.weight - inputs.external_force_z)
        if self._general:
            self._gplant = GeneralPlant(params, inputs)
            self._steps: dict[tuple[int, float, float, float, float, int, bool], Step] = {}
            self._plant = KostekPlant(params, inputs)  # (its omega times the anchor)
            self._can_slip = True
        else:
            self._can_slip = can_ever_slip(params, inputs)
            self._plant = KostekPlant(params, inputs)

    def _rebase(self, params: SliderParams, inputs: Inputs) -> None:
        """Start a new segment at the current time from the current state."""
        seg = self._seg
        tau = self._t - seg.t0
        theta = seg.phase0 + seg.omega * tau
        x, xl = seg.position(tau)
        phase, cycles = reduce_phase(theta, seg.cycles)
        if isinstance(seg, Motion):
            (v, vz), z = seg.velocities(tau), seg.after(tau)[6]
            w = abs(v)
        else:
            w = seg.speed_and_travel(tau)[0] if seg.direction != 0 else 0.0
            v, vz, z = seg.direction * w, 0.0, 0.0
        if seg.direction == 0:
            self._stuck_time += tau
        elif seg.direction == FLIGHT:
            self._flight_time += tau
        self._set_plant(params, inputs, in_flight=seg.direction == FLIGHT)
        if inputs.excitation_frequency != self._frequency:
            self._set_anchor(self._t, cycles, phase)
        s = self._t - self._origin
        if self._general:
            mode = FLIGHT if seg.direction == FLIGHT else (STUCK if w == 0.0 else (1 if v > 0.0 else -1))
            self._start_motion(self._t, s, x, xl, v, phase, cycles, mode, vz=vz, z=max(z, 0.0))
        elif seg.direction != 0 and w > 0.0:
            self._start_slip(self._t, s, x, xl, w, phase, cycles, seg.direction)
        else:
            self._start_stuck(self._t, s, x, xl, phase, cycles)

    def _start_stuck(
        self, t: float, s: float, x: float, xl: float, phase: float, cycles: int, after_stop: int = 0
    ) -> None:
        plant = self._plant
        self._seg = KostekSegment(s, t, x, xl, 0.0, phase, cycles, 0, plant)
        direction = plant.direction
        delta, start_phase = NEVER, NEVER
        if self._can_slip:
            delta, start_phase = next_slip_start(phase, plant.b0[direction], plant.b1,
                                                 closing=after_stop == direction)
        # The start passes 2*pi on the way if it lies "behind" the present phase.
        wraps = start_phase < phase or (start_phase == phase and delta > 0.0)
        start_cycles = cycles + 1 if wraps else cycles
        self._next_start = (start_phase, direction, start_cycles)
        if delta == 0.0 or delta == NEVER:
            next_s = s + delta
        else:  # self._offset, inlined (once per period)
            next_s = ((start_cycles - self._origin_cycles) / self._frequency
                      + (start_phase - self._origin_phase) / plant.omega)
            if next_s < s:
                next_s = s
        self._next_s = next_s
        next_t = self._origin + next_s  # self._time, inlined
        self._next_t = next_t if next_t >= t else t

    def _start_slip(
        self, t: float, s: float, x: float, xl: float, w: float, phase: float, cycles: int, direction: int
    ) -> None:
        self._seg = seg = KostekSegment(s, t, x, xl, w, phase, cycles, direction, self._plant)
        if w == 0.0:
            # Every slip from rest at this phase under these inputs is this slip:
            # its stop (duration, travel, phase) is computed once.
            key = (phase, seg.b0, seg.b1, seg.omega, direction)
            entry = self._cache.get(key)
            if entry is None:
                if len(self._cache) >= _CACHE_LIMIT:
                    self._cache.clear()
                entry = self._cache[key] = self._slip_stop(seg, 0.0, phase, direction)
        else:
            entry = self._slip_stop(seg, w, phase, direction)
        delay, seg.stop = entry
        # The stop is timed from the slip's own (anchored) start: no sum of increments.
        self._next_s = next_s = s + delay
        next_t = self._origin + next_s  # self._time, inlined
        self._next_t = next_t if next_t >= t else t

    @staticmethod
    def _slip_stop(seg: KostekSegment, w: float, phase: float, direction: int) -> tuple[float, Any]:
        """(duration, (signed travel, raw phase) at the stop or None) of a slip."""
        delay = slip_stop_delay(w, seg.b0, seg.b1, phase, seg.omega)
        if delay == NEVER:
            return delay, None
        return delay, (direction * seg.speed_and_travel(delay)[1], phase + seg.omega * delay)

    # -- internals: the general model ---------------------------------------------

    def _start_motion(self, t: float, s: float, x: float, xl: float, v: float, phase: float, cycles: int,
                      mode: int, *, vz: float = 0.0, z: float = 0.0, closing: int = 0, grounded: bool = False) -> None:
        """Start a segment of the general model and schedule its next event
        (worked out once per distinct start: see :class:`motion.Step`)."""
        self._seg = seg = Motion(s, t, x, xl, v, phase, cycles, mode, self._gplant, vz, z)
        key = (mode, phase, v, vz, z, closing, grounded)
        step = self._steps.get(key)
        if step is None:
            if len(self._steps) >= _CACHE_LIMIT:
                self._steps.clear()
            step = self._steps[key] = next_step(seg, closing, grounded) if self._can_slip else NEVER_STEP
        self._step = step
        if step.tied:  # tied to a phase: timed from the anchor, as a slip onset
            next_s = self._offset(cycles + step.whole, step.phase)
            if next_s < s:
                next_s = s
        else:
            next_s = s + step.delay
        self._next_s = next_s
        next_t = self._origin + next_s
        self._next_t = next_t if next_t >= t else t

    def _apply_general(self) -> Event:
        """Carry out the worked-out event of a general segment and start the next."""
        seg: Motion = self._seg  # type: ignore[assignment]  # (general: a Motion)
        step, t, s = self._step, self._next_t, self._next_s
        then = step.then
        assert then is not None  # an endless segment has no event
        if t == seg.t0:
            self._at_instant += 1
            if self._at_instant > MAX_EVENTS_AT_ONE_INSTANT:
                raise SimulationFault(f"the general model made no progress: more than {MAX_EVENTS_AT_ONE_INSTANT} "
                                      f"events at t = {t!r} s (the last a {then.kind.value} at phase {step.phase!r})")
        else:
            self._at_instant = 0
        x, xl = two_sum(seg.x0, seg.xl + step.travel)
        phase, cycles = step.phase, seg.cycles + step.whole
        if seg.direction == STUCK:
            self._stuck_time += s - seg.s0
        elif seg.direction == FLIGHT:
            self._flight_time += s - seg.s0
        self._start_motion(t, s, x, xl, then.v, phase, cycles, then.mode, vz=then.vz, closing=then.closing,
                           grounded=then.grounded)
        if then.kind is EventKind.LANDING or then.kind is EventKind.LIFT_OFF:
            event = Event(t, then.kind, x, phase, _MODES[seg.direction], _MODES[then.mode], step.v, then.v,
                          step.vz, then.vz)
        else:
            event = Event(t, then.kind, x, phase, _MODES[seg.direction], _MODES[then.mode])
        return self._log(event)

    def _apply(self) -> Event:
        """Carry out the event at ``_next_t`` and start the segment after it."""
        if self._general:
            return self._apply_general()
        seg: KostekSegment = self._seg  # type: ignore[assignment]  # (not general: Kostek's segment)
        t, s = self._next_t, self._next_s
        if seg.direction == 0:
            self._stuck_time += s - seg.s0
            phase, direction, cycles = self._next_start
            event = Event(t, EventKind.SLIP_START, seg.x0, phase, Mode.STUCK, _MODES[direction])
            self._start_slip(t, s, seg.x0, seg.xl, 0.0, phase, cycles, direction)
            return self._log(event)
        assert seg.stop is not None  # an endless slip has no event
        travel, theta = seg.stop
        x0, part = seg.x0, seg.xl + travel
        x = x0 + part  # two_sum, inlined (once per slip)
        bb = x - x0
        xl = (x0 - (x - bb)) + (part - bb)
        phase, cycles = reduce_phase(theta, seg.cycles)
        plant = self._plant
        direction = plant.direction
        before = _MODES[seg.direction]
        if direction == -seg.direction and self._can_slip and next_slip_start(
            phase, plant.b0[direction], plant.b1
        )[0] == 0.0:
            self._start_slip(t, s, x, xl, 0.0, phase, cycles, direction)
            return self._log(Event(t, EventKind.REVERSAL, x, phase, before, _MODES[direction]))
        self._start_stuck(t, s, x, xl, phase, cycles, after_stop=seg.direction)
        return self._log(Event(t, EventKind.STICK, x, phase, before, Mode.STUCK))

    def _schedule_mark(self) -> None:
        """Aim at the start of period ``_next_mark_n``, timed from the anchor."""
        if self._marks is not None:
            self._next_mark_s = self._offset(self._next_mark_n, 0.0)
            self._next_mark_t = self._origin + self._next_mark_s

    def _mark_cycle(self) -> None:
        """Record the start of period ``_next_mark_n`` and aim at the next."""
        seg, n = self._seg, self._next_mark_n
        t = max(self._next_mark_t, seg.t0)  # a start that rounding put before this segment's is at it
        # Where the slider is when the phase passes 2*pi*n exactly (not at the rounded t).
        tau = seg.to_cycle(n)
        flight = self._flight_time
        if seg.direction == 0:  # only x is needed: no full state evaluation
            x, stuck = seg.x0, self._stuck_time + tau
        elif isinstance(seg, Motion):
            x, stuck = sum(seg.position(tau)), self._stuck_time
            flight += tau if seg.direction == FLIGHT else 0.0
        else:
            x, stuck = seg.x0 + (seg.xl + seg.direction * seg.speed_and_travel(tau)[1]), self._stuck_time
        assert self._marks is not None
        self._marks.append(CycleMark(n, t, x, stuck, flight))
        self._next_mark_n += 1
        self._schedule_mark()

    def _log(self, event: Event) -> Event:
        self._events.append(event)
        self._counts[event.kind] += 1
        return event


__all__ = ["MAX_POSITION", "MAX_TIME", "CycleMark", "Event", "EventKind", "Mode", "Slider", "SliderState",
           "Trajectory"]
