"""The shipped Foxglove layout (config/friction_sim.foxglove_layout.json) opens and shows real data.

Foxglove cannot run here, so this checks what would make the layout break or
show empty panels: the file is a layout as Foxglove exports it (configById,
a react-mosaic layout tree, globalVariables, userNodes, playbackConfig), the
tree and configById name the same panels, and every message path names a
topic the slider, the controller or a recording has and fields that exist in
that topic's ROS 2 message type (walked through the generated message
classes, with Foxglove's message-path syntax: ``/topic.field.field``,
``[:]`` slices and ``{field=="value"}`` filters).  The Pause, Resume, Step
and Reset buttons are Service Call panels: each control of the slider once,
by its service name, with a request std_srvs/srv/Trigger accepts, and config
keys and values that the Foxglove SDK's own ``ServiceCallConfig``
(foxglove.layouts) takes.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import json
import re
import typing
from collections import Counter
from pathlib import Path
from typing import Any

import foxglove.layouts as fl
import pytest
from std_srvs.srv import Trigger

from friction_sim.core.model.commands import CONTROLS
from friction_sim.core.model.events import EventKind
from friction_sim.io.messages import SIM_CONTROL, TOPIC_TYPES
from friction_sim.ros.slider import SliderNode

ROOT = Path(__file__).resolve().parents[1]
LAYOUT_FILE = ROOT / "config" / "friction_sim.foxglove_layout.json"

#: Every topic of a recording (the simulation control calls ~/pause, ~/resume,
#: ~/step and ~/reset included, on sim_control), and the status both nodes
#: publish on diagnostics (a slider's recording keeps it as the slider sees it).
TOPICS: dict[str, str] = {"diagnostics": "diagnostic_msgs/msg/DiagnosticArray", **TOPIC_TYPES}
#: The Service Call panel's type id, as the Foxglove SDK writes it into a layout.
SERVICE_CALL: str = json.loads(fl.ServiceCallPanel().to_json())["panelType"]
#: The panel types the layout uses.
PANEL_TYPES = {"Plot", "StateTransitions", "RawMessages", SERVICE_CALL}
NUMERIC = {"double", "float", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64", "octet"}


def load_layout() -> dict[str, Any]:
    return json.loads(LAYOUT_FILE.read_text())  # type: ignore[no-any-return]


def tree_panels(node: Any) -> list[str]:
    """The panel ids at the leaves of a react-mosaic layout tree (checking each split)."""
    if isinstance(node, str):
        return [node]
    assert isinstance(node, dict) and set(node) <= {"first", "second", "direction", "splitPercentage"}, node
    assert {"first", "second", "direction"} <= set(node), f"a split needs first, second and direction: {node}"
    assert node["direction"] in ("row", "column"), node["direction"]
    assert 0 < node.get("splitPercentage", 50) < 100, node
    return tree_panels(node["first"]) + tree_panels(node["second"])


def panel_paths(panel_id: str, config: dict[str, Any]) -> list[str]:
    """The message paths a panel reads."""
    kind = panel_id.split("!", 1)[0]
    if kind in ("Plot", "StateTransitions"):
        return [series["value"] for series in config["paths"]]
    if kind == SERVICE_CALL:  # calls a service, reads no topic
        return []
    assert kind == "RawMessages", panel_id
    return [config["topicPath"]]


# -- Foxglove message paths over ROS 2 message types ------------------------------

_TOPIC = re.compile(r'/[A-Za-z0-9_/]*[A-Za-z0-9_]')
_FIELD = re.compile(r'\.([A-Za-z_][A-Za-z0-9_]*)')
_SLICE = re.compile(r'\[(?:-?\d+|-?\d*:-?\d*)\]')
_FILTER = re.compile(r'\{([A-Za-z_][A-Za-z0-9_]*)==("(?:[^"\\]|\\.)*"|\'[^\']*\'|-?\d+(?:\.\d+)?|true|false)\}')
_SEQUENCE = re.compile(r'^sequence<([^,>]+)(?:,\s*\d+)?>$|^(.+)\[\d+\]$')


def message_fields(type_name: str) -> dict[str, str]:
    """field -> type of a ROS 2 message type ``pkg/Name`` or ``pkg/msg/Name``."""
    package, name = type_name.split("/")[0], type_name.split("/")[-1]
    cls = getattr(importlib.import_module(f"{package}.msg"), name)
    return cls.get_fields_and_field_types()  # type: ignore[no-any-return]


def element_type(type_name: str) -> str | None:
    """The element type of a sequence or array type, None for anything else."""
    match = _SEQUENCE.match(type_name)
    return None if match is None else (match.group(1) or match.group(2)).strip()


def resolve(path: str) -> tuple[str, str, list[tuple[str, str]]]:
    """(topic, type of the value the path reaches, [(filter field, literal)])
    for a Foxglove message path; an AssertionError names the first part that
    does not exist."""
    topic_match = _TOPIC.match(path)
    assert topic_match, f"{path}: no topic name"
    topic = topic_match.group(0)
    assert topic.lstrip("/") in TOPICS, f"{path}: {topic} is no topic of the slider, controller or a recording"
    current, rest, filters = TOPICS[topic.lstrip("/")], path[topic_match.end():], []
    while rest:
        if (match := _FIELD.match(rest)) is not None:
            assert element_type(current) is None and "/" in current, f"{path}: {current} has no fields"
            fields = message_fields(current)
            assert match.group(1) in fields, f"{path}: {current} has no field {match.group(1)!r} ({sorted(fields)})"
            current = fields[match.group(1)]
        elif (match := _SLICE.match(rest)) is not None:
            element = element_type(current)
            assert element is not None, f"{path}: {current} is not an array, cannot slice it"
            current = element
        elif (match := _FILTER.match(rest)) is not None:
            assert element_type(current) is None and "/" in current, f"{path}: {current} is no message to filter"
            fields = message_fields(current)
            field, literal = match.groups()
            assert field in fields, f"{path}: filter on {field!r}, which {current} lacks"
            quoted = literal[0] in "\"'"
            assert quoted == (fields[field] == "string"), f"{path}: {field} is {fields[field]}, compared with {literal}"
            filters.append((field, literal.strip("\"'")))
        else:
            raise AssertionError(f"{path}: cannot read {rest!r} as a Foxglove message path")
        rest = rest[match.end():]
    return topic, current, filters


# -- the file ------------------------------------------------------------------


def test_the_layout_is_foxglove_export_json() -> None:
    layout = load_layout()
    assert set(layout) == {"configById", "globalVariables", "userNodes", "playbackConfig", "layout"}
    assert layout["globalVariables"] == {} and layout["userNodes"] == {}
    assert layout["playbackConfig"]["speed"] == 1
    for panel_id, config in layout["configById"].items():
        kind, _, suffix = panel_id.partition("!")
        assert kind in PANEL_TYPES and re.fullmatch(r"[a-z0-9]+", suffix), f"panel id {panel_id!r}"
        assert isinstance(config, dict) and config.get("foxglovePanelTitle"), f"{panel_id} has no title"


def test_the_tree_and_configs_name_the_same_panels() -> None:
    layout = load_layout()
    leaves = tree_panels(layout["layout"])
    assert len(leaves) == len(set(leaves)), f"a panel appears twice in the tree: {leaves}"
    assert set(leaves) == set(layout["configById"]), (
        f"in the tree only: {set(leaves) - set(layout['configById'])}; "
        f"configured only: {set(layout['configById']) - set(leaves)}")


def test_time_series_share_one_time_axis() -> None:
    """Plots and state transitions sync their time axes and all read the
    receive (log) time: the Float64 command topics have no header, and in a
    recording the log time is simulation time, as the header stamps are."""
    for panel_id, config in load_layout()["configById"].items():
        if panel_id.startswith(("Plot!", "StateTransitions!")):
            assert config["isSynced"] is True, panel_id
            for series in config["paths"]:
                assert series["timestampMethod"] == "receiveTime" and series["enabled"] is True, series


def _all_paths() -> list[tuple[str, str]]:
    return [(panel_id, path) for panel_id, config in load_layout()["configById"].items()
            for path in panel_paths(panel_id, config)]


@pytest.mark.parametrize(("panel_id", "path"), _all_paths())
def test_every_message_path_exists_in_its_ros_type(panel_id: str, path: str) -> None:
    _, value_type, filters = resolve(path)
    if panel_id.startswith("Plot!"):
        assert value_type in NUMERIC, f"{panel_id}: {path} is {value_type}, not a number to plot"
    elif panel_id.startswith("StateTransitions!"):
        assert value_type == "string" or value_type in NUMERIC, f"{panel_id}: {path} is {value_type}"
    for field, literal in filters:  # the diagnostics panels pick a node's status by the name it publishes
        assert field == "name" and literal in ("slider", "controller"), (panel_id, path)
        # The node's module and its parts (ros/controller.py, ros/controller_outputs.py, ...).
        sources = [module.read_text() for module in sorted((ROOT / "friction_sim" / "ros").glob(f"{literal}*.py"))]
        assert any(f'DiagnosticStatus(name="{literal}"' in source for source in sources), \
            f"{literal} publishes no status named {literal!r}"


def test_the_panels_show_what_the_issue_asks_for() -> None:
    """Position and height, velocity, friction force and R, mean speed against
    target, Pa, the event timeline, simulation control, diagnostics and
    refused commands."""
    paths = {path for _, path in _all_paths()}
    for wanted in ("/pose.pose.position.x", "/pose.pose.position.z", "/velocity.twist.linear.x",
                   "/friction_force.wrench.force.x", "/friction_force.wrench.force.z",
                   "/mean_velocity.twist.linear.x", "/target_speed.data", "/excitation_amplitude.data",
                   "/events.name", "/sim_control.name", "/rejected_commands"):
        assert wanted in paths, f"the layout does not show {wanted}"
    assert {resolve(path)[0] for path in paths} >= {"/diagnostics"}
    config = load_layout()["configById"]
    mean_speed = next(c for c in config.values() if "/mean_velocity.twist.linear.x" in str(c.get("paths")))
    assert "/target_speed.data" in {series["value"] for series in mean_speed["paths"]}, "target beside mean speed"


def test_state_colours_cover_every_event_kind_and_control_call() -> None:
    """The timeline's named states are exactly the event kinds the core emits
    and the calls ~/pause, ~/resume, ~/step and ~/reset record."""
    series = {s["value"]: s for c in load_layout()["configById"].values()
              if "customStates" in str(c) for s in c["paths"]}
    events = {state["value"] for state in series["/events.name"]["customStates"]["states"]}
    assert events == {kind.value for kind in EventKind}
    calls = {state["value"] for state in series[f"/{SIM_CONTROL}.name"]["customStates"]["states"]}
    assert calls == set(CONTROLS)


@pytest.mark.parametrize("path", [
    "/pose.pose.position.w", "/nowhere.data", "/velocity.twist.linear[:]", "/diagnostics.status{name==\"slider\"}",
    "/diagnostics.status[:]{level==\"slider\"}", "/events.name.@upper",
])
def test_the_path_checker_refuses_what_foxglove_would_show_empty(path: str) -> None:
    with pytest.raises(AssertionError):
        resolve(path)


# -- the simulation control buttons ------------------------------------------------


def service_call_panels() -> dict[str, dict[str, Any]]:
    return {panel_id: config for panel_id, config in load_layout()["configById"].items()
            if panel_id.startswith(f"{SERVICE_CALL}!")}


def _snake(key: str) -> str:
    return re.sub(r"(?<!^)(?=[A-Z])", "_", key).lower()


def _accepts(hint: Any, value: Any) -> bool:
    """Whether ``value`` is of the (str, bool, float, Literal, optional) type ``hint``."""
    if typing.get_origin(hint) is typing.Literal:
        return value in typing.get_args(hint)
    if typing.get_origin(hint) in (typing.Union, type(str | None)):
        return any(_accepts(arm, value) for arm in typing.get_args(hint))
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    return hint is not type(None) and isinstance(value, hint)


def test_a_button_for_each_control_service_of_the_slider() -> None:
    """One Service Call panel per ~/pause, ~/resume, ~/step and ~/reset, each
    once, named as the slider node (in the root namespace) serves them, with a
    request std_srvs/srv/Trigger accepts (it has no fields: ``{}``)."""
    node = inspect.signature(SliderNode.__init__).parameters["node_name"].default
    panels = service_call_panels()
    called = Counter(config["serviceName"] for config in panels.values())
    assert called == Counter(f"/{node}/{name}" for name in CONTROLS), called
    assert Trigger.Request.get_fields_and_field_types() == {}
    for panel_id, config in panels.items():
        name = config["serviceName"].rsplit("/", 1)[1]
        assert panel_id == f"{SERVICE_CALL}!{name}" and config["buttonText"] == name.capitalize(), panel_id
        assert json.loads(config["requestPayload"]) == {}, f"{panel_id}: Trigger takes an empty request"
        assert config["editingMode"] is False, f"{panel_id}: a button only (refusals show in Rejected commands)"


def test_button_configs_are_what_the_sdk_service_call_panel_takes() -> None:
    """Every key (but the title every exported panel has) is a field of
    foxglove.layouts.ServiceCallConfig with a value of its type, and the SDK
    writes the same config back."""
    fields = typing.get_type_hints(fl.ServiceCallConfig)
    assert {field.name for field in dataclasses.fields(fl.ServiceCallConfig)} == set(fields)
    for panel_id, config in service_call_panels().items():
        settings = {_snake(key): value for key, value in config.items() if key != "foxglovePanelTitle"}
        unknown = set(settings) - set(fields)
        assert not unknown, f"{panel_id}: {sorted(unknown)} are no fields of ServiceCallConfig ({sorted(fields)})"
        for key, value in settings.items():
            assert _accepts(fields[key], value), f"{panel_id}: {key}={value!r} is not {fields[key]}"
        written = json.loads(fl.ServiceCallConfig(**settings).to_json())
        assert written == {key: value for key, value in config.items() if key != "foxglovePanelTitle"}


def test_button_colours_are_the_timeline_colours_of_their_calls() -> None:
    timeline = next(s for c in load_layout()["configById"].values() if "customStates" in str(c)
                    for s in c["paths"] if s["value"] == f"/{SIM_CONTROL}.name")
    colours = {state["value"]: state["color"] for state in timeline["customStates"]["states"]}
    for config in service_call_panels().values():
        name = config["serviceName"].rsplit("/", 1)[1]
        assert config["buttonColor"] == colours[name], name


@pytest.mark.parametrize(("hint", "value"), [
    (bool | None, 1), (float | None, True), (str | None, None), (typing.Literal["vertical"], "diagonal"),
])
def test_the_config_type_checker_refuses_wrong_values(hint: Any, value: Any) -> None:
    assert not _accepts(hint, value)
