"""The one place that turns friction_sim's records into ROS 2 messages.

The slider node publishes these messages and the recorder
(:mod:`friction_sim.io.recorder`) logs them, so a recording holds exactly what
the node publishes.  Every function returns a new message; nothing here
imports rclpy, only the message packages.

Topics of a recording (the node's own relative names, without namespace):

==========================  ===============================  ==========================================
topic                       type                             content
==========================  ===============================  ==========================================
``pose``                    geometry_msgs/msg/PoseStamped    pose.position.x = x, .z = z [m] (height)
``velocity``                geometry_msgs/msg/TwistStamped   twist.linear.x = v, .z = vz [m/s]
``friction_force``          geometry_msgs/msg/WrenchStamped  force.x = friction force, force.z = R [N]
                                                             (0 in flight)
``mean_velocity``           geometry_msgs/msg/TwistStamped   twist.linear.x = mean v over the window
``drive_force``             std_msgs/msg/Float64             accepted command, Fd [N]
``excitation_amplitude``    std_msgs/msg/Float64             accepted command, Pa [N]
``excitation_frequency``    std_msgs/msg/Float64             accepted command, f [Hz]
``target_speed``            std_msgs/msg/Float64             accepted command (controller), V* [m/s]
``external_wrench``         geometry_msgs/msg/WrenchStamped  accepted command, force.x, force.z [N]
                                                             (force.z > 0 lifts: see below)
``events``                  diagnostic_msgs/msg/DiagnosticStatus  stick/slip/flight events (see below)
``rejected_commands``       diagnostic_msgs/msg/DiagnosticStatus  refused commands, level WARN
``parameters``              rcl_interfaces/msg/ParameterEvent     parameters at start (new_parameters)
                                                             and every change (changed_parameters)
``sim_control``             diagnostic_msgs/msg/DiagnosticStatus  ~/pause, ~/resume, ~/step, ~/reset calls
                                                             (name; a step's duration [s] in values)
==========================  ===============================  ==========================================

Header stamps and the recording's log times are simulation time, in whole
nanoseconds (:func:`seconds_to_ns`), the resolution of a ROS time stamp.

The frame is the track's: x along it (+ = conveying), z normal to it, away
from it.  So ``external_wrench`` force.z (``external_force_z``) > 0 lifts the
slider; recordings made before that convention (positive pressed the slider
on the track) carry no marker and are read in it (:mod:`friction_sim.io.reader`).
"""

from __future__ import annotations

import functools
import importlib
import re
from collections.abc import Mapping
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
from rcl_interfaces.msg import Parameter, ParameterEvent, ParameterType, ParameterValue

from friction_sim.core.model.commands import (
    COMMANDS,
    CONTROLS,
    PARAMETERS,
    PAUSE,
    RESET,
    RESUME,
    STEP,
    Command,
    Outcome,
    float_values,
)
from friction_sim.core.model.events import Event, EventKind, Mode, SliderState
from friction_sim.core.model.records import Acceleration, PeriodSummary
from friction_sim.core.model.spec import NS_PER_S
from friction_sim.errors import RecordingError

#: The topic of the simulation controls (pause, resume, step, reset) in a recording.
SIM_CONTROL = "sim_control"
#: The state topics, sampled on the recording's uniform grid.
STATE_TOPICS = ("pose", "velocity", "friction_force")
#: topic -> message type name of every topic a recording can hold (the
#: command topics come from the one table, :data:`friction_sim.core.model.commands.COMMANDS`).
TOPIC_TYPES: dict[str, str] = {
    "pose": "geometry_msgs/msg/PoseStamped",
    "velocity": "geometry_msgs/msg/TwistStamped",
    "friction_force": "geometry_msgs/msg/WrenchStamped",
    "mean_velocity": "geometry_msgs/msg/TwistStamped",
    **{name: entry.message_type for name, entry in COMMANDS.items()},
    "events": "diagnostic_msgs/msg/DiagnosticStatus",
    "rejected_commands": "diagnostic_msgs/msg/DiagnosticStatus",
    PARAMETERS: "rcl_interfaces/msg/ParameterEvent",
    SIM_CONTROL: "diagnostic_msgs/msg/DiagnosticStatus",
    "accelerometer": "sensor_msgs/msg/Imu",
}
#: Topics that hold accepted commands (``parameters`` holds other changes too).
COMMAND_TOPICS = (*COMMANDS, PARAMETERS, SIM_CONTROL)


