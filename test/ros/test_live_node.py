"""The Foxglove live view of the nodes, seen by a real WebSocket client.

``foxglove_port`` on the slider (``--foxglove`` on the command line) serves
every published topic, the events, diagnostics, refused commands and the
simulation controls; a client that speaks the SDK's protocol and decodes
with mcap-ros2-support (not our code) receives exactly what the node
published.  A taken port stops the node at start with one line naming it."""

from __future__ import annotations

import math
import os
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from rclpy.parameter import Parameter

from friction_sim.errors import LiveViewError
from friction_sim.io.reader import read_recording
from friction_sim.io.sinks import (
    AccelerationsRecord,
    ClockRecord,
    CommandRecord,
    EventRecord,
    MessageRecord,
    ParametersRecord,
    PeriodRecord,
    Record,
    StatesRecord,
)
from friction_sim.ros.slider import SliderNode

from foxglove_client import FoxgloveClient, Received
from ros_harness import Probe, kill_if_running, namespace, stamp_ns

#: ``foxglove_port`` -1: the system chooses a free port as the server binds it, and the node
#: reports it (``live.port``; in a process's log, the line that names the URL).  A port picked
#: here and released before the node binds it could be taken by anyone in between.
ANY_PORT = -1
#: The slider's start-up line naming where its live view serves.
SERVING = re.compile(r"live view: open (ws://127\.0\.0\.1:(\d+)) in Foxglove")


class LiveRig:
    """A slider serving a live view, a probe, and a client subscribed to ``topics``."""

    def __init__(self, tmp_path: Path) -> None:
        self.ns = namespace()
        self.node = SliderNode(namespace=self.ns, parameter_overrides=[
            Parameter("foxglove_port", value=ANY_PORT), Parameter("log_path", value=str(tmp_path / "run.mcap"))])
        assert self.node.live is not None
        self.port = self.node.live.port
        assert self.port > 0 and self.node.live.url == f"ws://127.0.0.1:{self.port}"
        self.probe = Probe(self.ns, self.node)
        self.probe.wait_for_connection()
        self.client = FoxgloveClient(self.node.live.url).__enter__()

    def topic(self, name: str) -> str:
        return f"{self.ns}/{name}"

    def call(self, name: str) -> Any:
        return self.probe.control(name)

    def collect_until(self, done: Callable[[list[Received]], bool], timeout: float = 60.0) -> list[Received]:
        """Spin and read until ``done(received so far)``; the timeout only guards a hang
        (it is never reached on a working node, however loaded the machine)."""
        got: list[Received] = []
        deadline = time.monotonic() + timeout
        while not done(got):
            assert time.monotonic() < deadline, f"still waiting after {timeout} s: {len(got)} messages"
            self.probe.spin_for(0.03)
            got.extend(self.client.collect(0.02))
        return got

    def close(self) -> None:
        self.client.close()
        self.probe.close()
        self.node.destroy_node()


@pytest.fixture
def live(ros: None, tmp_path: Path) -> Iterator[LiveRig]:
    rig = LiveRig(tmp_path)
    yield rig
    rig.close()


