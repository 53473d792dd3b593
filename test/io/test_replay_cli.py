"""``friction-sim replay``: CSV and plot export, the description of a
recording, one-line errors with exit code 2."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from friction_sim.cli.main import main
from friction_sim.cli.recording_figure import command_marks, plot
from friction_sim.cli.replay import run
from friction_sim.errors import RecordingError
from friction_sim.io.reader import read_recording

from recording_helpers import replay_args

# -- export -----------------------------------------------------------------------------


def test_csv_has_one_file_per_topic_with_every_field(real_recording: Path, tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    recording = read_recording(real_recording)
    assert run(replay_args(real_recording, csv=tmp_path / "csv")) == 0
    assert f"wrote {len(recording.topics)} CSV files" in capsys.readouterr().out
    files = {path.stem: path for path in (tmp_path / "csv").glob("*.csv")}
    assert set(files) == {recording.relative_name(topic) for topic in recording.topics}
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
    assert json.loads(refused[0]["values"]) == [{"key": "excitation_amplitude", "value": "-4.0"}]
    with files["parameters"].open() as stream:
        events = list(csv.DictReader(stream))
    names = [p["name"] for p in json.loads(events[0]["new_parameters"])]
    assert {"mass", "mu", "gravity", "drive_force", "excitation_amplitude"} <= set(names)


def test_plot_marks_every_command(real_recording: Path, tmp_path: Path) -> None:
    recording = read_recording(real_recording)
    marks = command_marks(recording)
    labels = [label for _, label, _ in marks]
    assert "refused excitation_amplitude" in labels
    assert "mass = 1.3" in labels, "a plant change carries the fields it changed"
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
        assert main(["replay", str(path), "--verify"]) == 2
        captured = capsys.readouterr()
        assert captured.err == f"friction-sim replay: error: {words}: {path}\n" and captured.out == ""
