"""The slider node's simulation control: ``~/pause``, ``~/resume``, ``~/step``, ``~/reset``.

Each is a std_srvs/Trigger service of the node, and the same call again for
Foxglove clients of the live view (its Call Service panel: same names, type and
answers, CDR-encoded).  A call is done on the core under the node's lock,
handed to the sinks as a command (so a recording holds it) and counted like any
command; a step or a reset answers once the tick thread has published the state
it left (see :class:`~friction_sim.core.runtime.realtime.RealtimeSlider`).

Kept apart from :mod:`friction_sim.ros.slider`, which ticks and publishes:
this module is what an operator's call does.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from rclpy.serialization import serialize_message
from std_srvs.srv import Trigger

from friction_sim.core.model.commands import CONTROLS, RESET, STEP, Outcome
from friction_sim.errors import SimulationFault
from friction_sim.ros.run import wall_ns
from friction_sim.ros.slider_outputs import control_text


class PublishedTicks(Protocol):
    """The node's count of ticks (:class:`~friction_sim.ros.slider_topics.SliderTopics`)."""

    @property
    def ticks_computed(self) -> int: ...
    def wait_published(self, tick: int, timeout: float = 2.0) -> None: ...


class ControlledNode(Protocol):
    """What the control calls need of the slider node (:class:`~friction_sim.ros.slider.SliderNode`)."""

    @property
    def realtime(self) -> Any: ...
    @property
    def lock(self) -> Any: ...
    @property
    def topics(self) -> PublishedTicks: ...
    def get_logger(self) -> Any: ...
    def get_parameter(self, name: str) -> Any: ...
    def get_fully_qualified_name(self) -> str: ...
    def create_service(self, *args: Any, **kwargs: Any) -> Any: ...
    def record(self, outcomes: Sequence[Outcome]) -> None: ...
    def warn_refused(self, outcome: Outcome, warn: Callable[[str], Any] | None = None) -> None: ...
    def fail(self, error: BaseException) -> None: ...


class SimulationControl:
    """The control calls of the slider node (see the module), over ROS and the live view."""

    def __init__(self, node: ControlledNode) -> None:
        self.node = node
        self._serving = threading.Event()  # set once the node is whole: the live view may call in before

    def live_services(self) -> list[Any]:
        """The control services again, for Foxglove clients of the live view
        (its Call Service panel): same names, type and answers as over ROS."""
        from friction_sim.io.live import LiveService

        return [LiveService(f"{self.node.get_fully_qualified_name()}/{name}", "std_srvs/srv/Trigger",
                            functools.partial(self._on_live_call, name)) for name in CONTROLS]

    def serve(self) -> None:
        """``~/pause``, ``~/resume``, ``~/step`` and ``~/reset`` (std_srvs/Trigger) as ROS
        services, and the live view's calls answered from now on (the node is whole)."""
        for name in CONTROLS:
            self.node.create_service(Trigger, f"~/{name}", functools.partial(self.call, name))
        self._serving.set()

    def _on_live_call(self, name: str, request: bytes) -> bytes:
        """A control call from a Foxglove client: answered as the ROS service answers (CDR)."""
        if not self._serving.is_set():
            raise RuntimeError("the slider is still starting; call again")
        return bytes(serialize_message(self.call(name, Trigger.Request(), Trigger.Response())))

    def call(self, name: str, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """A ``~/pause``, ``~/resume``, ``~/step`` or ``~/reset`` call: done on
        the core under the lock, recorded and counted like any command; a step
        or reset answers once the tick thread has published the state it left."""
        node = self.node
        try:
            with node.lock:
                outcome = self._control(name, wall_ns())
                state, published = node.realtime.slider.state(), node.topics.ticks_computed + 1
                node.record([outcome])
        except SimulationFault as fault:  # the run cannot go on: say so, answer, stop
            node.fail(fault)
            response.success, response.message = False, str(fault)
            return response
        node.warn_refused(outcome, node.get_logger().warning)  # each refused call is warned
        if outcome.accepted and name in (STEP, RESET):
            node.topics.wait_published(published)
        response.success = outcome.accepted
        response.message = outcome.reason or control_text(outcome, state)
        if outcome.accepted:
            node.get_logger().info(response.message)
        return response

    def _control(self, name: str, now: int) -> Outcome:
        """Pause, resume, step (by step_time, or step_periods periods) or reset the core (lock held)."""
        rt = self.node.realtime
        if name == STEP:
            duration = rt.step_length(self.node.get_parameter("step_periods").value,
                                      self.node.get_parameter("step_time").value)
            return rt.step(duration, now)
        act: Callable[[int], Outcome] = getattr(rt, name)
        return act(now)
