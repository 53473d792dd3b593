"""Every command in the README and in the documentation's pages works as written.

Blocks fenced as ```sh, in README.md and in every page of doc/ (in the order of DOCS: a
page's commands may use what an earlier command of the same page wrote), are run here,
line by line, from the repository root (with the venv's bin/ first on PATH, as after
`make`).  `make test` is the command that runs this very test, so it is the one line not
run again.  Blocks fenced as ```sh ros2 need a ROS 2 install (ros2, colcon); they are
checked instead against the nodes' real interface: every topic, message type, node and
parameter they name must exist, and the values must be accepted; a `ros2 launch` line
must name a launch file of launch/ and only its declared arguments, with values the
settings behind them accept.  A `ros2 topic pub` line is also run (test/ros2_topic_pub.py
does what ros2cli does) against the setup of the page it is on (its slider recording):
each message must reach every subscription of the topic, so `-w` must count them all.
"""

from __future__ import annotations

import os
import re
import shlex
import signal
import subprocess
import sys
import time
import uuid
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
import yaml
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from ros2_topic_pub import fill, parse, publish
from test_foxglove_layout import load_layout, panel_paths, resolve
from test_launch_file import launch_arguments
from test_package_layout import ROSDEP_KEYS

from friction_sim.core.model.commands import COMMANDS, CONTROLS
from friction_sim.core.model.spec import CONTROLLER_NODE, SLIDER_NODE

ROOT = Path(__file__).resolve().parents[2]
#: The documents whose commands run: the README, then the site's pages in its reading order
#: (doc/index.md's contents), then any other page of doc/.
PAGE_ORDER = ("getting_started", "model", "tutorials/ros", "tutorials/experiments", "tutorials/record_replay",
              "tutorials/calibrate", "tutorials/resonance", "tutorials/sweeps", "tutorials/foxglove",
              "tutorials/offline")
DOCS = [ROOT / "README.md", *(ROOT / "doc" / f"{page}.md" for page in PAGE_ORDER),
        *sorted(set((ROOT / "doc").rglob("*.md")) - {ROOT / "doc" / f"{page}.md" for page in PAGE_ORDER})]
README = (ROOT / "README.md").read_text()
#: The page whose ROS 2 setup (`ros2 run` lines) its `ros2 topic pub` lines are proven with.
ROS_TUTORIAL = ROOT / "doc" / "tutorials" / "ros.md"
NOT_RUN_HERE = {"make test", "make demo"}  # this test is part of it; the demo has a test of its own


def blocks(kind: str, text: str = README) -> list[str]:
    pattern = re.compile(r"^```" + re.escape(kind) + r"\n(.*?)^```", re.M | re.S)
    return pattern.findall(text)


def commands(kind: str, text: str = README) -> list[str]:
    """The command lines of ``text``'s blocks fenced as ```KIND (comments and blank lines left out)."""
    found = []
    for block in blocks(kind, text):
        for line in block.splitlines():
            line = line.strip()
            if line and not line.startswith("#"):
                found.append(line)
    return found


def doc_commands(kind: str) -> list[tuple[str, str]]:
    """(document, command) of every ```KIND line of DOCS, in their order."""
    return [(str(doc.relative_to(ROOT)), command) for doc in DOCS for command in commands(kind, doc.read_text())]


def _id(value: object) -> str:
    return str(value) if not isinstance(value, tuple) else f"{value[0]}: {value[1]}"


def test_the_readme_has_runnable_and_ros2_blocks() -> None:
    assert "make demo" in commands("sh") and "make test" in commands("sh")
    assert any(c.startswith("ros2 run friction_sim slider") for c in commands("sh ros2"))
    assert any(c.startswith("ros2 run friction_sim controller") for c in commands("sh ros2"))
    assert any(c.startswith("ros2 launch friction_sim feeder.launch.py") for _, c in doc_commands("sh ros2"))


