"""The slider node's loop in real time: a tick at ``publish_rate`` on absolute deadlines.

Each tick takes the waiting commands (:meth:`SliderNode.take_commands`), advances
the core to the present and publishes what it made (through
:class:`~friction_sim.ros.slider_topics.SliderTopics`), then lets the wall time the
recorder made it wait pass without simulation time.  After a stall the loop goes
on from now rather than bursting to catch up: the physics follows the clock.
While paused a tick publishes only what changed (a step, a reset, a command).

The lockstep counterpart, which keeps no pace, is
:class:`~friction_sim.ros.slider_lockstep.LockstepLoop`; the node runs one of the
two in its tick thread.
"""

from __future__ import annotations

import threading
import time
from typing import Any, Protocol

from friction_sim.ros.run import wall_ns
from friction_sim.ros.slider_outputs import RecorderHealth
from friction_sim.ros.slider_topics import SliderTopics


class ClockedNode(Protocol):
    """What the real-time loop needs of the slider node (:class:`~friction_sim.ros.slider.SliderNode`)."""

    @property
    def realtime(self) -> Any: ...
    @property
    def lock(self) -> Any: ...
    @property
    def context(self) -> Any: ...
    @property
    def topics(self) -> SliderTopics: ...
    def take_commands(self) -> None: ...


class RealtimeLoop:
    """The slider node's loop in real time (see the module)."""

    def __init__(self, node: ClockedNode, stop: threading.Event, recorder: RecorderHealth) -> None:
        """``stop`` is set when the node goes; ``recorder`` tells how long the recorder made it wait."""
        self.node, self._stop, self._recorder = node, stop, recorder

    def run(self) -> None:
        """Tick at publish_rate on absolute deadlines; after a stall, go on from
        now rather than bursting to catch up (the physics follows the clock)."""
        node, rt = self.node, self.node.realtime
        deadline = time.monotonic()
        while not self._stop.is_set():
            period = 1.0 / rt.publish_rate
            deadline += period
            delay = deadline - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
            elif delay < -period:
                deadline = time.monotonic()
            if self._stop.is_set() or not node.context.ok():
                return
            node.take_commands()
            self._tick()
            self._hold_for_recorder()

    def _tick(self) -> None:
        """Advance, then publish the state (and /clock).  While paused nothing
        is published unless something changed (a step, a reset, a command):
        simulation time, and /clock with it, stands still."""
        node = self.node
        topics = node.topics
        with node.lock:
            tick = node.realtime.tick(wall_ns())
            fresh = not tick.paused or tick.state != topics.last_published or bool(tick.events or tick.periods)
            number = topics.clock_of(tick, fresh)
        topics.publish_states(tick, fresh, number)  # outside the lock: a set waits for the computation only

    def _hold_for_recorder(self) -> None:
        """The recorder makes a producer wait rather than drop a message; the
        wall time the tick waited passes without simulation time (no jump;
        the achieved real-time factor in diagnostics shows it, and the next
        tick counts as late)."""
        waited_ns = self._recorder.newly_waited_ns()
        if waited_ns:
            with self.node.lock:
                self.node.realtime.hold(waited_ns, wall_ns())
