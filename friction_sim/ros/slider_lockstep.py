"""The slider node's runtime, and its loop in lockstep.

:func:`runtime_for` builds the node's runtime from its parameters: the
real-time slider, or with ``lockstep`` the lockstep slider
(:mod:`friction_sim.core.runtime.lockstep`).  :class:`LockstepLoop` replaces the
real-time tick thread in lockstep: it takes the stamped messages of the
participants (``control_answer``, ``stamped_command``: :mod:`friction_sim.io.stamped`),
applies what is due, advances as far as the gate allows and publishes what
that made, with no sleep while it can move.  While it waits it publishes the
awaited sample again every :data:`REPEAT` s (a controller that joined late
missed it), and after ``lockstep_timeout`` of wall time it names the
participant it waited for and stops the run (a fault: the node exits with
code 3) rather than hang.  Diagnostics come every ``diagnostics_period`` of
simulation time, stamped with it, so a recording of a lockstep run holds the
same messages every time.  A controller in the same process takes its turns
through a link instead of the topics (:mod:`friction_sim.ros.lockstep_link`):
the loop hands it each sample and reading as it publishes them, and takes its
answer as if it had come on ``control_answer``.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from friction_sim.core.model import spec
from friction_sim.core.model.commands import PARAMETERS, Command, Outcome
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.model.records import PeriodSummary, Tick
from friction_sim.core.runtime.accelerometer import Accelerometer
from friction_sim.core.runtime.lockstep import LockstepGate, LockstepSlider, participants, to_ns
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.errors import ParameterError, SimulationFault
from friction_sim.io.messages import ACCELEROMETER, mean_velocity_message, message_class, seconds_to_ns, stamp_ns
from friction_sim.io.sinks import MessageRecord, deliver
from friction_sim.io.stamped import CONTROL_ANSWER, STAMPED_COMMAND, STAMPED_DEPTH, STAMPED_TYPE, stamped_commands
from friction_sim.ros import lockstep_link
from friction_sim.ros.intake import Arrivals, PolledGroup, take_all
from friction_sim.ros.run import wall_ns


class SteppedNode(Protocol):
    """What the lockstep loop needs of the slider node (:class:`~friction_sim.ros.slider.SliderNode`)."""

    @property
    def realtime(self) -> Any: ...
    @property
    def lock(self) -> Any: ...
    @property
    def stopping(self) -> bool: ...
    @property
    def frame_id(self) -> str: ...
    @property
    def topics(self) -> Any: ...
    @property
    def sinks(self) -> Any: ...
    @property
    def context(self) -> Any: ...
    def get_parameter(self, name: str) -> Any: ...
    def get_logger(self) -> Any: ...
    def resolve_topic_name(self, topic: str, *, only_expand: bool = False) -> str: ...
    def create_subscription(self, *args: Any, **kwargs: Any) -> Any: ...
    def create_guard_condition(self, callback: Callable[[], None]) -> Any: ...

    def take_commands(self) -> None: ...
    def record(self, outcomes: Sequence[Outcome]) -> None: ...
    def publish_tick(self, tick: Tick, fresh: bool = True) -> None: ...
    def warn_refused(self, outcome: Outcome, warn: Callable[[str], Any] | None = None) -> None: ...
    def fail(self, error: BaseException) -> None: ...
    def publish_diagnostics(self, stamp_ns: int | None = None) -> None: ...
    def publish_mean_velocity(self, msg: Any) -> None: ...
    def flush_readings(self) -> None: ...

#: Wall time [s] after which an awaited sample is published again while the slider waits.
REPEAT = 0.25
#: Wall time [s] between looks at the command topics (plain topic commands have no stamp: in
#: lockstep they apply when taken); the loop waits at most this long for a participant's message.
_COMMANDS_EVERY = 0.002


def runtime_for(values: dict[str, Any], params: SliderParams, inputs: Inputs) -> RealtimeSlider:
    """The slider's runtime for the node's parameter ``values``: in real time, or in lockstep."""
    options: dict[str, Any] = dict(
        real_time_factor=values["real_time_factor"], publish_rate=values["publish_rate"],
        mean_window_periods=values["mean_window_periods"], max_catch_up=values["max_catch_up"],
        load_blame=_load_blame(values), log_rate=values["log_rate"] if values["log_path"] else None,
        accelerometer=Accelerometer(values["accelerometer_rate"], values["accelerometer_noise"],
                                    values["accelerometer_bias"], values["accelerometer_seed"]))
    if not values["lockstep"]:
        return RealtimeSlider(params, inputs, wall_ns=wall_ns(), **options)
    gate = LockstepGate(participants(values["lockstep_participants"]), values["actuation_delay"],
                        values["lockstep_timeout"])
    return LockstepSlider(params, inputs, wall_ns=wall_ns(), gate=gate, **options)


def _load_blame(values: dict[str, Any]) -> str:
    """The parameter a start-up refusal of f x real_time_factor blames: the
    real-time factor if it was set (differs from its default), else the frequency."""
    return "real_time_factor" if values["real_time_factor"] != spec.REAL_TIME_FACTOR.default \
        else "excitation_frequency"


class LockstepLoop:
    """The slider node's loop in lockstep (see the module)."""

    def __init__(self, node: SteppedNode) -> None:
        self.node = node
        rt = node.realtime
        assert isinstance(rt, LockstepSlider)
        self.rt = rt
        kind, polled = message_class(STAMPED_TYPE), PolledGroup()
        #: The participants' topics, drained by the loop itself: an executor's wake-up per answer
        #: would cost more than the period it lets the slider simulate.
        self._stamped = [(topic, node.create_subscription(kind, topic, _unused, STAMPED_DEPTH, callback_group=polled))
                         for topic in (CONTROL_ANSWER, STAMPED_COMMAND)]
        #: Wakes the loop when a participant's message comes (it sleeps until then, rather than poll).
        self._arrivals = Arrivals([subscription for _, subscription in self._stamped], node.context)
        self._period_ns = to_ns(node.get_parameter("diagnostics_period").value)
        self._next_diagnostics_ns = self._period_ns
        #: The recent samples published, by stamp [ns], to publish again while awaited.
        self._recent: dict[int, PeriodSummary] = {}
        #: A controller in this process takes its turns through this link, not DDS
        #: (:mod:`~friction_sim.ros.lockstep_link`).
        self._link = lockstep_link.offer(node.context, lockstep_link.TurnTopics(
            *(node.resolve_topic_name(topic) for topic in ("mean_velocity", CONTROL_ANSWER, ACCELEROMETER))),
            self._arrivals.wake)
        #: Triggered when the scheduler's promise holds the slider: the executor spinning this node (an
        #: experiment's driver, waiting for the slider to stand there before it acts) looks at once,
        #: not at the end of its wait's timeout.
        self._held = node.create_guard_condition(_nothing)
        self._held_there = False  # whether it was triggered where the slider stands
        #: The readings (stamp [ns], normal [m/s^2]) of samples not yet answered: what a linked controller needs.
        self._readings: deque[tuple[int, float]] = deque()
        #: The link's controller handed to last (its generation), and the last sample and reading handed to it [ns].
        self._handed = (0, -1, -1)

    def run(self) -> None:
        """Apply, advance and publish until stopped; wait (at most ``lockstep_timeout``
        for a participant) only when the gate allows no step."""
        if self._link is not None:
            self._link.slider_thread = threading.current_thread()
        try:
            self._run()
        finally:
            if self._link is not None:
                lockstep_link.withdraw(self._link)
            self._arrivals.destroy()

    def _run(self) -> None:
        node, rt = self.node, self.rt
        with node.lock:  # where it stands at start (a driver attached to it follows the stamps)
            node.publish_tick(Tick(rt.slider.state(), [], [], paused=rt.gate.paused))
        blocked_since: float | None = None
        repeated = last = looked = 0.0
        while not node.stopping:
            if time.monotonic() - looked > _COMMANDS_EVERY:
                node.take_commands()
                looked = time.monotonic()
            with node.lock:
                outcomes = self._take_inbox() + rt.due_commands(wall_ns())
                node.record(outcomes)
                tick = rt.advance(wall_ns())
                if tick is not None:
                    node.publish_tick(tick)
                    self._recent = {to_ns(p.t): p for p in (*self._recent.values(), *tick.periods)
                                    if to_ns(p.t) in rt.gate.awaited}
                    self._keep_readings(tick)
            self._hand_over()
            for outcome in outcomes:
                node.warn_refused(outcome)
            if tick is not None:
                blocked_since = None
                self._held_there = False
                self._diagnostics_due()
                continue
            if outcomes or (self._link is not None and self._link.answers):
                continue
            node.flush_readings()  # (a controller that began to read the accelerometer gets what it needs)
            self._wake_driver_when_held()
            blocker, joined = rt.gate.blocker(rt.t_ns)
            now = time.monotonic()
            if not blocker:
                blocked_since = None
            else:
                if blocked_since is None:
                    blocked_since = last = now
                rt.gate.waited += now - last
                last = now
                if now - blocked_since > rt.gate.timeout:
                    if joined:
                        self._time_out(blocker)
                        return
                    self._not_joined(blocker)
                    blocked_since = now
                if now - repeated > REPEAT:
                    self._repeat_awaited()
                    repeated = now
            self._arrivals.wait(_COMMANDS_EVERY)

    def _wake_driver_when_held(self) -> None:
        """Trigger the guard condition once the slider stands at the scheduler's promise with
        every sample answered: what a driver waits for before it acts at that time."""
        gate = self.rt.gate
        held = gate.promise_ns <= self.rt.t_ns and not gate.awaited
        if held and not self._held_there:
            self._held.trigger()
        self._held_there = held

    def _take_inbox(self) -> list[Any]:
        """Hand the queued stamped messages to the gate (lock held); the outcomes of
        the refused ones (a malformed message, a stamp in the past)."""
        rt, refused = self.rt, []
        linked: deque[Any] = self._link.answers if self._link is not None else deque()
        waiting = [(CONTROL_ANSWER, linked.popleft()) for _ in range(len(linked))]
        waiting += [(topic, msg) for topic, subscription in self._stamped
                    for msg in take_all(subscription, STAMPED_DEPTH)]
        for topic, msg in waiting:
            t = rt.slider.t
            try:
                stamp, commands = stamped_commands(topic, msg, t)
            except ParameterError as error:
                refused.append(self._refused(str(error)))
                continue
            if topic == CONTROL_ANSWER:
                rt.gate.answer(stamp, commands)
                continue
            why = rt.gate.promise(stamp, commands, rt.t_ns)
            if why:
                refused.append(self._refused(why))
        return refused

    def _keep_readings(self, tick: Tick) -> None:
        """Keep the tick's accelerometer readings until their window is answered (lock held)."""
        readings = self._readings
        readings.extend((seconds_to_ns(sample.t), sample.z) for sample in tick.accelerations)
        answered = self.rt.gate.answered_ns
        while readings and readings[0][0] <= answered:
            readings.popleft()

    def _hand_over(self) -> None:
        """Hand a linked controller the samples and readings it has not had (all that await an
        answer, to a controller linked since the last call); it may answer at once, in this thread."""
        link = self._link
        controller = link.controller if link is not None else None
        topics = self.node.topics
        topics.linked_readers = int(controller is not None)  # (its own subscription to the samples)
        topics.linked_name = link.controller_name if link is not None and controller is not None else ""
        if link is not None:
            self._record_reports(link)
        if link is None or controller is None:
            return
        generation, sample_ns, reading_ns = self._handed
        if generation != link.generation:
            sample_ns = reading_ns = -1
        samples = [(stamp, self._recent[stamp].mean_velocity) for stamp in sorted(self._recent) if stamp > sample_ns]
        readings = [reading for reading in self._readings if reading[0] > reading_ns]
        if not (samples or readings) and generation == link.generation:
            return
        self._handed = (link.generation, samples[-1][0] if samples else sample_ns,
                        readings[-1][0] if readings else reading_ns)
        controller.deliver(samples, readings)
        self._record_reports(link)

    def _record_reports(self, link: lockstep_link.Link) -> None:
        """The linked controller's diagnostics to the recording: those stamped in the run
        (0 < stamp <= now), as the slider records other nodes' diagnostics it hears."""
        now_ns = self.rt.t_ns
        while link.reports:
            msg = link.reports.popleft()
            if 0 < stamp_ns(msg.header.stamp) <= now_ns:
                deliver(self.node.sinks, MessageRecord("diagnostics", msg, now_ns))

    def _refused(self, why: str) -> Outcome:
        """Count input refused before it became a command (a malformed stamped message; lock held)."""
        return self.rt.refuse(Command(self.rt.slider.t, PARAMETERS, {}), why, wall_ns())

    def _repeat_awaited(self) -> None:
        """Publish the state and the oldest awaited sample again (for a driver or a controller that
        joined after they went out: it follows the stamps; they carry the same stamps again)."""
        with self.node.lock:
            self.node.publish_tick(Tick(self.rt.slider.state(), [], [], paused=self.rt.gate.paused))
        awaited = self.rt.gate.awaited
        period = self._recent.get(awaited[0]) if awaited else None
        if period is not None:
            self.node.publish_mean_velocity(mean_velocity_message(period, self.node.frame_id))

    def _diagnostics_due(self) -> None:
        """Diagnostics once per diagnostics_period of simulation time, stamped with the time reached,
        once every period that ended by then is reported (they then say the same every run)."""
        t_ns = self.rt.t_ns
        if t_ns < self._next_diagnostics_ns or not self.rt.reported_through(t_ns):
            return
        while self._next_diagnostics_ns <= t_ns:
            self._next_diagnostics_ns += self._period_ns
        self.node.publish_diagnostics(stamp_ns=t_ns)

    def _not_joined(self, blocker: str) -> None:
        """A participant that has not joined yet: waited for, and said so once per lockstep_timeout."""
        self.rt.gate.join_waits += 1
        self.node.get_logger().warning(
            f"lockstep: waiting for {blocker} at t = {self.rt.slider.t:.9f} s: it has not joined yet (start it in "
            f"this namespace; the slider waits for it, and stops once a participant that joined is silent for "
            f"lockstep_timeout {self.rt.gate.timeout:g} s)")

    def _time_out(self, blocker: str) -> None:
        """No participant answered in time: name it, and stop the run (a fault)."""
        gate = self.rt.gate
        self.node.fail(SimulationFault(
            f"lockstep: waited {gate.timeout:g} s (lockstep_timeout) for {blocker}, at t = "
            f"{self.rt.slider.t:.9f} s; the run stops (is the participant running, in this namespace, "
            "with lockstep?)"))


def _unused(msg: Any) -> None:
    """The callback of a polled subscription: never called (the loop takes its messages)."""


def _nothing() -> None:
    """The callback of the guard condition that wakes the executor: the wake-up is the point."""


__all__ = ["REPEAT", "LockstepLoop", "runtime_for"]