def test_every_tutorial_page_has_commands_the_suite_runs() -> None:
    """A tutorial is a page whose commands CI runs: each has ```sh or ```sh ros2 lines."""
    for page in sorted((ROOT / "doc" / "tutorials").glob("*.md")):
        if page.name != "index.md":
            text = page.read_text()
            assert commands("sh", text) or commands("sh ros2", text), f"{page.name}: no command to run"


def on_this_platform(command: str) -> str:
    """``command`` as it runs on the venv running these tests: under `make test-jazzy`
    (.venv-jazzy) the docs' ``.venv/bin/`` is that venv's bin (and `make` builds
    and uses it, since PLATFORM=jazzy is in the environment); from a checkout whose
    tests run on another checkout's venv, that venv's bin."""
    venv = Path(sys.prefix)
    if venv != ROOT / ".venv":
        return command.replace(".venv/bin/", f"{venv.name}/bin/" if venv.parent == ROOT else f"{venv}/bin/")
    return command


@pytest.mark.parametrize(("doc", "command"), [(d, c) for d, c in doc_commands("sh") if c not in NOT_RUN_HERE],
                         ids=_id)
def test_doc_command_runs(doc: str, command: str) -> None:
    run_doc_command(command)


def run_doc_command(command: str) -> None:
    """Run ``command`` as a reader does, from the repository root; it must exit 0 without a traceback."""
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
    run_doc_command("make demo")
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


@pytest.mark.parametrize(("doc", "command"), doc_commands("sh ros2"), ids=_id)
def test_ros2_command_matches_the_real_interface(doc: str, command: str) -> None:
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
    elif words[:3] == ["ros2", "topic", "pub"]:  # -w: test_readme_topic_pub_waits_for_every_subscription
        line = parse(command)
        assert TOPIC_TYPES[line.topic] == line.message_type
        fill(_message(line.message_type)(), line.values)
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


# -- `ros2 topic pub` against the ROS tutorial's own setup, recording ----------------------

#: The `ros2 topic pub` lines of the docs; each page that has them has the `ros2 run` lines of its setup.
TOPIC_PUB_LINES = [c for c in commands("sh ros2", ROS_TUTORIAL.read_text()) if c.startswith("ros2 topic pub")]


def test_every_topic_pub_line_is_on_the_page_of_its_setup() -> None:
    """The pub lines are proven with the ROS tutorial's nodes: a page with others would need its own setup."""
    elsewhere = [c for _, c in doc_commands("sh ros2") if c.startswith("ros2 topic pub") and c not in TOPIC_PUB_LINES]
    assert TOPIC_PUB_LINES and not elsewhere, elsewhere


#: Where the ROS tutorial's `ros2 run` lines read the installed package's files; the repository has them.
INSTALLED = "install/friction_sim/share/friction_sim/"
#: Terminals that run one tutorial line at once.  With one, a `-w` one short loses the message to a
#: subscription that matched late only now and then (issue 28: 6 published, 4 recorded); with
#: several, some of them publish before the last subscription matched every time, while the
#: commands stay within the nodes' queues (QOS_DEPTH 10 per topic).
TERMINALS = 8
#: ros2cli's --keep-alive the ROS tutorial's lines need at least [s].  ``-w`` counts the matches the
#: publisher has seen; the subscriber's side of a match can come later, and the message it dropped
#: meanwhile is sent again only while the publisher lives: with ros2cli's 0.1 s, two runs of
#: test_readme_topic_pub_line_is_recorded_once_per_publish_by_the_recording_slider in ten lost
#: messages on a loaded 2-CPU machine with every -w right; with 1 s none in sixteen.
KEEP_ALIVE = 1.0
#: Seconds a published message may take to show in the recording (flushed every 0.25 s) and in
#: the controller's diagnostics (every 1 s).
DELIVERY = 15.0