def test_a_client_receives_what_the_node_publishes(live: LiveRig) -> None:
    names = ("pose", "velocity", "friction_force", "mean_velocity", "events", "rejected_commands", "diagnostics",
             "sim_control", "excitation_amplitude")
    at_start = [live.topic(n) for n in names]  # advertised before anything happens
    channels = live.client.wait_for_channels(*at_start, timeout=5.0)
    assert channels[live.topic("pose")]["schemaName"] == "geometry_msgs/msg/PoseStamped"
    assert all(c["encoding"] == "cdr" and c["schemaEncoding"] == "ros2msg" for c in channels.values())
    live.client.subscribe(*at_start)

    def seen(got: list[Received], *names: str) -> bool:
        return set(names) <= {item.topic.removeprefix(live.ns + "/") for item in got}

    # Waits are for what is needed, counted, never for a rate: 300 states, the
    # reactions to two commands, a diagnostics message (1 Hz), two controls.
    got = live.collect_until(lambda got: sum(item.topic.endswith("/pose") for item in got) >= 300)
    live.probe.send("excitation_amplitude", 6.0)
    live.probe.send("drive_force", math.nan)
    got += live.collect_until(lambda more: seen(got + more, "rejected_commands", "diagnostics", "events",
                                                  "mean_velocity", "excitation_amplitude"))
    assert live.call("pause").success and live.call("step").success
    step_end = round(live.node.realtime.slider.t * 1e9)  # paused: the step has ended
    got += live.collect_until(lambda more: sum(item.topic.endswith("/sim_control") for item in more) >= 2
                              and any(item.log_time_ns == step_end for item in more))
    by_topic: dict[str, list[Received]] = {}
    for item in got:
        by_topic.setdefault(item.topic.removeprefix(live.ns + "/"), []).append(item)
    # The states: each one the client got is the one the node published with that
    # stamp, once and in order.  The probe's own DDS subscription may drop states
    # on a loaded machine (depth-limited queue), so those it has are the witnesses.
    published = {stamp_ns(m): m for m in live.probe.received["pose"]}
    poses = by_topic["pose"]
    stamps = [p.log_time_ns for p in poses]
    assert stamps == sorted(set(stamps)), "each state once, in order"
    matched = [p for p in poses if p.log_time_ns in published]
    assert len(matched) >= 100, (len(matched), len(poses), len(published))
    for item in matched:
        sent = published[item.log_time_ns]
        assert item.message.pose.position.x == sent.pose.position.x
        assert stamp_ns(item.message) == item.log_time_ns
    assert {e.message.name for e in by_topic["events"]} <= {"slip_start", "stick", "reversal", "lift_off", "landing"}
    assert by_topic["events"] and by_topic["mean_velocity"]
    refused = by_topic["rejected_commands"]
    assert any(r.message.name == "drive_force" and "nan" in r.message.message for r in refused)
    assert any(s.message.status[0].name == "slider" for s in by_topic.get("diagnostics", [])), by_topic.keys()
    assert [c.message.name for c in by_topic.get("sim_control", [])] == ["pause", "step"]
    assert [a.message.data for a in by_topic["excitation_amplitude"]] == [6.0]
    # While paused, the step's end is the last state sent.
    assert max(p.log_time_ns for p in poses) == step_end == round(live.node.realtime.slider.t * 1e9)
    stats = live.node.live.stats()  # type: ignore[union-attr]
    assert stats["live_view_clients"] == 1 and stats["live_view_sent"] > 0 and not stats["live_view_error"]


class RecordLog:
    """A sink beside the recorder and the live view: keeps every record the node hands its sinks."""

    def __init__(self) -> None:
        self.records: list[Record] = []

    def write(self, record: Record) -> bool:
        self.records.append(record)
        return True

    def close(self) -> None: ...


