"""launch/feeder.launch.py names only what exists, and its defaults are valid.

PyPI has no ``launch`` or ``launch_ros``, so ``ros2 launch`` cannot run here.
What can be checked is checked: the file parses and compiles; its
``generate_launch_description()`` runs against small stand-ins for the launch
API that take the real constructors' keywords (from ros2/launch and
ros2/launch_ros, branch jazzy) and evaluate substitutions the way launch does
(LaunchConfiguration, PathJoinSubstitution, FindPackageShare, ParameterValue
with its value_type coercion).  Then every executable is a console script of
this package, every argument is declared and used, and each node's parameters
(its parameter file, then the launch file's overrides, the last one winning as
in ROS 2) are parameters of that node in ``friction_sim.core.model.spec``, each
accepted by its ``Setting.check``, for the default arguments and for the
README's example.
"""

from __future__ import annotations

import ast
import configparser
import importlib.util
import os
import sys
import types
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from friction_sim.core.model.spec import CONTROLLER_NODE, SLIDER_NODE, Setting
from friction_sim.errors import ParameterError

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_FILE = ROOT / "launch" / "feeder.launch.py"
PACKAGE = "friction_sim"
ARGUMENTS = {"namespace", "slider_params", "controller_params", "log_path", "foxglove_port", "use_sim_time"}
#: ROS's own parameter, declared by every rclpy node.
USE_SIM_TIME = Setting("use_sim_time", False, "-", "follow /clock")
NODE_PARAMETERS = {"slider": SLIDER_NODE, "controller": {**CONTROLLER_NODE, "use_sim_time": USE_SIM_TIME}}
#: README's example line.
README_ARGUMENTS = {"namespace": "/feeder1", "log_path": "run.mcap", "foxglove_port": "8765", "use_sim_time": "true"}


def launch_arguments(path: Path = LAUNCH_FILE) -> set[str]:
    """The names a launch file declares with DeclareLaunchArgument('name', ...),
    read from its syntax tree (no launch package needed)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", "")) == \
                "DeclareLaunchArgument":
            assert node.args and isinstance(node.args[0], ast.Constant), f"line {node.lineno}: name not a literal"
            names.add(node.args[0].value)
    return names


# -- stand-ins for launch and launch_ros ----------------------------------------------


class Context:
    """The launch configurations (argument values) and where the package's share is."""

    def __init__(self, configurations: dict[str, str], share: Path) -> None:
        self.configurations, self.share = configurations, share
        self.read: set[str] = set()


def perform(value: Any, context: Context) -> str:
    """A substitution (or a list of them, or text) as the text launch makes of it."""
    if isinstance(value, str):
        return value
    if isinstance(value, list | tuple):
        return "".join(perform(part, context) for part in value)
    return value.perform(context)  # type: ignore[no-any-return]


class LaunchConfiguration:
    def __init__(self, variable_name: str, *, default: Any = None) -> None:
        assert default is None, "defaults belong to DeclareLaunchArgument"
        self.variable_name = variable_name

    def perform(self, context: Context) -> str:
        context.read.add(self.variable_name)
        return context.configurations[self.variable_name]


class PathJoinSubstitution:
    def __init__(self, substitutions: list[Any]) -> None:
        self.substitutions = substitutions

    def perform(self, context: Context) -> str:
        return os.path.join(*(perform(part, context) for part in self.substitutions))


class FindPackageShare:
    def __init__(self, package: str) -> None:
        self.package = package

    def perform(self, context: Context) -> str:
        assert self.package == PACKAGE, f"FindPackageShare({self.package!r})"
        return str(context.share)


class ParameterValue:
    def __init__(self, value: Any, *, value_type: type | None = None) -> None:
        self.value, self.value_type = value, value_type

    def evaluate(self, context: Context) -> Any:
        """launch.utilities.type_utils.coerce_to_type for the scalar types."""
        text = perform(self.value, context)
        if self.value_type is str:
            return text
        if self.value_type in (int, float):
            return self.value_type(text)
        assert self.value_type is bool, f"value_type {self.value_type}: give one (int, float, bool, str)"
        value = yaml.safe_load({"1": "true", "0": "false"}.get(text, text))
        assert isinstance(value, bool), f"cannot convert {text!r} to bool"
        return value


