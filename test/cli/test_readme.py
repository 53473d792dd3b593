"""Every command in the README works as written.

Blocks fenced as ```sh are run here, line by line, from the repository root
(with the venv's bin/ first on PATH, as after `make`).  `make test` is the
command that runs this very test, so it is the one line not run again.  Blocks
fenced as ```sh ros2 need a ROS 2 install (ros2, colcon); they are checked
instead against the nodes' real interface: every topic, message type, node
and parameter they name must exist, and the values must be accepted; a
`ros2 launch` line must name a launch file of launch/ and only its declared
arguments, with values the settings behind them accept.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from test_foxglove_layout import load_layout, panel_paths, resolve
from test_launch_file import launch_arguments
from test_package_layout import ROSDEP_KEYS

from friction_sim.core.model.commands import COMMANDS, CONTROLS
from friction_sim.core.model.spec import CONTROLLER_NODE, SLIDER_NODE

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()
NOT_RUN_HERE = {"make test", "make demo"}  # this test is part of it; the demo has a test of its own


def blocks(kind: str) -> list[str]:
    pattern = re.compile(r"^```" + re.escape(kind) + r"\n(.*?)^```", re.M | re.S)
    return pattern.findall(README)


def commands(kind: str) -> list[str]:
    found = []
    for block in blocks(kind):
        for line in block.splitlines():
            line = line.strip()
            if line and not line.startswith("#"):
                found.append(line)
    return found


def test_the_readme_has_runnable_and_ros2_blocks() -> None:
    assert "make demo" in commands("sh") and "make test" in commands("sh")
    assert any(c.startswith("ros2 run friction_sim slider") for c in commands("sh ros2"))
    assert any(c.startswith("ros2 run friction_sim controller") for c in commands("sh ros2"))
    assert any(c.startswith("ros2 launch friction_sim feeder.launch.py") for c in commands("sh ros2"))


def on_this_platform(command: str) -> str:
    """``command`` as it runs on the venv running these tests: under `make test-jazzy`
    (.venv-jazzy) the README's ``.venv/bin/`` is that venv's bin (and `make` builds
    and uses it, since PLATFORM=jazzy is in the environment)."""
    venv = Path(sys.prefix)
    if venv.parent == ROOT and venv.name != ".venv":
        return command.replace(".venv/bin/", f"{venv.name}/bin/")
    return command


@pytest.mark.parametrize("command", [c for c in commands("sh") if c not in NOT_RUN_HERE])
def test_readme_command_runs(command: str) -> None:
    command = on_this_platform(command)
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env['PATH']}"
    done = subprocess.run(command, shell=True, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{command}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    assert "Traceback" not in done.stderr


def test_make_demo_runs_and_its_recording_fills_every_panel_of_the_shipped_layout() -> None:
    """Issue 23, defect 2: ``make demo`` as the README gives it, then its
    recording opened as a user opens it with the shipped layout: every topic a
    panel reads is in the file under the name the layout gives, with the
    layout's message type and at least one message (an empty panel otherwise)."""
    from friction_sim.io.reader import read_recording

    assert "make demo" in commands("sh")
    test_readme_command_runs("make demo")
    recording = read_recording(ROOT / "out" / "demo" / "demo.mcap")
    layout = load_layout()
    wanted = {resolve(path)[0] for panel, config in layout["configById"].items() for path in panel_paths(panel, config)}
    assert wanted >= {"/pose", "/events", "/sim_control", "/target_speed", "/diagnostics"}, wanted
    topics = recording.topics
    for topic in sorted(wanted):
        assert topic in topics, f"{topic}: the layout reads it, the demo recording has {sorted(topics)}"
        channel = topics[topic]
        assert recording.counts.get(channel.id, 0) > 0, f"{topic}: no message in the demo recording"
    demo = yaml.safe_load((ROOT / "config" / "demo.yaml").read_text())
    decoded = [(raw.topic, recording.decode(raw)) for raw in recording.messages
               if raw.topic in ("/sim_control", "/rejected_commands")]
    calls = [name for action in demo["operator"] for name in action.get("calls", [])]
    assert [msg.name for topic, msg in decoded if topic == "/sim_control"] == calls
    refused = [{kv.key: kv.value for kv in msg.values} for topic, msg in decoded if topic == "/rejected_commands"]
    assert refused == [{"excitation_amplitude": "-1.0"}], refused
    targets = [entry["target_speed"] for entry in demo["schedule"] if "target_speed" in entry]
    seen = [recording.decode(raw).data for raw in recording.messages if raw.topic == "/target_speed"]
    assert seen == targets, "each target the demo sends is recorded once, as the slider saw it"


TOPIC_TYPES = {
    "/target_speed": "std_msgs/msg/Float64", "/drive_force": "std_msgs/msg/Float64",
    "/excitation_amplitude": "std_msgs/msg/Float64", "/excitation_frequency": "std_msgs/msg/Float64",
    "/external_wrench": "geometry_msgs/msg/WrenchStamped", "/mean_velocity": "geometry_msgs/msg/TwistStamped",
    "/pose": "geometry_msgs/msg/PoseStamped", "/velocity": "geometry_msgs/msg/TwistStamped",
    "/friction_force": "geometry_msgs/msg/WrenchStamped", "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
}
NODES = {"/slider": SLIDER_NODE, "/controller": CONTROLLER_NODE}


def _message(type_name: str) -> type:
    """The message class (imported here: the module itself needs no ROS)."""
    from friction_sim.io.messages import message_class

    return message_class(type_name)


