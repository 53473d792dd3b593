"""What the readers do with what a recording says about itself: messages the
recorder dropped (refused, never summarised; issue 10, item 12) and topic
names stored fully qualified the way rosbag2 does, or relative as older
files have them (item 10)."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from friction_sim.cli.main import main
from friction_sim.cli.recording_figure import command_marks
from friction_sim.cli.replay import run
from friction_sim.errors import RecordingError
from friction_sim.experiment.report import build_report, run_data_from_recording
from friction_sim.experiment.verify import verify
from friction_sim.io.reader import Channel, Recording, read_recording
from friction_sim.io.recorder import SUMMARY_METADATA_NAME

from recording_helpers import copy_recording, replay_args

# -- dropped messages ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def with_drops(real_recording: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The real recording less a command and every 7th pose, with the summary
    record the recorder writes when it dropped them."""
    source = read_recording(real_recording)
    first_command = source.messages_on("drive_force")[0].log_time
    poses = [raw.log_time for raw in source.messages_on("pose")][::7]
    lost = {("drive_force", first_command), *(("pose", t) for t in poses)}
    kept = source.message_count - len(lost)
    return copy_recording(real_recording, tmp_path_factory.mktemp("drops") / "drops.mcap",
                          keep=lambda topic, t: (topic.lstrip("/"), t) not in lost,
                          metadata={SUMMARY_METADATA_NAME: {"messages": str(kept), "dropped": str(len(lost))}})


def test_verify_and_report_refuse_a_file_with_drops_in_one_line(with_drops: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    dropped = read_recording(with_drops).dropped
    assert dropped is not None and dropped > 200
    for command, what in ((["replay", str(with_drops), "--verify"], "verified"),
                          (["report", str(with_drops), "--output", str(with_drops.parent / "out")], "summarised")):
        assert main(command) == 2
        captured = capsys.readouterr()
        assert captured.out == "", "never a summary or a verdict"
        assert captured.err == (f"friction-sim {command[0]}: error: {with_drops}: {dropped} messages were dropped "
                                f"while recording; the file cannot be {what}\n")
    assert not (with_drops.parent / "out").exists()
    with pytest.raises(RecordingError, match="cannot be verified"):
        verify(read_recording(with_drops))
    assert run(replay_args(with_drops)) == 0, "describing it is fine"
    assert f"Dropped:    {dropped} messages while recording" in capsys.readouterr().out


def test_a_file_without_a_summary_record_still_verifies_what_it_holds(real_recording: Path, tmp_path: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    copy = copy_recording(real_recording, tmp_path / "copy.mcap", chunk_size=16 * 1024,
                          without=(SUMMARY_METADATA_NAME, "rosbag2"))  # as a file never finished
    data = copy.read_bytes()
    cut = tmp_path / "cut.mcap"  # the writer died (disk full, SIGKILL): no footer, no summary record
    cut.write_bytes(data[:len(data) * 2 // 3])
    recording = read_recording(cut)
    assert not recording.complete and recording.dropped is None and recording.message_count > 0
    assert main(["replay", str(cut), "--verify"]) == 0
    assert capsys.readouterr().out.rstrip().endswith("reproducible (tolerance 1e-09 relative)")


# -- topic names ------------------------------------------------------------------------------


@pytest.mark.parametrize("style", ["relative", "root", "namespaced"])
def test_every_reader_takes_old_relative_and_fully_qualified_names(real_recording: Path, tmp_path: Path, style: str,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    prefix = {"relative": "", "root": "/", "namespaced": "/feeder1/"}[style]
    path = copy_recording(real_recording, tmp_path / f"{style}.mcap", topic=lambda name: prefix + name.lstrip("/"))
    recording = read_recording(path)
    assert set(recording.topics) == {prefix + name.lstrip("/") for name in read_recording(real_recording).topics}
    assert recording.namespace_prefix == prefix
    for name in ("pose", "/pose", prefix + "pose"):
        assert recording.topic_name(name) == prefix + "pose"
    reference = read_recording(real_recording)
    assert len(recording.messages_on("pose")) == reference.count("pose") == recording.count("pose") == 2001
    result = verify(recording)
    assert result.passed and result.commands == verify(reference).commands > 10
    assert command_marks(recording) == command_marks(reference)
    rows = build_report(run_data_from_recording(path))
    assert len(rows) > 10 and repr(rows) == repr(build_report(run_data_from_recording(real_recording)))
    assert run(replay_args(path, csv=tmp_path / "csv", topics=["/pose", "rejected_commands"])) == 0
    assert sorted(p.name for p in (tmp_path / "csv").iterdir()) == ["pose.csv", "rejected_commands.csv"]
    with (tmp_path / "csv" / "pose.csv").open() as stream:
        assert len(list(csv.DictReader(stream))) == 2001
    assert run(replay_args(path)) == 0
    assert f"Topics:     {prefix}parameters" in capsys.readouterr().out


def test_a_relative_name_picks_the_recorded_nodes_namespace(tmp_path: Path) -> None:
    def channel(cid: int, topic: str, type_name: str) -> Channel:
        return Channel(cid, topic, type_name, "cdr", {})

    recording = Recording(tmp_path / "x.mcap", channels={
        1: channel(1, "/other/events", "diagnostic_msgs/msg/DiagnosticStatus"),
        2: channel(2, "/feeder1/pose", "geometry_msgs/msg/PoseStamped"),
        3: channel(3, "/feeder1/events", "diagnostic_msgs/msg/DiagnosticStatus"),
        4: channel(4, "/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"),
    }, counts={1: 5, 2: 100, 3: 7, 4: 3})
    assert recording.topic_name("events") == "/feeder1/events"
    assert recording.topic_name("/other/events") == "/other/events"
    assert recording.topic_name("diagnostics") == "/diagnostics"
    assert recording.topic_name("velocity") is None
    assert recording.relative_name("/feeder1/events") == "events"