class DeclareLaunchArgument:
    def __init__(self, name: str, *, default_value: Any = None, description: str | None = None,
                 choices: list[str] | None = None) -> None:
        assert default_value is not None, f"{name}: give a default (ros2 launch would require the argument)"
        if choices is not None and isinstance(default_value, str):
            assert default_value in choices, f"{name}: default {default_value!r} not in {choices}"
        self.name, self.default_value, self.description, self.choices = name, default_value, description, choices


class Node:
    def __init__(self, *, executable: str, package: str | None = None, name: str | None = None,
                 namespace: Any = None, exec_name: str | None = None, parameters: list[Any] | None = None,
                 remappings: Any = None, ros_arguments: Any = None, arguments: Any = None,
                 output: str = "log") -> None:
        self.executable, self.package, self.name, self.namespace = executable, package, name, namespace
        self.parameters, self.remappings, self.ros_arguments, self.arguments = \
            parameters or [], remappings, ros_arguments, arguments

    def parameter_values(self, context: Context) -> dict[str, Any]:
        """The parameters the node starts with: each file's ``/**`` (or this
        node's) section, then each dictionary, later ones winning."""
        values: dict[str, Any] = {}
        for entry in self.parameters:
            if isinstance(entry, dict):
                values.update({key: value.evaluate(context) if isinstance(value, ParameterValue) else value
                               for key, value in entry.items()})
                continue
            path = Path(perform(entry, context))
            assert path.is_file(), f"{self.name}: parameter file {path} does not exist"
            for key, section in yaml.safe_load(path.read_text()).items():
                if key in ("/**", self.name, f"/{self.name}"):
                    values.update(section["ros__parameters"])
        return values


class LaunchDescription:
    def __init__(self, initial_entities: list[Any] | None = None) -> None:
        self.entities = list(initial_entities or [])


STUBS = {
    "launch": {"LaunchDescription": LaunchDescription},
    "launch.actions": {"DeclareLaunchArgument": DeclareLaunchArgument},
    "launch.substitutions": {"LaunchConfiguration": LaunchConfiguration,
                             "PathJoinSubstitution": PathJoinSubstitution},
    "launch_ros": {},
    "launch_ros.actions": {"Node": Node},
    "launch_ros.parameter_descriptions": {"ParameterValue": ParameterValue},
    "launch_ros.substitutions": {"FindPackageShare": FindPackageShare},
}


@pytest.fixture(scope="module")
def description() -> Iterator[LaunchDescription]:
    """What generate_launch_description() returns, built from the stand-ins."""
    saved = {name: sys.modules.get(name) for name in STUBS}
    try:
        for name, members in STUBS.items():
            module = types.ModuleType(name)
            module.__dict__.update(members)
            sys.modules[name] = module
        spec = importlib.util.spec_from_file_location("feeder_launch", LAUNCH_FILE)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        result = module.generate_launch_description()
    finally:
        for name, previous in saved.items():
            if previous is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = previous
    assert isinstance(result, LaunchDescription)
    yield result


def declared(description: LaunchDescription) -> dict[str, DeclareLaunchArgument]:
    return {entity.name: entity for entity in description.entities if isinstance(entity, DeclareLaunchArgument)}


def nodes(description: LaunchDescription) -> dict[str, Node]:
    found = [entity for entity in description.entities if isinstance(entity, Node)]
    assert len({node.name for node in found}) == len(found)
    return {str(node.name): node for node in found}


def context_for(description: LaunchDescription, **given: str) -> Context:
    """The configurations ``ros2 launch ... name:=value`` makes: the values given,
    the declared defaults for the rest (evaluated, as launch does)."""
    unknown = set(given) - set(declared(description))
    assert not unknown, f"not launch arguments: {unknown}"
    context = Context({}, share=ROOT)  # the share dir holds config/ as the repository does (see setup.py)
    for name, argument in declared(description).items():
        context.configurations[name] = given[name] if name in given else perform(argument.default_value, context)
    context.read.clear()
    return context