@functools.cache
def message_class(type_name: str) -> type:
    """The message class for ``pkg/msg/Type`` (or ``pkg/Type``), imported by name."""
    match = TYPE_NAME.match(type_name)
    if match is None:
        raise RecordingError(f"not a ROS 2 message type name: {type_name!r}")
    package, _, name = match.groups()
    try:
        module = importlib.import_module(f"{package}.msg")
        return getattr(module, name)  # type: ignore[no-any-return]
    except (ImportError, AttributeError):
        raise RecordingError(f"message type {package}/msg/{name} is not installed") from None


#: A ROS 2 type name: ``pkg/msg/Type``, ``pkg/srv/Type`` or ``pkg/Type`` (package, kind, name).
TYPE_NAME = re.compile(r"^([a-zA-Z][a-zA-Z0-9_]*)/((?:msg|srv)/)?([a-zA-Z][a-zA-Z0-9_]*)$")


# -- time ---------------------------------------------------------------------


def seconds_to_ns(seconds: float) -> int:
    """Simulation time [s] as whole nanoseconds (rounded to the nearest)."""
    return round(seconds * NS_PER_S)


def ns_to_seconds(ns: int) -> float:
    """Whole nanoseconds as seconds (the float closest to ns/1e9)."""
    return ns / NS_PER_S


def time_msg(ns: int, msg: Time | None = None) -> Time:
    """Nanoseconds as a builtin_interfaces/Time (filled in place if given);
    nanosec stays in [0, 1e9) also for negative times."""
    msg = msg if msg is not None else Time()
    msg.sec, msg.nanosec = divmod(int(ns), NS_PER_S)
    return msg


def stamp_ns(stamp: Any) -> int:
    """A builtin_interfaces/Time (generated ROS 2 or decoded rosbags message) as nanoseconds."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


# -- the state ----------------------------------------------------------------


def fill_state_messages(
    state: SliderState, frame_id: str, pose: PoseStamped, twist: TwistStamped, wrench: WrenchStamped,
) -> None:
    """Fill existing messages in place with ``state`` (what :func:`state_messages` returns)."""
    ns = seconds_to_ns(state.t)
    for msg in (pose, twist, wrench):
        time_msg(ns, msg.header.stamp)
        msg.header.frame_id = frame_id
    pose.pose.position.x = state.x
    pose.pose.position.z = state.z
    twist.twist.linear.x = state.v
    twist.twist.linear.z = state.vz
    wrench.wrench.force.x = state.friction_force
    wrench.wrench.force.z = state.normal_force


def state_messages(state: SliderState, frame_id: str = "slideway") -> tuple[PoseStamped, TwistStamped, WrenchStamped]:
    """(pose, velocity, friction_force): position x and height z, velocity v
    and vz, and the friction force (force.x) with the normal reaction R
    (force.z, 0 in flight), stamped with the state's simulation time."""
    pose, twist, wrench = PoseStamped(), TwistStamped(), WrenchStamped()
    fill_state_messages(state, frame_id, pose, twist, wrench)
    return pose, twist, wrench


def mean_velocity_message(period: PeriodSummary, frame_id: str = "slideway") -> TwistStamped:
    """The mean velocity of the window ending with period ``period.n``,
    stamped with the period's end."""
    msg = TwistStamped()
    time_msg(seconds_to_ns(period.t), msg.header.stamp)
    msg.header.frame_id = frame_id
    msg.twist.linear.x = period.mean_velocity
    return msg


#: The accelerometer's topic (sensor_msgs/Imu).
ACCELEROMETER = "accelerometer"
#: The accelerometer topic's queue depth, both ends: in lockstep a period's readings go out at once
#: before the controller answers (at most rate/f of them), and none may be lost.
ACCELEROMETER_DEPTH = 10_000


