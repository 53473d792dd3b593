"""Lockstep: the slider advances when its participants have answered, not with the wall clock.

In real time (:mod:`friction_sim.core.runtime.realtime`) simulation time follows
the wall clock, so a closed loop over ROS depends on how the operating system
schedules its processes.  In lockstep it depends on nothing but the messages:

* **The controller** answers each ``mean_velocity`` sample on ``control_answer``
  (a message stamped with the sample it answers).  The slider never runs more
  than ``actuation_delay`` past a sample whose answer has not come, and the
  answer acts exactly ``actuation_delay`` after the sample: the loop's delay is a
  model parameter, not an accident of scheduling.
* **The scheduler** (an experiment's driver) sends stamped commands on
  ``stamped_command``; each one applies at its stamp and promises that nothing
  stamped earlier follows (one with no values is that promise alone).  The
  slider never runs past the latest promise, and a window that ends exactly
  there is reported only once the promise moves on: what the scheduler does at
  a time (a parameter set, a service call while the slider stands there) comes
  before the controller is asked about that time.
* **Pause, resume and step** still work: a pause holds the slider where it is,
  a step moves the hold on by its length.

:class:`LockstepGate` keeps those promises and answers (pure bookkeeping in
integer nanoseconds, the stamps' unit); :class:`LockstepSlider` is the real-time
slider advanced by the gate instead of a clock, so commands, refusals, log
samples, period means and diagnostics are made by the same code either way.
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from friction_sim.core.model import spec
from friction_sim.core.model.commands import PAUSE, RESUME, STEP, Command, Outcome
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.model.records import Tick
from friction_sim.core.model.spec import NS_PER_S
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.errors import ParameterError

CONTROLLER, SCHEDULER = spec.LOCKSTEP_ROLES
#: No limit (a hold or promise that does not bound the slider), in ns.
UNBOUNDED = 2**63 - 1
#: Answers act before a scheduler's commands stamped at the same time.
_ANSWER, _SCHEDULED = 0, 1


def participants(text: str) -> frozenset[str]:
    """The participants named in ``lockstep_participants`` (comma-separated; '' = none)."""
    names = [name.strip() for name in str(text).split(",") if name.strip()]
    unknown = [name for name in names if name not in spec.LOCKSTEP_ROLES]
    if unknown:
        raise ParameterError("lockstep_participants", text,
                             f"must name some of {', '.join(spec.LOCKSTEP_ROLES)} (comma-separated), "
                             f"not {unknown[0]!r}")
    return frozenset(names)


def to_ns(seconds: float) -> int:
    """Simulation time [s] in whole nanoseconds (the stamps' unit)."""
    return round(seconds * NS_PER_S)


@dataclass(order=True)
class _Due:
    """A stamped command waiting for its time: ordered by time, then answers first, then arrival."""

    t_ns: int
    rank: int
    seq: int
    command: Command = field(compare=False)


class LockstepGate:
    """How far a slider in lockstep may go, and the stamped commands due on the way."""

    def __init__(self, who: frozenset[str], delay: float, timeout: float) -> None:
        self.controller = CONTROLLER in who
        self.scheduler = SCHEDULER in who
        self.delay_ns = to_ns(float(spec.ACTUATION_DELAY.check(delay)))
        self.timeout = float(spec.LOCKSTEP_TIMEOUT.check(timeout))
        #: The scheduler's latest promise [ns]: nothing stamped before it will come (0 until it speaks).
        self.promise_ns = 0 if self.scheduler else UNBOUNDED
        #: Where a pause (or a step) holds the slider [ns]; UNBOUNDED while it runs; and whether a step moves it.
        self.hold_ns = UNBOUNDED
        self.stepping = False
        #: Stamps [ns] of the samples published whose answer has not come, oldest first.
        self.awaited: deque[int] = deque()
        self._due: list[_Due] = []
        self._seq = itertools.count()
        #: Answers taken, answers that answered no awaited sample (a repeat), stamped commands taken.
        self.answers = self.stale_answers = self.scheduled = 0
        #: The stamps [ns] of the stamped messages taken, oldest first, until a report counts them
        #: (:meth:`values`): a report at simulation time t counts those stamped before t, which have
        #: all come by then whenever they were sent (the scheduler sends its stamps in order, and one
        #: at t or later let the slider get to t); those stamped at t or later may have come or not.
        self._stamps: deque[int] = deque()
        self._scheduled_by = 0
        #: The stamp [ns] of the last sample answered (-1: none yet).
        self.answered_ns = -1
        #: Wall time [s] spent waiting for participants; lockstep_timeouts spent waiting for one to join.
        self.waited = 0.0
        self.join_waits = 0

    @property
    def held(self) -> bool:
        """Whether a pause or a step holds the slider."""
        return self.hold_ns != UNBOUNDED

    @property
    def paused(self) -> bool:
        """Whether a pause holds the slider (a step under way is not a pause: it ends in one)."""
        return self.held and not self.stepping

    def pause(self, t_ns: int) -> None:
        self.hold_ns, self.stepping = t_ns, False

    def resume(self) -> None:
        self.hold_ns, self.stepping = UNBOUNDED, False

    def step(self, t_ns: int, duration_ns: int) -> None:
        """Move the hold on by ``duration_ns`` from where the slider stands or the hold is, the later."""
        self.hold_ns, self.stepping = max(self.hold_ns if self.stepping else t_ns, t_ns) + duration_ns, True

    def stepped_to(self, t_ns: int) -> None:
        """Where the slider stands now: at its step's end it is paused again."""
        if self.stepping and t_ns >= self.hold_ns:
            self.stepping = False

    # -- what the participants send ------------------------------------------------------

    def sample(self, t_ns: int) -> None:
        """A mean_velocity sample stamped ``t_ns`` was published: its answer is awaited."""
        if self.controller:
            self.awaited.append(t_ns)

    def answer(self, stamp_ns: int, commands: Sequence[Command]) -> bool:
        """The controller's answer to the sample stamped ``stamp_ns``: due ``actuation_delay``
        later.  False (nothing taken) if it answers no awaited sample (a repeat)."""
        if stamp_ns not in self.awaited:
            self.stale_answers += 1
            return False
        while self.awaited and self.awaited[0] <= stamp_ns:  # answers come in order: earlier ones are past
            self.awaited.popleft()
        self.answers += 1
        self.answered_ns = stamp_ns
        self._queue(stamp_ns + self.delay_ns, _ANSWER, commands)
        return True

    def promise(self, stamp_ns: int, commands: Sequence[Command], t_ns: int) -> str:
        """The scheduler's commands stamped ``stamp_ns`` (none: a promise alone);
        '' or why they are refused (stamped before its own promise or the slider's time)."""
        floor = max(self.promise_ns if self.scheduler else 0, t_ns)
        if stamp_ns < floor:
            return (f"stamped_command: header.stamp = {stamp_ns / NS_PER_S!r} s rejected: must be >= "
                    f"{floor / NS_PER_S!r} s (the slider's time and the scheduler's last promise)")
        if self.scheduler:
            self.promise_ns = stamp_ns
        self.scheduled += 1
        self._stamps.append(stamp_ns)
        self._queue(stamp_ns, _SCHEDULED, commands)
        return ""

    def _queue(self, t_ns: int, rank: int, commands: Sequence[Command]) -> None:
        for command in commands:
            heapq.heappush(self._due, _Due(t_ns, rank, next(self._seq), command))

    # -- how far the slider may go ---------------------------------------------------------

    def due(self, t_ns: int) -> list[Command]:
        """The stamped commands due by ``t_ns``, in order, taken off the queue."""
        ready = []
        while self._due and self._due[0].t_ns <= t_ns:
            ready.append(heapq.heappop(self._due).command)
        return ready

    def limit_ns(self) -> int:
        """The furthest the slider may go now: the hold, the scheduler's promise, the
        oldest awaited sample plus the actuation delay, the next stamped command."""
        limit = min(self.hold_ns, self.promise_ns)
        if self.awaited:
            limit = min(limit, self.awaited[0] + self.delay_ns)
        if self._due:
            limit = min(limit, self._due[0].t_ns)
        return limit

    def held_ns(self) -> int:
        """Where a hold or promise stops the slider: a window ending there is reported once it moves on."""
        return min(self.hold_ns, self.promise_ns)

    def blocker(self, t_ns: int) -> tuple[str, bool]:
        """(the participant the slider, standing at ``t_ns``, waits for, whether it has
        spoken before): ('', False) when it can go on or a pause or step holds it.  One
        that has not spoken yet has not joined: it is waited for (a controller starting
        up, a driver attaching); one that has, and goes silent, is not."""
        if self.awaited and t_ns >= self.awaited[0] + self.delay_ns:
            return (f"the controller: no answer on control_answer to the mean_velocity sample of "
                    f"t = {self.awaited[0] / NS_PER_S:.9f} s", self.answers > 0)
        if self.promise_ns <= t_ns < self.hold_ns:
            if self.scheduled:
                return f"the scheduler: no stamped_command past t = {self.promise_ns / NS_PER_S:.9f} s", True
            return "the scheduler: no stamped_command yet", False
        return "", False

    def values(self, t_ns: int = UNBOUNDED) -> dict[str, Any]:
        """The gate's figures for diagnostics at simulation time ``t_ns``: the stamped messages
        are those stamped before then (the same every run; how far the scheduler has promised,
        ``lockstep_promise``, depends on when its messages came)."""
        while self._stamps and self._stamps[0] < t_ns:
            self._stamps.popleft()
            self._scheduled_by += 1
        return {"lockstep": True, "actuation_delay": self.delay_ns / NS_PER_S,
                "lockstep_answers": self.answers, "lockstep_stale_answers": self.stale_answers,
                "lockstep_scheduled": self._scheduled_by, "lockstep_waited_s": self.waited,
                "lockstep_join_waits": self.join_waits,
                "lockstep_promise": math.inf if self.promise_ns == UNBOUNDED else self.promise_ns / NS_PER_S}


class LockstepSlider(RealtimeSlider):
    """The real-time slider with its gate instead of a wall clock: the same
    commands, log samples, period means and diagnostics, at the times the
    participants allow (see the module)."""

    def __init__(self, params: SliderParams, inputs: Inputs, *, wall_ns: int, gate: LockstepGate,
                 **options: Any) -> None:
        super().__init__(params, inputs, wall_ns=wall_ns, **options)
        self.clock.pause(wall_ns)  # simulation time stands still unless the gate moves it
        self.gate = gate

    @property
    def t_ns(self) -> int:
        return to_ns(self.slider.t)

    @property
    def paused(self) -> bool:
        return self.gate.paused

    def pause(self, wall_ns: int) -> Outcome:
        t = self._advance(wall_ns)
        if self.gate.paused:
            return self._refuse(Command(t, PAUSE), f"pause: already paused at t = {t:.9f} s")
        self.gate.pause(self.t_ns)
        return Outcome(Command(t, PAUSE))

    def resume(self, wall_ns: int) -> Outcome:
        t = self._advance(wall_ns)
        if not self.gate.held:  # (a step under way ends in a pause: a resume lets it run on instead)
            return self._refuse(Command(t, RESUME), "resume: not paused")
        self.gate.resume()
        return Outcome(Command(t, RESUME))

    def step(self, duration: float, wall_ns: int) -> Outcome:
        """While paused: let the slider go on by ``duration`` [s] once its participants
        allow (it does not wait here: the node's loop advances it)."""
        t = self._advance(wall_ns)
        command = Command(t, STEP, {"duration": duration})
        step_ns = to_ns(duration) if math.isfinite(duration) else 0
        if not self.gate.held:
            return self._refuse(command, "step: the simulation is running; call pause first")
        if step_ns < 1:
            return self._refuse(command, f"step: duration = {duration!r} s rejected: must be >= 1 ns")
        self.gate.step(self.t_ns, step_ns)
        return Outcome(command)

    def due_commands(self, wall_ns: int) -> list[Outcome]:
        """Take the stamped commands due now, each a change of its own (as any command).  Not
        while a window that ended by now waits to be reported (the slider stands where a hold
        or promise stopped it, at a period's end): commands at a period's end act after its
        window is reported, whether or not a promise held the slider there, so its diagnostics
        say the same every run (the slider does not move meanwhile: they act at their time)."""
        if not self.reported_through(self.t_ns):
            return []
        due = self.gate.due(self.t_ns)
        return self.commands(due, wall_ns) if due else []

    def advance(self, wall_ns: int) -> Tick | None:
        """Go as far as the gate allows, stopping at the next period's end (its
        sample must be answered before the slider goes on); None if it cannot
        move.  A window that ended at a hold is reported first, once the hold
        has moved on (its answer then bounds the advance)."""
        gate = self.gate
        self._mark_hold()
        if any(mark.t < self.marks_before for mark in self.slider.cycle_marks_after(self.period_means.last_mark_n)):
            return self._tick(wall_ns)
        limit = gate.limit_ns()
        if limit <= self.t_ns:
            return None
        self._advance_sim(min(limit / NS_PER_S, self.slider.next_mark_time))
        self.clock.step(max(0, self.t_ns - self.clock.now_ns(wall_ns)))
        gate.stepped_to(self.t_ns)
        self._mark_hold()
        return self._tick(wall_ns)

    def reported_through(self, t_ns: int) -> bool:
        """Whether every period that ended by ``t_ns`` has been reported.  A window ending where
        a hold or a promise stops the slider is reported once it moves on: the diagnostics of
        that time wait for it, so they say the same whether or not the scheduler's next promise
        had come when the slider got there."""
        return not any(to_ns(mark.t) <= t_ns for mark in self.slider.cycle_marks_after(self.period_means.last_mark_n))

    def _mark_hold(self) -> None:
        """Report no window ending at or after where a hold or promise stops the slider."""
        held = self.gate.held_ns()
        self.marks_before = math.inf if held == UNBOUNDED else held / NS_PER_S

    def _tick(self, wall_ns: int) -> Tick:
        """What the advance made, its samples awaited by the gate."""
        tick = self.tick(wall_ns, paused=self.gate.paused)
        for period in tick.periods:
            self.gate.sample(to_ns(period.t))
        return tick

    def diagnostics(self, wall_ns: int, prediction: Any = None) -> dict[str, Any]:
        report = super().diagnostics(wall_ns, prediction)
        report["paused"] = self.gate.paused
        return {**report, **self.gate.values(self.t_ns)}


__all__ = ["CONTROLLER", "SCHEDULER", "UNBOUNDED", "LockstepGate", "LockstepSlider", "participants", "to_ns"]
