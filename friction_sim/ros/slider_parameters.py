"""The slider node's parameters: declared from the one vocabulary, judged by the core, applied.

The node's settings are declared once, in :data:`PARAMETERS` (``spec.SLIDER_NODE``),
with the descriptors of :mod:`friction_sim.ros.parameters` (ranges, units,
read-only).  A set then passes three stages, each here:

* rclpy's own checks (descriptor range, type, read-only, undeclared): what they
  refuse is counted and recorded by :meth:`SliderParameters.refused`, as any
  refusal, with the value as sent;
* the on-set callback :meth:`SliderParameters.judge`, the one place for
  cross-field rules: the whole set is checked by the core against the state in
  force and reaches the simulation as one new state, under the node's lock, or
  it is refused and nothing changes;
* the post-set callback :meth:`SliderParameters.applied`: the settings the tick
  thread reads (``publish_clock``, ``frame_id``) follow, and the non-physics
  changes are recorded (physics changes were recorded as commands).

Kept apart from :mod:`friction_sim.ros.slider` so the node holds its wiring
and its tick loop, and this module what a parameter set does.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol, cast

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from friction_sim.core.model import spec
from friction_sim.core.model.commands import PARAMETERS as PARAMETER_COMMAND
from friction_sim.core.model.commands import PHYSICS_FIELDS, Command, Outcome
from friction_sim.errors import SimulationFault
from friction_sim.io.sinks import ParametersRecord, Sink, deliver
from friction_sim.ros.parameters import declare_settings, watch_parameter_refusals
from friction_sim.ros.run import wall_ns

#: The node's parameters: declared once in the one vocabulary.
PARAMETERS = spec.SLIDER_NODE


class ConfiguredNode(Protocol):
    """What the parameter callbacks need of the slider node (:class:`~friction_sim.ros.slider.SliderNode`)."""

    sinks: list[Sink]

    @property
    def realtime(self) -> Any: ...
    @property
    def lock(self) -> Any: ...
    def get_logger(self) -> Any: ...
    def get_parameter(self, name: str) -> Any: ...
    def add_on_set_parameters_callback(self, callback: Any) -> None: ...
    def add_post_set_parameters_callback(self, callback: Any) -> None: ...
    def record(self, outcomes: Sequence[Outcome]) -> None: ...
    def warn_refused(self, outcome: Outcome, warn: Callable[[str], Any] | None = None) -> None: ...
    def fail(self, error: BaseException) -> None: ...
    def follow_settings(self) -> None: ...


def declare(node: Node) -> dict[str, Any]:
    """Declare the slider's parameters on ``node``; the values in force at start."""
    return declare_settings(node, PARAMETERS)


class SliderParameters:
    """The slider node's parameter callbacks (see the module): refusals, judgement, application."""

    def __init__(self, node: ConfiguredNode) -> None:
        self.node = node

    def watch(self) -> None:
        """Take part in every set from now on: rclpy's refusals, then the node's own
        callbacks (added after the refusal watch, which must run first)."""
        watch_parameter_refusals(cast(Node, self.node), PARAMETERS, self.refused)  # the node is an rclpy Node
        self.node.add_on_set_parameters_callback(self.judge)
        self.node.add_post_set_parameters_callback(self.applied)

    def refused(self, name: str, value: Any, why: str) -> None:
        """rclpy refused a parameter value before our callbacks (range, type,
        read-only): counted and recorded like any refusal (common has warned),
        with the value as it was sent (an integer 2 stays 2: the refusal is
        about its type)."""
        values = {name: value} if name in PHYSICS_FIELDS else {}
        node = self.node
        with node.lock:
            outcome = node.realtime.refuse(Command(0.0, PARAMETER_COMMAND, values), why, wall_ns())
            node.record([outcome])

    def judge(self, changes: list[Parameter]) -> SetParametersResult:
        """The one place for cross-field rules, and atomic: the whole set is
        checked by the core against the state in force (which topic commands
        may have changed since the parameters were last set) and reaches the
        simulation as one new state, under the lock, or it is refused and
        nothing changes."""
        node = self.node
        values = {p.name: p.value for p in changes}
        try:
            with node.lock:
                outcome = node.realtime.configure(values, wall_ns())
                if outcome.values or not outcome.accepted:
                    node.record([outcome])
        except SimulationFault as fault:  # the run cannot go on: say so, answer, stop
            node.fail(fault)
            return SetParametersResult(successful=False, reason=str(fault))
        node.warn_refused(outcome, node.get_logger().warning)  # each refused set is warned
        if not outcome.accepted:
            return SetParametersResult(successful=False, reason=outcome.reason)
        return SetParametersResult(successful=True)

    def applied(self, changes: list[Parameter]) -> None:
        """After a successful set: the settings the tick thread reads, and the
        record of the non-physics ones (physics changes were recorded as commands)."""
        node = self.node
        node.get_logger().info("parameters set: " + ", ".join(f"{p.name} = {p.value!r}" for p in changes))
        node.follow_settings()
        others = {p.name for p in changes} - set(spec.PLANT) - set(spec.INPUTS)
        if others:
            t = node.realtime.clock.now(wall_ns())
            deliver(node.sinks, ParametersRecord({n: node.get_parameter(n).value for n in others}, t, True))
