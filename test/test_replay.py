"""Replay: --verify on real and tampered recordings, reading files cut short,
--publish timing over real topics, CSV and plot export, one-line errors."""

from __future__ import annotations

import argparse
import csv
import io
import json
import threading
import time
import uuid
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor

from friction_sim.io import messages as M
from friction_sim.errors import RecordingError
from friction_sim.core.params import Inputs, SliderParams
from friction_sim.io.recording import METADATA_NAME, Recorder, record_offline
from friction_sim.io.replay import command_marks, export_csv, main, plot, publish, read_recording, run, verify
from friction_sim.core.simulation import Command, random_schedule


def replay_args(path: Path, **options: Any) -> argparse.Namespace:
    defaults = dict(file=path, verify=False, tolerance=1e-9, publish=False, rate=1.0, loop=False, topics=None,
                    namespace="", delay=0.0, csv=None, plot=None)
    defaults.update(options)
    return argparse.Namespace(**defaults)


def rewrite(source: Path, target: Path, edit: Callable[[str, int, Any], Any] = lambda topic, t, msg: msg,
            **recorder_options: Any) -> Path:
    """Copy a recording message by message; ``edit`` may change a message or
    drop it (None)."""
    recording = read_recording(source)
    with Recorder(target, metadata=recording.metadata[METADATA_NAME], **recorder_options) as out:
        for raw in recording.messages:
            msg = edit(raw.topic, raw.log_time, recording.decode(raw))
            if msg is not None:
                out.write(raw.topic, msg, raw.log_time)
    return target


@pytest.fixture(scope="module")
def real_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """2 s at 1 kHz with random commands, external forces, a refused command
    and a plant change."""
    path = tmp_path_factory.mktemp("rec") / "run.mcap"
    schedule = random_schedule(np.random.default_rng(21), 2.0, external=True)
    schedule += [Command(0.7, {"excitation_amplitude": 40.0}), Command(1.1, {"mass": 1.3})]
    record_offline(path, schedule=schedule, duration=2.0)
    return path


# -- verify ---------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_verify_passes_on_recordings_of_random_schedules(tmp_path: Path, seed: int,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(seed)
    params = SliderParams(mass=float(rng.uniform(0.5, 2.0)), mu=float(rng.uniform(0.05, 0.3)))
    inputs = Inputs(drive_force=float(rng.uniform(-0.5, 0.5)) * params.mu * params.weight,
                    excitation_amplitude=float(rng.uniform(0.1, 0.8)) * params.weight)
    schedule = random_schedule(rng, 1.5, weight=params.weight, external=bool(seed % 2))
    path = tmp_path / "run.mcap"
    record_offline(path, params, inputs, schedule, duration=1.5, log_rate=float(rng.choice([1000.0, 2500.0, 300.0])))
    result = verify(read_recording(path))
    assert result.passed and result.samples > 400 and result.commands >= len(schedule)
    assert result.rel_dx <= 1e-9 and result.rel_dv <= 1e-9 and result.x_scale > 0.0
    assert run(replay_args(path, verify=True)) == 0
    out = capsys.readouterr().out
    assert "largest position difference" in out and "largest velocity difference" in out
    assert out.rstrip().endswith("reproducible (tolerance 1e-09 relative)")


