"""The controller node's answers while its plant runs in lockstep.

A slider in lockstep (:mod:`friction_sim.core.runtime.lockstep`) waits for an
answer to each ``mean_velocity`` sample on ``control_answer``
(:mod:`friction_sim.io.stamped`): a JointState stamped with the sample it
answers, carrying what the controller sets (Pa, or the drive level and a
frequency tracking moved; nothing while it stands by or refuses the sample).
:class:`LockstepAnswers` holds the node's side: the samples and accelerometer
readings in the order the answers need them
(:class:`~friction_sim.core.runtime.answers.AnswerQueue`), the answer itself,
and the diagnostics, which come every ``diagnostics_period`` of simulation
time, stamped with the sample answered.  The controller learns that its plant
runs in lockstep, and the actuation delay, from the plant node at start-up.

The answers have a thread of their own (:meth:`LockstepAnswers._run`): it sleeps
until a sample (or, while an answer waits for them, a reading) waits on its
subscription, takes them and answers, holding the node's callback lock as every
callback does.  Through the executor each sample cost a wake-up and a rebuild of
its wait set over every entity of the node (parameter services, timers, ...):
more than the answer itself, fifty times a simulated second.  With the slider
in this process (an experiment, the feeder) there is no such thread: the two are
linked (:mod:`friction_sim.ros.lockstep_link`) and the slider's loop hands the
samples and readings over in its own thread, which answers at once.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import Any, Protocol, cast

from friction_sim.core.control.reach import ControlOutput
from friction_sim.core.model.spec import NS_PER_S
from friction_sim.core.runtime.answers import AnswerQueue
from friction_sim.core.runtime.controller import RealtimeController
from friction_sim.errors import ParameterError
from friction_sim.io.messages import ACCELEROMETER, message_class, stamp_ns
from friction_sim.io.series import imu_normals
from friction_sim.io.stamped import CONTROL_ANSWER, STAMPED_DEPTH, STAMPED_TYPE, stamped_message
from friction_sim.ros import lockstep_link
from friction_sim.ros.intake import Arrivals, PolledGroup, take_all


class AnsweringNode(Protocol):
    """What the answers need of the controller node (:class:`~friction_sim.ros.controller.ControllerNode`)."""

    @property
    def runtime(self) -> RealtimeController: ...
    @property
    def accelerometer_group(self) -> PolledGroup: ...
    @property
    def accelerometer(self) -> Any: ...
    @property
    def samples_group(self) -> PolledGroup: ...
    @property
    def mean_velocity(self) -> Any: ...
    @property
    def callback_lock(self) -> Any: ...
    @property
    def context(self) -> Any: ...
    @property
    def ready(self) -> bool: ...
    def get_parameter(self, name: str) -> Any: ...
    def get_fully_qualified_name(self) -> str: ...
    def resolve_topic_name(self, topic: str, *, only_expand: bool = False) -> str: ...
    def create_publisher(self, *args: Any, **kwargs: Any) -> Any: ...

    def subscribe_accelerometer(self, *, lockstep: bool, reading: bool = True) -> Any: ...
    def warn(self, text: str) -> None: ...
    def decide(self, output: ControlOutput, boundary: float) -> dict[str, float]: ...
    def publish_diagnostics(self) -> None: ...
    def guarded(self, where: str, callback: Any) -> Any: ...
    def internal_error(self, where: str, error: BaseException) -> None: ...

#: The plant node's parameters read at start-up besides its model: whether it runs in
#: lockstep, with what actuation delay, and its accelerometer's rate (the answers wait for it).
LOCKSTEP_READ = ("lockstep", "actuation_delay", "accelerometer_rate")
#: Accelerometer readings taken from the topic at once (its queue's depth).
ACCELEROMETER_BATCH = 10_000
#: Samples taken at once (the slider waits for each answer: a few at most are on their way).
SAMPLES_BATCH = 100
#: Wall time [s] the answers' thread sleeps at most before it looks whether it is stopped.
_LOOK_EVERY = 0.05


class LockstepAnswers:
    """Answer each sample once, in order, when what it needs has come (see the module)."""

    def __init__(self, node: AnsweringNode, delay: float, accelerometer_rate: float) -> None:
        self.node = node
        self.queue = AnswerQueue(round(float(delay) * NS_PER_S), float(accelerometer_rate),
                                 round(node.get_parameter("diagnostics_period").value * NS_PER_S))
        self._publisher = node.create_publisher(message_class(STAMPED_TYPE), CONTROL_ANSWER, STAMPED_DEPTH)
        self.runtime = node.runtime
        self.runtime.control.clock.exact = True
        node.accelerometer_group.open = False  # drained with each sample: a wake-up per reading costs too much
        node.samples_group.open = False  # taken by the answers' thread
        #: Whether this node reads the accelerometer topic (see :meth:`_reads_accelerometer`).
        self._reading = False
        #: Whether an answer waits for readings (the thread then wakes for one too).
        self._awaiting_readings = False
        node.subscribe_accelerometer(lockstep=True, reading=False)
        #: The slider of this process that hands this node its samples (None: they come on the topics;
        #: linked last, once this object is whole: the slider's thread may hand it samples at once).
        self._link: lockstep_link.Link | None = None
        self._deliver = node.guarded("lockstep answers (linked)", self._take_delivered)
        self._topics = lockstep_link.TurnTopics(node.mean_velocity.topic_name, self._publisher.topic_name,
                                                node.resolve_topic_name(ACCELEROMETER))
        self._reads_accelerometer(lockstep_link.linkable(node.context, self._topics))
        #: The simulation time [ns] of the sample being (or last) answered: the diagnostics' stamp.
        self.stamp_ns = 0
        #: The law decided between samples (a target, a parameter): the change acts with the next
        #: answer, so the sample it answers was measured before it (noted before that sample is judged).
        self.changed = False
        self._arrivals = Arrivals([node.mean_velocity], node.context, capacity=2)
        self._stop = threading.Event()
        self._take = node.guarded("lockstep answers", self._take_waiting)
        self._thread = threading.Thread(target=self._run, name="controller_answers", daemon=True)

    def start(self) -> None:
        """Begin to answer (once the node holds this object): linked to the slider of this
        process if there is one, else from the topics, in a thread of their own."""
        self._link = lockstep_link.attach(self.node.context, self._topics, self, self.node.get_fully_qualified_name())
        if self._link is None:  # (linked, the slider's thread brings every sample)
            self._thread.start()

    def _run(self) -> None:
        """Until stopped: sleep until a sample (or an awaited reading) waits, then answer.  An
        error in an answer is reported like any callback's, and the thread goes on; one in the
        wait itself (the context shut down under it) is reported, and the thread ends."""
        while not self._stop.is_set() and self.node.context.ok():
            reading = self.node.accelerometer if self._awaiting_readings else None
            self._arrivals.subscriptions = [self.node.mean_velocity] + ([reading] if reading is not None else [])
            try:
                self._arrivals.wait(_LOOK_EVERY)
            except Exception as error:  # noqa: BLE001 - said, never a thread that dies in silence
                if not self._stop.is_set() and self.node.context.ok():
                    self.node.internal_error("lockstep answers (the thread stops)", error)
                return
            if not self._stop.is_set():
                self._take()

    def stop(self) -> None:
        """End the answers' thread (the node is being destroyed), at once: its wait is woken."""
        self._stop.set()
        if self._link is not None:
            lockstep_link.detach(self._link, self)
        self._arrivals.wake()
        if self._thread is not threading.current_thread():
            if self._thread.ident is not None:
                self._thread.join(timeout=2.0)
            if not self._thread.is_alive():
                self._arrivals.destroy()

    def _take_waiting(self) -> None:
        """Take the waiting samples, in order, and answer what can be (callback lock held)."""
        messages: list[Any] = take_all(self.node.mean_velocity, SAMPLES_BATCH)
        for msg in messages:
            self.sample(stamp_ns(msg.header.stamp), msg.twist.linear.x)
        if not messages and self._awaiting_readings:
            self._drain()
            self.answer_waiting()

    def deliver(self, samples: Sequence[tuple[int, float]], readings: Sequence[tuple[int, float]]) -> None:
        """From a linked slider, in its thread: readings and samples (see :mod:`~friction_sim.ros.lockstep_link`)."""
        self._deliver(samples, readings)

    def _take_delivered(self, samples: Sequence[tuple[int, float]], readings: Sequence[tuple[int, float]]) -> None:
        """Queue the readings, then take the samples in order (callback lock held)."""
        self.queue.accelerations(readings)
        for stamp, speed in samples:
            self.sample(stamp, speed)
        if not samples:
            self.answer_waiting()

    def acts_at(self, boundary: float) -> float:
        """When the answer to the sample stamped ``boundary`` [s] acts on the plant [s]."""
        return boundary + self.queue.delay_ns / NS_PER_S

    def sample(self, stamp_ns: int, speed: float) -> None:
        """A mean_velocity sample: queue it (or send a repeated one its answer again), answer what can be."""
        seen = self.queue.sample(stamp_ns, speed)
        if seen == "repeat":
            self._send(stamp_ns, self.queue.last_answer)
        if self._reads_accelerometer() and self._link is None:
            self._drain()
        self.answer_waiting()

    def _reads_accelerometer(self, linked: bool = False) -> bool:
        """Whether the answers need the accelerometer (the inner loop of a resonant plant);
        subscribed the first time they do.  Until then the node has no reader on the topic:
        a reader as deep as a lockstep window needs costs the slider ~0.1 ms a reading (a
        thousand a second); joining later costs nothing, the topic is transient local."""
        drive = self.runtime.drive
        reads = drive is not None and drive.inner_loop
        if reads and not self._reading and not linked and self._link is None:
            self.node.subscribe_accelerometer(lockstep=True, reading=True)
            self._reading = True
        return reads

    def _drain(self) -> None:
        """Queue every accelerometer reading waiting on the topic (taken serialized: see
        :func:`~friction_sim.io.series.imu_normals`)."""
        datas = cast(list[bytes], take_all(self.node.accelerometer, ACCELEROMETER_BATCH))  # (a raw subscription)
        self.queue.accelerations(imu_normals(datas))

    def answer_waiting(self) -> None:
        """Answer every queued sample whose turn has come (none before the model is settled)."""
        if not self.node.ready:
            return
        while True:
            ready = self.queue.next_ready(self._reads_accelerometer())
            # (a sample that waits for readings lets the next reading wake the answers' thread)
            self._awaiting_readings = ready is None and self.queue.waiting
            if ready is None:
                return
            stamp_ns, speed, readings = ready
            for error in self.runtime.take_accelerations([(t_ns / NS_PER_S, normal) for t_ns, normal in readings]):
                self.node.warn(f"{error}; sample ignored")
            self._answer(stamp_ns, speed)

    def _answer(self, stamp_ns: int, speed: float) -> None:
        self.stamp_ns = stamp_ns
        t = stamp_ns / NS_PER_S
        values: dict[str, float] = {}
        if self.changed:
            control = self.runtime.control
            control.clock.note_change(0, 1.0 / control.frequency, self.acts_at(t))
            self.changed = False
        try:
            output = self.runtime.take_sample(speed, t, 0, self.runtime.active)
        except ParameterError as error:
            self.node.warn(f"{error}; sample ignored")
            output = None
        if output is not None:
            values = self.node.decide(output, t)
        self.queue.answered(stamp_ns, values)
        self._send(stamp_ns, values)
        if self.queue.diagnostics_due(stamp_ns):
            self.node.publish_diagnostics()

    def _send(self, stamp_ns: int, values: dict[str, float]) -> None:
        """The answer: to a linked slider directly, and on the topic whenever another listens."""
        msg = stamped_message(stamp_ns, values)
        if self._link is not None:
            self._link.answer(msg)
            if self._publisher.get_subscription_count() <= 1:  # (the slider's own: it has the answer)
                return
        self._publisher.publish(msg)

    def report(self, msg: Any) -> None:
        """The node's diagnostics just published: to a linked slider's recording too."""
        if self._link is not None:
            self._link.reports.append(msg)

    def values(self) -> dict[str, Any]:
        """The answers' figures for diagnostics."""
        return self.queue.values()


__all__ = ["LOCKSTEP_READ", "LockstepAnswers"]
