"""The exact, event-driven core (no ROS, numpy only).

The slider acts on the physics of :mod:`friction_sim.core.physics`, written
once for it and for the compiled population engine: the general model
(flight, inclined vibration, a sloped track, static friction) and Kostek's
model, the default special case described below, with its own fast onsets;
it switches between them whenever a change of parameters or inputs makes the
other apply.

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
result.  Every segment that starts alike (mode, phase, velocities, guards)
under the same inputs has the same next event, which is why the periodic
regime is cheap: its steps are kept in a memo.

The design follows scipy's ``_ivp`` solvers: one object owns the state and
advances it; detecting the next event (:func:`~friction_sim.core.physics.segment.next_step`)
is kept apart from acting on it (:func:`~friction_sim.core.physics.stepper.advance`,
the stepper the compiled population engine runs too), and the state within a
segment comes from its dense output (:func:`~friction_sim.core.physics.segment.evaluate`);
results come back as typed records (:class:`SliderState`, :class:`Event`,
:class:`Trajectory`).
"""

from __future__ import annotations

from bisect import bisect_left
from collections import deque
from collections.abc import Iterator
from typing import Any

import numpy as np

from friction_sim.core.engine.actuator import Exciter
from friction_sim.core.engine.checkpoint import Checkpoint
from friction_sim.core.engine.history import History
from friction_sim.core.engine.transient_kernel import prepare as prepare_transient
from friction_sim.core.engine.transient_segment import (
    STEADY,
    ExciterReadings,
    cut_by,
    exciter_after,
    segment_end,
    states,
    states_at,
)
from friction_sim.core.engine.transient_segment import start as start_transient
from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.model.events import MODES as _MODES
from friction_sim.core.model.events import CycleMark, Event, EventKind, Mode, SliderState, Trajectory
from friction_sim.core.model.params import Inputs, SliderParams, require_finite
from friction_sim.core.physics.plant import plant_of
from friction_sim.core.physics.roots import NEVER, reduce_phase
from friction_sim.core.physics.segment import (
    FLIGHT,
    LANDING,
    LIFT_OFF,
    START,
    STUCK,
    Segment,
    Step,
)
from friction_sim.core.physics.stepper import (
    MAX_EVENTS_AT_ONE_INSTANT,
    Anchor,
    advance,
    continued,
    schedule,
    spent,
    step_of,
)
from friction_sim.errors import ParameterError, SimulationFault

#: Steps kept in the memo (one per distinct segment start under the plant in force).
_CACHE_LIMIT = 256
#: The latest time [s] a slider runs to (2**53 s, 285 million years, far beyond
#: the end of ROS 2 time at 2**31 s) and the largest |x0| [m]: together with the
#: ranges of core/spec.py they keep every state finite (the fastest accepted
#: slider, at 2e12 m/s^2, covers 1e44 m by then).
MAX_TIME = 2.0**53
MAX_POSITION = 1e100
#: Event kinds by the numbers of :mod:`friction_sim.core.physics.segment`.
_KINDS = tuple(EventKind)


# --------------------------------------------------------------------------
# The slider: owns the state, advances it event by event.
# --------------------------------------------------------------------------


