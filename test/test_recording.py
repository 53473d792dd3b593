"""Recording: the messages, the MCAP layout rosbag2 and Foxglove expect, an
independent reader (rosbags) decoding every message from the schema text
stored in the file, durability (flush, SIGKILL, SIGINT/SIGTERM) and the
non-blocking queue."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

from friction_sim.io import messages as M
from friction_sim.core.slider import Event, EventKind, Mode, Slider, SliderState
from friction_sim.errors import RecordingError
from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.realtime import CommandOutcome, PeriodSummary, RealtimeSlider
from friction_sim.io.recording import (
    METADATA_NAME, Recorder, message_definition, record_offline, share_directory, type_hash,
)
from friction_sim.io.replay import read_recording, run
from friction_sim.core.simulation import Command, random_schedule

ROOT = Path(__file__).resolve().parents[1]


def replay_args(path: Path, **options: Any) -> argparse.Namespace:
    defaults = dict(file=path, verify=False, tolerance=1e-9, publish=False, rate=1.0, loop=False, topics=None,
                    namespace="", csv=None, plot=None)
    defaults.update(options)
    return argparse.Namespace(**defaults)


# -- messages -------------------------------------------------------------------


STATE = SliderState(t=1.2345678901, x=1.5e-4, v=-2.5e-3, acceleration=0.3, friction_force=-0.95,
                    normal_force=9.5, phase=1.0, mode=Mode.BACKWARD)


def test_state_messages_carry_x_v_friction_and_normal_force() -> None:
    pose, twist, wrench = M.state_messages(STATE, "rail")
    assert pose.pose.position.x == STATE.x and pose.pose.orientation.w == 1.0
    assert twist.twist.linear.x == STATE.v
    assert (wrench.wrench.force.x, wrench.wrench.force.z) == (STATE.friction_force, STATE.normal_force)
    for msg in (pose, twist, wrench):
        assert msg.header.frame_id == "rail"
        assert M.stamp_ns(msg.header.stamp) == 1_234_567_890


def test_time_helpers_round_trip_whole_nanoseconds() -> None:
    for ns in (0, 1, 999_999_999, 1_000_000_000, 3_600_123_456_789, -1, -1_500_000_000):
        stamp = M.time_msg(ns)
        assert 0 <= stamp.nanosec < 1_000_000_000
        assert M.stamp_ns(stamp) == ns
        assert M.seconds_to_ns(M.ns_to_seconds(ns)) == ns


def test_command_messages_per_topic() -> None:
    for topic in M.FLOAT_COMMANDS:
        msg = M.command_message(CommandOutcome(0.5, topic, {topic: 0.25}, True))
        assert type(msg).__name__ == "Float64" and msg.data == 0.25
    wrench = M.command_message(CommandOutcome(0.5, "external_wrench",
                                              {"external_force_x": 0.1, "external_force_z": -2.0}, True))
    assert (wrench.wrench.force.x, wrench.wrench.force.z) == (0.1, -2.0)
    assert M.stamp_ns(wrench.header.stamp) == 500_000_000
    change = M.command_message(CommandOutcome(0.5, "parameters", {"mass": 2.0, "mu": 0.2}, True))
    assert M.parameter_event_values(change) == ({}, {"mass": 2.0, "mu": 0.2})
    with pytest.raises(ValueError, match="no message for command topic"):
        M.command_message(CommandOutcome(0.5, "warp_drive", {"x": 1.0}, True))


def test_rejection_and_event_messages_are_readable_diagnostics() -> None:
    refused = M.rejection_message(CommandOutcome(0.5, "excitation_amplitude", {"excitation_amplitude": 12.5},
                                                 False, "excitation_amplitude = 12.5 rejected: must be < 10"))
    assert refused.level == M.DiagnosticStatus.WARN
    assert refused.name == "excitation_amplitude"
    assert refused.message == "excitation_amplitude = 12.5 rejected: must be < 10"
    assert [(kv.key, kv.value) for kv in refused.values] == [("excitation_amplitude", "12.5")]
    event = M.event_message(Event(0.0123, EventKind.SLIP_START, 1e-5, 0.7, Mode.STUCK, Mode.FORWARD))
    assert (event.level, event.name, event.message) == (M.DiagnosticStatus.OK, "slip_start", "stuck -> forward")
    values = {kv.key: kv.value for kv in event.values}
    assert float(values["t"]) == 0.0123 and float(values["x"]) == 1e-5 and float(values["phase"]) == 0.7
    assert (values["before"], values["after"]) == ("stuck", "forward")


def test_parameter_values_keep_their_types() -> None:
    values = {"mass": 1.5, "window": 3, "clock": True, "frame_id": "rail", "gains": [1.0, 2.5],
              "counts": [1, 2], "names": ["a", "b"], "flags": [True, False], "blob": b"\x01\x02"}
    msg = M.parameters_message(values, 2.0)
    new, changed = M.parameter_event_values(msg)
    assert new == values and changed == {}
    assert {p.name: p.value.type for p in msg.new_parameters} == {
        "mass": 3, "window": 2, "clock": 1, "frame_id": 4, "gains": 8, "counts": 7, "names": 9, "flags": 6,
        "blob": 5}
    assert M.stamp_ns(msg.stamp) == 2_000_000_000 and msg.node == "/slider"


# -- round trip through the file ------------------------------------------------------


def every_record() -> dict[str, Any]:
    return {
        "state": STATE,
        "event": Event(1.0, EventKind.STICK, 2e-4, 3.0, Mode.FORWARD, Mode.STUCK),
        "period": PeriodSummary(n=7, t=0.14, mean_velocity=2.1e-3, window_periods=1, stick_fraction=0.4),
        "commands": [CommandOutcome(0.3 + 0.01 * k, topic, {topic: 0.5 + k}, True)
                     for k, topic in enumerate(M.FLOAT_COMMANDS)]
        + [CommandOutcome(0.4, "external_wrench", {"external_force_x": 0.05, "external_force_z": 1.5}, True),
           CommandOutcome(0.45, "parameters", {"mu": 0.12}, True),
           CommandOutcome(0.5, "excitation_amplitude", {"excitation_amplitude": 20.0}, False, "too large")],
        "parameters": {"mass": 1.0, "mu": 0.1, "gravity": 10.0, "drive_force": 0.7, "excitation_amplitude": 5.0,
                       "excitation_frequency": 50.0, "frame_id": "slideway", "mean_window_periods": 2},
    }


def test_every_message_type_round_trips_through_the_file(tmp_path: Path) -> None:
    records = every_record()
    path = tmp_path / "all.mcap"
    from std_msgs.msg import String

    with Recorder(path, metadata={"mass": 1.0}) as recorder:
        assert recorder.record_parameters(records["parameters"], 0.0)
        assert recorder.record_state(records["state"], "rail")
        assert recorder.record_event(records["event"])
        assert recorder.record_period(records["period"], "rail")
        for outcome in records["commands"]:
            assert recorder.record_command(outcome, "rail")
        assert recorder.write("notes", String(data="hello"), 42)
    expected: list[tuple[str, int, Any]] = [("parameters", 0, M.parameters_message(records["parameters"], 0.0))]
    ns = M.seconds_to_ns(STATE.t)
    expected += [(topic, ns, msg) for topic, msg in zip(M.STATE_TOPICS, M.state_messages(STATE, "rail"))]
    expected.append(("events", 1_000_000_000, M.event_message(records["event"])))
    expected.append(("mean_velocity", 140_000_000, M.mean_velocity_message(records["period"], "rail")))
    for outcome in records["commands"]:
        topic = outcome.topic if outcome.accepted else "rejected_commands"
        msg = M.command_message(outcome, "rail") if outcome.accepted else M.rejection_message(outcome)
        expected.append((topic, M.seconds_to_ns(outcome.t), msg))
    expected.append(("notes", 42, String(data="hello")))

    recording = read_recording(path)
    assert recording.complete and recording.profile == "ros2"
    got = [(raw.topic, raw.log_time, recording.decode(raw)) for raw in recording.messages]
    assert [(topic, t) for topic, t, _ in got] == [(topic, t) for topic, t, _ in expected]
    for (topic, _, msg), (_, _, want) in zip(got, expected):
        assert type(msg) is type(want) and msg == want, topic
    assert recording.topics["parameters"].type_name == "rcl_interfaces/msg/ParameterEvent"
    assert recording.topics["rejected_commands"].type_name == "diagnostic_msgs/msg/DiagnosticStatus"


# -- an independent reader ----------------------------------------------------------------


def plain(value: Any) -> Any:
    """rclpy and rosbags messages as comparable plain Python values."""
    if hasattr(value, "get_fields_and_field_types"):
        return {name: plain(getattr(value, name)) for name in value.get_fields_and_field_types()}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: plain(getattr(value, f.name)) for f in dataclasses.fields(value)
                if f.name != "__msgtype__" and not f.name.isupper()}  # constants are not fields
    if isinstance(value, bytes):
        return value[0] if len(value) == 1 else list(value)
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple, np.ndarray)) or type(value).__name__ == "array":
        return [plain(v) for v in value]
    return value


def varied_schedule() -> list[Command]:
    schedule = random_schedule(np.random.default_rng(7), 1.5, external=True)
    schedule.append(Command(0.5, {"excitation_amplitude": 50.0}))  # refused: the slider would lift off
    schedule.append(Command(0.8, {"mass": 1.2, "mu": 0.12}))  # a plant change, as ros2 param set makes it
    return schedule


def test_rosbags_decodes_every_message_from_the_stored_schema_text(tmp_path: Path) -> None:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    path = tmp_path / "run.mcap"
    stats = record_offline(path, schedule=varied_schedule(), duration=1.5)
    ours = read_recording(path)
    assert {"rejected_commands", "parameters", "external_wrench", "events", "mean_velocity"} <= set(ours.topics)
    ours_by_topic = {topic: ours.decoded(topic) for topic in ours.topics}
    with AnyReader([path]) as reader:
        # AnyReader builds its types only from the definitions stored in the file.
        assert reader.typestore is not get_typestore(Stores.ROS2_JAZZY)
        assert reader.message_count == stats.messages == len(ours.messages)
        theirs: dict[str, list[tuple[int, Any]]] = {}
        for connection, timestamp, raw in reader.messages():
            theirs.setdefault(connection.topic, []).append((timestamp, reader.deserialize(raw, connection.msgtype)))
        for connection in reader.connections:
            channel = ours.topics[connection.topic]
            assert connection.msgtype == channel.type_name
            # The hash rosbags computes from the stored text is the installed type's RIHS01.
            assert reader.typestore.hash_rihs01(connection.msgtype) == channel.metadata["topic_type_hash"]
            qos = connection.ext.offered_qos_profiles[0]
            assert (qos.reliability.name, qos.durability.name, qos.history.name, qos.depth) == (
                "RELIABLE", "VOLATILE", "KEEP_LAST", 10)
    assert set(theirs) == set(ours_by_topic)
    for topic, messages in ours_by_topic.items():
        assert [t for t, _ in theirs[topic]] == [t for t, _ in messages], topic
        for (_, mine), (_, other) in zip(messages, theirs[topic]):
            assert plain(mine) == plain(other), topic


def test_file_layout_is_what_rosbag2s_mcap_plugin_writes(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    stats = record_offline(path, schedule=varied_schedule(), duration=1.0, log_rate=500.0)
    with path.open("rb") as stream:
        reader = make_reader(stream)
        header = reader.get_header()
        summary = reader.get_summary()
        metadata = {record.name: dict(record.metadata) for record in reader.iter_metadata()}
    assert summary is not None, "summary section"
    assert header.profile == "ros2" and header.library.startswith("friction_sim/")
    assert summary.statistics.message_count == stats.messages
    assert summary.statistics.chunk_count == len(summary.chunk_indexes) >= 1
    assert {index.compression for index in summary.chunk_indexes} == {"zstd"}
    assert sum(summary.statistics.channel_message_counts.values()) == stats.messages
    for schema in summary.schemas.values():
        assert schema.encoding == "ros2msg"
        package, kind, name = schema.name.split("/")
        assert kind == "msg"
        installed = (share_directory(package) / "msg" / f"{name}.msg").read_text()
        text = schema.data.decode()
        assert text == message_definition(schema.name) and text.startswith(installed)
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        assert channel.message_encoding == "cdr"
        assert set(channel.metadata) == {"offered_qos_profiles", "topic_type_hash"}
        package, _, name = schema.name.split("/")
        described = json.loads((share_directory(package) / "msg" / f"{name}.json").read_text())
        assert channel.metadata["topic_type_hash"] == described["type_hashes"][0]["hash_string"]
        assert channel.metadata["topic_type_hash"].startswith("RIHS01_")
        assert yaml.safe_load(channel.metadata["offered_qos_profiles"]) == [{
            "history": "keep_last", "depth": 10, "reliability": "reliable", "durability": "volatile",
            "deadline": {"sec": 9223372036, "nsec": 854775807}, "lifespan": {"sec": 9223372036, "nsec": 854775807},
            "liveliness": "automatic", "liveliness_lease_duration": {"sec": 9223372036, "nsec": 854775807},
            "avoid_ros_namespace_conventions": False}]
    ours = metadata[METADATA_NAME]
    assert float(ours["log_rate"]) == 500.0 and float(ours["mass"]) == 1.0 and float(ours["drive_force"]) == 0.7
    assert metadata["friction_sim_summary"] == {"messages": str(stats.messages), "dropped": "0"}
    bag = yaml.safe_load(metadata["rosbag2"]["serialized_metadata"])
    assert bag["version"] == 9 and bag["storage_identifier"] == "mcap" and bag["ros_distro"] == "jazzy"
    assert bag["message_count"] == stats.messages
    assert bag["duration"]["nanoseconds"] == stats.last_ns - stats.first_ns == 1_000_000_000
    assert bag["relative_file_paths"] == [path.name] and bag["files"][0]["message_count"] == stats.messages
    counts = {topic["topic_metadata"]["name"]: topic["message_count"] for topic in bag["topics_with_message_count"]}
    assert counts == stats.per_topic
    for topic in bag["topics_with_message_count"]:
        meta = topic["topic_metadata"]
        assert meta["serialization_format"] == "cdr"
        assert meta["type_description_hash"] == type_hash(meta["type"])
        assert meta["offered_qos_profiles"][0]["reliability"] == "reliable"


def test_message_definitions_follow_rosbag2s_layout() -> None:
    text = message_definition("geometry_msgs/msg/PoseStamped")
    sections = text.split("\n" + "=" * 80 + "\n")
    assert [s.split("\n", 1)[0] for s in sections[1:]] == [
        "MSG: geometry_msgs/Pose", "MSG: geometry_msgs/Point", "MSG: geometry_msgs/Quaternion",
        "MSG: std_msgs/Header", "MSG: builtin_interfaces/Time"]
    share = share_directory("geometry_msgs")
    assert share is not None and (share / "msg" / "PoseStamped.msg").is_file(), "the wheels ship .msg files"
    assert sections[0] == (share / "msg" / "PoseStamped.msg").read_text()
    status = message_definition("diagnostic_msgs/msg/DiagnosticStatus")
    key_value = (share_directory("diagnostic_msgs") / "msg" / "KeyValue.msg").read_text()
    assert status.endswith("\n" + "=" * 80 + "\nMSG: diagnostic_msgs/KeyValue\n" + key_value)


# -- durability ------------------------------------------------------------------------


def test_written_data_is_readable_within_the_flush_interval_while_recording(tmp_path: Path) -> None:
    path = tmp_path / "live.mcap"
    recorder = Recorder(path, metadata={"mass": 1.0}, flush_interval=0.2)
    try:
        written = time.monotonic()
        recorder.record_state(STATE)
        while time.monotonic() - written < 10.0:
            live = read_recording(path, require_friction_sim=False)
            if live.messages:
                break
            time.sleep(0.02)
        # Flushed every 0.2 s; without the periodic flush nothing reaches the disk before finish().
        assert time.monotonic() - written < 3.0, "on disk within the flush interval (3 s for a loaded machine)"
        assert not live.complete and len(live.messages) == 3
        assert "no footer" in (live.recovery_note() or "")
    finally:
        recorder.finish()
    assert read_recording(path).complete


CHILD = r"""
import os, signal, sys, time
from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.realtime import RealtimeSlider
from friction_sim.io.recording import Recorder, plant_parameters, recording_metadata