def test_clock_and_diagnostics_reach_the_sinks_by_the_one_path_and_the_recording_holds_no_clock(
        ros: None, tmp_path: Path) -> None:
    """With publish_clock the node hands /clock to its sinks as it publishes it: the live
    view serves it (stamped with the simulation time it carries), the recording keeps none
    (its log times are that time already); a sink the node was given gets every kind of
    record the recorder and the live view get, /clock and diagnostics included."""
    ns, path, log = namespace(), tmp_path / "run.mcap", RecordLog()
    node = SliderNode(namespace=ns, parameter_overrides=[
        Parameter("foxglove_port", value=ANY_PORT), Parameter("log_path", value=str(path)),
        Parameter("publish_clock", value=True), Parameter("diagnostics_period", value=0.2)])
    node.sinks.append(log)
    probe = Probe(ns, node)
    try:
        assert node.live is not None
        with FoxgloveClient(node.live.url) as client:
            client.subscribe("/clock")
            clocks = client.collect(until=lambda got: len(got) >= 100, timeout=60.0)
        probe.send("drive_force", 0.5)
        assert node.set_parameters([Parameter("frame_id", value="slideway")])[0].successful
        assert probe.spin_until(lambda: any(isinstance(r, CommandRecord) for r in log.records)
                                and any(isinstance(r, MessageRecord) and r.topic == "diagnostics"
                                        for r in log.records), 60.0)
    finally:
        probe.close()
        node.destroy_node()
    assert len(clocks) >= 100 and all(c.topic == "/clock" for c in clocks)
    stamps = [c.log_time_ns for c in clocks]
    assert stamps == sorted(set(stamps)), "each tick's time once, in order"
    assert all(c.message.clock.sec * 1_000_000_000 + c.message.clock.nanosec == c.log_time_ns for c in clocks)
    kinds = {type(r) for r in log.records}
    assert {ParametersRecord, StatesRecord, PeriodRecord, EventRecord, CommandRecord, ClockRecord,
            MessageRecord} <= kinds, kinds
    assert all(isinstance(r, (StatesRecord, EventRecord, PeriodRecord, AccelerationsRecord, CommandRecord,
                              ParametersRecord, ClockRecord, MessageRecord)) for r in log.records)
    recording = read_recording(path)
    assert recording.topic_name("/clock") is None and recording.count(recording.topic_name("pose") or "") > 100
    assert recording.topic_name("diagnostics") is not None


def test_a_taken_port_stops_the_node_at_start_naming_it(ros: None) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(LiveViewError, match=f"foxglove_port = {port} rejected"):
            SliderNode(namespace=namespace(), parameter_overrides=[Parameter("foxglove_port", value=port)])


def _started(command: list[str], log: Path) -> subprocess.Popen[str]:
    """``command`` running, its log (stderr, where the nodes log) in ``log``: a file, read while it runs."""
    with log.open("w") as err:
        return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=err, text=True, env=os.environ.copy())


def _feeder(port: int, ns: str, log: Path) -> subprocess.Popen[str]:
    return _started([sys.executable, "-m", "friction_sim", "feeder", "--foxglove", str(port), "--ros-args", "-r",
                     f"__ns:={ns}"], log)


def _serving(process: subprocess.Popen[str], log: Path, timeout: float = 60.0) -> tuple[str, int]:
    """The URL and port the live view of a starting ``process`` serves on, once its log names them
    (the slider logs the line after its server is listening); the timeout only guards a hang."""
    deadline = time.monotonic() + timeout
    while not (found := SERVING.search(log.read_text())):
        if process.poll() is not None or time.monotonic() > deadline:
            raise AssertionError(f"the server never opened (exit {process.poll()}): {log.read_text()[-2000:]}")
        time.sleep(0.05)  # poll interval: waiting for the log line
    return found[1], int(found[2])


def test_friction_sim_feeder_foxglove_serves_both_nodes_and_a_taken_port_is_one_line(
        ros: None, tmp_path: Path) -> None:
    ns = namespace()
    feeder = _feeder(ANY_PORT, ns, tmp_path / "feeder.log")
    try:
        url, port = _serving(feeder, tmp_path / "feeder.log")
        client = FoxgloveClient(url).__enter__()
        try:
            client.wait_for_channels(f"{ns}/pose", timeout=10.0)
            client.subscribe(f"{ns}/pose")
            got = client.collect(until=lambda r: sum(x.topic == f"{ns}/pose" for x in r) >= 500, timeout=60.0)
            client.subscribe(*(t for t in (f"{ns}/diagnostics", f"{ns}/target_speed") if t in client.channels))

            def both_reported(more: list[Received]) -> bool:
                return {"slider", "controller"} <= {s.name for r in more if r.topic == f"{ns}/diagnostics"
                                                     for s in r.message.status}

            got += client.collect(until=both_reported, timeout=60.0)
        finally:
            client.close()
        statuses = {s.name for r in got if r.topic == f"{ns}/diagnostics" for s in r.message.status}
        assert sum(r.topic == f"{ns}/pose" for r in got) >= 500
        assert {"slider", "controller"} <= statuses, statuses
        second = _feeder(port, namespace(), tmp_path / "second.log")  # the port the first one holds
        second.communicate(timeout=60)
        err = (tmp_path / "second.log").read_text()
        assert second.returncode == 2, err
        assert f"foxglove_port = {port} rejected" in err and "Traceback" not in err
    finally:
        if feeder.poll() is None:
            feeder.send_signal(signal.SIGINT)
            try:
                feeder.communicate(timeout=20)
            finally:
                kill_if_running(feeder)
    assert feeder.returncode == 0