def imu_message(sample: Acceleration, frame_id: str = "slideway", noise: float = 0.0) -> Any:
    """The accelerometer ``sample`` as sensor_msgs/Imu: linear_acceleration in
    the track frame; orientation and angular velocity not provided (element 0
    of their covariance -1, REP 145); the acceleration's covariance noise**2 on
    the diagonal (all 0, unknown, without noise)."""
    msg = message_class("sensor_msgs/msg/Imu")()
    time_msg(seconds_to_ns(sample.t), msg.header.stamp)
    msg.header.frame_id = frame_id
    msg.orientation_covariance[0] = -1.0
    msg.angular_velocity_covariance[0] = -1.0
    msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = sample.x, sample.y, sample.z
    variance = noise * noise
    msg.linear_acceleration_covariance[0] = msg.linear_acceleration_covariance[4] = variance
    msg.linear_acceleration_covariance[8] = variance
    return msg


# -- commands -----------------------------------------------------------------

#: The slider node's name when it is not renamed (``__node:=``).
SLIDER_NODE = "slider"
#: The fully qualified name of a slider node in the root namespace.
DEFAULT_NODE = "/" + SLIDER_NODE


def node_name(namespace: str, name: str = SLIDER_NODE) -> str:
    """The fully qualified name of node ``name`` in ``namespace`` (as
    rclpy's get_fully_qualified_name gives it): /slider, /feeder2/slider."""
    return f"{namespace.rstrip('/')}/{name}"



def command_message(command: Command, frame_id: str = "", node: str = DEFAULT_NODE) -> Any:
    """A command as the message it travels in (see :data:`COMMANDS`): the
    values written at their message fields; a stamped message gets the
    command's time and ``frame_id``.  A ``parameters`` command (a change made
    with ``ros2 param set``) becomes a ParameterEvent whose changed_parameters
    carry the field names and values, and names ``node`` (the slider's fully
    qualified name) as ROS's own /parameter_events does."""
    if command.name == PARAMETERS:
        return parameters_message(command.values, command.t, changed=True, node=node)
    if command.is_control:
        return DiagnosticStatus(level=DiagnosticStatus.OK, name=command.name, message=_CONTROL_TEXT[command.name],
                                values=key_values({"t": float(command.t), **command.values}))
    entry = COMMANDS[command.name]
    msg = message_class(entry.message_type)()
    if hasattr(msg, "header"):
        time_msg(seconds_to_ns(command.t), msg.header.stamp)
        msg.header.frame_id = frame_id
    for name, path in zip(entry.fields, entry.message_fields):
        *parents, leaf = path.split(".")
        holder = msg
        for parent in parents:
            holder = getattr(holder, parent)
        setattr(holder, leaf, float(command.values.get(name, 0.0)))
    return msg


def command_topic(name: str) -> str:
    """The topic command ``name`` is recorded on: its own, or ``sim_control``
    for pause, resume, step and reset."""
    return SIM_CONTROL if name in CONTROLS else name


def command_from_message(name: str, msg: Any, t: float) -> Command:
    """The command that message ``msg`` on command topic ``name`` carries, at
    simulation time ``t`` (a ParameterEvent on ``parameters``: its changed
    plant and input fields; a DiagnosticStatus on ``sim_control``: the
    control it names)."""
    if name == PARAMETERS:
        new, changed = parameter_event_values(msg)
        return Command(t, PARAMETERS, float_values({**new, **changed}))
    if name == SIM_CONTROL:
        fields = CONTROLS.get(msg.name, ())
        return Command(t, msg.name, {kv.key: float(kv.value) for kv in msg.values if kv.key in fields})
    entry = COMMANDS[name]
    values = {}
    for field, path in zip(entry.fields, entry.message_fields):
        value = msg
        for part in path.split("."):
            value = getattr(value, part)
        values[field] = float(value)
    return Command(t, name, values)


