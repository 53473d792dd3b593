"""Scenario files for ``friction-sim experiment``: parsing and validation.

A scenario is a YAML file::

    name: demo                      # optional; names the output files
    duration: 15.0                  # simulated seconds
    real_time_factor: 1.0           # optional (default 1)
    lockstep: true                  # optional: the slider advances when this driver and the controller
                                    #   have answered: the same numbers every run, as fast as the CPU allows
    actuation_delay: 0.0            # optional, lockstep: simulated seconds from a sample to its answer acting
    output: out/demo                # optional folder (default out/<name>)
    log_rate: 1000.0                # optional state samples per simulated second
    accelerometer_rate: 1000.0      # optional: the slider publishes (and records) its accelerometer
    accelerometer_noise: 0.1        # optional: its white noise [m/s^2] (seeded, reproducible)
    plant:                          # the slider's parameters and initial inputs
      mass: 1.0                     #   (or plant_params: config/slider.yaml)
      mu: 0.1
      gravity: 10.0
      drive_force: 0.7
      excitation_amplitude: 5.0
      excitation_frequency: 50.0
    controller:                     # optional; omit (or false) for open loop
      mu: 0.1                       #   any controller parameter (its model, gains...)
    schedule:                       # commands at simulation times, one topic each
      - {t: 1.0, excitation_amplitude: 6.0}
      - {t: 5.0, target_speed: 0.0003}
      - {t: 9.0, external_wrench: {x: 0.0, z: 1.0}}
      - {t: 9.2, parameters: {natural_frequency: 49.4}}   # a slider parameter (a load on the slideway)
    expect:                         # optional acceptance criteria, checked after the run
      - {t: 5.0, within: 0.01, periods: 3, overshoot: 0.1}
    operator:                       # optional: what an operator does beside the schedule
      - {t: 9.5, send: {excitation_amplitude: -1.0}}   # a command the slider refuses
      - {t: 9.8, calls: [pause, step, step, resume]}   # the slider's ~/pause, ~/step, ...

An ``expect`` entry says: after the change at ``t`` the mean speed is within
``within`` (relative) of the target in force in at most ``periods`` excitation
periods, overshooting by at most ``overshoot`` of the step (optional).  With
``quantity: amplitude_per_drive`` (a controller of a resonant plant) it is
the slideway's amplitude per unit drive, as the controller's lock-in reads it,
that comes back within ``within`` of its value before the change.

Everything is checked before anything starts: an unknown key or a bad value is
a :class:`ScenarioError` naming the file, the line, the key and the reason.
The plant and every open-loop command are validated with the same rules the
slider applies (an amplitude above the weight is valid: the slider hops), and
a ``target_speed`` needs a controller.

``operator`` entries change none of the inputs the report is made of: a
``send`` must be a command the slider refuses in the state the schedule
leaves at its time (one it would take belongs in the schedule), and
``calls`` must leave the slider running (a pause is resumed, steps only
while paused, all at that time).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from friction_sim.core.control.law import MeanSpeedController
from friction_sim.core.model import spec as settings
from friction_sim.core.model.commands import (
    COMMANDS,
    CONTROLS,
    PARAMETERS,
    PAUSE,
    RESUME,
    STEP,
    Command,
    apply,
    in_force,
)
from friction_sim.core.model.params import Inputs, SliderParams, check_load, plant_from
from friction_sim.core.runtime.controller import MODEL, law_of
from friction_sim.errors import FrictionSimError, ParameterError, ScenarioError
from friction_sim.experiment.job import ExperimentSpec, OperatorAction
from friction_sim.io.paramfile import read_params_file

#: Keys of ``plant:``: the plant and those inputs the slider takes as parameters.
PLANT_KEYS = tuple(name for name in (*settings.PLANT, *settings.INPUTS) if name in settings.SLIDER_NODE)
#: Controller parameters the scenario derives itself: the initial drive force
#: and frequency come from the plant, the mean window from the slider, and
#: ``active`` from whether a target is given.
_DERIVED_CONTROLLER_KEYS = ("excitation_frequency", "drive_force", "mean_window_periods", "active")
#: Keys of ``controller:``: the controller node's other parameters.
CONTROLLER_KEYS = tuple(name for name in settings.CONTROLLER_NODE if name not in _DERIVED_CONTROLLER_KEYS)
TOP_KEYS = ("name", "description", "duration", "real_time_factor", "lockstep", "actuation_delay", "output",
            "log_rate", "accelerometer_rate", "accelerometer_noise", "plant",
            "plant_params", "controller", "schedule", "namespace", "expect", "operator")
EXPECT_KEYS = ("t", "within", "periods", "overshoot", "quantity")
#: What an expect entry may judge.
QUANTITIES = ("mean_speed", "amplitude_per_drive")
OPERATOR_KEYS = ("t", "send", "calls")

Entry = tuple[yaml.Node, Any]  # a YAML node and its plain value


@dataclass(frozen=True)
class Expectation:
    """An acceptance criterion for the change at ``t`` (see the module docstring)."""

    t: float
    within: float
    periods: int
    overshoot: float = math.inf
    #: What is judged: the mean speed, or the amplitude per unit drive (see the module doc).
    quantity: str = "mean_speed"


@dataclass(frozen=True)
class Scenario:
    """A validated scenario (times in simulated seconds)."""

    name: str
    duration: float
    params: SliderParams
    inputs: Inputs
    schedule: tuple[Command, ...]
    controller: dict[str, Any] | None
    real_time_factor: float = float(settings.REAL_TIME_FACTOR.default)
    output: Path = Path("out")
    log_rate: float = float(settings.LOG_RATE.default)
    accelerometer_rate: float = float(settings.ACCELEROMETER_RATE.default)
    accelerometer_noise: float = float(settings.ACCELEROMETER_NOISE.default)
    #: Run in lockstep (the slider advances when the driver and the controller have answered).
    lockstep: bool = False
    actuation_delay: float = float(settings.ACTUATION_DELAY.default)
    namespace: str | None = None
    description: str = ""
    expect: tuple[Expectation, ...] = ()
    operator: tuple[OperatorAction, ...] = ()
    source: str = field(default="", repr=False)  # the YAML text, kept with the recording

    @property
    def closed_loop(self) -> bool:
        """Whether a controller runs."""
        return self.controller is not None

    @property
    def initial_target(self) -> float | None:
        """The target the controller starts with (None: it stands by until one is scheduled)."""
        if self.controller is None or "target_speed" not in self.controller:
            return None
        return float(self.controller["target_speed"])

    def spec(self) -> ExperimentSpec:
        """The experiment to run for this scenario."""
        controller = dict(self.controller or {})
        if self.controller is not None and "target_speed" not in controller:
            controller["active"] = False  # stand by: steer open loop until the first target
        return ExperimentSpec(
            duration=self.duration, schedule=self.schedule, plant=self.params, inputs=self.inputs,
            controller=self.controller is not None, controller_parameters=controller,
            real_time_factor=self.real_time_factor, log_rate=self.log_rate, name=self.name,
            notes={"scenario": self.source}, operator=self.operator, lockstep=self.lockstep,
            slider_parameters={name: value for name, value in (("accelerometer_rate", self.accelerometer_rate),
                                                               ("accelerometer_noise", self.accelerometer_noise),
                                                               ("actuation_delay", self.actuation_delay))
                               if value},
        )


def load_scenario(path: Path) -> Scenario:
    """Read and validate a scenario file (see the module docstring)."""
    try:
        text = Path(path).read_text()
    except OSError as error:
        raise ScenarioError(f"{path}: cannot read: {error.strerror or error}") from error
    return parse_scenario(text, str(path), base=Path(path).parent)


def compose_mapping(text: str, where: str, error: type[FrictionSimError], what: str) -> yaml.MappingNode:
    """The YAML node tree of ``text`` (nodes keep their lines for every later
    message), refusing invalid YAML or a top level that is not a mapping with
    ``error``; ``what`` says what the file is a mapping of."""
    try:
        root = yaml.compose(text)
    except yaml.YAMLError as problem:
        mark = getattr(problem, "problem_mark", None)
        line = f"line {mark.line + 1}: " if mark is not None else ""
        raise error(f"{where}: {line}not valid YAML: {getattr(problem, 'problem', problem)}") from problem
    if not isinstance(root, yaml.MappingNode):
        raise error(f"{where}: {what}")
    return root


def parse_scenario(text: str, where: str = "<scenario>", base: Path = Path(".")) -> Scenario:
    """Validate scenario text; ``base`` resolves a relative plant_params path."""
    root = compose_mapping(text, where, ScenarioError,
                           "a scenario is a mapping of keys (duration, plant, schedule, ...)")
    return YamlParser(where, base).scenario(root, text)


class YamlParser:
    """Walks the YAML node tree so that every error can name its line (the
    scenario files' parser; sweep files reuse it, see experiment/sweep.py)."""

    def __init__(self, where: str, base: Path) -> None:
        self.where = where
        self.base = base

    def fail(self, node: yaml.Node, message: str) -> ScenarioError:
        """The one-line refusal ``file: line N: message``."""
        return ScenarioError(f"{self.where}: line {node.start_mark.line + 1}: {message}")

    def mapping(self, node: yaml.Node, allowed: tuple[str, ...], what: str) -> dict[str, Entry]:
        """The entries of a mapping node, refusing unknown and repeated keys."""
        if not isinstance(node, yaml.MappingNode):
            raise self.fail(node, f"{what} must be a mapping")
        entries: dict[str, Entry] = {}
        for key_node, value_node in node.value:
            key = key_node.value
            if key not in allowed:
                raise self.fail(key_node, f"unknown key '{key}' in {what} (allowed: {', '.join(allowed)})")
            if key in entries:
                raise self.fail(key_node, f"'{key}' given twice in {what}")
            entries[key] = (value_node, yaml.safe_load(yaml.serialize(value_node)))
        return entries

    def checked(self, entry: Entry, setting: settings.Setting) -> Any:
        """A value checked against ``setting`` (its type and range; the refusal names the
        line), as the setting's type: a float, an integer or a bool."""
        node, value = entry
        try:
            return setting.check(value)
        except ParameterError as error:
            raise self.fail(node, str(error) + _text_number_hint(value)) from None

    def number(self, entry: Entry, key: str, *, positive: bool = False) -> float:
        """A finite number (> 0 with ``positive``)."""
        node, value = entry
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.fail(node, f"{key} = {value!r} rejected: must be a finite number{_text_number_hint(value)}")
        if positive and value <= 0:
            raise self.fail(node, f"{key} = {value!r} rejected: must be > 0")
        return float(value)

    def scenario(self, root: yaml.MappingNode, text: str) -> Scenario:
        """The whole scenario, validated section by section."""
        top = self.mapping(root, TOP_KEYS, "the scenario")
        if "duration" not in top:
            raise self.fail(root, "missing key 'duration' (simulated seconds)")
        duration = self.number(top["duration"], "duration", positive=True)
        rate = self.checked(top["real_time_factor"], settings.REAL_TIME_FACTOR) \
            if "real_time_factor" in top else float(settings.REAL_TIME_FACTOR.default)
        log_rate = self.checked(top["log_rate"], settings.LOG_RATE) if "log_rate" in top \
            else float(settings.LOG_RATE.default)
        accelerometer_rate = self.checked(top["accelerometer_rate"], settings.ACCELEROMETER_RATE) \
            if "accelerometer_rate" in top else float(settings.ACCELEROMETER_RATE.default)
        accelerometer_noise = self.checked(top["accelerometer_noise"], settings.ACCELEROMETER_NOISE) \
            if "accelerometer_noise" in top else float(settings.ACCELEROMETER_NOISE.default)
        lockstep = self.checked(top["lockstep"], settings.LOCKSTEP) if "lockstep" in top else False
        delay = self.checked(top["actuation_delay"], settings.ACTUATION_DELAY) if "actuation_delay" in top else 0.0
        name = str(top["name"][1]) if "name" in top else "experiment"
        params, inputs = self.plant(top, rate)
        controller = self.controller(top.get("controller"), params, inputs)
        schedule = _Schedule(self, params, inputs, rate, controller).read(top.get("schedule"), duration)
        expect = self.expectations(top.get("expect"), schedule)
        if not (controller is not None and params.resonant) and any(e.quantity == "amplitude_per_drive"
                                                                     for e in expect):
            raise self.fail(top["expect"][0], "quantity amplitude_per_drive needs a controller and a plant with "
                                              "actuator resonant (its lock-in reads the amplitude)")
        operator = _Operator(self, params, inputs, schedule).read(top.get("operator"), duration)
        return Scenario(
            name=name, duration=duration, params=params, inputs=inputs, schedule=schedule,
            controller=controller, real_time_factor=rate, output=_text(top, "output", Path("out") / name, Path),
            log_rate=log_rate, accelerometer_rate=accelerometer_rate, accelerometer_noise=accelerometer_noise,
            lockstep=lockstep, actuation_delay=delay, namespace=_text(top, "namespace", None, str),
            description=_text(top, "description", "", str), expect=expect,
            operator=operator, source=text,
        )

    def expectations(self, entry: Entry | None, schedule: tuple[Command, ...]) -> tuple[Expectation, ...]:
        """The ``expect`` list; each judges a change the schedule makes (or the start)."""
        if entry is None:
            return ()
        if not isinstance(entry[0], yaml.SequenceNode):
            raise self.fail(entry[0], "expect must be a list of {t, within, periods[, overshoot]}")
        return tuple(self.expectation(item, schedule) for item in entry[0].value)

    def expectation(self, item: yaml.Node, schedule: tuple[Command, ...]) -> Expectation:
        """One ``expect`` entry."""
        fields = self.mapping(item, EXPECT_KEYS, "an expect entry")
        for key in ("t", "within", "periods"):
            if key not in fields:
                raise self.fail(item, f"an expect entry needs '{key}'")
        t = self.number(fields["t"], "t")
        if t != 0.0 and not any(c.t == t for c in schedule):
            raise self.fail(fields["t"][0], f"t = {t!r}: no scheduled command at that time to judge")
        periods = self.number(fields["periods"], "periods", positive=True)
        overshoot = self.number(fields["overshoot"], "overshoot") if "overshoot" in fields else math.inf
        quantity = str(fields["quantity"][1]) if "quantity" in fields else "mean_speed"
        if quantity not in QUANTITIES:
            raise self.fail(fields["quantity"][0], f"quantity = {quantity!r} rejected: must be one of "
                                                   f"{', '.join(QUANTITIES)}")
        return Expectation(t=t, within=self.number(fields["within"], "within", positive=True), periods=int(periods),
                           overshoot=overshoot, quantity=quantity)

    def plant(self, top: dict[str, Entry], rate: float) -> tuple[SliderParams, Inputs]:
        """The plant and initial inputs (``plant:`` or ``plant_params:``), checked as the slider would."""
        if "plant" in top and "plant_params" in top:
            raise self.fail(top["plant_params"][0], "give either 'plant' or 'plant_params', not both")
        values: dict[str, Any] = {}
        if "plant" in top:
            values = {key: self.plant_value(entry, key)
                      for key, entry in self.mapping(top["plant"][0], PLANT_KEYS, "plant").items()}
        elif "plant_params" in top:
            values = self.params_file(top["plant_params"])
        try:
            params, inputs = plant_from(values)
            check_load(inputs.excitation_frequency, rate)
        except ParameterError as error:
            raise self.plant_error(top, error) from error
        return params, inputs

    def plant_value(self, entry: Entry, key: str) -> Any:
        """One ``plant:`` value: a finite number, or one of the choices of a
        text setting (``landing_friction: none``)."""
        setting = settings.SLIDER_NODE[key]
        if setting.kind is not str:
            return self.number(entry, key)
        try:
            return setting.check(entry[1])
        except ParameterError as error:
            raise self.fail(entry[0], f"plant: {error}") from error

    def plant_error(self, top: dict[str, Entry], error: ParameterError) -> ScenarioError:
        """A refused plant, at the line of the key it blames (or of the section)."""
        node = top["plant"][0] if "plant" in top else top.get("plant_params", (None,))[0]
        if node is None:
            return ScenarioError(f"{self.where}: plant: {error}")
        if "plant" in top:
            node = next((key for key, _ in node.value if key.value == error.field), node)
        return self.fail(node, f"plant: {error}")

    def params_file(self, entry: Entry) -> dict[str, Any]:
        """The slider's values from a ROS 2 parameters file (``/**`` or ``slider`` section)."""
        node, value = entry
        path = (self.base / str(value)) if not Path(str(value)).is_absolute() else Path(str(value))
        if not path.is_file():
            path = Path(str(value))
        try:
            values = read_params_file(path, "slider")
        except FrictionSimError as error:
            raise self.fail(node, f"plant_params: {error}") from error
        return {k: v for k, v in values.items() if k in PLANT_KEYS}

    def controller(self, entry: Entry | None, params: SliderParams, inputs: Inputs) -> dict[str, Any] | None:
        """The controller's parameters (None: open loop), checked as the controller node would."""
        if entry is None or entry[1] is False or entry[1] is None:
            return None
        if entry[1] is True:
            return {}
        items = self.mapping(entry[0], CONTROLLER_KEYS, "controller")
        try:
            values = {key: settings.CONTROLLER_NODE[key].check(item[1]) for key, item in items.items()}
            controller_law(values, params, inputs)
        except ParameterError as error:
            node = items[error.field][0] if error.field in items else entry[0]
            raise self.fail(node, f"controller: {error}") from error
        return values


def controller_values(section: Mapping[str, Any], params: SliderParams, inputs: Inputs) -> dict[str, Any]:
    """Every parameter of the controller node as it runs in a scenario's experiment,
    with the plant ``params`` and ``inputs`` in force: its defaults; the plant's drive
    force and frequency (which it is started with and follows); the ``controller:``
    ``section``; and, with ``plant_node`` set (the default), the plant's model and
    mean window, which the node takes from the slider at start-up and follows
    (friction_sim/ros/controller_plant.py).  The slider's window is its default: a
    scenario does not set it."""
    values = {**settings.defaults(settings.CONTROLLER_NODE), "drive_force": inputs.drive_force,
              "excitation_frequency": inputs.excitation_frequency, **section}
    if values["plant_node"]:
        values.update({name: getattr(params, name) for name in MODEL},
                      mean_window_periods=settings.SLIDER_NODE["mean_window_periods"].default)
    return values


def controller_law(section: Mapping[str, Any], params: SliderParams, inputs: Inputs) -> MeanSpeedController:
    """The controller the node would build in the scenario's experiment (built by the
    node's own :func:`~friction_sim.core.runtime.controller.law_of`), or the
    ParameterError it would refuse with."""
    return law_of(controller_values(section, params, inputs))


def _text(top: dict[str, Entry], key: str, default: Any, kind: type) -> Any:
    """An optional top-level value as ``kind`` (``default`` when absent)."""
    return kind(str(top[key][1])) if key in top else default


class _Schedule:
    """Reads the schedule: one command per entry, each checked against the
    state the entries before it leave, through the core's gate."""

    def __init__(self, parser: YamlParser, params: SliderParams, inputs: Inputs, rate: float,
                 controller: dict[str, Any] | None) -> None:
        self.parser = parser
        self.params, self.inputs, self.rate = params, inputs, rate
        self.controller = controller

    def read(self, entry: Entry | None, duration: float) -> tuple[Command, ...]:
        """The validated, time-ordered schedule."""
        if entry is None:
            return ()
        node = entry[0]
        if not isinstance(node, yaml.SequenceNode):
            raise self.parser.fail(node, "schedule must be a list of {t: ..., <topic>: value}")
        commands: list[Command] = []
        for item in node.value:
            command = self.command(item, duration)
            if commands and command.t < commands[-1].t:
                raise self.parser.fail(item, f"t = {command.t!r} s comes before the previous command's "
                                             f"{commands[-1].t!r} s")
            self.take(item, command)
            commands.append(command)
        return tuple(commands)

    def command(self, item: yaml.Node, duration: float) -> Command:
        """One schedule entry: its time and exactly one command topic with its value."""
        entries = self.parser.mapping(item, ("t", *COMMANDS, PARAMETERS), "a schedule entry")
        if "t" not in entries:
            raise self.parser.fail(item, "a schedule entry needs 't' (simulation time in s)")
        t = self.parser.number(entries["t"], "t")
        if not 0.0 <= t < duration:
            raise self.parser.fail(entries["t"][0], f"t = {t!r} rejected: must be in [0, duration = {duration!r}) s")
        names = [k for k in entries if k != "t"]
        if len(names) != 1:
            raise self.parser.fail(item, f"a schedule entry sets exactly one of {', '.join((*COMMANDS, PARAMETERS))} "
                                         f"(found {', '.join(names) or 'none'})")
        name = names[0]
        if not Command(t, name).for_slider and self.controller is None:
            raise self.parser.fail(entries[name][0], f"{name} needs a controller: add a 'controller:' section")
        return Command(t, name, self.values(name, entries[name]))

    def values(self, name: str, entry: Entry) -> dict[str, Any]:
        """The command's fields: a number for a one-field command; for several
        (external_wrench), a mapping keyed by their message fields (x, z), 0 when
        left out; for ``parameters``, slider parameters as in ``plant:``."""
        if name == PARAMETERS:
            given = self.parser.mapping(entry[0], PLANT_KEYS, PARAMETERS)
            if not given:
                raise self.parser.fail(entry[0], "parameters must set at least one slider parameter")
            return {key: self.parser.plant_value(value, key) for key, value in given.items()}
        spec = COMMANDS[name]
        if len(spec.fields) == 1:
            return {spec.fields[0]: self.parser.number(entry, name)}
        keys = tuple(path.rsplit(".", 1)[-1] for path in spec.message_fields)
        given = self.parser.mapping(entry[0], keys, name)
        return {field_name: self.parser.number(given[key], f"{name}.{key}") if key in given else 0.0
                for field_name, key in zip(spec.fields, keys)}

    def take(self, item: yaml.Node, command: Command) -> None:
        """Apply ``command`` to the state in force, refusing what the nodes would refuse."""
        try:
            params, inputs = apply(command, self.params, self.inputs)
            check_load(inputs.excitation_frequency, self.rate)
            if "target_speed" in command.values:
                controller_law({**(self.controller or {}), **command.values}, params, inputs)
        except ParameterError as error:
            raise self.parser.fail(item, f"{command.name} at t = {command.t!r} s: {error}") from error
        self.params, self.inputs = params, inputs


class _Operator:
    """Reads the ``operator`` list (see the module docstring)."""

    def __init__(self, parser: YamlParser, params: SliderParams, inputs: Inputs,
                 schedule: tuple[Command, ...]) -> None:
        self.parser, self.params, self.inputs, self.schedule = parser, params, inputs, schedule

    def read(self, entry: Entry | None, duration: float) -> tuple[OperatorAction, ...]:
        if entry is None:
            return ()
        if not isinstance(entry[0], yaml.SequenceNode):
            raise self.parser.fail(entry[0], "operator must be a list of {t: ..., send: {...}} or "
                                             "{t: ..., calls: [...]}")
        return tuple(self.action(item, duration) for item in entry[0].value)

    def action(self, item: yaml.Node, duration: float) -> OperatorAction:
        fields = self.parser.mapping(item, OPERATOR_KEYS, "an operator entry")
        if "t" not in fields or ("send" in fields) == ("calls" in fields):
            raise self.parser.fail(item, "an operator entry needs 't' and one of 'send' or 'calls'")
        t = self.parser.number(fields["t"], "t")
        if not 0.0 <= t < duration:
            raise self.parser.fail(fields["t"][0], f"t = {t!r} rejected: must be in [0, duration = {duration!r}) s")
        if "send" in fields:
            return OperatorAction(t, send=self.refused(fields["send"], t))
        return OperatorAction(t, calls=self.calls(fields["calls"]))

    def refused(self, entry: Entry, t: float) -> Command:
        """The command to send: one the slider refuses in the state in force at ``t``."""
        given = self.parser.mapping(entry[0], tuple(COMMANDS), "send")
        if len(given) != 1:
            raise self.parser.fail(entry[0], f"send sets exactly one of {', '.join(COMMANDS)}")
        (name, value), = given.items()
        spec = COMMANDS[name]
        if len(spec.fields) != 1:
            raise self.parser.fail(value[0], f"send {name}: only one-number commands ({name} has several fields)")
        command = Command(t, name, {spec.fields[0]: self.parser.number(value, name)})
        params, inputs = in_force(self.schedule, self.params, self.inputs, t)
        try:
            apply(command, params, inputs)
        except ParameterError:
            return command
        raise self.parser.fail(value[0], f"send {name} = {value[1]!r} at t = {t!r} s: the slider would take it "
                                         "(put it in the schedule; send is for a command it refuses)")

    def calls(self, entry: Entry) -> tuple[str, ...]:
        """Simulation-control calls that leave the slider running."""
        node, names = entry
        if not (isinstance(names, list) and names and all(name in CONTROLS for name in names)):
            raise self.parser.fail(node, f"calls must be a list of {', '.join(CONTROLS)} (found {names!r})")
        paused = False
        for name in names:
            if (name == PAUSE and paused) or (name in (RESUME, STEP) and not paused):
                raise self.parser.fail(node, f"calls {names!r}: {name} while {'paused' if paused else 'running'}")
            paused = name == PAUSE or (paused and name != RESUME)
        if paused:
            raise self.parser.fail(node, f"calls {names!r}: end with resume (the run must go on)")
        return tuple(names)



def _text_number_hint(value: Any) -> str:
    """For a number YAML read as text (YAML 1.1 wants a dot in a float: ``1e-12`` is a
    string, ``1.0e-12`` a number), how to write it; else ''."""
    if not isinstance(value, str):
        return ""
    try:
        number = float(value)
    except ValueError:
        return ""
    if not math.isfinite(number):
        return ""
    mantissa, _, exponent = value.strip().lower().partition("e")
    written = f"{mantissa if '.' in mantissa else mantissa + '.0'}e{exponent}" if exponent else value.strip()
    return f" (YAML read it as text: write {written})"

__all__ = [
    "CONTROLLER_KEYS", "OPERATOR_KEYS", "PLANT_KEYS", "Expectation", "Scenario", "YamlParser", "compose_mapping",
    "controller_law", "controller_values", "load_scenario",
    "parse_scenario",
]