def _fill(msg: object, values: dict) -> None:
    for key, value in values.items():
        assert hasattr(msg, key), f"{type(msg).__name__} has no field {key}"
        if isinstance(value, dict):
            _fill(getattr(msg, key), value)
        else:
            setattr(msg, key, type(getattr(msg, key))(value))


@pytest.mark.parametrize("command", commands("sh ros2"))
def test_ros2_command_matches_the_real_interface(command: str) -> None:
    words = shlex.split(command)
    if words[:2] == ["ros2", "run"]:
        assert words[2] == "friction_sim" and words[3] in ("slider", "controller")
        params = NODES[f"/{words[3]}"]
        for i, word in enumerate(words):
            if word == "-p":
                name, value = words[i + 1].split(":=")
                assert name in params
                assert isinstance(yaml.safe_load(value), params[name].kind)
            if word == "--params-file":
                assert words[i + 1].endswith("config/slider.yaml") and (ROOT / "config/slider.yaml").is_file()
    elif words[:3] == ["ros2", "topic", "pub"]:
        options = {w: words[i + 1] for i, w in enumerate(words) if w in ("-w", "--wait-matching-subscriptions")}
        positional = [w for i, w in enumerate(words[3:], 3) if not w.startswith("-") and words[i - 1] != "-w"]
        topic, type_name, payload = positional[:3]
        assert TOPIC_TYPES[topic] == type_name
        _fill(_message(type_name)(), yaml.safe_load(payload))
        if "--once" in words:  # --once publishes as soon as ONE subscriber matches: wait for every consumer
            consumers = COMMANDS[topic.lstrip("/")].consumers
            assert options and int(next(iter(options.values()))) == len(consumers), \
                f"{topic} is taken by {consumers}: publish once with -w {len(consumers)}"
    elif words[:3] == ["ros2", "topic", "echo"]:
        assert words[3] in TOPIC_TYPES
    elif words[:3] == ["ros2", "param", "set"]:
        node, name, value = words[3:6]
        assert isinstance(yaml.safe_load(value), NODES[node][name].kind)
    elif words[:2] == ["ros2", "launch"]:
        _check_launch(words[2], words[3], words[4:])
    elif words[:3] == ["ros2", "service", "call"]:
        service, type_name = words[3:5]  # the slider's control services: /slider/<pause|resume|step|reset>
        node, name = service.rsplit("/", 1)
        assert node == "/slider" and name in CONTROLS and type_name == "std_srvs/srv/Trigger", command
    elif words[0] == "pip":
        _check_ros_pip_line(words)
    elif words[0] == "rosdep":
        assert words[:2] == ["rosdep", "install"] and words[words.index("--from-paths") + 1] == "src"
        assert {"--ignore-src", "-y"} <= set(words)
    else:
        assert words[0] in ("colcon", "source"), f"unchecked command: {command}"


def _pins(path: Path) -> dict[str, str]:
    """name -> pinned version of a constraints file (names normalised as pip does)."""
    pins = {}
    for line in path.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if "==" in line:
            name, version = line.split("==", 1)
            pins[canonicalize_name(name)] = version.strip()
    return pins


def _check_ros_pip_line(words: list[str]) -> None:
    """The ROS 2 route's pip line installs exactly the requirements rosdep has no key
    for (test_package_layout.ROSDEP_KEYS), each in a range that holds the version the
    Jazzy platform tests (constraints-jazzy.txt over constraints.txt) and is at least
    as strict as requirements.txt's."""
    assert words[:2] == ["pip", "install"] and {"--user", "--break-system-packages"} <= set(words)
    wanted = {Requirement(w) for w in words[2:] if not w.startswith("-")}
    declared = {canonicalize_name(r.name): r for r in _requirements()}
    pip_only = {name for name, keys in ROSDEP_KEYS.items() if not keys}
    assert {canonicalize_name(r.name) for r in wanted} == pip_only
    jazzy = _pins(ROOT / "constraints.txt") | _pins(ROOT / "constraints-jazzy.txt")
    for requirement in wanted:
        name = canonicalize_name(requirement.name)
        assert requirement.specifier.contains(jazzy[name]), f"{requirement} excludes the tested {name} {jazzy[name]}"
        assert set(declared[name].specifier) <= set(requirement.specifier), \
            f"{requirement} is looser than requirements.txt's {declared[name]}"


def _requirements() -> list[Requirement]:
    lines = (line.split("#", 1)[0].strip() for line in (ROOT / "requirements.txt").read_text().splitlines())
    return [Requirement(line) for line in lines if line]


def _check_launch(package: str, launch_file: str, arguments: list[str]) -> None:
    """``ros2 launch PACKAGE FILE name:=value ...``: a launch file of launch/ (setup.py
    installs them in share/friction_sim/launch) and only arguments it declares,
    each value one the setting behind it accepts."""
    path = ROOT / "launch" / launch_file
    assert package == "friction_sim" and path.is_file(), f"no launch file launch/{launch_file}"
    declared = launch_arguments(path)
    for argument in arguments:
        name, separator, value = argument.partition(":=")
        assert separator and name in declared, f"{argument}: {launch_file} declares {sorted(declared)}"
        if name in SLIDER_NODE:  # log_path, foxglove_port: set on the slider as they are
            SLIDER_NODE[name].check(value if SLIDER_NODE[name].kind is str else yaml.safe_load(value))
        elif name == "use_sim_time":
            assert value in ("true", "false"), argument
        elif name == "namespace":
            assert re.fullmatch(r"/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*", value), argument
        else:  # the parameter files
            assert (ROOT / value).is_file(), f"{argument}: no such file"