class Slider(History, ExciterReadings):
    """One slider, advanced exactly in time (what it has done: :class:`History`; what its
    resonant exciter reads: :class:`~friction_sim.core.engine.transient_segment.ExciterReadings`).

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
    anchor (:class:`~friction_sim.core.physics.stepper.Anchor`: time ``t_a`` at
    total phase 2*pi*cycles_a + phase_a), set at the start and whenever the
    frequency changes, and computes the time of every event and period start
    afresh from it, as t_a + (cycles - cycles_a)/f + (phase - phase_a)/omega
    (plus the slip's duration for a stop).  Rounding errors therefore do not add
    up from one event to the next: after a million periods a slip still starts
    within a few units in the last place of t of its exact time, wherever the
    run started.
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
        self._steps: dict[tuple[int, float, float, float, float, int, bool], Step] = {}  # (by seg[:START])
        self._marks: deque[CycleMark] | None = None
        self._next_mark_n, self._next_mark_t, self._next_mark_s = 1, NEVER, NEVER
        x0 = require_finite("x0", x0)
        if abs(x0) > MAX_POSITION:
            raise ParameterError("x0", x0, f"must be within +-{MAX_POSITION:g} m")
        if cycle_log_size != 0:
            self._marks = deque(maxlen=cycle_log_size)
            if phase == 0.0:
                self._marks.append(CycleMark(0, self._t, x0, 0.0))
        self._set_plant(self._params, self._inputs, in_flight=False)
        self._exciter = Exciter(self._params, self._inputs, t0=self._t) if self._params.resonant else None
        if self._exciter is not None:
            prepare_transient(self._plant)  # (its compiled step loads while the slider's user starts up)
        self._transient = STEADY  # the exciter's transient over the segment (see transient_segment)
        self._set_anchor(self._t, 0, phase)
        self._start(Segment(STUCK, phase, 0.0, 0.0, 0.0, 0, False, 0.0, self._t, x0, 0.0, 0, 0.0, 0.0, 0))

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
    def next_event_time(self) -> float:
        """When the next event happens under the present inputs (inf: never)."""
        return self._next_t

    def state(self) -> SliderState:
        """The state at the current time :attr:`t`."""
        seg = self._seg
        x, v, acc, friction, normal, theta, z, vz = states(self._plant, seg, self._transient, self._t - seg.t0)
        return SliderState(self._t, x, v, acc, friction, normal, theta % TWO_PI, _MODES[seg.mode], z, vz)

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
            if self._transient.c and (boundary := cut_by(self._seg, self._transient, self._next_t, t,
                                                         self.next_mark_time)) is not None:
                # the segment's closed form ends here: a new one from the same motion
                self._t = boundary
                self._rebase(self._params, self._inputs, boundary=True)
                continue
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

    def sample_grids(self, state_times: list[float], reading_times: list[float]
                     ) -> tuple[list[SliderState], list[list[float]], list[Event]]:
        """Advance through two ascending lists of times (>= :attr:`t`) at once, to the
        last: the state at each of ``state_times``, the slideway's (along, normal)
        acceleration at each of ``reading_times``, and the events on the way.  Each is
        what :meth:`advance_to` to its time then :meth:`state` (or
        :meth:`slideway_acceleration`) gives, bit for bit, evaluated a segment at a
        time (compiled once the transient kernel is ready): a log grid's hot path."""
        states: list[SliderState] = []
        readings: list[list[float]] = []
        happened: list[Event] = []
        for state_range, reading_range in self._by_segment(happened, state_times, reading_times):
            if state_range:
                seg, t0, mode = self._seg, self._seg.t0, _MODES[self._seg.mode]
                times = state_times[state_range.start:state_range.stop]
                rows = states_at(self._plant, seg, self._transient, [t - t0 for t in times])
                states.extend(SliderState(t, x, v, acc, friction, normal, theta % TWO_PI, mode, z, vz)
                              for t, (x, v, acc, friction, normal, theta, z, vz) in zip(times, rows))
            if reading_range:
                readings.extend(self._accelerations_at(reading_times[reading_range.start:reading_range.stop]))
        return states, readings, happened

    def _by_segment(self, happened: list[Event], *grids: Any) -> Iterator[list[range]]:
        """Advance through ascending grids of times (lists or arrays, >= :attr:`t`) at once,
        to the last time of any, segment by segment: with the slider in each segment, the
        indices of each grid's times that fall in it (a time at the segment's end is the
        next one's, as :meth:`advance_to` leaves it); the events on the way go to ``happened``."""
        firsts = [0] * len(grids)
        last = max((float(grid[-1]) for grid in grids if len(grid)), default=self._t)
        while any(first < len(grid) for first, grid in zip(firsts, grids)):
            end = segment_end(self._seg, self._transient, self._next_t)[0]
            lasts = [bisect_left(grid, end, first) for first, grid in zip(firsts, grids)]
            yield [range(first, stop) for first, stop in zip(firsts, lasts)]
            firsts = lasts
            if any(first < len(grid) for first, grid in zip(firsts, grids)):
                happened.extend(self.advance_to(end))
        happened.extend(self.advance_to(last))

    def sample(self, times: np.ndarray) -> Trajectory:
        """Advance through ascending ``times`` (>= :attr:`t`) and return the exact
        state at each, evaluated segment by segment with numpy: the state
        :meth:`advance_to` and :meth:`state` give at each time, because both cut
        the time axis where :func:`~friction_sim.core.engine.transient_segment.segment_end`
        says (:func:`~friction_sim.core.engine.transient_segment.states`: under
        the exciter's transient the very same scalar evaluation; on the steady
        forms numpy's, which may differ in the last bits)."""
        times = np.asarray(times, dtype=float)
        if times.ndim != 1 or times.size == 0:
            raise ParameterError("times", times.shape, "must be a non-empty 1-d array")
        if times[0] < self._t or np.any(np.diff(times) < 0.0):
            raise ParameterError("times", float(times[0]), f"must ascend from >= {self._t!r} s")
        columns = [np.empty_like(times) for _ in range(9)]
        happened: list[Event] = []
        for (part,) in self._by_segment(happened, times):
            if part:
                first, last = part.start, part.stop
                seg = self._seg
                values = states(self._plant, seg, self._transient, times[first:last] - seg.t0)
                for column, value in zip(columns, values):
                    column[first:last] = value
                columns[5][first:last] %= TWO_PI
                columns[8][first:last] = seg.mode
        x, v, acc, friction, normal, phase, z, vz, mode = columns
        return Trajectory(times, x, v, acc, friction, normal, phase, mode.astype(np.int8), tuple(happened), z, vz)

    # -- changing inputs and parameters ----------------------------------------

    def set_inputs(self, inputs: Inputs | None = None, **changes: Any) -> Inputs:
        """Change the inputs at the current time; the phase stays continuous.

        Pass a whole :class:`Inputs` or field changes (validated as a new
        :class:`Inputs`; a bad value is refused and nothing changes).  Every
        valid combination is followed, including one that lifts the slider off.
        """
        new = (inputs if inputs is not None else self._inputs).replace(**changes)
        self._rebase(self._params, new)
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
        stuck, flight = spent(seg, tau)
        cycles = reduce_phase(seg.phase0 + self._plant.omega * tau, seg.cycles)[1] + 1
        self._set_plant(self._params, self._inputs, in_flight=False)
        self._next_mark_n = cycles
        if self._marks is not None:
            self._marks.append(CycleMark(cycles, self._t, 0.0, stuck, flight))
            self._next_mark_n = cycles + 1
        self._set_anchor(self._t, cycles, 0.0)
        self._start(Segment(STUCK, 0.0, 0.0, 0.0, 0.0, 0, False, 0.0, self._t, 0.0, 0.0, cycles, stuck, flight, 0))

    def checkpoint(self) -> Checkpoint:
        """The state as it is now, for :meth:`restore` (about a microsecond)."""
        return Checkpoint(self)

    def restore(self, checkpoint: Checkpoint) -> None:
        """Put back the state of ``checkpoint`` exactly (a change that failed
        half-way leaves no trace)."""
        checkpoint.restore(self)

    # -- internals: acting on events -------------------------------------------

    def _set_anchor(self, t: float, cycles: int, phase: float) -> None:
        """Tie time ``t`` to total phase 2*pi*cycles + phase under the present
        frequency; every later event time is computed from here."""
        self._anchor = Anchor(t, cycles, phase, self._inputs.excitation_frequency, self._plant.omega)
        self._schedule_mark()

    def _set_plant(self, params: SliderParams, inputs: Inputs, in_flight: bool) -> None:
        """Take new parameters and inputs.  Kostek's model (normal excitation,
        level track, one friction coefficient, never leaving the track) takes
        its own fast onsets, everything else the general ones; a flight under
        way at the change goes on in the general model until the next change."""
        self._params, self._inputs = params, inputs
        self._plant, self._steps = plant_of(params, inputs, in_flight), {}

    def _rebase(self, params: SliderParams, inputs: Inputs, boundary: bool = False) -> None:
        """Start a new segment at the current time from the current state
        (:func:`~friction_sim.core.physics.stepper.continued`); at a ``boundary`` of
        the exciter's transient's segment nothing else changes (the transient is
        dropped once it has settled)."""
        seg, t = self._seg, self._t
        retimed = inputs.excitation_frequency != self._anchor.frequency  # (the anchor moves to t)
        new = continued(self._plant, seg, self._transient.c, self._transient.lam, t, t if retimed else self._anchor.t)
        self._set_plant(params, inputs, seg.mode == FLIGHT)
        self._exciter = exciter_after(self._exciter, params, inputs, self._plant, t, new.phase0, boundary)
        if retimed:
            self._set_anchor(t, new.cycles, new.phase0)
        self._start(new)

    def _start(self, seg: Segment) -> None:
        """Start ``seg`` and schedule its next event (on the steady forms worked out
        once per distinct start and kept in the memo: see
        :data:`~friction_sim.core.physics.segment.START`)."""
        self._seg = seg
        transient = start_transient(self._exciter, self._plant, seg, self._anchor.frequency)
        if transient is not None:  # under the exciter's transient: no memo
            self._transient, step = transient
        else:
            self._transient = STEADY
            key = seg[:START]
            cached = self._steps.get(key)
            if cached is None:
                if len(self._steps) >= _CACHE_LIMIT:
                    self._steps.clear()
                cached = self._steps[key] = step_of(self._plant, seg)
            step = cached
        self._step = step
        self._next_s, self._next_t = schedule(self._anchor, seg, step)

    def _apply(self) -> Event:
        """Carry out the worked-out event of the segment and start the next."""
        seg, step = self._seg, self._step
        after = advance(seg, step, self._next_s, self._next_t)
        t, x = after.t0, after.x0
        if after.at_instant > MAX_EVENTS_AT_ONE_INSTANT:
            raise SimulationFault(f"the general model made no progress: more than {MAX_EVENTS_AT_ONE_INSTANT} "
                                  f"events at t = {t!r} s (the last a {_KINDS[step.kind].value} at phase "
                                  f"{step.phase!r})")
        self._start(after)
        kind = _KINDS[step.kind]
        if step.kind == LANDING or step.kind == LIFT_OFF:
            event = Event(t, kind, x, step.phase, _MODES[seg.mode], _MODES[step.mode], step.v, step.v_after, step.vz,
                          step.vz_after)
        else:
            event = Event(t, kind, x, step.phase, _MODES[seg.mode], _MODES[step.mode])
        self._events.append(event)
        self._counts[kind] += 1
        return event



__all__ = ["MAX_POSITION", "MAX_TIME", "CycleMark", "Event", "EventKind", "Mode", "Slider", "SliderState",
           "Trajectory"]
