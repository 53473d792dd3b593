"""The slider node's publications: what a tick makes, out on its topics and to the sinks.

``pose``, ``velocity`` and ``friction_force`` (one state per fresh tick),
``mean_velocity`` (each completed period), ``accelerometer`` (its samples, when
it is on), ``diagnostics`` (the message the node builds) and ``/clock`` (only
while ``publish_clock`` is true: the publisher exists only then).  Whatever goes
out on a topic is handed to the node's sinks as it goes (a recording, a live
view), in the same order.  The states, the period means and /clock go out on a
topic only while someone reads it (they are volatile: a reader gets what comes
after it matched, either way), besides a controller that a lockstep link
serves; the sinks get them always.

:class:`SliderTopics` also counts the ticks computed and published, so a
``~/step`` or ``~/reset`` answers once the state it left is out
(:meth:`SliderTopics.wait_published`).  It is the tick thread's and the
lockstep loop's hot path: the state messages are made once and filled in place
(:func:`~friction_sim.io.messages.fill_state_messages`).

Kept apart from :mod:`friction_sim.ros.slider`, which wires the node and
ticks: this module is what goes out.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg

from friction_sim.core.model.events import SliderState
from friction_sim.core.model.records import Tick
from friction_sim.core.runtime.accelerometer import Accelerometer
from friction_sim.io.messages import (
    ACCELEROMETER,
    fill_state_messages,
    mean_velocity_message,
    message_class,
    seconds_to_ns,
    time_msg,
)
from friction_sim.io.sinks import ClockRecord, Sink, deliver, deliver_tick
from friction_sim.ros.intake import accelerometer_qos
from friction_sim.ros.slider_outputs import AccelerometerPublisher

#: The depth of each publisher's queue (and of the command subscriptions: the node's).
QOS_DEPTH = 10


class SliderTopics:
    """The slider node's publishers and the ticks they have published (see the module)."""

    def __init__(self, node: Node, sinks: list[Sink], lock: threading.Lock, stop: threading.Event,
                 accelerometer: Accelerometer | None, frame_id: str, publish_clock: bool,
                 answered_ns: Callable[[], int | None]) -> None:
        """``lock`` is the node's (held while the runtime changes), ``stop`` set when the
        node goes; ``answered_ns`` gives, in lockstep, the stamp of the last sample the
        controller answered (None in real time: see :class:`AccelerometerPublisher`)."""
        self._node, self.sinks, self._lock, self._stop = node, sinks, lock, stop
        self._answered_ns = answered_ns
        #: The frame of the states and period means (the parameter ``frame_id`` in force).
        self.frame_id = frame_id
        self._pose_pub = self._publisher(PoseStamped, "pose")
        self._velocity_pub = self._publisher(TwistStamped, "velocity")
        self._friction_pub = self._publisher(WrenchStamped, "friction_force")
        self._mean_pub = self._publisher(TwistStamped, "mean_velocity")
        self._diag_pub = self._publisher(DiagnosticArray, "diagnostics")
        self._imu_noise = accelerometer.noise if accelerometer else 0.0
        self._imu_pub = AccelerometerPublisher(self._publisher(
            message_class("sensor_msgs/msg/Imu"), ACCELEROMETER, accelerometer_qos()), self.frame_id,
            self._imu_noise) if accelerometer else None
        self._pose, self._velocity, self._friction = PoseStamped(), TwistStamped(), WrenchStamped()
        #: The state's publishers, each with its message (filled in place).  A state goes out on those
        #: that someone reads: rclpy converts a message even for no reader, ~10 us each, three a tick.
        self._state_msgs = {self._pose_pub: self._pose, self._velocity_pub: self._velocity,
                            self._friction_pub: self._friction}
        self._state_pubs = list(self._state_msgs)
        self._clock_msg = ClockMsg()
        self._clock_pub: Any = None
        self.set_publish_clock(publish_clock)
        self._published = threading.Condition()  # the tick thread's count of ticks published, for ~/step
        #: Ticks computed (counted under the lock) and published (under ``_published``).
        self.ticks_computed = self._ticks_published = 0
        #: Readers of mean_velocity in this process that a lockstep link hands the samples to
        #: (:mod:`~friction_sim.ros.lockstep_link`): the topic goes out only if another reads it.
        self.linked_readers = 0
        #: The node name of that controller ('' while none is linked): its diagnostics reach the
        #: recording through the link, not from the topic.
        self.linked_name = ""
        #: The state last published (a paused tick publishes only when it differs).
        self.last_published: SliderState | None = None

    def _publisher(self, kind: type, topic: str, depth: Any = QOS_DEPTH) -> Any:
        return self._node.create_publisher(kind, topic, depth)

    def set_publish_clock(self, on: bool) -> None:
        """Advertise /clock only while it is published (the tick thread publishes
        it under the lock, so it never sees a publisher being destroyed)."""
        with self._lock:
            if on and self._clock_pub is None:
                self._clock_pub = self._publisher(ClockMsg, "/clock")
            elif not on and self._clock_pub is not None:
                self._node.destroy_publisher(self._clock_pub)
                self._clock_pub = None

    def publish_tick(self, tick: Tick, fresh: bool = True) -> None:
        """Publish what a tick made (lock held: /clock first, then the states, the
        period means and the accelerometer's samples) and hand it to the sinks."""
        self.publish_states(tick, fresh, self.clock_of(tick, fresh))

    def clock_of(self, tick: Tick, fresh: bool) -> int:
        """Count the tick and publish /clock, to the topic and the sinks (lock held: the
        publisher may go); its number."""
        self.ticks_computed += 1
        if fresh and self._clock_pub is not None:
            t_ns = seconds_to_ns(tick.state.t)
            if self._clock_pub.get_subscription_count():
                time_msg(t_ns, self._clock_msg.clock)
                self._clock_pub.publish(self._clock_msg)
            deliver(self.sinks, ClockRecord(t_ns))
        return self.ticks_computed

    def publish_states(self, tick: Tick, fresh: bool, number: int) -> None:
        """The states, period means and accelerometer samples of tick ``number``, to the topics and sinks."""
        if fresh:
            state = tick.state
            readers = [publisher for publisher in self._state_pubs if publisher.get_subscription_count()]
            if readers:
                fill_state_messages(state, self.frame_id, self._pose, self._velocity, self._friction)
                for publisher in readers:
                    publisher.publish(self._state_msgs[publisher])
            if tick.periods and self._mean_pub.get_subscription_count() > self.linked_readers:
                for period in tick.periods:
                    self._mean_pub.publish(mean_velocity_message(period, self.frame_id))
            if self._imu_pub is not None:
                self._imu_pub.publish(tick.accelerations, hold_after_ns=self._answered_ns())
            self.last_published = state
            deliver_tick(self.sinks, tick, self.frame_id, self._imu_noise)
        with self._published:
            self._ticks_published = number
            self._published.notify_all()

    @property
    def ticks_published(self) -> int:
        """How many ticks are out (a step waits for this to reach the tick it made)."""
        return self._ticks_published

    def wait_published(self, tick: int, timeout: float = 2.0) -> None:
        """Wait until the tick thread has published tick number ``tick`` (or the node stops)."""
        with self._published:
            self._published.wait_for(lambda: self._ticks_published >= tick or self._stop.is_set(), timeout)

    def publish_mean_velocity(self, msg: Any) -> None:
        self._mean_pub.publish(msg)

    def publish_diagnostics(self, msg: DiagnosticArray) -> None:
        self._diag_pub.publish(msg)

    def flush_readings(self) -> None:
        """Lockstep, while the loop waits: publish the held accelerometer samples a reader
        that came since needs (see :class:`AccelerometerPublisher`)."""
        answered = self._answered_ns()
        if self._imu_pub is not None and answered is not None:
            self._imu_pub.flush(answered)