def readme_nodes() -> dict[str, list[str]]:
    """The ROS tutorial's ROS 2 setup: executable -> the arguments its `ros2 run
    friction_sim ...` line gives (all after ``--ros-args``), the installed
    files read from the repository."""
    nodes = {}
    for command in commands("sh ros2", ROS_TUTORIAL.read_text()):
        words = shlex.split(command)
        if words[:3] == ["ros2", "run", "friction_sim"]:
            arguments = [word.replace(INSTALLED, f"{ROOT}/") for word in words[4:]]
            assert arguments[:1] in ([], ["--ros-args"]), command
            nodes[words[3]] = arguments[1:]
    assert set(nodes) == {"slider", "controller"}, nodes
    return nodes


def readme_log_path() -> str:
    """The slider's log_path in the ROS tutorial's setup: its pub lines are proven with the slider recording."""
    words = readme_nodes()["slider"]
    paths = [words[i + 1].split(":=", 1)[1] for i, word in enumerate(words[:-1])
             if word == "-p" and words[i + 1].startswith("log_path:=")]
    assert paths and paths[-1], "the ROS tutorial's slider records (-p log_path:=...), so that its " \
                                "`ros2 topic pub` lines are proven with recording on"
    return paths[-1]


def fresh_namespace() -> str:
    """Nodes of different tests never meet (the ROS tutorial's topics are moved into it)."""
    return f"/t{uuid.uuid4().hex[:8]}"


def readme_subscriptions(topic: str) -> dict[str, int]:
    """node -> how many subscriptions of ``topic`` it has, for the ROS tutorial's
    nodes built in this process from their `ros2 run` lines (in a fresh
    namespace; the current directory takes the recording)."""
    from friction_sim.ros.controller import ControllerNode
    from friction_sim.ros.slider import SliderNode

    ns = fresh_namespace()
    kinds: dict[str, Any] = {"slider": SliderNode, "controller": ControllerNode}
    counts = {}
    for name, arguments in readme_nodes().items():
        node = kinds[name](cli_args=["--ros-args", *arguments, "-r", f"__ns:={ns}"])
        try:
            counts[name] = sum(1 for subscription in node.subscriptions if subscription.topic_name == ns + topic)
        finally:
            node.destroy_node()
    return counts


@pytest.mark.parametrize("command", TOPIC_PUB_LINES)
def test_readme_topic_pub_waits_for_every_subscription_of_the_readme_setup(
        ros: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: str) -> None:
    """Issue 28, finding 3: `--once -w N` publishes once N subscriptions have
    matched; any other subscription of the topic misses the message.  N must
    be the subscriptions the ROS tutorial's setup has: the recording slider's
    too (it subscribes to target_speed only to record it).  And the publisher
    stays long enough for a subscriber whose side of the match came after the
    message (KEEP_ALIVE; ros2cli's 0.1 s lost some on a loaded machine)."""
    readme_log_path()
    monkeypatch.chdir(tmp_path)
    line = parse(command)
    subscriptions = readme_subscriptions(line.topic)
    total = sum(subscriptions.values())
    assert line.wait == total, \
        f"{command}: the ROS tutorial's setup has {subscriptions} subscriptions of {line.topic}: -w {total}"
    assert line.keep_alive >= KEEP_ALIVE, f"{command}: --keep-alive {KEEP_ALIVE:g} (see the ROS tutorial)"


def _controller_received(recording: Any, ns: str) -> int | None:
    """The commands the controller counted (accepted and refused), in the last of
    its diagnostics the recording holds (None before the first)."""
    received = None
    for _, msg in recording.iter_decoded(f"{ns}/diagnostics"):
        for status in msg.status:
            if status.name == "controller":
                values = {kv.key: kv.value for kv in status.values}
                received = int(values["commands_accepted"]) + int(values["commands_rejected"])
    return received