def test_verify_fails_on_a_tampered_copy(real_recording: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    recording = read_recording(real_recording)
    poses = recording.decoded("pose")
    worst_t, worst = max(poses, key=lambda item: abs(item[1].pose.position.x))

    def nudge(topic: str, t: int, msg: Any) -> Any:
        if topic == "pose" and t == worst_t:
            msg.pose.position.x *= 1.0 + 1e-6
        return msg

    untouched = rewrite(real_recording, tmp_path / "copy.mcap")
    assert run(replay_args(untouched, verify=True)) == 0, "copying alone keeps it reproducible"
    tampered = rewrite(real_recording, tmp_path / "tampered.mcap", nudge)
    capsys.readouterr()
    assert run(replay_args(tampered, verify=True)) == 1
    out = capsys.readouterr().out
    assert "NOT reproducible" in out and f"at t = {worst_t / 1e9:.6f} s" in out
    result = verify(read_recording(tampered))
    assert result.rel_dx == pytest.approx(1e-6, rel=1e-3) and result.rel_dv == 0.0


def test_verify_fails_when_a_command_is_missing(real_recording: Path, tmp_path: Path) -> None:
    recording = read_recording(real_recording)
    x = {t: msg.pose.position.x for t, msg in recording.decoded("pose")}
    times = [raw.log_time for raw in recording.messages_on("drive_force")] + [recording.end_ns]

    def travel(k: int) -> float:  # motion between command k and the next, to the nearest samples
        start, end = (max(t for t in x if t <= when) for when in times[k:k + 2])
        return abs(x[end] - x[start])

    dropped = times[max(range(len(times) - 1), key=travel)]  # the command that mattered most
    copy = rewrite(real_recording, tmp_path / "lost.mcap",
                   lambda topic, t, msg: None if topic == "drive_force" and t == dropped else msg)
    result = verify(read_recording(copy))
    assert not result.passed and result.worst_dx_t >= dropped / 1e9
    assert run(replay_args(copy, verify=True)) == 1


def test_a_file_cut_short_is_read_up_to_its_last_complete_chunk(real_recording: Path, tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    chunked = rewrite(real_recording, tmp_path / "chunked.mcap", chunk_size=16 * 1024)
    data = chunked.read_bytes()
    full = read_recording(chunked)
    assert full.complete and full.chunks > 10
    recovered = []
    for fraction in (0.25, 0.5, 0.75):  # the summary is in the last few %
        cut = tmp_path / f"cut{fraction}.mcap"
        cut.write_bytes(data[:int(len(data) * fraction)])
        part = read_recording(cut)
        assert not part.complete and 0 < part.truncated_bytes < len(data)
        assert [m.log_time for m in part.messages] == [m.log_time for m in full.messages[:len(part.messages)]]
        recovered.append(part.end_ns)
        assert run(replay_args(cut, verify=True)) == 0, "what was recovered re-simulates exactly"
        err = capsys.readouterr().err
        assert err == f"recovered {len(part.messages)} messages up to t = {part.end_ns / 1e9:.6f} s; " \
                      "the file has no footer (writer killed?)\n"
    assert recovered == sorted(recovered) and recovered[0] < recovered[-1] < full.end_ns


# -- publish ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def ros() -> Iterator[None]:
    rclpy.init()
    yield
    rclpy.try_shutdown()


def test_publish_keeps_the_recorded_timing(ros: None, tmp_path: Path) -> None:
    path = tmp_path / "short.mcap"
    record_offline(path, schedule=[Command(0.3, {"drive_force": 0.9}), Command(0.62, {"drive_force": 0.6})],
                   duration=1.0, log_rate=100.0)
    recording = read_recording(path)
    topics = ["pose", "velocity", "events", "drive_force"]
    namespace = f"/replay_{uuid.uuid4().hex[:8]}"
    listener = rclpy.create_node("listener", namespace=namespace)
    arrivals: dict[str, list[tuple[float, Any]]] = {topic: [] for topic in topics}

    def keeper(topic: str) -> Callable[[Any, Any], None]:
        # The time the middleware received the sample (not when the executor got to it).
        return lambda msg, info: arrivals[topic].append((info["received_timestamp"] / 1e9, msg))

    for topic in topics:
        listener.create_subscription(recording.message_type(topic), topic, keeper(topic), 200)
    executor = SingleThreadedExecutor()
    executor.add_node(listener)
    outcome: dict[str, Any] = {}
    player = threading.Thread(target=lambda: outcome.update(result=publish(
        recording, topics=topics, namespace=namespace, wait_for_subscribers=1, wait_timeout=10.0, delay=0.3)))
    expected = {topic: recording.decoded(topic) for topic in topics}
    total = sum(len(v) for v in expected.values())
    try:
        player.start()
        deadline = time.monotonic() + 20.0
        while sum(len(v) for v in arrivals.values()) < total and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.002)
        player.join(timeout=10.0)
    finally:
        executor.shutdown(timeout_sec=0.0)
        listener.destroy_node()
    assert outcome["result"].messages == total
    pairs = []  # (recorded log time [s], arrival [s]); reliable topics arrive in order
    for topic in topics:
        assert len(arrivals[topic]) == len(expected[topic]), topic
        for (log_time, sent), (arrived, received) in zip(expected[topic], arrivals[topic]):
            assert received == sent, topic
            pairs.append((log_time / 1e9, arrived))
    pairs.sort()
    # Timing error: each arrival's offset from the typical offset (the median, so one late first message
    # does not shift them all). Deadlines are absolute, so errors do not add up; on a loaded CI machine a
    # few messages may still arrive late, which the 90th percentile tolerates and the maximum bounds.
    offsets = [arrived - recorded for recorded, arrived in pairs]
    typical = float(np.median(offsets))
    errors = np.sort([abs(offset - typical) for offset in offsets])
    p90 = errors[int(0.9 * len(errors))]
    assert p90 <= 0.003, f"90th percentile timing error {p90 * 1e3:.2f} ms"
    assert errors[-1] <= 0.05, f"largest timing error {errors[-1] * 1e3:.2f} ms"
    half = len(offsets) // 2
    drift = float(np.median(offsets[half:]) - np.median(offsets[:half]))
    assert abs(drift) <= 0.002, f"the second half runs {drift * 1e3:.2f} ms behind the first"
    assert pairs[-1][0] - pairs[0][0] == pytest.approx(1.0)


def test_publish_loops_at_a_faster_rate_and_reports_progress(ros: None, tmp_path: Path) -> None:
    path = tmp_path / "short.mcap"
    record_offline(path, duration=0.5, log_rate=100.0)
    recording = read_recording(path)
    stop = threading.Event()
    threading.Timer(1.5, stop.set).start()
    progress = io.StringIO()
    started = time.monotonic()
    result = publish(recording, rate=5.0, loop=True, topics=["/pose"], stop=stop, progress=progress)
    assert time.monotonic() - started < 5.0, "the stop event ends it"
    # At x1 a 0.5 s recording loops at most 3 times in 1.5 s; x5 manages about 15.
    assert result.loops >= 6 and result.messages >= 5 * 51 and result.interrupted
    assert "replay:" in progress.getvalue() and "x5 " in progress.getvalue()
    with pytest.raises(RecordingError, match="no topic warp"):
        publish(recording, topics=["warp"])


# -- export -----------------------------------------------------------------------------


def test_csv_has_one_file_per_topic_with_every_field(real_recording: Path, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    recording = read_recording(real_recording)
    assert run(replay_args(real_recording, csv=tmp_path / "csv")) == 0
    assert f"wrote {len(recording.topics)} CSV files" in capsys.readouterr().out
    files = {path.stem: path for path in (tmp_path / "csv").glob("*.csv")}
    assert set(files) == set(recording.topics)
    with files["pose"].open() as stream:
        rows = list(csv.DictReader(stream))
    poses = recording.decoded("pose")
    assert len(rows) == len(poses)
    assert {"log_time_ns", "t", "header.stamp.sec", "header.frame_id", "pose.position.x",
            "pose.orientation.w"} <= set(rows[0])
    for row, (t, msg) in zip(rows, poses):
        assert int(row["log_time_ns"]) == t and float(row["pose.position.x"]) == msg.pose.position.x
    with files["rejected_commands"].open() as stream:
        refused = list(csv.DictReader(stream))
    assert refused[0]["name"] == "excitation_amplitude" and refused[0]["level"] == "1"
    assert json.loads(refused[0]["values"]) == [{"key": "excitation_amplitude", "value": "40.0"}]
    with files["parameters"].open() as stream:
        events = list(csv.DictReader(stream))
    names = [p["name"] for p in json.loads(events[0]["new_parameters"])]
    assert {"mass", "mu", "gravity", "drive_force", "excitation_amplitude"} <= set(names)


def test_plot_marks_every_command(real_recording: Path, tmp_path: Path) -> None:
    recording = read_recording(real_recording)
    marks = command_marks(recording)
    labels = [label for _, label, _ in marks]
    assert "refused excitation_amplitude" in labels
    assert "mass = 1.3, mu = 0.1, gravity = 10.0" in labels, "a plant change carries the whole plant"
    assert sum(1 for _, _, accepted in marks if not accepted) == 1
    figure = plot(recording)
    axes = figure.axes
    assert len(axes) == 4
    assert [ax.get_ylabel() for ax in axes] == ["position x [mm]", "velocity v [mm/s]", "friction force [N]",
                                              "normal force R [N]"]
    assert len(axes[3].lines) == 1 + len(marks), "the R trace and one line per command"
    picture = tmp_path / "out" / "run.png"
    assert run(replay_args(real_recording, plot=picture)) == 0
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_without_an_action_it_describes_the_recording(real_recording: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    assert run(replay_args(real_recording)) == 0
    out = capsys.readouterr().out
    assert "Topics:" in out and "geometry_msgs/msg/PoseStamped" in out and "2001" in out
    assert "Time:       0.000000 .. 2.000000 s" in out


# -- errors -------------------------------------------------------------------------------


def test_errors_are_one_line_and_exit_code_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from mcap.writer import Writer

    text = tmp_path / "notes.mcap"
    text.write_text("these are notes, not a recording\n")
    foreign = tmp_path / "foreign.mcap"
    with foreign.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile="ros2", library="someone else")
        schema = writer.register_schema("std_msgs/msg/String", "ros2msg", b"string data\n")
        channel = writer.register_channel("chatter", "cdr", schema)
        writer.add_message(channel, 1, b"\x00\x01\x00\x00\x03\x00\x00\x00hi\x00\x00", 1)
        writer.finish()
    cases = [(tmp_path / "missing.mcap", "no such file"), (text, "not an MCAP file"),
             (foreign, "not a friction_sim recording (no friction_sim metadata record)"),
             (tmp_path, "is a directory, not a recording")]
    for path, words in cases:
        with pytest.raises(RecordingError, match=words.replace("(", r"\(").replace(")", r"\)")):
            run(replay_args(path, verify=True))
        assert main([str(path), "--verify"]) == 2
        captured = capsys.readouterr()
        assert captured.err == f"friction-sim replay: error: {words}: {path}\n" and captured.out == ""