#: The ``message`` of a recorded simulation control.
_CONTROL_TEXT = {PAUSE: "simulation time stopped", RESUME: "simulation time runs again",
                 STEP: "advanced while paused by duration [s]",
                 RESET: "back to the initial state (x = 0 at rest, phase 0): a discontinuity"}


def rejection_message(outcome: Outcome) -> DiagnosticStatus:
    """A refused command: level WARN, name = its topic, message = the reason,
    values = the refused values."""
    return DiagnosticStatus(
        level=DiagnosticStatus.WARN, name=outcome.name, message=outcome.reason,
        values=key_values(outcome.values),
    )


# -- events ---------------------------------------------------------------------


#: Event kinds whose message also carries the velocities just before and after
#: (a landing changes them: an impact; at a lift-off they are continuous).
FLIGHT_EVENTS = (EventKind.LIFT_OFF, EventKind.LANDING)


def event_message(event: Event) -> DiagnosticStatus:
    """An event of the motion as a diagnostic_msgs/DiagnosticStatus.

    name = the kind (``slip_start``, ``stick``, ``reversal``, ``lift_off``,
    ``landing``), message = the transition in words (``stuck -> forward``,
    ``forward -> flight``), values = t, x, phase, before, after (numbers at
    full precision) and, for lift_off and landing, v_before, v_after,
    vz_before, vz_after (tangential and normal velocity just before and just
    after); level OK.

    Why DiagnosticStatus rather than a JSON std_msgs/String: in Foxglove's Raw
    Messages panel each field is shown on its own line and the values as a
    key/value table, without unpacking a string; the State Transitions panel
    can plot ``/events.name`` directly as a timeline of event kinds; and
    every ROS 2 install has the type (diagnostic_msgs is in common_interfaces),
    so ``ros2 bag play`` and ``ros2 topic echo`` work without our package.
    The time of the event is the message's log time and the ``t`` value.
    """
    name, message, values = event_fields(event)
    return DiagnosticStatus(level=DiagnosticStatus.OK, name=name, message=message,
                            values=[KeyValue(key=key, value=value) for key, value in values])


def event_fields(event: Event) -> tuple[str, str, list[tuple[str, str]]]:
    """The name, message and (key, value text) pairs of :func:`event_message`'s status
    (what a recording serializes directly, :func:`~friction_sim.io.cdr.diagnostic_status`)."""
    before, after = _mode(event.before), _mode(event.after)
    values: dict[str, Any] = {"t": float(event.t), "x": float(event.x), "phase": float(event.phase),
                              "before": before, "after": after}
    if event.kind in FLIGHT_EVENTS:
        values.update(v_before=float(event.v_before), v_after=float(event.v_after),
                      vz_before=float(event.vz_before), vz_after=float(event.vz_after))
    return event.kind.value, f"{before} -> {after}", [(str(key), value_text(value)) for key, value in values.items()]


def _mode(mode: Mode | int) -> str:
    return _MODE_NAMES[mode]


#: A mode's name as an event's status says it.
_MODE_NAMES: dict[Mode | int, str] = {mode: mode.name.lower() for mode in Mode}


# -- parameters -------------------------------------------------------------------


def parameter_value(value: Any) -> ParameterValue:
    """A Python value as an rcl_interfaces/ParameterValue of the matching type
    (bool, int, float, str, bytes, or a list of one of them)."""
    if isinstance(value, bool):
        return ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=value)
    if isinstance(value, int):
        return ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=value)
    if isinstance(value, float):
        return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
    if isinstance(value, str):
        return ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
    if isinstance(value, (bytes, bytearray)):
        return ParameterValue(type=ParameterType.PARAMETER_BYTE_ARRAY, byte_array_value=[bytes([b]) for b in value])
    if isinstance(value, (list, tuple)):
        items = list(value)
        if all(isinstance(v, bool) for v in items):
            return ParameterValue(type=ParameterType.PARAMETER_BOOL_ARRAY, bool_array_value=items)
        if all(isinstance(v, int) and not isinstance(v, bool) for v in items):
            return ParameterValue(type=ParameterType.PARAMETER_INTEGER_ARRAY, integer_array_value=items)
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in items):
            return ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY,
                                  double_array_value=[float(v) for v in items])
        if all(isinstance(v, str) for v in items):
            return ParameterValue(type=ParameterType.PARAMETER_STRING_ARRAY, string_array_value=items)
    if value is None:
        return ParameterValue(type=ParameterType.PARAMETER_NOT_SET)
    # numpy scalars and other numbers
    if isinstance(value, float) or hasattr(value, "__float__"):
        return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=float(value))
    raise TypeError(f"cannot express {value!r} as a ROS parameter value")


