"""How the nodes take what users send them: in batches, with refusals warned about sparingly.

:class:`PolledGroup` and :func:`take_with_info` take a command topic's queue in
one go (a flood costs one small batch, not a wake-up per message);
:class:`ThrottledWarning` warns about refused input at most once a second at
the cost of one clock read per call (rclpy's own ``throttle_duration_sec``
costs about 0.18 ms per call even when it prints nothing, which a flood of
bad commands turns into a starved node).
"""

from __future__ import annotations

import math
import time
from typing import Any

from rclpy.callback_groups import CallbackGroup
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription

from friction_sim.io.messages import ACCELEROMETER_DEPTH

#: At most one warning about refused input per this many seconds (and node).
WARN_INTERVAL = 1.0
#: What rclpy raises when it cannot turn a message it has taken into a Python object: seen twice in
#: about twenty CI runs on a loaded machine, once in a slider's take, once in a test driver's executor
#: (the cause is inside rclpy's C++ take).  The message is lost; the node counts it and goes on.
CONVERSION_FAILURE = "Unable to convert call argument"


class LostMessages:
    """Messages rclpy took but could not convert (:data:`CONVERSION_FAILURE`), counted per process."""

    count = 0
    last = ""

    @classmethod
    def lost(cls, error: RuntimeError) -> bool:
        """Count ``error`` if it is rclpy's conversion failure (True), else leave it (False)."""
        if CONVERSION_FAILURE not in str(error):
            return False
        cls.count += 1
        cls.last = str(error).split(" (#define")[0]
        return True


class ThrottledWarning:
    """``logger.warning`` at most once per ``interval`` seconds; the calls in
    between cost one monotonic clock read, and the next warning says how many
    it stood for."""

    def __init__(self, logger: Any, interval: float = WARN_INTERVAL) -> None:
        self._logger = logger
        self.interval = interval
        self._next = -math.inf
        self.suppressed = 0

    def __call__(self, text: str) -> None:
        now = time.monotonic()
        if now < self._next:
            self.suppressed += 1
            return
        self._next = now + self.interval
        if self.suppressed:
            text += f" (+{self.suppressed} more refused in the last {self.interval:g} s, not shown)"
            self.suppressed = 0
        self._logger.warning(text)


class PolledGroup(CallbackGroup):
    """A callback group whose subscriptions their owner drains itself (with
    :func:`take_all`), at a time of its choosing, while the group is shut;
    while :attr:`open`, a waiting message wakes the executor, which runs one
    callback of the group at a time.  rclpy leaves an entity whose group cannot
    execute out of its wait set, so a shut group costs the executor nothing.

    The slider's group is always shut: it takes its commands at the start of
    each tick, so a flood costs a bounded amount of work per tick instead of an
    executor wake-up (and a wait-set rebuild in Python) per message.  The
    controller opens its group while quiet and shuts it for a hold-off after
    each batch.
    """

    def __init__(self, *, open: bool = False) -> None:
        super().__init__()
        self.open = open
        self._busy = False

    def can_execute(self, entity: object) -> bool:
        return self.open and not self._busy

    def beginning_execution(self, entity: object) -> bool:
        if not self.open or self._busy:
            return False
        self._busy = True
        return True

    def ending_execution(self, entity: object) -> None:
        self._busy = False


def take_all(subscription: Subscription, limit: int) -> list[object]:
    """Take up to ``limit`` waiting messages from ``subscription``, oldest first."""
    return [message for message, _ in take_with_info(subscription, limit)]


def take_with_info(subscription: Subscription, limit: int) -> list[tuple[Any, dict[str, Any]]]:
    """Up to ``limit`` waiting (message, message info) pairs, oldest first
    (rclpy's executor takes messages with the same call; the info holds the
    arrival time, ``received_timestamp`` in ns)."""
    taken_all = []
    handle = subscription.handle
    for _ in range(limit):
        try:
            with handle:
                taken = handle.take_message(subscription.msg_type, subscription.raw)
        except RuntimeError as error:
            if LostMessages.lost(error):
                continue  # counted (diagnostics ``messages_lost``); the queue's next message may be fine
            raise
        if taken is None:
            break
        taken_all.append((taken[0], taken[1]))
    return taken_all


class Arrivals:
    """Sleep until a message waits on one of ``subscriptions`` (drained by their
    owner, :class:`PolledGroup`) or a timeout passes.

    A loop that drains its own subscriptions (the slider's lockstep loop, the
    controller's lockstep answers) must
    not poll them while it waits for an answer: a poll every 0.1 ms costs as
    much CPU as the answer it waits for, and the GIL with it.  rclpy has no
    public call for this; its own ``rclpy.wait_for_message`` uses the same
    wait set of the rclpy implementation, which releases the GIL while it waits.
    """

    def __init__(self, subscriptions: list[Subscription], context: Any, capacity: int | None = None) -> None:
        #: The subscriptions waited on (at most ``capacity``: the owner may change them between waits).
        self.subscriptions = subscriptions
        self._wait_set = _rclpy.WaitSet(capacity or len(subscriptions), 1, 0, 0, 0, 0, context.handle)
        with context.handle:
            self._wake = _rclpy.GuardCondition(context.handle)

    def wait(self, timeout: float) -> None:
        """Until a message waits, :meth:`wake` is called, or ``timeout`` seconds."""
        wait_set = self._wait_set
        wait_set.clear_entities()
        for subscription in self.subscriptions:
            wait_set.add_subscription(subscription.handle)
        wait_set.add_guard_condition(self._wake)
        wait_set.wait(round(timeout * 1e9))

    def wake(self) -> None:
        """End the present (or the next) wait at once: its owner stops."""
        self._wake.trigger_guard_condition()

    def destroy(self) -> None:
        self._wait_set.destroy_when_not_in_use()
        self._wake.destroy_when_not_in_use()


def arrival(info: Any) -> int:
    """When a message arrived (ns), from rclpy's message info."""
    return int(info.get("received_timestamp") or 0) if isinstance(info, dict) else 0


#: Readings a real-time controller keeps queued: a tenth of a second at 1 kHz.
REAL_TIME_READINGS = 100


def accelerometer_qos(*, lockstep: bool = True) -> Any:
    """The accelerometer topic's QoS.  The slider's publisher, and a controller's subscription
    in lockstep: reliable, :data:`ACCELEROMETER_DEPTH` deep and transient local, so a controller
    that joins late still gets the readings of the windows it has to answer, and none is lost
    while it answers.  A controller's subscription in real time: volatile and
    :data:`REAL_TIME_READINGS` deep, so a controller that falls behind drops old readings
    instead of working through a backlog of the past (it matches the publisher too, as
    ``ros2 topic echo`` does)."""
    if not lockstep:
        return QoSProfile(depth=REAL_TIME_READINGS, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
    return QoSProfile(depth=ACCELEROMETER_DEPTH, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
