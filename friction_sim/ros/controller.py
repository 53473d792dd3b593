"""The mean-speed controller node: ``ros2 run friction_sim controller``.

A thin ROS 2 adapter around :class:`friction_sim.core.control.MeanSpeedController`.
All names are relative, so it runs in the same namespace as its slider.

Subscriptions: ``target_speed`` (std_msgs/Float64, m/s), ``mean_velocity``
(geometry_msgs/TwistStamped, from the slider), ``drive_force`` and
``excitation_frequency`` (std_msgs/Float64, the same commands the slider
takes, so the model follows the plant's inputs).
Publications: ``excitation_amplitude`` (std_msgs/Float64, Pa in N) after each
mean_velocity sample and on every change of target, drive force or
frequency; ``diagnostics`` (DiagnosticArray, status name ``controller``) at
1 Hz and whenever the target becomes unreachable or reachable again.

With ``plant_node`` set (default ``slider``) the controller reads mass, mu,
gravity and mean_window_periods from that node's parameters at start-up
through the parameter services; if the node does not answer within 5 s it
says so and keeps its own.  With ``active`` false it stands by, publishing
nothing, until the first target_speed message (or parameter) arrives: an
experiment can steer the slider open loop first.  It publishes nothing until
the model is settled and
something has subscribed to ``excitation_amplitude`` for 0.5 s (or 5 s have
passed): a command published while discovery is still matching the two ends
can arrive late, and the controller would misjudge when its output took
effect.
"""

from __future__ import annotations

import copy
import functools
import time
from collections.abc import Callable, Sequence
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import TwistStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from std_msgs.msg import Float64

from friction_sim.core import spec
from friction_sim.core.commands import CONTROLLER, consumed_by
from friction_sim.core.control import ControllerConfig, ControlOutput, MeanSpeedController
from friction_sim.core.params import SliderParams
from friction_sim.errors import ParameterError
from friction_sim.io.messages import command_from_message, key_values, message_class, ns_to_seconds, stamp_ns
from friction_sim.ros.common import declare_settings, run_node, wall_ns

QOS_DEPTH = 10
PLANT_TIMEOUT = 5.0
DISCOVERY_SETTLE = 0.5
MODEL = tuple(spec.PLANT)
#: The node's parameters: declared once in the one vocabulary.
PARAMETERS = spec.CONTROLLER_NODE
#: Parameters that make up the ControllerConfig.
CONFIG = {*MODEL, "integral_gain", "max_amplitude_ratio", "settle_margin", "mean_window_periods"}


