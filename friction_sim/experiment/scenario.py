"""Scenario files for ``friction-sim experiment``: parsing and validation.

A scenario is a YAML file::

    name: demo                      # optional; names the output files
    duration: 15.0                  # simulated seconds
    real_time_factor: 1.0           # optional (default 1)
    output: out/demo                # optional folder (default out/<name>)
    log_rate: 1000.0                # optional state samples per simulated second
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
    expect:                         # optional acceptance criteria, checked after the run
      - {t: 5.0, within: 0.01, periods: 3, overshoot: 0.1}

An ``expect`` entry says: after the change at ``t`` the mean speed is within
``within`` (relative) of the target in force in at most ``periods`` excitation
periods, overshooting by at most ``overshoot`` of the step (optional).

Everything is checked before anything starts: an unknown key or a bad value is
a :class:`ScenarioError` naming the file, the line, the key and the reason.
The plant and every open-loop command are validated with the same rules the
slider applies (so a scenario that would lift the slider off is refused), and
a ``target_speed`` needs a controller.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from friction_sim.core.control import ControllerConfig, MeanSpeedController
from friction_sim.errors import FrictionSimError, ParameterError
from friction_sim.experiment.runner import COMMAND_TOPICS, ExperimentSpec, ScheduledCommand
from friction_sim.io.paramfile import read_params_file
from friction_sim.core.params import Inputs, SliderParams, check_contact

PLANT_KEYS = ("mass", "mu", "gravity", "drive_force", "excitation_amplitude", "excitation_frequency")
CONTROLLER_KEYS = ("mass", "mu", "gravity", "integral_gain", "max_amplitude_ratio", "settle_margin",
                   "plant_node", "target_speed")
TOP_KEYS = ("name", "description", "duration", "real_time_factor", "output", "log_rate", "plant",
            "plant_params", "controller", "schedule", "namespace", "expect")
EXPECT_KEYS = ("t", "within", "periods", "overshoot")


@dataclass(frozen=True)
class Expectation:
    """An acceptance criterion for the change at ``t`` (see the module docstring)."""

    t: float
    within: float
    periods: int
    overshoot: float = math.inf


class ScenarioError(FrictionSimError):
    """A scenario file that cannot be run, with where and why."""


@dataclass(frozen=True)
class Scenario:
    """A validated scenario (times in simulated seconds)."""

    name: str
    duration: float
    params: SliderParams
    inputs: Inputs
    schedule: tuple[ScheduledCommand, ...]
    controller: dict[str, Any] | None
    real_time_factor: float = 1.0
    output: Path = Path("out")
    log_rate: float = 1000.0
    namespace: str | None = None
    description: str = ""
    expect: tuple[Expectation, ...] = ()
    source: str = field(default="", repr=False)  # the YAML text, kept with the recording

    @property
    def closed_loop(self) -> bool:
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
            real_time_factor=self.real_time_factor, log_rate=self.log_rate,
            notes={"scenario": self.source, "name": self.name},
        )


def load_scenario(path: Path) -> Scenario:
    """Read and validate a scenario file (see the module docstring)."""
    try:
        text = Path(path).read_text()
    except OSError as error:
        raise ScenarioError(f"{path}: cannot read: {error.strerror or error}") from error
    return parse_scenario(text, str(path), base=Path(path).parent)


def parse_scenario(text: str, where: str = "<scenario>", base: Path = Path(".")) -> Scenario:
    """Validate scenario text; ``base`` resolves a relative plant_params path."""
    try:
        root = yaml.compose(text)
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        line = f"line {mark.line + 1}: " if mark is not None else ""
        raise ScenarioError(f"{where}: {line}not valid YAML: {getattr(error, 'problem', error)}") from error
    if not isinstance(root, yaml.MappingNode):
        raise ScenarioError(f"{where}: a scenario is a mapping of keys (duration, plant, schedule, ...)")
    return _Parser(where, base).scenario(root, text)


class _Parser:
    """Walks the YAML node tree so that every error can name its line."""

    def __init__(self, where: str, base: Path) -> None:
        self.where = where
        self.base = base

    def fail(self, node: yaml.Node, message: str) -> ScenarioError:
        return ScenarioError(f"{self.where}: line {node.start_mark.line + 1}: {message}")

    def mapping(self, node: yaml.Node, allowed: tuple[str, ...], what: str) -> dict[str, tuple[yaml.Node, Any]]:
        if not isinstance(node, yaml.MappingNode):
            raise self.fail(node, f"{what} must be a mapping")
        entries: dict[str, tuple[yaml.Node, Any]] = {}
        for key_node, value_node in node.value:
            key = key_node.value
            if key not in allowed:
                raise self.fail(key_node, f"unknown key '{key}' in {what} (allowed: {', '.join(allowed)})")
            if key in entries:
                raise self.fail(key_node, f"'{key}' given twice in {what}")
            entries[key] = (value_node, yaml.safe_load(yaml.serialize(value_node)))
        return entries

    def number(self, entry: tuple[yaml.Node, Any], key: str, *, positive: bool = False) -> float:
        node, value = entry
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.fail(node, f"{key} = {value!r} rejected: must be a finite number")
        if positive and value <= 0:
            raise self.fail(node, f"{key} = {value!r} rejected: must be > 0")
        return float(value)

    def scenario(self, root: yaml.MappingNode, text: str) -> Scenario:
        top = self.mapping(root, TOP_KEYS, "the scenario")
        if "duration" not in top:
            raise self.fail(root, "missing key 'duration' (simulated seconds)")
        duration = self.number(top["duration"], "duration", positive=True)
        rate = self.number(top["real_time_factor"], "real_time_factor", positive=True) \
            if "real_time_factor" in top else 1.0
        log_rate = self.number(top["log_rate"], "log_rate", positive=True) if "log_rate" in top else 1000.0
        name = str(top["name"][1]) if "name" in top else "experiment"
        params, inputs = self.plant(top)
        controller = self.controller(top.get("controller"), params, inputs)
        schedule = self.schedule(top.get("schedule"), duration, params, inputs, controller is not None)
        output = Path(str(top["output"][1])) if "output" in top else Path("out") / name
        return Scenario(
            name=name, duration=duration, params=params, inputs=inputs, schedule=schedule,
            controller=controller, real_time_factor=rate, output=output, log_rate=log_rate,
            namespace=str(top["namespace"][1]) if "namespace" in top else None,
            description=str(top["description"][1]) if "description" in top else "",
            expect=self.expectations(top.get("expect"), schedule), source=text,
        )

    def expectations(self, entry: tuple[yaml.Node, Any] | None,
                     schedule: tuple[ScheduledCommand, ...]) -> tuple[Expectation, ...]:
        if entry is None:
            return ()
        if not isinstance(entry[0], yaml.SequenceNode):
            raise self.fail(entry[0], "expect must be a list of {t, within, periods[, overshoot]}")
        found = []
        for item in entry[0].value:
            fields = self.mapping(item, EXPECT_KEYS, "an expect entry")
            for key in ("t", "within", "periods"):
                if key not in fields:
                    raise self.fail(item, f"an expect entry needs '{key}'")
            t = self.number(fields["t"], "t")
            if t != 0.0 and not any(c.t == t for c in schedule):
                raise self.fail(fields["t"][0], f"t = {t!r}: no scheduled command at that time to judge")
            periods = self.number(fields["periods"], "periods", positive=True)
            found.append(Expectation(
                t=t, within=self.number(fields["within"], "within", positive=True), periods=int(periods),
                overshoot=self.number(fields["overshoot"], "overshoot") if "overshoot" in fields else math.inf))
        return tuple(found)

    def plant(self, top: dict[str, tuple[yaml.Node, Any]]) -> tuple[SliderParams, Inputs]:
        if "plant" in top and "plant_params" in top:
            raise self.fail(top["plant_params"][0], "give either 'plant' or 'plant_params', not both")
        values: dict[str, float] = {}
        if "plant" in top:
            for key, entry in self.mapping(top["plant"][0], PLANT_KEYS, "plant").items():
                values[key] = self.number(entry, key)
        elif "plant_params" in top:
            values = self.params_file(top["plant_params"])
        try:
            params = SliderParams(**{k: v for k, v in values.items() if k in ("mass", "mu", "gravity")})
            inputs = Inputs(**{k: v for k, v in values.items() if k not in ("mass", "mu", "gravity")})
            check_contact(params, inputs)
        except ParameterError as error:
            node = top["plant"][0] if "plant" in top else top.get("plant_params", (None,))[0]
            if "plant" in top:
                for key_node, _ in node.value:
                    if key_node.value == error.field:
                        node = key_node
            raise self.fail(node, f"plant: {error}") if node is not None else ScenarioError(
                f"{self.where}: plant: {error}") from error
        return params, inputs

    def params_file(self, entry: tuple[yaml.Node, Any]) -> dict[str, float]:
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

    def controller(self, entry: tuple[yaml.Node, Any] | None, params: SliderParams,
                   inputs: Inputs) -> dict[str, Any] | None:
        if entry is None or entry[1] is False or entry[1] is None:
            return None
        if entry[1] is True:
            return {}
        settings: dict[str, Any] = {}
        items = self.mapping(entry[0], CONTROLLER_KEYS, "controller")
        for key, item in items.items():
            settings[key] = str(item[1]) if key == "plant_node" else self.number(item, key)
        try:  # the rules the controller node applies to its parameters
            model = params.replace(**{k: settings[k] for k in ("mass", "mu", "gravity") if k in settings})
            config = ControllerConfig(model=model, **{k: settings[k] for k in (
                "integral_gain", "max_amplitude_ratio", "settle_margin") if k in settings})
            MeanSpeedController(config, drive_force=inputs.drive_force, frequency=inputs.excitation_frequency,
                                target_speed=settings.get("target_speed", 0.0))
        except ParameterError as error:
            node = items[error.field][0] if error.field in items else entry[0]
            raise self.fail(node, f"controller: {error}") from error
        return settings

    def schedule(self, entry: tuple[yaml.Node, Any] | None, duration: float, params: SliderParams,
                 inputs: Inputs, closed_loop: bool) -> tuple[ScheduledCommand, ...]:
        if entry is None:
            return ()
        node = entry[0]
        if not isinstance(node, yaml.SequenceNode):
            raise self.fail(node, "schedule must be a list of {t: ..., <topic>: value}")
        commands: list[ScheduledCommand] = []
        current = inputs
        for item in node.value:
            command = self.command(item, duration, closed_loop)
            if commands and command.t < commands[-1].t:
                raise self.fail(item, f"t = {command.t!r} s comes before the previous command's {commands[-1].t!r} s")
            current = self.check_effect(item, command, params, current)
            commands.append(command)
        return tuple(commands)

    def command(self, item: yaml.Node, duration: float, closed_loop: bool) -> ScheduledCommand:
        entries = self.mapping(item, ("t", *COMMAND_TOPICS), "a schedule entry")
        if "t" not in entries:
            raise self.fail(item, "a schedule entry needs 't' (simulation time in s)")
        t = self.number(entries["t"], "t")
        if not 0.0 <= t < duration:
            raise self.fail(entries["t"][0], f"t = {t!r} rejected: must be in [0, duration = {duration!r}) s")
        topics = [k for k in entries if k != "t"]
        if len(topics) != 1:
            raise self.fail(item, f"a schedule entry sets exactly one of {', '.join(COMMAND_TOPICS)} "
                                  f"(found {', '.join(topics) or 'none'})")
        topic = topics[0]
        if topic == "target_speed" and not closed_loop:
            raise self.fail(entries[topic][0], "target_speed needs a controller: add a 'controller:' section")
        if topic == "external_wrench":
            wrench = entries[topic]
            force = self.mapping(wrench[0], ("x", "z"), "external_wrench")
            value: Any = (self.number(force["x"], "external_wrench.x") if "x" in force else 0.0,
                          self.number(force["z"], "external_wrench.z") if "z" in force else 0.0)
        else:
            value = self.number(entries[topic], topic)
        return ScheduledCommand(t, topic, value)

    def check_effect(self, item: yaml.Node, command: ScheduledCommand, params: SliderParams,
                     current: Inputs) -> Inputs:
        """Apply an open-loop command to the inputs in force, refusing what the slider would refuse."""
        changes: dict[str, float]
        if command.topic == "target_speed":
            target = float(command.value)  # type: ignore[arg-type]
            if target != 0.0 and (current.drive_force == 0.0 or (target > 0.0) != (current.drive_force > 0.0)):
                raise self.fail(item, f"target_speed = {target!r} at t = {command.t!r} s rejected: must have the "
                                      f"sign of drive_force = {current.drive_force!r} N in force then")
            return current
        if command.topic == "external_wrench":
            x, z = command.value  # type: ignore[misc]
            changes = {"external_force_x": x, "external_force_z": z}
        else:
            changes = {command.topic: float(command.value)}  # type: ignore[arg-type]
        try:
            new = current.replace(**changes)
            check_contact(params, new, changes)
        except ParameterError as error:
            raise self.fail(item, f"{command.topic} at t = {command.t!r} s: {error}") from error
        return new