def checked_parameters(description: LaunchDescription, context: Context) -> dict[str, dict[str, Any]]:
    """node -> its start-up parameters, each checked by its Setting (type and range)."""
    result = {}
    for name, node in nodes(description).items():
        settings = NODE_PARAMETERS[name]
        values = node.parameter_values(context)
        for key, value in values.items():
            assert key in settings, f"{name} has no parameter {key!r}"
            assert type(settings[key].check(value)) is type(value) is settings[key].kind, (name, key, value)
        result[name] = values
    return result


# -- the tests ------------------------------------------------------------------------


def test_the_file_parses_and_compiles() -> None:
    source = LAUNCH_FILE.read_text()
    compile(ast.parse(source, str(LAUNCH_FILE)), str(LAUNCH_FILE), "exec")
    assert "def generate_launch_description" in source


def test_the_arguments_are_exactly_the_documented_ones(description: LaunchDescription) -> None:
    assert set(declared(description)) == ARGUMENTS
    assert launch_arguments() == ARGUMENTS  # what the README test reads from the syntax tree
    for argument in declared(description).values():
        assert argument.description, f"{argument.name} has no description (ros2 launch --show-args shows it)"


def test_every_argument_is_read_and_only_declared_ones_are(description: LaunchDescription) -> None:
    context = context_for(description)
    for node in nodes(description).values():
        perform(node.namespace, context)
        node.parameter_values(context)
    assert context.read == ARGUMENTS


def test_every_executable_is_a_console_script_of_this_package(description: LaunchDescription) -> None:
    setup = ast.parse((ROOT / "setup.py").read_text())
    scripts = {text.split("=")[0].strip() for node in ast.walk(setup)
               if isinstance(node, ast.Constant) and isinstance(text := node.value, str)
               and "=" in text and ":main" in text}
    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg")
    assert cfg["install"]["install_scripts"] == f"$base/lib/{PACKAGE}", "ros2 run/launch look in lib/<package>"
    started = nodes(description)
    assert {node.executable for node in started.values()} == {"slider", "controller"}
    for node in started.values():
        assert node.package == PACKAGE and node.executable in scripts, (node.package, node.executable, scripts)


def test_default_arguments_give_valid_parameters(description: LaunchDescription) -> None:
    values = checked_parameters(description, context_for(description))
    slider, controller = values["slider"], values["controller"]
    assert slider["log_path"] == "" and slider["foxglove_port"] == 0 and slider["publish_clock"] is False
    assert controller["use_sim_time"] is False
    assert slider["mass"] == SLIDER_NODE["mass"].default  # the installed config/slider.yaml was read


def test_readme_arguments_reach_the_nodes(description: LaunchDescription) -> None:
    context = context_for(description, **README_ARGUMENTS)
    values = checked_parameters(description, context)
    slider, controller = values["slider"], values["controller"]
    assert slider["log_path"] == "run.mcap" and slider["foxglove_port"] == 8765
    # The slider makes the clock: publish_clock follows use_sim_time, and it never takes use_sim_time itself.
    assert slider["publish_clock"] is True and "use_sim_time" not in slider
    assert controller["use_sim_time"] is True
    assert {perform(node.namespace, context) for node in nodes(description).values()} == {"/feeder1"}


def test_a_log_path_that_reads_as_a_number_stays_text(description: LaunchDescription) -> None:
    values = checked_parameters(description, context_for(description, log_path="2024"))
    assert values["slider"]["log_path"] == "2024"


def test_out_of_range_port_is_refused_by_the_slider_setting(description: LaunchDescription) -> None:
    with pytest.raises(ParameterError, match="foxglove_port"):
        checked_parameters(description, context_for(description, foxglove_port="70000"))


def test_the_controller_reads_its_model_from_this_slider(description: LaunchDescription) -> None:
    """plant_node is a relative name: the slider started here, in the same namespace."""
    started = nodes(description)
    plant = checked_parameters(description, context_for(description))["controller"].get(
        "plant_node", CONTROLLER_NODE["plant_node"].default)
    assert plant == started["slider"].name
    context = context_for(description, namespace="ns")
    assert perform(started["slider"].namespace, context) == perform(started["controller"].namespace, context) == "ns"