def test_friction_sim_experiment_foxglove_serves_the_in_process_run(tmp_path: Path) -> None:
    """The in-process experiment (slider and controller in the job's process)
    serves its run; with --attach the slider is elsewhere and the flag is refused."""
    scenario = tmp_path / "short.yaml"
    scenario.write_text("name: short\nduration: 4.0\noutput: out\nplant: {excitation_amplitude: 5.0}\ncontroller: {}\n"
                        "schedule:\n  - {t: 1.0, excitation_amplitude: 6.0}\n  - {t: 2.0, target_speed: 0.0002}\n")
    log = tmp_path / "job.log"
    job = _started([sys.executable, "-m", "friction_sim", "experiment", str(scenario), "--output",
                    str(tmp_path / "out"), "--foxglove", str(ANY_PORT)], log)
    try:
        client = FoxgloveClient(_serving(job, log)[0]).__enter__()
        try:
            client.collect(until=lambda _: any(t.endswith("/pose") for t in client.channels), timeout=10.0)
            poses = [t for t in client.channels if t.endswith("/pose")]  # in the experiment's own namespace
            client.subscribe(*poses, *(t for t in client.channels if t.endswith("/excitation_amplitude")))
            got = client.collect(until=lambda r: sum(x.topic in poses for x in r) >= 300, timeout=60.0)
        finally:
            client.close()
        job.communicate(timeout=120)
    finally:
        kill_if_running(job)
    assert job.returncode == 0, log.read_text()[-2000:]
    assert len(poses) == 1 and sum(r.topic in poses for r in got) >= 300
    assert (tmp_path / "out" / "short.mcap").is_file()
    attached = subprocess.run([sys.executable, "-m", "friction_sim", "experiment", str(scenario), "--attach", "/x",
                               "--foxglove"], capture_output=True, text=True, env=os.environ.copy(), timeout=60)
    assert attached.returncode != 0 and "--foxglove with --attach" in attached.stderr
    assert "Traceback" not in attached.stderr


def test_a_foxglove_client_pauses_steps_and_resets_the_slider(live: LiveRig) -> None:
    """The live view offers the control services to Foxglove clients (its Call
    Service panel): same names, type and answers as over ROS, counted like those."""
    name = f"{live.ns}/slider"

    def call(service: str) -> Any:
        return live.client.call_service(f"{name}/{service}")

    paused = call("pause")
    assert live.client.services[f"{name}/pause"]["type"] == "std_srvs/srv/Trigger"
    assert paused.success and paused.message.startswith("paused at t = ")
    t_paused = live.node.realtime.slider.t
    stepped = call("step")
    assert stepped.success and "stepped 0.02 s" in stepped.message
    assert live.node.realtime.slider.t == pytest.approx(t_paused + 0.02, abs=1e-9)
    first, second = call("resume"), call("resume")
    assert first.success and not second.success and "not paused" in second.message
    reset = call("reset")
    assert reset.success and "x = 0 m" in reset.message
    assert live.node.realtime.slider.state().x < 1e-5 and not live.node.realtime.paused
    assert live.node.realtime.rejected == 1  # the second resume, counted like any refusal
