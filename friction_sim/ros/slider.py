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
from collections.abc import Sequence
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.subscription import Subscription
from rosgraph_msgs.msg import Clock as ClockMsg

from friction_sim.core import spec
from friction_sim.core.commands import SLIDER, Outcome, consumed_by
from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.realtime import RealtimeSlider
from friction_sim.io.messages import (
    command_from_message,
    fill_state_messages,
    key_values,
    mean_velocity_message,
    message_class,
    seconds_to_ns,
    time_msg,
)
from friction_sim.io.sinks import Sink, deliver_tick
from friction_sim.ros.common import PolledGroup, declare_settings, run_node, take_all, wall_ns

QOS_DEPTH = 10
COMMANDS_PER_TICK = QOS_DEPTH
_QUIET_PUBLISHER = PublisherEventCallbacks(use_default_callbacks=False)
_QUIET_SUBSCRIPTION = SubscriptionEventCallbacks(use_default_callbacks=False)
TICK_SWITCH_INTERVAL = 0.0005
#: The node's parameters: declared once in the one vocabulary.
PARAMETERS = spec.SLIDER_NODE


class SliderNode(Node):
    """Publishes the exact slider state in real time and takes commands."""

    def __init__(self, node_name: str = "slider", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        values = declare_settings(self, PARAMETERS)
        params = SliderParams(**{name: values[name] for name in spec.PLANT})
        inputs = Inputs(**{name: values[name] for name in spec.INPUTS if name in values})
        self._rt = RealtimeSlider(
            params, inputs, wall_ns=wall_ns(), real_time_factor=values["real_time_factor"],
            publish_rate=values["publish_rate"], mean_window_periods=values["mean_window_periods"],
            log_rate=values["log_rate"] if values["log_path"] else None,
        )
        #: Consumers of the run (the recorder, a live view, a test's probe).
        self.sinks: list[Sink] = []
        self.recorder = _open_recorder(values)
        if self.recorder is not None:
            self.sinks.append(self.recorder)
            self.recorder.on_parameters(_recorded(values), 0.0, changed=False)
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
        """Stop the tick thread before the publishers go away; close the sinks
        (finishing the recording)."""
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
        for sink in self.sinks:
            sink.close()
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
        """One polled subscription per command topic the slider consumes (from
        the command table); the tick thread drains them."""
        polled = PolledGroup()
        self._commands: list[tuple[str, Subscription]] = [
            (entry.name, self.create_subscription(
                message_class(entry.message_type), entry.name, _unused, QOS_DEPTH, callback_group=polled,
                event_callbacks=_QUIET_SUBSCRIPTION))
            for entry in consumed_by(SLIDER)
        ]

    def _take_commands(self) -> None:
        """Apply every command waiting on the command topics (tick thread)."""
        waiting = [(name, msg) for name, subscription in self._commands
                   for msg in take_all(subscription, COMMANDS_PER_TICK)]
        if not waiting:
            return
        with self._lock:
            now = wall_ns()
            t = self._rt.now(now)
            outcomes = self._rt.commands([command_from_message(name, msg, t) for name, msg in waiting], now)
        for outcome in outcomes:
            self._report(outcome)

    # -- commands ---------------------------------------------------------------

    def _report(self, outcome: Outcome) -> None:
        if not outcome.accepted:
            self.get_logger().warning(
                f"{outcome.reason}; last valid value kept", throttle_duration_sec=1.0
            )
        for sink in self.sinks:
            sink.on_command(outcome, self._frame_id)

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
            except Exception:
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
        deliver_tick(self.sinks, tick, self._frame_id)

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
        """The one place for cross-field rules, and atomic: the whole set is
        checked by the core against the state in force (which topic commands
        may have changed since the parameters were last set) and reaches the
        simulation as one new state, under the lock, or it is refused and
        nothing changes."""
        values = {p.name: p.value for p in changes}
        with self._lock:
            outcome = self._rt.configure(values, wall_ns())
        if outcome.values or not outcome.accepted:
            self._report(outcome)
        if not outcome.accepted:
            return SetParametersResult(successful=False, reason=outcome.reason)
        return SetParametersResult(successful=True)

    def _parameters_set(self, changes: list[Parameter]) -> None:
        """After a successful set: the settings the tick thread reads, and the
        record of the non-physics ones (physics changes were recorded as commands)."""
        self._publish_clock = self.get_parameter("publish_clock").value
        self._frame_id = self.get_parameter("frame_id").value
        others = {p.name for p in changes} - set(spec.PLANT) - set(spec.INPUTS)
        if others:
            t = self._rt.clock.now(wall_ns())
            for sink in self.sinks:
                sink.on_parameters({n: self.get_parameter(n).value for n in others}, t, changed=True)


def _unused(msg: Any) -> None:
    """The callback of a polled subscription: never called (the tick thread takes its messages)."""


def _open_recorder(values: dict[str, Any]) -> Any:
    """A Recorder for ``log_path`` (None when it is empty), with the run's
    parameters as the file's metadata."""
    if not values["log_path"]:
        return None
    from friction_sim.io.recorder import Recorder

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