class ControllerNode(Node):
    """Publishes the excitation amplitude that makes the slider creep at the target speed."""

    def __init__(self, node_name: str = "controller", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        values = declare_settings(self, PARAMETERS)
        self._control = MeanSpeedController(
            _config(values), drive_force=values["drive_force"], frequency=values["excitation_frequency"],
            target_speed=values["target_speed"],
        )
        self.accepted = 0
        self.rejected = 0
        self.last_rejection = ""
        self.model_source = "own parameters"
        self._last_published: float | None = None
        self._warned_unreachable = False
        self._warned_runaway = False
        self.output_listeners: list[Callable[[ControlOutput], None]] = []
        self._amplitude_pub = self.create_publisher(Float64, "excitation_amplitude", QOS_DEPTH)
        self._diag_pub = self.create_publisher(DiagnosticArray, "diagnostics", QOS_DEPTH)
        for entry in consumed_by(CONTROLLER):  # target_speed, drive_force, excitation_frequency
            self.create_subscription(message_class(entry.message_type), entry.name,
                                     functools.partial(self._on_command, entry.name), QOS_DEPTH)
        self.create_subscription(TwistStamped, "mean_velocity", self._on_mean_velocity, QOS_DEPTH)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(1.0, self._publish_diagnostics, clock=steady)
        self.add_on_set_parameters_callback(self._set_parameters)
        self.add_post_set_parameters_callback(self._parameters_set)
        self.ready = False
        self.active: bool = values["active"]
        self._plant_settled = not values["plant_node"]
        self._deadline = time.monotonic() + PLANT_TIMEOUT
        if not self._plant_settled:
            self._plant = AsyncParameterClient(self, values["plant_node"])
            self._plant_future: Any = None
        self._matched_at: float | None = None
        self._startup_timer = self.create_timer(0.05, self._start_up, clock=steady)

    @property
    def control(self) -> MeanSpeedController:
        return self._control

    # -- start-up: the plant's parameters ---------------------------------------

    def _start_up(self) -> None:
        """Settle the model, then wait for a listener to the output; then go."""
        if not self._plant_settled:
            self._poll_plant()
            return
        now = time.monotonic()
        if self._amplitude_pub.get_subscription_count() == 0:
            self._matched_at = None
            if now < self._deadline:
                return
        elif self._matched_at is None:
            self._matched_at = now
        if self._matched_at is not None and now - self._matched_at < DISCOVERY_SETTLE:
            return  # both ends of a new connection need a moment to match
        self.destroy_timer(self._startup_timer)
        self.ready = True
        self._publish(self._control.output)

    def _poll_plant(self) -> None:
        if self._plant_future is None and self._plant.services_are_ready():
            self._plant_future = self._plant.get_parameters([*MODEL, "mean_window_periods"])
        if self._plant_future is not None and self._plant_future.done():
            self._adopt_plant(self._plant_future.result())
        elif time.monotonic() > self._deadline:
            self._settle(f"plant node '{self.get_parameter('plant_node').value}' did not answer within "
                         f"{PLANT_TIMEOUT:g} s: using this node's own mass, mu and gravity", warn=True)

    def _adopt_plant(self, response: Any) -> None:
        """Take the plant's mass, mu, gravity and window as this node's own
        parameters (validated and applied like any parameter change)."""
        names = [*MODEL, "mean_window_periods"]
        try:
            values = [Parameter.from_parameter_msg(_named(name, value)).value
                      for name, value in zip(names, response.values)]
            update = [Parameter(n, value=float(v)) for n, v in zip(MODEL, values[:3])]
            update.append(Parameter("mean_window_periods", value=int(values[3])))
        except (TypeError, ValueError, IndexError) as error:
            self._settle(f"plant parameters unusable ({error}): using this node's own", warn=True)
            return
        result = self.set_parameters_atomically(update)
        if not result.successful:
            self._settle(f"plant parameters unusable ({result.reason}): using this node's own", warn=True)
            return
        model = self._control.config.model
        self.model_source = f"plant node '{self.get_parameter('plant_node').value}'"
        self._settle(f"model from {self.model_source}: mass {model.mass:g} kg, mu {model.mu:g}, "
                     f"gravity {model.gravity:g} m/s^2")

    def _settle(self, message: str, warn: bool = False) -> None:
        (self.get_logger().warning if warn else self.get_logger().info)(message)
        self._plant_settled = True
        self._deadline = time.monotonic() + PLANT_TIMEOUT

    # -- commands -----------------------------------------------------------------

    def _on_command(self, name: str, msg: Any) -> None:
        """A command on one of the topics the controller consumes: each sets one
        input of the control law (a target makes a standing-by controller active)."""
        command = command_from_message(name, msg, 0.0)
        (field, value), = command.values.items()
        setters = {"target_speed": self._control.set_target, "drive_force": self._control.set_drive_force,
                   "excitation_frequency": self._control.set_frequency}
        if self._apply(name, value, setters[field]) and field == "target_speed" and not self.active:
            self.active = True
            self._publish(self._control.output)

    def _on_mean_velocity(self, msg: TwistStamped) -> None:
        t = ns_to_seconds(stamp_ns(msg.header.stamp))
        if not (self.ready and self.active):
            self._control.clock.observe(t, wall_ns())  # learn the plant's pace while standing by
            return
        self._apply("mean_velocity", msg.twist.linear.x,
                    lambda v: self._control.on_mean_velocity(v, t, wall_ns()), always_publish=True)

    def _apply(self, topic: str, value: float, change: Callable[[float], ControlOutput],
               always_publish: bool = False) -> bool:
        before = self._control.output
        try:
            output = change(value)
        except ParameterError as error:
            self.rejected += 1
            self.last_rejection = str(error)
            self.get_logger().warning(f"{topic}: {error}; last valid value kept", throttle_duration_sec=1.0)
            return False
        if topic != "mean_velocity":
            self.accepted += 1
        if always_publish or output.amplitude != before.amplitude or topic != "mean_velocity":
            self._publish(output)
        return True

    # -- publishing ---------------------------------------------------------------

    def _publish(self, output: ControlOutput) -> None:
        if not (self.ready and self.active):
            return
        if output.amplitude != self._last_published:
            self._control.clock.note_change(wall_ns())
            self._last_published = output.amplitude
        self._amplitude_pub.publish(Float64(data=output.amplitude))
        self._warn_on_conditions(output)
        for listener in self.output_listeners:
            listener(output)

    def _warn_on_conditions(self, output: ControlOutput) -> None:
        """Warn once each time the target becomes unreachable or the drive runs away."""
        if output.unreachable and not self._warned_unreachable:
            self.get_logger().warning(
                f"target {output.target_speed!r} m/s is unreachable with Pa <= "
                f"{self._control.config.max_amplitude_ratio:g} m g: saturated at {output.amplitude:g} N")
            self._publish_diagnostics()
        if output.runaway and not self._warned_runaway:
            self.get_logger().warning(
                f"phi = {output.phi:.3f} >= 1: the drive force exceeds friction, the slider slides on "
                "whatever the excitation; Pa set to 0")
        if output.unreachable != self._warned_unreachable and not output.unreachable:
            self._publish_diagnostics()
        self._warned_unreachable, self._warned_runaway = output.unreachable, output.runaway

    def _publish_diagnostics(self) -> None:
        out = self._control.output
        status = DiagnosticStatus(name="controller", hardware_id=self.get_fully_qualified_name())
        problems = [text for flag, text in ((out.unreachable, "target unreachable"),
                                            (out.saturated and not out.unreachable, "saturated"),
                                            (out.runaway, "phi >= 1: no control over the speed"),
                                            (not self.ready, "waiting for the plant's parameters"),
                                            (self.ready and not self.active, "standing by for a target")) if flag]
        status.level = DiagnosticStatus.WARN if problems else DiagnosticStatus.OK
        status.message = "; ".join(problems) if problems else "regulating"
        values = {
            "target_speed": out.target_speed, "measured_mean_speed": self._control.measured_speed,
            "u_target": out.u_target, "phi": out.phi, "feedforward_ratio": out.feedforward_ratio,
            "applied_ratio": out.applied_ratio, "excitation_amplitude": out.amplitude,
            "integral": out.integral, "saturated": out.saturated, "unreachable": out.unreachable,
            "runaway": out.runaway, "drive_force": self._control.drive_force,
            "excitation_frequency": self._control.frequency, "model_source": self.model_source,
            "commands_accepted": self.accepted, "commands_rejected": self.rejected,
            "last_rejection": self.last_rejection,
        }
        status.values = key_values(values)
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(msg)

    # -- parameters ---------------------------------------------------------------

    def _set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """Cross-field rules, checked on a copy of the controller as it is now
        (drive force and frequency follow the topics): the change takes effect
        whole, or it is refused and nothing changes."""
        values = {p.name: p.value for p in changes}
        candidate = copy.copy(self._control)
        try:
            if values.keys() & CONFIG:
                current = {name: self.get_parameter(name).value for name in PARAMETERS}
                candidate.config = _config({**current, **values})
            if "drive_force" in values:
                candidate.set_drive_force(values["drive_force"])
            if "excitation_frequency" in values:
                candidate.set_frequency(values["excitation_frequency"])
            if "target_speed" in values:
                candidate.set_target(values["target_speed"])
        except ParameterError as error:
            self.rejected += 1
            self.last_rejection = str(error)
            return SetParametersResult(successful=False, reason=str(error))
        self._control = candidate
        if "active" in values or "target_speed" in values:
            self.active = values.get("active", True) or "target_speed" in values
        return SetParametersResult(successful=True)

    def _parameters_set(self, changes: list[Parameter]) -> None:
        self._publish(self._control.output)


def _config(values: dict[str, Any]) -> ControllerConfig:
    return ControllerConfig(
        model=SliderParams(**{name: values[name] for name in MODEL}),
        integral_gain=values["integral_gain"], max_amplitude_ratio=values["max_amplitude_ratio"],
        mean_window_periods=values["mean_window_periods"], settle_margin=values["settle_margin"],
    )


def _named(name: str, value: Any) -> Any:
    """A rcl_interfaces/Parameter message from a ParameterValue (for Parameter.from_parameter_msg)."""
    from rcl_interfaces.msg import Parameter as ParameterMsg

    return ParameterMsg(name=name, value=value)


def main(args: Sequence[str] | None = None) -> int:
    """``ros2 run friction_sim controller [--ros-args ...]``."""
    return run_node(ControllerNode, args, prog="controller")


if __name__ == "__main__":
    raise SystemExit(main())
