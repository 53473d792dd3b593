"""Stamped commands: what lockstep's participants send the slider (:mod:`friction_sim.core.runtime.lockstep`).

The command topics (``drive_force``, ``excitation_amplitude``, ...) carry
std_msgs/Float64, which has no stamp: a command takes effect when the slider
takes it.  Lockstep needs each command tied to a simulation time, and an answer
tied to the sample it answers, in one message (DDS does not order messages
across topics, so a separate acknowledgement could overtake the value).
Both channels use ``sensor_msgs/msg/JointState`` as a stamped list of named
values, as simulators do for joint commands (Isaac Sim's ``joint_command``):

* ``header.stamp``: simulation time (``control_answer``: the stamp of the
  mean_velocity sample answered; ``stamped_command``: when the values apply);
* ``name[i]``, ``position[i]``: a command field and its value (``drive_level``,
  ``excitation_amplitude``, ``excitation_frequency``, ``drive_force``,
  ``external_force_x``, ``external_force_z``); the fields of one command topic
  make one command (``external_force_x`` and ``_z``: one ``external_wrench``);
* no names: an answer that changes nothing, or a promise alone.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from friction_sim.core.model.commands import COMMANDS, SLIDER, Command
from friction_sim.errors import ParameterError
from friction_sim.io.messages import message_class, stamp_ns, time_msg

CONTROL_ANSWER = "control_answer"
STAMPED_COMMAND = "stamped_command"
STAMPED_TYPE = "sensor_msgs/msg/JointState"
#: Stamped messages on their way at once, both channels and both ends (the slider waits for each
#: answer; a driver sends a stretch of its schedule at once).
STAMPED_DEPTH = 1000
#: A slider command field -> the command topic it belongs to.
_TOPIC_OF = {field: entry.name for entry in COMMANDS.values() if SLIDER in entry.consumers for field in entry.fields}


def stamped_message(stamp: int, values: Mapping[str, float] | Sequence[Command] = ()) -> Any:
    """A JointState stamped ``stamp`` [ns] carrying ``values`` (field -> value), or the
    values of some commands, in order."""
    if not isinstance(values, Mapping):
        values = {field: value for command in values for field, value in command.values.items()}
    msg = message_class(STAMPED_TYPE)()
    time_msg(stamp, msg.header.stamp)
    msg.name = list(values)
    msg.position = [float(value) for value in values.values()]
    return msg


def stamped_commands(topic: str, msg: Any, t: float) -> tuple[int, list[Command]]:
    """(stamp [ns], the commands) a stamped message carries, each command at
    simulation time ``t``, in the order of their first field; a ParameterError
    names what is malformed (an unknown name, lengths that differ)."""
    names, values = list(msg.name), list(msg.position)
    if len(names) != len(values):
        raise ParameterError(f"{topic}.position", len(values), f"must have one value per name ({len(names)})")
    grouped: dict[str, dict[str, float]] = {}
    for name, value in zip(names, values):
        topic_of = _TOPIC_OF.get(name)
        if topic_of is None:
            raise ParameterError(f"{topic}.name", name, f"must be a slider command field: {', '.join(_TOPIC_OF)}")
        if name in grouped.get(topic_of, {}):
            raise ParameterError(f"{topic}.name", name, "must appear once per message")
        grouped.setdefault(topic_of, {})[name] = float(value)
    return stamp_ns(msg.header.stamp), [Command(t, name, fields) for name, fields in grouped.items()]


__all__ = ["CONTROL_ANSWER", "STAMPED_COMMAND", "STAMPED_DEPTH", "STAMPED_TYPE", "stamped_commands", "stamped_message"]