def parameter_python_value(value: Any) -> Any:
    """The Python value of an rcl_interfaces/ParameterValue (None if not set),
    a generated ROS 2 message or a decoded rosbags one."""
    kind = value.type
    if kind == ParameterType.PARAMETER_BOOL:
        return bool(value.bool_value)
    if kind == ParameterType.PARAMETER_INTEGER:
        return int(value.integer_value)
    if kind == ParameterType.PARAMETER_DOUBLE:
        return float(value.double_value)
    if kind == ParameterType.PARAMETER_STRING:
        return str(value.string_value)
    if kind == ParameterType.PARAMETER_BYTE_ARRAY:  # rclpy: a list of bytes; rosbags: a uint8 array
        items = value.byte_array_value
        return b"".join(items) if len(items) and isinstance(items[0], bytes) else bytes(bytearray(items))
    if kind == ParameterType.PARAMETER_BOOL_ARRAY:
        return [bool(v) for v in value.bool_array_value]
    if kind == ParameterType.PARAMETER_INTEGER_ARRAY:
        return [int(v) for v in value.integer_array_value]
    if kind == ParameterType.PARAMETER_DOUBLE_ARRAY:
        return [float(v) for v in value.double_array_value]
    if kind == ParameterType.PARAMETER_STRING_ARRAY:
        return [str(v) for v in value.string_array_value]
    return None


def parameters_message(
    values: Mapping[str, Any], t: float, *, changed: bool = False, node: str = DEFAULT_NODE,
) -> ParameterEvent:
    """The parameters ``values`` at simulation time ``t`` as an
    rcl_interfaces/ParameterEvent of ``node`` (fully qualified: /feeder2/slider
    under namespace /feeder2): as new_parameters (the set at start), or with
    ``changed`` as changed_parameters (a later change)."""
    parameters = [Parameter(name=name, value=parameter_value(value)) for name, value in values.items()]
    msg = ParameterEvent(node=node)
    time_msg(seconds_to_ns(t), msg.stamp)
    if changed:
        msg.changed_parameters = parameters
    else:
        msg.new_parameters = parameters
    return msg


def parameter_event_values(msg: Any) -> tuple[dict[str, Any], dict[str, Any]]:
    """(new, changed) parameter values of a ParameterEvent (generated ROS 2 or
    decoded rosbags message), by name."""
    new = {p.name: parameter_python_value(p.value) for p in msg.new_parameters}
    changed = {p.name: parameter_python_value(p.value) for p in msg.changed_parameters}
    return new, changed


def value_text(value: Any) -> str:
    """A value as text: full precision for floats (repr), str() otherwise."""
    return repr(value) if isinstance(value, float) else str(value)


def key_values(values: Mapping[str, Any]) -> list[KeyValue]:
    """diagnostic_msgs/KeyValue pairs with the values as :func:`value_text`."""
    return [KeyValue(key=str(key), value=value_text(value)) for key, value in values.items()]


__all__ = [
    "ACCELEROMETER", "COMMAND_TOPICS", "DEFAULT_NODE", "FLIGHT_EVENTS", "NS_PER_S", "SIM_CONTROL", "SLIDER_NODE",
    "STATE_TOPICS", "TOPIC_TYPES", "command_from_message", "command_message", "command_topic", "event_fields",
    "event_message", "fill_state_messages", "imu_message", "mean_velocity_message", "message_class", "node_name",
    "ns_to_seconds", "parameter_event_values", "parameter_python_value", "parameter_value", "parameters_message",
    "rejection_message", "seconds_to_ns", "stamp_ns", "state_messages", "time_msg",
]
