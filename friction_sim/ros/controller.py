"""The mean-speed controller node: ``ros2 run friction_sim controller``.

A thin ROS 2 adapter around :class:`friction_sim.core.control.law.MeanSpeedController`.
All names are relative, so it runs in the same namespace as its slider.

Subscriptions: ``target_speed`` (std_msgs/Float64, m/s), ``mean_velocity``
(geometry_msgs/TwistStamped, from the slider), ``drive_force`` and
``excitation_frequency`` (std_msgs/Float64, the same commands the slider
takes, so the model follows the plant's inputs).
Publications: ``excitation_amplitude`` (std_msgs/Float64, Pa in N) after each
mean_velocity sample taken and after each batch of commands that changed
something, while the plant's actuator is the force actuator; with the resonant
actuator ``drive_level`` (std_msgs/Float64) instead, and ``excitation_frequency``
when resonance tracking moves the drive (see below); ``diagnostics`` (DiagnosticArray, status name ``controller``,
stamped by the node's clock like the slider's) every ``diagnostics_period``
(1 s) and whenever the
target becomes unreachable or reachable again or an internal error occurs.

Commands are taken in batches: while the node is quiet, a command wakes it at
once; after each batch the command topics are polled every
``COMMAND_HOLD_OFF`` (20 ms) until they are quiet again.  The commands of a
batch are judged one by one in the order they arrived, each against the
state the ones before it left, and the law then decides once: one
excitation_amplitude message answers the batch.  So a flood of commands
costs one small batch per 20 ms (at most the queue depth, 10, per topic),
not an executor wake-up and a control decision per message.  Refused
commands, parameter values (rclpy's own checks included) and mean_velocity
samples (not finite, or faster than any plant in force can creep: see
:mod:`friction_sim.core.control.law`) are counted in diagnostics
(``commands_rejected``, all of them; ``samples_rejected``, the samples among
them) with the latest reason, and warned about at most once a second (the
others cost a clock read).  An unexpected error in a callback is logged
once, reported as ERROR on diagnostics, and the input that caused it is
refused (the law's state is left as it was); the node goes on.

With ``plant_node`` set (default ``slider``) the controller takes its whole
plant from that node's parameters at start-up through the parameter services:
the model (mass, mu, gravity and the general model's static_ratio,
excitation_angle, excitation_phase, track_inclination, restitution and
landing_friction), the actuator and the exciter's data, mean_window_periods,
drive_force and excitation_frequency, and the drive level the plant runs at
(where the inner loop starts): a controller started on a feeder that has run
for hours with other settings regulates from the first window.  Its
diagnostics name every value it took (``taken_from_plant``).  A parameter the
plant node does not have keeps this node's value, and if the node does not
answer within 5 s it says so and keeps its own.  Afterwards it follows the plant
node's changes of those parameters, of ``drive_force`` and of
``excitation_frequency`` on ``/parameter_events`` (validated like any
parameter set; what it cannot take is warned about and counted), and its
diagnostics name the plant it inverts (``plant_node``, ``plant``).  A plant
that runs beyond its model is handled as
:mod:`friction_sim.core.runtime.controller` says: one warning, Pa 0, its
samples taken, regulation again once they are back within the limit.
An initial ``target_speed`` that only the plant's model allows (a target without a drive force, for a
tilted vibration) waits for that model and is judged then.  Beyond Kostek's model (or with
max_amplitude_ratio >= 1) the law inverts the general mean speed on its
rising branch (see :mod:`friction_sim.core.control.law`).  With ``active`` false it stands by, publishing
nothing, until the first target_speed message (or parameter) arrives: an
experiment can steer the slider open loop first.  It publishes nothing until
the model is settled and
something has subscribed to ``excitation_amplitude`` for 0.5 s (or 5 s have
passed): a command published while discovery is still matching the two ends
can arrive late, and the controller would misjudge when its output took
effect.

With the plant's ``actuator`` resonant the law's Pa is what the slideway's
vibration should come to, and the inner loop (:mod:`friction_sim.core.runtime.drive`)
gets it there: the node subscribes to the slider's ``accelerometer``
(sensor_msgs/Imu, linear_acceleration.z, stamped at each sample's simulation
time), and at each mean_velocity stamp (a window's end, the drive phase a
whole turn) it publishes the drive level for the next window, with
``track_resonance`` also the drive frequency.  The exciter's data (f_n, zeta, A)
are read from plant_node at start-up and not followed afterwards: a load on
the slideway moves them without telling anyone, and the inner loop learns that
from the accelerometer.  With ``inner_loop`` false the level is the model's
steady gain's answer to each new Pa (no accelerometer needed).  The law's Pa
never asks for more than full drive gives (the inner loop's model of it, or
the data sheet's without the inner loop): a target beyond it is flagged
unreachable with ``reachable_speed`` (:mod:`friction_sim.core.runtime.controller`).
An accelerometer sample that is not finite, is stamped ahead of any plant in
force, or reads more than any slideway of the model gives is refused and
counted (:mod:`friction_sim.core.runtime.drive`), never held for later.

When its plant runs in lockstep (read from plant_node at start-up) the node answers
each mean_velocity sample on ``control_answer`` instead of publishing on the command
topics (:mod:`friction_sim.ros.controller_lockstep`).

The node wires its parts together: the command batches
(:mod:`friction_sim.ros.controller_commands`), its own and its plant's
parameters (:mod:`friction_sim.ros.controller_parameters`) and what it
publishes (:mod:`friction_sim.ros.controller_outputs`).
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from geometry_msgs.msg import TwistStamped
from rcl_interfaces.msg import ParameterEvent
from rclpy.clock import Clock, ClockType
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import qos_profile_parameter_events

from friction_sim.core.control.law import MeanSpeedController
from friction_sim.core.control.reach import ControlOutput
from friction_sim.core.model import spec
from friction_sim.core.model.commands import CONTROLLER
from friction_sim.core.runtime.controller import RealtimeController
from friction_sim.core.runtime.drive import DriveCommand
from friction_sim.errors import ParameterError, one_line
from friction_sim.io.messages import (
    ACCELEROMETER_DEPTH,
    command_from_message,
    message_class,
    ns_to_seconds,
    stamp_ns,
)
from friction_sim.ros.controller_commands import CommandBatches
from friction_sim.ros.controller_lockstep import LockstepAnswers
from friction_sim.ros.controller_outputs import QOS_DEPTH, ControllerOutputs
from friction_sim.ros.controller_parameters import PLANT_TIMEOUT, OwnParameters, PlantParameters
from friction_sim.ros.controller_plant import qualified
from friction_sim.ros.graph import NameWatch
from friction_sim.ros.intake import PolledGroup, ThrottledWarning, accelerometer_qos, take_all
from friction_sim.ros.parameters import declare_settings, watch_parameter_refusals
from friction_sim.ros.run import CONTROLLER_EXIT_CODES, QuietNode, node_help, run_node, wall_ns

_T = TypeVar("_T")

DISCOVERY_SETTLE = 0.5
#: The node's parameters: declared once in the one vocabulary.
PARAMETERS = spec.CONTROLLER_NODE
PUBLICATIONS = (
    ("excitation_amplitude", "std_msgs/msg/Float64",
     "data = Pa [N] for the plant (force actuator), after each mean_velocity sample and each batch of commands"),
    ("drive_level", "std_msgs/msg/Float64",
     "data = u in [0, 1] (resonant actuator), after each mean_velocity sample (and at start-up)"),
    ("excitation_frequency", "std_msgs/msg/Float64",
     "data = the drive frequency [Hz] (resonant actuator, track_resonance), when tracking moves it"),
    ("diagnostics", "diagnostic_msgs/msg/DiagnosticArray",
     "status 'controller', every diagnostics_period (1 s) and when"
     " the target becomes (un)reachable or an internal error occurs"),
)


class ControllerNode(QuietNode):
    """Publishes the excitation amplitude that makes the slider creep at the target speed."""

    def __init__(self, node_name: str = "controller", **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        #: Held by every callback and by the lockstep answers' thread: one at a time touches the law.
        self.callback_lock = threading.RLock()
        values = declare_settings(self, PARAMETERS)
        #: The law with its counters, pending target and reports (core/runtime/controller.py).
        self.runtime = RealtimeController(values)
        #: The first of each kind of unexpected error is logged.
        self._reported_errors: set[str] = set()
        self._warn = ThrottledWarning(self.get_logger())
        #: The command topics and diagnostics (controller_outputs.py).
        self.outputs = ControllerOutputs(self)
        #: Called with each decision carried out, and with each drive command published (resonant actuator).
        self.output_listeners: list[Callable[[ControlOutput], None]] = self.outputs.output_listeners
        self.drive_listeners: list[Callable[[DriveCommand], None]] = self.outputs.drive_listeners
        #: The answers to the slider's samples while it runs in lockstep (None in real time).
        self.lockstep: LockstepAnswers | None = None
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.commands = CommandBatches(self, self._apply_batch, self.guarded)
        #: Open in real time; shut in lockstep, where the answers' own thread takes the samples.
        self.samples_group = PolledGroup(open=True)
        self.mean_velocity = self.create_subscription(
            TwistStamped, "mean_velocity", self.guarded("mean_velocity callback", self._on_mean_velocity), QOS_DEPTH,
            callback_group=self.samples_group)
        #: Open: each reading wakes the node.  Shut until the model is settled (the inner loop is built
        #: then); in lockstep shut while no answer waits for a reading (they are drained with each sample).
        self.accelerometer_group = PolledGroup()
        self.accelerometer: Any = None
        self.subscribe_accelerometer(lockstep=False)
        self.names = NameWatch(self)
        self.create_timer(values["diagnostics_period"],
                          self.guarded("diagnostics", self.outputs.publish_diagnostics_timed), clock=steady)
        #: The handlers of a set of this node's parameters (controller_parameters.py).
        self.parameters = OwnParameters(self)
        watch_parameter_refusals(self, PARAMETERS, self.parameters.refused)
        self.add_on_set_parameters_callback(self.parameters.on_set)
        self.add_post_set_parameters_callback(self.guarded("parameter update", self.parameters.after_set))
        self.ready = False
        self._deadline = time.monotonic() + PLANT_TIMEOUT
        #: The plant node's parameters, taken at start-up and followed (controller_parameters.py).
        self.plant = PlantParameters(self, AsyncParameterClient(self, values["plant_node"])
                                     if values["plant_node"] else None)
        if not self.plant.settled:
            self.runtime.plant_node = qualified(values["plant_node"], self.get_namespace())
            self.create_subscription(ParameterEvent, "/parameter_events",
                                     self.guarded("plant parameter event", self.plant.on_event),
                                     qos_profile_parameter_events)
        elif values["lockstep"]:  # no plant node to say so: this node's own word
            self.start_lockstep(values["actuation_delay"], values["accelerometer_rate"])
        else:
            self.accelerometer_group.open = True
        self._matched_at: float | None = None
        self._startup_timer = self.create_timer(0.05, self.guarded("start-up", self._start_up), clock=steady)

    def subscribe_accelerometer(self, *, lockstep: bool, reading: bool = True) -> Any:
        """The accelerometer subscription: volatile in real time (only readings from now on
        are the plant's now); in lockstep transient local, so the readings of the windows
        still to answer, sent before this node joined, come too (and replacing the volatile
        one); with ``reading`` false, none (None: lockstep and no inner loop)."""
        if lockstep:
            if self.accelerometer is not None:
                self.destroy_subscription(self.accelerometer)
            self.accelerometer = None
            if not reading:
                return None
        qos = accelerometer_qos(lockstep=lockstep)
        self.accelerometer = self.create_subscription(  # (in lockstep the answers take them, serialized)
            message_class("sensor_msgs/msg/Imu"), "accelerometer",
            self.guarded("accelerometer callback", self._on_acceleration), qos,
            callback_group=self.accelerometer_group, raw=lockstep)
        return self.accelerometer

    @property
    def control(self) -> MeanSpeedController:
        """The law in force."""
        return self.runtime.control

    @property
    def in_lockstep(self) -> bool:
        """True when the plant runs in lockstep (the node answers samples on ``control_answer``)."""
        return self.lockstep is not None

    def start_lockstep(self, delay: float, accelerometer_rate: float) -> None:
        """Answer each sample on ``control_answer`` from now on (:mod:`friction_sim.ros.controller_lockstep`)."""
        self.lockstep = LockstepAnswers(self, delay, accelerometer_rate)
        self.lockstep.start()

    @property
    def polling(self) -> bool:
        """True while the command topics are polled every hold-off (after a
        batch); False while the node is quiet and a command wakes it at once."""
        return self.commands.polling

    # -- start-up: the plant's parameters ---------------------------------------

    def _start_up(self) -> None:
        """Settle the model, then wait for a listener to the output; then go."""
        if not self.plant.settled:
            self.plant.poll()
            return
        now = time.monotonic()
        if self.lockstep is not None:  # answers are stamped: no discovery to wait for
            self.destroy_timer(self._startup_timer)
            self.ready = True
            self.lockstep.answer_waiting()
            return
        output_pub = self.outputs.amplitude if self.runtime.drive is None else self.outputs.level
        if output_pub.get_subscription_count() == 0:
            self._matched_at = None
            if now < self._deadline:
                return
        elif self._matched_at is None:
            self._matched_at = now
        if self._matched_at is not None and now - self._matched_at < DISCOVERY_SETTLE:
            return  # both ends of a new connection need a moment to match
        self.destroy_timer(self._startup_timer)
        self.ready = True
        self.outputs.publish(self.runtime.control.output)

    def settle(self, message: str, warn: bool = False) -> None:
        """The model is settled (taken from the plant, or this node's own): say ``message``,
        take the accelerometer's readings from now on and judge a waiting target."""
        (self.get_logger().warning if warn else self.get_logger().info)(message)
        self.plant.settled = True
        self._deadline = time.monotonic() + PLANT_TIMEOUT
        if self.lockstep is None:  # readings of before: of a loop that adopting the plant replaced
            take_all(self.accelerometer, ACCELEROMETER_DEPTH)
            self.accelerometer_group.open = True
        refusal = self.runtime.settle()
        if refusal:
            self._warn(f"{refusal}; target 0 kept")

    # -- commands -----------------------------------------------------------------

    def _apply_batch(self, batch: list[tuple[str, Any]]) -> None:
        """The commands of a batch in order, each judged against the state the
        ones before it left (as if they came one by one); the law decides once
        and the batch is answered with one excitation_amplitude message."""
        changes = []
        for name, msg in batch:
            (field, value), = command_from_message(name, msg, 0.0).values.items()
            changes.append((field, value))
        refusals = self.runtime.take_batch(changes)
        for reason in refusals:
            self._warn(f"{reason}; last valid value kept")
        if len(refusals) < len(changes):
            self.outputs.publish(self.runtime.control.output)

    def _on_mean_velocity(self, msg: TwistStamped) -> None:
        if self.lockstep is not None:
            self.lockstep.sample(stamp_ns(msg.header.stamp), msg.twist.linear.x)
            return
        t, now = ns_to_seconds(stamp_ns(msg.header.stamp)), wall_ns()
        try:
            output = self.runtime.take_sample(msg.twist.linear.x, t, now, self.ready and self.runtime.active)
        except ParameterError as error:
            self._warn(f"{error}; sample ignored")
            return
        if output is not None:
            self.outputs.publish(output, boundary=t)

    def _on_acceleration(self, msg: Any) -> None:
        """An accelerometer sample for the inner loop (its normal specific force; in lockstep the
        answers take the readings themselves)."""
        try:
            self.runtime.take_acceleration(ns_to_seconds(stamp_ns(msg.header.stamp)), msg.linear_acceleration.z)
        except ParameterError as error:
            self._warn(f"{error}; sample ignored")

    def destroy_node(self) -> None:
        """Stop the lockstep answers' thread (if any), then the node."""
        if self.lockstep is not None:
            self.lockstep.stop()
        super().destroy_node()

    # -- unexpected errors ------------------------------------------------------------

    def guarded(self, where: str, callback: Callable[..., _T]) -> Callable[..., _T | None]:
        """``callback`` for the executor (or the lockstep answers' thread): run holding
        :attr:`callback_lock`; an unexpected error in it is reported (:meth:`internal_error`)
        instead of ending the node's spin."""

        def run(*args: Any) -> _T | None:
            with self.callback_lock:
                try:
                    return callback(*args)
                except Exception as error:  # noqa: BLE001 - the node must outlive a bug, and say so
                    self.internal_error(where, error)
                    return None

        return run

    def internal_error(self, where: str, error: BaseException) -> None:
        """Count it, keep the reason for diagnostics (ERROR from now on), log
        each distinct error once.  The law's state is as before the input (each change
        of it is a transaction), so the input is refused and the node goes on."""
        reason = f"{where}: {one_line(error, with_type=True)}"
        self.runtime.internal_error(reason)
        kind = f"{type(error).__name__}: {error}"  # the same bug, whichever callback met it
        if kind in self._reported_errors:
            return
        self._reported_errors.add(kind)
        self.get_logger().error(f"internal error in {reason}; the input was refused and the controller goes on "
                                "with its last valid state (diagnostics ERROR)")
        if where != "diagnostics":
            with contextlib.suppress(Exception):  # it is logged already
                self.outputs.publish_diagnostics()

    # -- publishing ---------------------------------------------------------------

    def decide(self, output: ControlOutput, boundary: float) -> dict[str, float]:
        """The law's decision at the window's end ``boundary`` (lockstep: the answer's values)."""
        return self.outputs.publish(output, boundary)

    def warn(self, text: str) -> None:
        """Warn about refused input (at most once a second)."""
        self._warn(text)

    def publish_diagnostics(self) -> None:
        """The controller's status on ``diagnostics`` now."""
        self.outputs.publish_diagnostics()

    def publish_output(self) -> None:
        """Carry out the law's decision in force (after a parameter set)."""
        self.outputs.publish(self.runtime.control.output)


def help_text() -> str:
    """What ``controller --help`` prints after the usage line."""
    sample = ("mean_velocity", "geometry_msgs/msg/TwistStamped",
              "the slider's mean speed [m/s] per window (refused if no plant in force could creep that fast)")
    accelerometer = ("accelerometer", "sensor_msgs/msg/Imu",
                     "the slideway's acceleration (resonant actuator: the inner loop reads linear_acceleration.z)")
    return node_help("The mean-speed controller: publishes the excitation amplitude Pa that makes the slider "
                     "creep at target_speed (exact U-relation feedforward, integral action on the measured "
                     "mean speed); on a resonant plant the drive level that brings the slideway's vibration to "
                     "that Pa, from its accelerometer.", PARAMETERS, CONTROLLER, PUBLICATIONS, CONTROLLER_EXIT_CODES,
                     [sample, accelerometer])


def main(args: Sequence[str] | None = None) -> int:
    """``ros2 run friction_sim controller [--help] [--ros-args ...]``."""
    return run_node(ControllerNode, args, prog="controller", help_text=help_text())


if __name__ == "__main__":
    raise SystemExit(main())
