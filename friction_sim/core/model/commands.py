"""The command vocabulary: what can be sent to the plant, and one record for it.

:data:`COMMANDS` is the one table of the inputs a user or a controller sends
over ROS topics: per command its topic name, the fields it sets, the ROS
message type and where in the message each field sits, and which node
consumes it.  :class:`Command` is the one record of "this command at
simulation time t", used by the simulation, the scenario parser, the
experiment runner, the recorder, the reader, verify, the report and the
nodes.  :func:`apply` is the one way a command changes the plant: it goes
through the validated types of :mod:`friction_sim.core.model.params`;
:func:`take` the one way it changes a running core (the node's and verify's).

Adding an input is one entry here (plus its field in ``spec.INPUTS`` and its
physics in the core).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from friction_sim.core.model import spec
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.errors import ParameterError

#: The command that a parameter change (``ros2 param set``) makes: any plant or input field.
PARAMETERS = "parameters"
SLIDER = "slider"
CONTROLLER = "controller"


@dataclass(frozen=True)
class CommandSpec:
    """One command topic: the fields it sets, its message, who consumes it.

    ``message_fields`` gives, for each of ``fields``, the dotted path of the
    value in a message of ``message_type`` (``data`` for std_msgs/Float64).
    """

    name: str
    fields: tuple[str, ...]
    message_type: str
    message_fields: tuple[str, ...]
    consumers: tuple[str, ...]
    description: str


_FLOAT64 = "std_msgs/msg/Float64"

COMMANDS: dict[str, CommandSpec] = {
    spec_.name: spec_ for spec_ in (
        CommandSpec("drive_force", ("drive_force",), _FLOAT64, ("data",), (SLIDER, CONTROLLER),
                    "Fd [N] along +x (negative drives backwards)"),
        CommandSpec("excitation_amplitude", ("excitation_amplitude",), _FLOAT64, ("data",), (SLIDER,),
                    "Pa [N] >= 0 (above m g cos(alpha) - Fz the slider hops; the resonant actuator refuses it)"),
        CommandSpec("excitation_frequency", ("excitation_frequency",), _FLOAT64, ("data",), (SLIDER, CONTROLLER),
                    "f [Hz] > 0; the phase stays continuous (resonant actuator: the drive frequency)"),
        CommandSpec("drive_level", ("drive_level",), _FLOAT64, ("data",), (SLIDER,),
                    "u in [0, 1], the resonant actuator's drive level (the force actuator refuses it)"),
        CommandSpec("external_wrench", ("external_force_x", "external_force_z"), "geometry_msgs/msg/WrenchStamped",
                    ("wrench.force.x", "wrench.force.z"), (SLIDER,),
                    "extra force held until the next message: force.x tangential [N], force.z normal [N] "
                    "(z up, away from the track: > 0 lifts)"),
        CommandSpec("target_speed", ("target_speed",), _FLOAT64, ("data",), (CONTROLLER,),
                    "target mean speed V* [m/s] of the controller"),
    )
}

#: Simulation control: the slider's ``~/pause``, ``~/resume``, ``~/step`` and
#: ``~/reset`` services, recorded as commands (on ``sim_control``) so that a
#: replay knows where the run was reset.  They carry no physics: pause, resume
#: and step change only how simulation time follows the wall clock; reset
#: starts the slider again from rest (see :meth:`friction_sim.core.engine.single.Slider.restart`).
PAUSE, RESUME, STEP, RESET = "pause", "resume", "step", "reset"
#: control command -> the fields it carries (a step: how far it advanced [s]).
CONTROLS: dict[str, tuple[str, ...]] = {PAUSE: (), RESUME: (), STEP: ("duration",), RESET: ()}

#: Fields a ``parameters`` command may carry: the plant's and the inputs'.
PHYSICS_FIELDS = (*spec.PLANT, *spec.INPUTS)
#: A command's value: a number, or the text of a string setting (``landing_friction``).
Value = Any  # float, or str for a string setting: Any so that the many numeric uses need no narrowing


def consumed_by(node: str) -> tuple[CommandSpec, ...]:
    """The command topics ``node`` (``slider`` or ``controller``) subscribes to."""
    return tuple(entry for entry in COMMANDS.values() if node in entry.consumers)


@dataclass(frozen=True)
class Command:
    """Command ``name`` setting ``values`` (field -> value) at simulation time ``t`` [s].

    ``name`` is a topic of :data:`COMMANDS` or ``parameters`` (a change made
    through the parameter services, of any plant or input field).  The values
    are checked when the command is applied (:func:`apply`), not here, so that
    a refused command can still be recorded as it arrived.
    """

    t: float
    name: str
    values: Mapping[str, Value] = field(default_factory=dict)

    def __post_init__(self) -> None:
        allowed = COMMANDS[self.name].fields if self.name in COMMANDS else CONTROLS.get(self.name)
        if allowed is None and self.name != PARAMETERS:
            raise ParameterError("command", self.name,
                                 f"must be one of {', '.join([*COMMANDS, PARAMETERS, *CONTROLS])}")
        unknown = [key for key in self.values if key not in (allowed or PHYSICS_FIELDS)]
        if unknown:
            raise ParameterError(f"{self.name}.{unknown[0]}", self.values[unknown[0]],
                                 f"unknown field; known: {', '.join(allowed or PHYSICS_FIELDS)}")
        object.__setattr__(self, "values", dict(self.values))

    @property
    def plant(self) -> dict[str, Value]:
        """The values that change the plant (mass, mu, ..., landing_friction)."""
        return {k: v for k, v in self.values.items() if k in spec.PLANT}

    @property
    def inputs(self) -> dict[str, Value]:
        """The values that change the inputs (see :class:`Inputs`)."""
        return {k: v for k, v in self.values.items() if k in spec.INPUTS}

    @property
    def for_slider(self) -> bool:
        """Whether the slider takes this command: a parameter change of the
        physics, or a topic the slider subscribes to (a target speed is the
        controller's alone)."""
        return self.name in (PARAMETERS, *CONTROLS) or SLIDER in COMMANDS[self.name].consumers

    @property
    def is_control(self) -> bool:
        """Whether this is a simulation control (pause, resume, step, reset)."""
        return self.name in CONTROLS

    def at(self, t: float) -> Command:
        """The same command at another time."""
        return Command(t, self.name, self.values)


@dataclass(frozen=True)
class Outcome:
    """A command as handled: accepted, or refused with the reason (field, value, limit)."""

    command: Command
    reason: str = ""

    @property
    def accepted(self) -> bool:
        return not self.reason

    @property
    def t(self) -> float:
        return self.command.t

    @property
    def name(self) -> str:
        return self.command.name

    @property
    def values(self) -> Mapping[str, Value]:
        return self.command.values


def apply(command: Command, params: SliderParams, inputs: Inputs) -> tuple[SliderParams, Inputs]:
    """The plant and inputs after ``command``, validated as one new state.

    Raises :class:`ParameterError` (and nothing changes) if a value is out of
    its range, or if the command sets the input the actuator in force after it
    does not use (``excitation_amplitude`` for the resonant one, ``drive_level``
    for the force one): on its topic whatever the value, as a parameter to any
    value but the one held (a parameter dump loads back); the error names the
    field the command set.  Fields the plant does not have (a target speed)
    leave it as it is.
    """
    plant, changes = command.plant, command.inputs
    new_params = params.replace(**plant) if plant else params
    new_inputs = inputs.replace(**changes) if changes else inputs
    _check_actuator(new_params, changes, inputs if command.name == PARAMETERS else None)
    return new_params, new_inputs


#: The input each actuator takes for the size of the excitation, and the one it does not.
_ACTUATOR_INPUT = {"force": ("excitation_amplitude", "drive_level"),
                   "resonant": ("drive_level", "excitation_amplitude")}


def unused_input(actuator: str) -> str:
    """The input ``actuator`` (force or resonant) does not use: a command or a
    parameter set of it is refused (:func:`apply`); diagnostics mark it unused."""
    return _ACTUATOR_INPUT[actuator][1]


def _check_actuator(params: SliderParams, changes: Mapping[str, Value], held: Inputs | None) -> None:
    """Refuse a command that sets the input the actuator of ``params`` does not
    use, naming the one it does use: a command on its topic whatever the value
    (even the one held: it acts on nothing, and a user who sends it means the
    other input); a parameter set (``held``: the inputs before it) unless it
    keeps the value held, which is configuration, not a command (``ros2 param
    load`` of a dump sets every parameter)."""
    used, unused = _ACTUATOR_INPUT[params.actuator]
    if unused in changes and (held is None or changes[unused] != getattr(held, unused)):
        setting = spec.INPUTS[used]
        raise ParameterError(unused, changes[unused], f"is not used by actuator {params.actuator}: set {used} "
                                                      f"({setting.range_text()}{setting.unit_suffix}) instead")


class Core(Protocol):
    """What :func:`take` changes: the exact core (:class:`friction_sim.core.engine.single.Slider`)."""

    @property
    def params(self) -> SliderParams: ...
    @property
    def inputs(self) -> Inputs: ...
    def set_plant(self, params: SliderParams, inputs: Inputs) -> None: ...
    def restart(self) -> None: ...


def take(core: Core, command: Command, check: Callable[[SliderParams, Inputs], object] | None = None) -> bool:
    """Make ``command`` one change of ``core``, at the core's time: a reset
    starts it again from rest; any other command gives the plant and inputs
    :func:`apply` makes of those in force, which ``check`` (if given) may
    refuse, and the core takes them if they differ from those in force.
    Returns whether the core changed; a ParameterError of the gate or of
    ``check`` is raised before anything changes.

    The one way a handled command reaches the core: the slider node takes each
    command it accepts with it (a parameter set as one command), and verify
    replays a recording's accepted commands with it, one by one in recorded
    order.  Each command is a change of its own, even at one instant (several
    in one tick, or sent while paused): with the resonant exciter, a change
    followed by another at the same instant (the actuator switched, then the
    frequency set) leaves a transient that the two merged into one change do
    not, so the node and a replay must both take them one at a time.
    """
    if command.name == RESET:
        core.restart()
        return True
    params, inputs = apply(command, core.params, core.inputs)
    if check is not None:
        check(params, inputs)
    if params == core.params and inputs == core.inputs:
        return False
    core.set_plant(params, inputs)
    return True


def reason(command: Command, error: ParameterError) -> str:
    """The one-line refusal of ``command``: the error, prefixed by the command's
    name when the error names another field (``external_wrench: external_force_z = ...``)."""
    return str(error) if error.field == command.name else f"{command.name}: {error}"


def in_force(commands: Sequence[Command], params: SliderParams, inputs: Inputs, t: float) -> tuple[
        SliderParams, Inputs]:
    """Plant and inputs after every command at or before ``t`` (time-ordered
    ``commands``); a command that would be refused is skipped."""
    for command in commands:
        if command.t > t:
            break
        try:
            params, inputs = apply(command, params, inputs)
        except ParameterError:
            continue
    return params, inputs


def float_values(values: Mapping[str, Any]) -> dict[str, Value]:
    """The plant and input fields of ``values``, numbers as floats (for
    building a Command from parameter values, which may be ints); text (a
    string setting such as ``landing_friction``) stays text."""
    return {k: v if isinstance(v, str) else float(v) for k, v in values.items() if k in PHYSICS_FIELDS}


__all__ = [
    "COMMANDS", "CONTROLLER", "CONTROLS", "Core", "PARAMETERS", "PAUSE", "PHYSICS_FIELDS", "RESET", "RESUME", "SLIDER",
    "STEP", "Command", "CommandSpec", "Outcome", "Value", "apply", "consumed_by", "float_values",
    "in_force", "reason", "take", "unused_input",
]
