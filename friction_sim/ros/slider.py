"""The slider node: ``ros2 run friction_sim slider``.

A thin ROS 2 adapter around :class:`friction_sim.core.runtime.realtime.RealtimeSlider`:
it converts command messages into input changes, advances the exact core to
the present on every tick, and publishes the state.  There is no physics here.

All names are relative, so ``--ros-args -r __ns:=/feeder1`` moves a whole
feeder into a namespace (``/clock`` excepted, which is global by convention).

The frame is the track's: x along it (+ = conveying), z normal to it, away
from it.  Above the throw number 1 (Pa > m g cos(alpha) - Fz) the slider
hops, and the height z and its rate vz are published with x and v.

Subscriptions: ``drive_force``, ``excitation_amplitude``,
``excitation_frequency``, ``drive_level`` (std_msgs/Float64) and ``external_wrench``
(geometry_msgs/WrenchStamped: force.x tangential, force.z normal, > 0 lifts,
away from the track; held until the next message).  Of ``excitation_amplitude``
and ``drive_level`` the actuator in force takes one; the other is refused on its
topic whatever its value, and as a parameter set to any value but the one held
(a dump loads back), and diagnostics mark it unused.  What a parameter set does
is :mod:`friction_sim.ros.slider_parameters`'s.
Publications: ``pose``, ``velocity``, ``friction_force`` at ``publish_rate``;
``mean_velocity`` once per completed excitation period; ``diagnostics`` every
``diagnostics_period`` (1 s); ``/clock`` while ``publish_clock`` is true (the publisher exists only
then).  The states' and mean velocities' header stamps are simulation time
(when the state was); the diagnostics' stamp is the node's clock, as
``diagnostic_updater`` stamps it (wall time, or /clock with ``use_sim_time``),
the same rule the controller follows on the same topic.

Services (std_srvs/Trigger): ``~/pause``, ``~/resume``, ``~/step`` and
``~/reset`` (see :class:`~friction_sim.core.runtime.realtime.RealtimeSlider`), in
:mod:`friction_sim.ros.slider_control`; each call is handed to the sinks as a
command, so a recording holds it.  While
paused a tick publishes only what changed (a step, a reset, a command).

With ``foxglove_port`` set, a :class:`~friction_sim.io.live.LiveView` serves
the run to Foxglove: the published states, events, period means, commands and
refusals, parameters, ``/clock``, and what it sees on ``diagnostics`` and
``target_speed`` (the controller's too).

Bad input is refused, counted and warned about at most once a second (the
rest cost a clock read).  If the exact core cannot take a command, it is
refused and the state stays as it was; if the simulation itself fails, the
node logs the reason once, reports ERROR on ``diagnostics`` and exits with
code 3 (:data:`~friction_sim.ros.run.EXIT_FAULT`): it never keeps running
without ticking.

With ``lockstep`` the thread runs :class:`~friction_sim.ros.slider_lockstep.LockstepLoop`
instead of ticks: simulation time advances when the controller has answered each
``mean_velocity`` sample on ``control_answer`` and a scheduler has promised what comes
on ``stamped_command`` (sensor_msgs/JointState, :mod:`friction_sim.io.stamped`), as fast
as they compute (:mod:`friction_sim.core.runtime.lockstep`).

Ticks run in a dedicated thread (:class:`~friction_sim.ros.slider_realtime.RealtimeLoop`)
rather than an executor timer: rclpy's
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

import contextlib
import sys
import threading
from collections.abc import Callable, Sequence
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.clock import Clock, ClockType
from rclpy.subscription import Subscription

from friction_sim.core.model.commands import SLIDER, Outcome, consumed_by
from friction_sim.core.model.params import plant_from
from friction_sim.core.model.records import Tick
from friction_sim.core.runtime.lockstep import LockstepSlider
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.errors import SimulationFault, one_line
from friction_sim.io.messages import (
    command_from_message,
    key_values,
    message_class,
    time_msg,
)
from friction_sim.io.sinks import (
    CommandRecord,
    MessageRecord,
    ParametersRecord,
    Sink,
    deliver,
)
from friction_sim.ros.graph import NameWatch
from friction_sim.ros.intake import LostMessages, PolledGroup, ThrottledWarning, take_all
from friction_sim.ros.run import (
    EXIT_FAULT,
    EXIT_RECORDING_FAILED,
    SLIDER_EXIT_CODES,
    FaultSignal,
    QuietNode,
    node_help,
    run_node,
    wall_ns,
)
from friction_sim.ros.slider_control import SimulationControl
from friction_sim.ros.slider_lockstep import LockstepLoop, runtime_for
from friction_sim.ros.slider_outputs import (
    RecorderHealth,
    consistent_report,
    finish_recording,
    health,
    open_live_view,
    open_recorder,
    recorded,
    watch_namespace,
)
from friction_sim.ros.slider_parameters import PARAMETERS, SliderParameters, declare
from friction_sim.ros.slider_realtime import RealtimeLoop
from friction_sim.ros.slider_topics import QOS_DEPTH, SliderTopics

COMMANDS_PER_TICK = QOS_DEPTH
TICK_SWITCH_INTERVAL = 0.0005
#: What the node publishes (topic, type, meaning), for --help.
PUBLICATIONS = (
    ("pose", "geometry_msgs/msg/PoseStamped",
     "position.x = x [m] along the track, position.z = z [m] height above it (> 0 in flight), at publish_rate"),
    ("velocity", "geometry_msgs/msg/TwistStamped", "linear.x = v [m/s], linear.z = vz [m/s], at publish_rate"),
    ("friction_force", "geometry_msgs/msg/WrenchStamped",
     "force.x = friction force [N] (signed), force.z = contact force R [N] (0 in flight), at publish_rate"),
    ("mean_velocity", "geometry_msgs/msg/TwistStamped",
     "linear.x = mean speed [m/s] over the last mean_window_periods whole periods, once per period"),
    ("diagnostics", "diagnostic_msgs/msg/DiagnosticArray",
     "status 'slider', every diagnostics_period (1 s): with the actuator's steady Pa and present envelope (the input "
     "it does not use marked unused), the throw number, flight fraction, lift-offs and landings"),
    ("/clock", "rosgraph_msgs/msg/Clock", "simulation time, while publish_clock is true"),
)


class SliderNode(QuietNode):
    """Publishes the exact slider state in real time and takes commands."""

    def __init__(self, node_name: str = "slider", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        values = declare(self)
        params, inputs = plant_from(values)
        self._rt = runtime_for(values, params, inputs)
        #: The exit code run_node ends with (0, or EXIT_RECORDING_FAILED after a failed recording).
        self.exit_code = 0
        #: The control calls (:mod:`friction_sim.ros.slider_control`), over ROS and the live view.
        self.control = SimulationControl(self)
        #: Consumers of the run (the recorder, a live view, a test's probe): whatever the node
        #: records or serves reaches them as sink records (:mod:`friction_sim.io.sinks`), and only so.
        self.sinks: list[Sink] = []
        self.recorder = open_recorder(values, self.get_namespace(), self.get_fully_qualified_name())
        self._recorder_health = RecorderHealth(self.recorder)
        if self.recorder is not None:
            self.sinks.append(self.recorder)
        try:
            self.live = open_live_view(values, self.get_namespace(), self.get_fully_qualified_name(),
                                       self.control.live_services())
        except BaseException:
            if self.recorder is not None:
                self.recorder.finish()  # a taken port must not leave a recording open
            raise
        if self.live is not None:
            self.sinks.append(self.live)
            self.get_logger().info(f"live view: open {self.live.url} in Foxglove (config/"
                                   "friction_sim.foxglove_layout.json is the layout)")
        deliver(self.sinks, ParametersRecord(recorded(values), 0.0, False))
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._warn = ThrottledWarning(self.get_logger())
        self._fault = FaultSignal(self)
        #: The publishers and the ticks they have published (:mod:`friction_sim.ros.slider_topics`).
        self.topics = SliderTopics(self, self.sinks, self._lock, self._stop, self._rt.accelerometer,
                                   values["frame_id"], values["publish_clock"], self._answered_ns)
        self._make_subscriptions()
        watch_namespace(self, lambda: self._rt.now(wall_ns()), lockstep=bool(values["lockstep"]))
        self.names = NameWatch(self)
        if not values["lockstep"]:  # in lockstep: every diagnostics_period of simulation time (the loop)
            self.create_timer(values["diagnostics_period"], self.publish_diagnostics,
                              clock=Clock(clock_type=ClockType.STEADY_TIME))
        #: The parameter sets' callbacks (:mod:`friction_sim.ros.slider_parameters`).
        self.parameter_sets = SliderParameters(self)
        self.parameter_sets.watch()
        #: The lockstep loop (None in real time): it replaces the clock's ticks.
        self.lockstep = LockstepLoop(self) if isinstance(self._rt, LockstepSlider) else None
        #: The loop the tick thread runs: the lockstep loop, or ticks at publish_rate.
        self._loop: LockstepLoop | RealtimeLoop = self.lockstep if self.lockstep is not None \
            else RealtimeLoop(self, self._stop, self._recorder_health)
        if self.lockstep is None:
            # In real time, let the tick thread take the GIL within 0.5 ms even while the executor
            # thread is busy with a flood of commands (default: 5 ms).  Not in lockstep, which keeps
            # no pace: there every switch costs (a process-wide setting: the offline recorder, a
            # producer and a writer thread, ran 4x slower with it).
            sys.setswitchinterval(min(sys.getswitchinterval(), TICK_SWITCH_INTERVAL))
        self._ticker = threading.Thread(target=self._tick_loop, name="slider_tick", daemon=True)
        self._ticker.start()
        self.control.serve()

    def destroy_node(self) -> None:
        """Stop the tick thread before the publishers go away; close the sinks
        (finishing the recording)."""
        self._stop.set()
        if self._ticker.is_alive() and threading.current_thread() is not self._ticker:
            self._ticker.join(timeout=2.0)
        if self.recorder is not None:
            failed, note = finish_recording(self.recorder)
            if failed:
                self.exit_code = EXIT_RECORDING_FAILED
            if self.context.ok():
                (self.get_logger().error if failed else self.get_logger().info)(note)
            else:  # after Ctrl-C the context (and /rosout) is gone already
                print(f"[slider] {note}", file=sys.stderr)
        for sink in self.sinks:
            sink.close()
        super().destroy_node()

    @property
    def realtime(self) -> RealtimeSlider:
        return self._rt

    @property
    def lock(self) -> threading.Lock:
        """Held while the runtime changes (the tick thread's and the executor's turns)."""
        return self._lock

    @property
    def stopping(self) -> bool:
        """Whether the node is being destroyed or its context shut down."""
        return self._stop.is_set() or not self.context.ok()

    @property
    def frame_id(self) -> str:
        return self.topics.frame_id

    def publish_mean_velocity(self, msg: Any) -> None:
        self.topics.publish_mean_velocity(msg)

    def flush_readings(self) -> None:
        """Lockstep, while the loop waits: the held accelerometer samples a reader that came since needs."""
        self.topics.flush_readings()

    def _answered_ns(self) -> int | None:
        """In lockstep the stamp [ns] of the last sample answered (-1: none); None in real time."""
        gate = getattr(self._rt, "gate", None)
        return None if gate is None else int(gate.answered_ns)

    @property
    def fault(self) -> str:
        """Why the node stopped ('' while it runs): see :class:`SimulationFault`."""
        return self._fault.reason

    # -- commands ---------------------------------------------------------------

    def _make_subscriptions(self) -> None:
        """One polled subscription per command topic the slider consumes (from
        the command table); the tick thread drains them."""
        polled = PolledGroup()
        self._commands: list[tuple[str, Subscription]] = [
            (entry.name, self.create_subscription(
                message_class(entry.message_type), entry.name, _unused, QOS_DEPTH, callback_group=polled))
            for entry in consumed_by(SLIDER)
        ]

    def take_commands(self) -> None:
        """Apply every command waiting on the command topics (tick thread)."""
        waiting = [(name, msg) for name, subscription in self._commands
                   for msg in take_all(subscription, COMMANDS_PER_TICK)]
        if not waiting:
            return
        with self._lock:
            now = wall_ns()
            t = self._rt.now(now)
            outcomes = self._rt.commands([command_from_message(name, msg, t) for name, msg in waiting], now)
            self.record(outcomes)
        for outcome in outcomes:
            self.warn_refused(outcome)

    def record(self, outcomes: Sequence[Outcome]) -> None:
        """Hand handled commands to the sinks, with the lock held: the tick thread
        and the executor's (parameters, control calls) take commands in turn, and
        a recording must hold them in the order the core took them (verify
        replays them in that order, each a change of its own)."""
        for outcome in outcomes:
            deliver(self.sinks, CommandRecord(outcome, self.topics.frame_id))

    def warn_refused(self, outcome: Outcome, warn: Callable[[str], Any] | None = None) -> None:
        """Warn about a refusal (by default on the node's throttle: a flood of bad
        commands costs a clock read each)."""
        if not outcome.accepted:
            kept = "nothing changed" if outcome.command.is_control else "last valid value kept"
            (warn or self._warn)(f"{outcome.reason}; {kept}")

    # -- ticking and diagnostics -----------------------------------------------------

    def _tick_loop(self) -> None:
        """Tick until stopped; any failure is reported once and ends the node
        (:meth:`fail`), never a thread that dies in silence."""
        try:
            self._loop.run()
        except Exception as error:  # noqa: BLE001 - reported, and the node stops
            if not self._stop.is_set() and self.context.ok():
                self.fail(error)

    def fail(self, error: BaseException) -> None:
        """The run cannot go on: log why and report ERROR on diagnostics (once),
        then end the executor (run_node exits with EXIT_FAULT)."""
        reason = str(error) if isinstance(error, SimulationFault) else \
            f"tick failed: {one_line(error, with_type=True)}"
        if not self._fault.claim(reason):
            return
        self.get_logger().error(f"{reason}; stopping (exit code {EXIT_FAULT})")
        with contextlib.suppress(Exception):  # the reason is logged already; the node stops anyway
            self.publish_diagnostics()
        self._fault.fire()

    def publish_tick(self, tick: Tick, fresh: bool = True) -> None:
        """Publish what a tick made (lock held, as the lockstep loop holds it: /clock
        first, then the states, the period means and the accelerometer's samples)
        and hand it to the sinks."""
        self.topics.publish_tick(tick, fresh)

    def publish_diagnostics(self, stamp_ns: int | None = None) -> None:
        """The status 'slider' on diagnostics, stamped ``stamp_ns`` (lockstep: the
        simulation time), else by the node's clock."""
        report = consistent_report(self._rt, self._lock, wall_ns)
        report.update(self._recorder_health.report())
        report["messages_lost"] = LostMessages.count  # taken by rclpy, not convertible (see ros/intake.py)
        if self.live is not None:
            report.update(self.live.stats())
        status = DiagnosticStatus(name="slider", hardware_id=self.get_fully_qualified_name())
        status.level, status.message = health(report, self.fault, self.names.problem)
        status.values = key_values(report)
        msg = DiagnosticArray(status=[status])
        if stamp_ns is None:
            msg.header.stamp = self.get_clock().now().to_msg()
        else:  # lockstep: recorded here, not when it comes back (the run may end before it does)
            time_msg(stamp_ns, msg.header.stamp)
            deliver(self.sinks, MessageRecord("diagnostics", msg, stamp_ns))
        self.topics.publish_diagnostics(msg)

    # -- parameters ---------------------------------------------------------------

    def follow_settings(self) -> None:
        """After an accepted parameter set: the settings the tick thread reads,
        from the parameters in force (:class:`SliderParameters` calls it)."""
        self.topics.set_publish_clock(self.get_parameter("publish_clock").value)
        self.topics.frame_id = self.get_parameter("frame_id").value


def _unused(msg: Any) -> None:
    """The callback of a polled subscription: never called (the tick thread takes its messages)."""


def help_text() -> str:
    """What ``slider --help`` prints after the usage line."""
    return node_help("The exact stick-slip slider in real time: advances the event-driven core to the "
                     "present at publish_rate and publishes its state; takes commands on topics and "
                     "parameters.  Services (std_srvs/srv/Trigger): ~/pause and ~/resume (simulation time "
                     "stops exactly, /clock too), ~/step (while paused: step_periods periods, or step_time "
                     "seconds), ~/reset (back to rest at x = 0, phase 0, under the parameters in force).",
                     PARAMETERS, SLIDER, PUBLICATIONS, SLIDER_EXIT_CODES)


def main(args: Sequence[str] | None = None) -> int:
    """``ros2 run friction_sim slider [--help] [--ros-args ...]``."""
    return run_node(SliderNode, args, prog="slider", help_text=help_text())


if __name__ == "__main__":
    raise SystemExit(main())