path, mode, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
params, inputs = SliderParams(), Inputs()

def stop(signum, frame):
    raise KeyboardInterrupt
signal.signal(signal.SIGTERM, stop)

rt = RealtimeSlider(params, inputs, wall_ns=time.monotonic_ns(), log_rate=1000.0)
try:
    with Recorder(path, recording_metadata(params, inputs, log_rate=1000.0)) as recorder:
        recorder.record_parameters({**plant_parameters(params, inputs), "log_rate": 1000.0}, 0.0)
        started, n, announced = time.monotonic(), 0, False
        while True:
            now = time.monotonic_ns()
            if rt.slider.t >= 0.075 + 0.15 * n:  # a command every 0.15 s of simulation time
                recorder.record_command(rt.command("drive_force", {"drive_force": 0.55 + 0.03 * (n % 7)}, now))
                n += 1
            recorder.record_tick(rt.tick(now))
            if not announced and time.monotonic() - started >= seconds:
                print(repr(rt.slider.t), flush=True)  # once: a signal must not cut a second print
                announced = True
                if mode == "kill":
                    os.kill(os.getpid(), signal.SIGKILL)
            time.sleep(0.001)
except KeyboardInterrupt:
    print("finished", flush=True)
"""


def test_sigkill_loses_at_most_the_last_second_and_the_tool_says_what_it_recovered(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "killed.mcap"
    done = subprocess.run([sys.executable, "-c", CHILD, str(path), "kill", "2.5"], capture_output=True,
                          text=True, timeout=60, cwd=ROOT)
    assert done.returncode == -signal.SIGKILL, done.stderr
    killed_at = float(done.stdout.split()[-1])  # simulated time handed to the recorder when killed
    recording = read_recording(path)
    assert not recording.complete
    recovered = recording.end_ns / 1e9
    assert killed_at - 1.0 <= recovered <= killed_at, (killed_at, recovered)
    assert len(recording.messages_on("drive_force")) >= 8  # one per 0.15 s of the >= 1.5 s recovered
    # The writer may end a chunk between a command and the tick that follows it, so the file can end
    # on a command stamped just after the last grid point: the grid has no gap and reaches the last tick.
    pose_ns = [message.log_time for message in recording.messages_on("pose")]
    assert pose_ns == [k * 1_000_000 for k in range(len(pose_ns))], "every grid point, no gap"
    assert recording.end_ns - pose_ns[-1] < 50_000_000, (recording.end_ns, pose_ns[-1])
    assert run(replay_args(path, verify=True)) == 0, "the recovered part re-simulates exactly"
    captured = capsys.readouterr()
    assert f"recovered {len(recording.messages)} messages up to t = {recovered:.6f} s; " \
           "the file has no footer (writer killed?)" in captured.err
    assert "reproducible" in captured.out


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_sigint_and_sigterm_finish_the_file(tmp_path: Path, signum: int) -> None:
    from rosbags.highlevel import AnyReader

    path = tmp_path / "stopped.mcap"
    process = subprocess.Popen([sys.executable, "-c", CHILD, str(path), "wait", "0.8"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, cwd=ROOT)
    assert process.stdout is not None
    stopped_at = float(process.stdout.readline())
    process.send_signal(signum)
    out, err = process.communicate(timeout=30)
    assert process.returncode == 0 and out.strip() == "finished", err
    recording = read_recording(path)
    assert recording.complete and "rosbag2" in recording.metadata
    assert recording.end_ns >= int(stopped_at * 1000) * 1_000_000, "nothing before the signal is lost"
    with AnyReader([path]) as reader:  # needs the summary and footer
        assert reader.message_count == len(recording.messages)


# -- the queue --------------------------------------------------------------------------


class StalledRecorder(Recorder):
    """A recorder whose writer thread is stuck (a slow disk)."""

    gate = threading.Event()

    def _handle(self, item: Any) -> None:
        self.gate.wait(10.0)
        super()._handle(item)


def test_a_full_queue_drops_and_counts_without_blocking_the_caller(tmp_path: Path) -> None:
    path = tmp_path / "stalled.mcap"
    recorder = StalledRecorder(path, metadata={"mass": 1.0}, queue_size=10)
    slowest, accepted = 0.0, 0
    for k in range(100):
        started = time.perf_counter()
        accepted += recorder.record_state(dataclasses.replace(STATE, t=k * 1e-3))
        slowest = max(slowest, time.perf_counter() - started)
    # A blocked call would wait for the stalled writer (10 s); 0.5 s leaves room for a loaded machine.
    assert slowest < 0.5, f"write() never waits for the writer (slowest call {slowest:.3f} s)"
    assert accepted in (10, 11) and recorder.dropped == 100 - accepted
    StalledRecorder.gate.set()
    stats = recorder.finish()
    assert stats.dropped == 100 - accepted and stats.per_topic["pose"] == accepted
    recording = read_recording(path)
    assert recording.dropped == 100 - accepted
    assert len(recording.messages_on("pose")) == accepted
    assert not recorder.record_state(STATE), "after finish nothing is written"


def test_finish_is_idempotent_and_unwritable_paths_are_one_line_errors(tmp_path: Path) -> None:
    recorder = Recorder(tmp_path / "a.mcap")
    first = recorder.finish()
    assert recorder.finish() is first and recorder.finished
    for bad in (tmp_path / "missing" / "run.mcap", tmp_path):
        with pytest.raises(RecordingError) as error:
            Recorder(bad)
        message = str(error.value)
        assert message.startswith("cannot write recording") and "\n" not in message


# -- sampling ---------------------------------------------------------------------------


def test_recorded_states_are_on_the_grid_whatever_the_tick_times(tmp_path: Path) -> None:
    """Jittery ticks and commands between them: the logged states are the
    exact states at k / log_rate, and every event is logged once, in order."""
    rng = np.random.default_rng(11)
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, log_rate=2000.0)
    path = tmp_path / "grid.mcap"
    commands = sorted(rng.integers(0, 500_000_000, 12))
    with Recorder(path, metadata={"log_rate": 2000.0}) as recorder:
        wall = 0
        while wall < 500_000_000:
            wall = min(500_000_000, wall + int(rng.integers(100_000, 4_000_000)))
            while commands and commands[0] <= wall:
                when = int(commands.pop(0))
                recorder.record_command(rt.command("drive_force", {"drive_force": float(rng.uniform(-1, 1))}, when))
            recorder.record_tick(rt.tick(wall))
    recording = read_recording(path, require_friction_sim=False)
    times = np.array([raw.log_time for raw in recording.messages_on("pose")])
    assert np.array_equal(times, np.round(np.arange(1001) / 2000.0 * 1e9).astype(np.int64))
    events = recording.decoded("events")
    assert len(events) == sum(rt.slider.event_counts.values())
    assert [float({kv.key: kv.value for kv in m.values}["t"]) for _, m in events] == [e.t for e in rt.slider.events]
    assert all(a <= b for (a, _), (b, _) in zip(events, events[1:]))


def test_state_log_matches_a_vectorised_sample_of_the_same_run(tmp_path: Path) -> None:
    schedule = random_schedule(np.random.default_rng(3), 0.6)
    path = tmp_path / "run.mcap"
    record_offline(path, schedule=schedule, duration=0.6, log_rate=1000.0)
    recording = read_recording(path)
    from friction_sim.core.simulation import run_schedule

    grid = np.arange(601) / 1000.0
    # Commands take effect at whole-nanosecond simulation times, as in the node.
    on_ns = [Command(M.ns_to_seconds(M.seconds_to_ns(c.t)), c.changes) for c in schedule]
    reference = run_schedule(Slider(), on_ns, grid)
    x = np.array([m.pose.position.x for _, m in recording.decoded("pose")])
    v = np.array([m.twist.linear.x for _, m in recording.decoded("velocity")])
    assert np.max(np.abs(x - reference.x)) <= 1e-12 * np.max(np.abs(reference.x))
    assert np.max(np.abs(v - reference.v)) <= 1e-12 * np.max(np.abs(reference.v))
    means = recording.decoded("mean_velocity")
    assert len(means) > 10 and all(M.stamp_ns(m.header.stamp) == t for t, m in means)


def test_a_bad_message_is_dropped_without_ending_the_recording(tmp_path: Path) -> None:
    from std_msgs.msg import Float64, String

    path = tmp_path / "bad.mcap"
    with Recorder(path, metadata={"mass": 1.0}) as recorder:
        recorder.write("drive_force", Float64(data=0.5), 1)
        recorder.write("drive_force", String(data="not a force"), 2)  # another type on the same topic
        recorder.record_parameters({"odd": object()}, 0.0)  # no ROS parameter type holds this
        recorder.record_state(STATE)
    assert recorder.stats.dropped == 2 and recorder.stats.error is None
    recording = read_recording(path)
    assert recording.complete and len(recording.messages_on("drive_force")) == 1 and recording.dropped == 2
    assert len(recording.messages_on("pose")) == 1