def _start_readme_setup(ns: str, cwd: Path) -> dict[str, subprocess.Popen[str]]:
    """The ROS tutorial's nodes, each in its own process as its `ros2 run` line starts
    it (the venv's console scripts), moved into ``ns``; returned once both
    report on diagnostics (fully built)."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray

    bin_dir = Path(sys.executable).parent
    processes = {}
    for name, arguments in readme_nodes().items():
        with open(cwd / f"{name}.log", "w") as log:
            processes[name] = subprocess.Popen([str(bin_dir / name), "--ros-args", *arguments, "-r", f"__ns:={ns}"],
                                               cwd=cwd, stdout=log, stderr=subprocess.STDOUT, text=True)
    probe = rclpy.create_node("readme_probe", namespace=ns)
    reported: set[str] = set()
    probe.create_subscription(DiagnosticArray, "diagnostics",
                              lambda msg: reported.update(status.name for status in msg.status), 10)
    try:
        deadline = time.monotonic() + 60.0
        while reported < set(processes) and time.monotonic() < deadline:
            assert all(p.poll() is None for p in processes.values()), _logs(processes, cwd)
            rclpy.spin_once(probe, timeout_sec=0.1)
    finally:
        probe.destroy_node()
    assert reported >= set(processes), f"only {reported} came up\n{_logs(processes, cwd)}"
    return processes


def _logs(processes: dict[str, subprocess.Popen[str]], cwd: Path) -> str:
    return "\n".join(f"{name} (exit {p.poll()}):\n{(cwd / f'{name}.log').read_text()[-3000:]}"
                     for name, p in processes.items())


def _stop(processes: dict[str, subprocess.Popen[str]], cwd: Path) -> None:
    """Ctrl-C to each node (the slider finishes its recording); each must end with exit code 0."""
    for process in processes.values():
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
    for process in processes.values():
        try:
            process.wait(timeout=60)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    assert all(p.returncode == 0 for p in processes.values()), _logs(processes, cwd)


@pytest.mark.parametrize("command", TOPIC_PUB_LINES)
def test_readme_topic_pub_line_is_recorded_once_per_publish_by_the_recording_slider(
        ros: None, tmp_path: Path, command: str) -> None:
    """Issue 28, finding 3, run: the ROS tutorial's slider (recording) and controller
    in their own processes, the line run from TERMINALS terminals at once
    (each as ros2cli runs it: a new participant that waits for -w matched
    subscriptions, publishes once, stays --keep-alive seconds); then Ctrl-C.
    The recording holds the topic's message exactly once per run, and the
    controller, if it takes the topic, counted each one: no subscription
    missed a message."""
    from friction_sim.io.reader import read_recording

    line, ns, path = parse(command), fresh_namespace(), tmp_path / readme_log_path()
    topic = ns + line.topic
    to_controller = "controller" in COMMANDS[line.topic.lstrip("/")].consumers
    processes = _start_readme_setup(ns, tmp_path)
    try:
        with ThreadPoolExecutor(TERMINALS) as terminals:
            matched = list(terminals.map(lambda _: publish(line, ns), range(TERMINALS)))

        def delivered() -> bool:
            recording = read_recording(path)  # the part written so far
            return recording.count(topic) >= TERMINALS and \
                (not to_controller or (_controller_received(recording, ns) or 0) >= TERMINALS)

        deadline = time.monotonic() + DELIVERY
        while not delivered() and time.monotonic() < deadline:
            time.sleep(0.25)  # the recorder writes its chunks every 0.25 s
    finally:
        _stop(processes, tmp_path)
    recording = read_recording(path)
    assert recording.complete, _logs(processes, tmp_path)
    recorded = recording.count(topic)
    said = f"{command}: published {TERMINALS} times, each when {matched} subscriptions had matched"
    assert recorded == TERMINALS, f"{said}; the recording holds {recorded}"
    if to_controller:
        received = _controller_received(recording, ns)
        assert received == TERMINALS, f"{said}; the controller took {received}"
