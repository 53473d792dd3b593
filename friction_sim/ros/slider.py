"""The slider node: ``ros2 run friction_sim slider``.

A thin ROS 2 adapter around :class:`friction_sim.core.realtime.RealtimeSlider`:
it converts command messages into input changes, advances the exact core to
the present on every tick, and publishes the state.  There is no physics here.

All names are relative, so ``--ros-args -r __ns:=/feeder1`` moves a whole
feeder into a namespace (``/clock`` excepted, which is global by convention).

Subscriptions: ``drive_force``, ``excitation_amplitude``,
``excitation_frequency`` (std_msgs/Float64) and ``external_wrench``
(geometry_msgs/WrenchStamped: force.x tangential, force.z normal, > 0 loads
the contact; held until the next message).
Publications: ``pose``, ``velocity``, ``friction_force`` at ``publish_rate``;
``mean_velocity`` once per completed excitation period; ``diagnostics`` at
1 Hz; ``/clock`` when ``publish_clock`` is true.  Header stamps are
simulation time.

Ticks run in a dedicated thread rather than an executor timer: rclpy's
executor rebuilds its wait set in Python on every wake-up (about 0.4 ms for a
node with parameter services), which at 1 kHz would cost most of a core and
make the tick rate depend on how many commands arrive.  Each tick first takes
the waiting commands (at most ``COMMANDS_PER_TICK`` per topic; the command
subscriptions keep the last ``QOS_DEPTH``), applies them at the present
simulation time, then advances and publishes.  So a flood of commands costs a
bounded amount of work per tick.  The executor thread handles parameters and
diagnostics; a lock keeps it and the tick thread apart.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any, Callable, Sequence

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMsg
from std_msgs.msg import Float64

from friction_sim.errors import ParameterError
from friction_sim.io.messages import fill_state_messages, key_values, mean_velocity_message, seconds_to_ns, time_msg
from friction_sim.ros.common import (
    PolledGroup, float_descriptor, int_descriptor, run_node, take_all, text_descriptor, wall_ns,
)
from friction_sim.core.params import Inputs, SliderParams, check_contact
from friction_sim.core.realtime import MAX_MEAN_WINDOW, MAX_PERIODS_PER_SECOND, CommandOutcome, RealtimeSlider, Tick, check_load

QOS_DEPTH = 10
COMMANDS_PER_TICK = QOS_DEPTH
_QUIET_PUBLISHER = PublisherEventCallbacks(use_default_callbacks=False)
_QUIET_SUBSCRIPTION = SubscriptionEventCallbacks(use_default_callbacks=False)
TICK_SWITCH_INTERVAL = 0.0005
PLANT = ("mass", "mu", "gravity")
INPUTS = ("drive_force", "excitation_amplitude", "excitation_frequency")

#: name -> (default, descriptor); defaults are the paper's Fig. 2 case.
PARAMETERS: dict[str, tuple[Any, Any]] = {
    "mass": (1.0, float_descriptor("slider mass m [kg]", 1e-6, 1e6)),
    "mu": (0.1, float_descriptor("Coulomb friction coefficient [-]", 1e-6, 10.0)),
    "gravity": (10.0, float_descriptor("gravity g [m/s^2]", 1e-6, 1e3)),
    "drive_force": (0.7, float_descriptor("drive force Fd [N] along +x", -1e6, 1e6)),
    "excitation_amplitude": (5.0, float_descriptor("excitation amplitude Pa [N], < m*g", 0.0, 1e6)),
    "excitation_frequency": (50.0, float_descriptor("excitation frequency f [Hz]", 1e-3, MAX_PERIODS_PER_SECOND)),
    "publish_rate": (1000.0, float_descriptor("state publishing rate [Hz]", 1.0, 10_000.0)),
    "real_time_factor": (1.0, float_descriptor("simulated seconds per wall second", 1e-3, 1e3)),
    "publish_clock": (False, text_descriptor("publish simulation time on /clock")),
    "mean_window_periods": (1, int_descriptor("whole periods averaged in mean_velocity", 1, MAX_MEAN_WINDOW)),
    "frame_id": ("slideway", text_descriptor("header.frame_id of published messages")),
    "log_path": ("", text_descriptor("record the run to this MCAP file ('' = no recording); set at start")),
    "log_rate": (1000.0, float_descriptor("recorded state samples per simulated second", 1.0, 100_000.0)),
}
#: Parameters that only take effect at start-up.
START_ONLY = ("log_path", "log_rate")


class SliderNode(Node):
    """Publishes the exact slider state in real time and takes commands."""

    def __init__(self, node_name: str = "slider", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.command_listeners: list[Callable[[CommandOutcome], None]] = []
        self.tick_listeners: list[Callable[[Tick], None]] = []
        for name, (default, descriptor) in PARAMETERS.items():
            self.declare_parameter(name, default, descriptor)
        values = {name: self.get_parameter(name).value for name in PARAMETERS}
        params = SliderParams(**{name: values[name] for name in PLANT})
        inputs = Inputs(**{name: values[name] for name in INPUTS})
        check_contact(params, inputs)
        self.recorder = _open_recorder(values)
        self._rt = RealtimeSlider(
            params, inputs, wall_ns=wall_ns(), real_time_factor=values["real_time_factor"],
            publish_rate=values["publish_rate"], mean_window_periods=values["mean_window_periods"],
            log_rate=values["log_rate"] if self.recorder is not None else None,
        )
        if self.recorder is not None:
            self.recorder.record_parameters(_recorded(values), 0.0)
            self.command_listeners.append(self.recorder.record_command)
            self.tick_listeners.append(lambda tick: self.recorder.record_tick(tick, self._frame_id))
        self._frame_id: str = values["frame_id"]
        self._publish_clock: bool = values["publish_clock"]
        self._make_publishers()
        self._make_subscriptions()
        self.create_timer(1.0, self._on_diagnostics, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.add_on_set_parameters_callback(self._set_parameters)
        self.add_post_set_parameters_callback(self._parameters_set)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        # Let the tick thread take the GIL within 0.5 ms even while the
        # executor thread is busy with a flood of commands (default: 5 ms).
        sys.setswitchinterval(min(sys.getswitchinterval(), TICK_SWITCH_INTERVAL))
        self._ticker = threading.Thread(target=self._tick_loop, name="slider_tick", daemon=True)
        self._ticker.start()

    def destroy_node(self) -> None:
        """Stop the tick thread before the publishers go away; finish the recording."""
        self._stop.set()
        if self._ticker.is_alive() and threading.current_thread() is not self._ticker:
            self._ticker.join(timeout=2.0)
        if self.recorder is not None:
            stats = self.recorder.finish()
            note = (f"recording finished: {stats.path} ({stats.messages} messages, "
                    f"{stats.last_ns / 1e9 if stats.last_ns else 0.0:.3f} s simulated, {stats.dropped} dropped)")
            if self.context.ok():
                self.get_logger().info(note)
            else:  # after Ctrl-C the context (and /rosout) is gone already
                print(f"[slider] {note}", file=sys.stderr)
        super().destroy_node()

    @property
    def realtime(self) -> RealtimeSlider:
        return self._rt

    # -- wiring ---------------------------------------------------------------

    def _make_publishers(self) -> None:
        def publisher(kind: type, topic: str) -> Any:
            return self.create_publisher(kind, topic, QOS_DEPTH, event_callbacks=_QUIET_PUBLISHER)

        self._pose_pub = publisher(PoseStamped, "pose")
        self._velocity_pub = publisher(TwistStamped, "velocity")
        self._friction_pub = publisher(WrenchStamped, "friction_force")
        self._mean_pub = publisher(TwistStamped, "mean_velocity")
        self._diag_pub = publisher(DiagnosticArray, "diagnostics")
        self._clock_pub = publisher(ClockMsg, "/clock")
        self._pose, self._velocity, self._friction = PoseStamped(), TwistStamped(), WrenchStamped()
        self._clock_msg = ClockMsg()

    def _make_subscriptions(self) -> None:
        polled = PolledGroup()

        def subscribe(kind: type, topic: str, convert: Callable[[Any], tuple[str, dict[str, float]]]) -> Any:
            # The "callback" of a polled subscription converts a message into a command.
            return self.create_subscription(kind, topic, convert, QOS_DEPTH, callback_group=polled,
                                            event_callbacks=_QUIET_SUBSCRIPTION)

        self._commands = [subscribe(Float64, name, _float_command(name)) for name in INPUTS]
        self._commands.append(subscribe(WrenchStamped, "external_wrench", _wrench_command))

    def _take_commands(self) -> None:
        """Apply every command waiting on the command topics (tick thread)."""
        batch = [subscription.callback(msg) for subscription in self._commands
                 for msg in take_all(subscription, COMMANDS_PER_TICK)]
        if batch:
            with self._lock:
                outcomes = self._rt.commands(batch, wall_ns())
            for outcome in outcomes:
                self._report(outcome)

    # -- commands ---------------------------------------------------------------

    def _command(self, topic: str, values: dict[str, float]) -> CommandOutcome:
        with self._lock:
            outcome = self._rt.command(topic, values, wall_ns())
        self._report(outcome)
        return outcome

    def _report(self, outcome: CommandOutcome) -> None:
        if not outcome.accepted:
            self.get_logger().warning(
                f"{outcome.reason}; last valid value kept", throttle_duration_sec=1.0
            )
        for listener in self.command_listeners:
            listener(outcome)

    # -- publishing -------------------------------------------------------------

    def _tick_loop(self) -> None:
        """Tick at publish_rate on absolute deadlines; after a stall, go on from
        now rather than bursting to catch up (the physics follows the clock)."""
        deadline = time.monotonic()
        while not self._stop.is_set():
            period = 1.0 / self._rt.publish_rate
            deadline += period
            delay = deadline - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
            elif delay < -period:
                deadline = time.monotonic()
            if self._stop.is_set() or not self.context.ok():
                return
            try:
                self._take_commands()
                self._on_tick()
            except Exception:  # noqa: BLE001 - a shutdown racing a publish ends the loop
                if self.context.ok() and not self._stop.is_set():
                    raise
                return

    def _on_tick(self) -> None:
        with self._lock:
            tick = self._rt.tick(wall_ns())
        state = tick.state
        fill_state_messages(state, self._frame_id, self._pose, self._velocity, self._friction)
        self._pose_pub.publish(self._pose)
        self._velocity_pub.publish(self._velocity)
        self._friction_pub.publish(self._friction)
        for period in tick.periods:
            self._mean_pub.publish(mean_velocity_message(period, self._frame_id))
        if self._publish_clock:
            time_msg(seconds_to_ns(state.t), self._clock_msg.clock)
            self._clock_pub.publish(self._clock_msg)
        for listener in self.tick_listeners:
            listener(tick)

    def _on_diagnostics(self) -> None:
        with self._lock:
            report = self._rt.diagnostics(wall_ns())
        status = DiagnosticStatus(name="slider", hardware_id=self.get_fully_qualified_name())
        status.level, status.message = _health(report)
        status.values = key_values(report)
        msg = DiagnosticArray(status=[status])
        time_msg(seconds_to_ns(report["sim_time"]), msg.header.stamp)
        self._diag_pub.publish(msg)

    # -- parameters ---------------------------------------------------------------

    def _set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        """The one place for cross-field rules, and atomic: the change reaches
        the core here, under the lock, or it is refused and nothing changes.
        It is checked against the inputs in force (which topic commands may
        have changed since the parameters were last set)."""
        late = [p.name for p in changes if p.name in START_ONLY]
        if late:
            reason = f"{late[0]} only takes effect at start-up (use --ros-args -p {late[0]}:=...)"
            return SetParametersResult(successful=False, reason=reason)
        values = {p.name: p.value for p in changes}
        plant = {n: values[n] for n in PLANT if n in values}
        inputs = {n: values[n] for n in INPUTS if n in values}
        now = wall_ns()
        with self._lock:
            rt = self._rt
            try:
                params = rt.slider.params.replace(**plant)
                new_inputs = rt.slider.inputs.replace(**inputs)
                check_contact(params, new_inputs, values)
                check_load(new_inputs.excitation_frequency, values.get("real_time_factor", rt.clock.rate),
                           "real_time_factor" if "real_time_factor" in values else "excitation_frequency")
                if "mean_window_periods" in values:
                    rt.set_mean_window(values["mean_window_periods"])
            except ParameterError as error:
                outcome = rt.refuse("parameters", values, str(error), now)
                refused = True
            else:
                refused = False
                outcomes = [rt.set_params(params, now)] if plant else []
                outcomes += rt.commands([("parameters", inputs)], now) if inputs else []
                if "real_time_factor" in values:
                    rt.set_real_time_factor(values["real_time_factor"], now)
                if "publish_rate" in values:
                    rt.set_publish_rate(values["publish_rate"])
        if refused:
            self._report(outcome)
            return SetParametersResult(successful=False, reason=outcome.reason)
        for outcome in outcomes:
            self._report(outcome)
        return SetParametersResult(successful=True)

    def _parameters_set(self, changes: list[Parameter]) -> None:
        """After a successful set: the settings the tick thread reads, and the
        record of the non-physics ones (physics changes were recorded as commands)."""
        self._publish_clock = self.get_parameter("publish_clock").value
        self._frame_id = self.get_parameter("frame_id").value
        others = {p.name for p in changes} - set(PLANT) - set(INPUTS)
        if self.recorder is not None and others:
            self.recorder.record_parameters({n: self.get_parameter(n).value for n in others},
                                            self._rt.clock.now(wall_ns()), changed=True)


def _float_command(name: str) -> Callable[[Float64], tuple[str, dict[str, float]]]:
    """std_msgs/Float64 on topic ``name`` -> the command setting input ``name``."""
    return lambda msg: (name, {name: msg.data})


def _wrench_command(msg: WrenchStamped) -> tuple[str, dict[str, float]]:
    """external_wrench: force.x tangential, force.z normal (torques and force.y
    have no meaning for a slider on a line and are ignored)."""
    force = msg.wrench.force
    return "external_wrench", {"external_force_x": force.x, "external_force_z": force.z}


def _open_recorder(values: dict[str, Any]) -> Any:
    """A Recorder for ``log_path`` (None when it is empty), with the run's
    parameters as the file's metadata."""
    if not values["log_path"]:
        return None
    from friction_sim.io.recording import Recorder

    return Recorder(values["log_path"], metadata=_recorded(values))


def _recorded(values: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in values.items() if k not in ("log_path",)}


def _health(report: dict[str, Any]) -> tuple[bytes, str]:
    """OK, or WARN with the reason: the timer falls behind or commands were refused."""
    problems = []
    if report["tick_rate"] < 0.8 * report["publish_rate"]:
        problems.append(f"tick rate {report['tick_rate']:.0f} Hz < 80% of {report['publish_rate']:g} Hz")
    if report["late_ticks"]:
        problems.append(f"{report['late_ticks']} late ticks")
    if report["commands_rejected_in_interval"]:
        problems.append(f"{report['commands_rejected_in_interval']} commands rejected ({report['last_rejection']})")
    if not problems:
        return DiagnosticStatus.OK, "running"
    return DiagnosticStatus.WARN, "; ".join(problems)


def main(args: Sequence[str] | None = None) -> int:
    """``ros2 run friction_sim slider [--ros-args ...]``."""
    return run_node(SliderNode, args, prog="slider")


if __name__ == "__main__":
    raise SystemExit(main())
