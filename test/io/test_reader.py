"""Reading recordings: an independent reader (rosbags) decodes every message
from the schema text stored in the file and agrees with ours; files whose
writer was killed or cut short are read up to their last complete record;
SIGINT/SIGTERM finish the file."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from friction_sim.cli.replay import run
from friction_sim.experiment.offline import record_offline
from friction_sim.io.reader import read_recording

from recording_helpers import plain, replay_args, rewrite, varied_schedule

ROOT = Path(__file__).resolve().parents[2]


def test_rosbags_decodes_every_message_from_the_stored_schema_text(tmp_path: Path) -> None:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    path = tmp_path / "run.mcap"
    stats = record_offline(path, schedule=varied_schedule(), duration=1.5)
    ours = read_recording(path)
    assert {"rejected_commands", "parameters", "external_wrench", "events", "mean_velocity"} <= {
        ours.relative_name(topic) for topic in ours.topics}
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


def test_a_file_cut_short_is_read_up_to_its_last_complete_chunk(real_recording: Path, tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    chunked = rewrite(real_recording, tmp_path / "chunked.mcap", chunk_size=16 * 1024)
    data = chunked.read_bytes()
    full = read_recording(chunked)
    assert full.complete and full.chunks > 10
    recovered = []
    for fraction in (0.25, 0.5, 0.75):  # the summary is in the last few %
        cut = tmp_path / f"cut{fraction}.mcap"
        size = int(len(data) * fraction)
        cut.write_bytes(data[:size])
        part = read_recording(cut)
        if part.truncated_bytes == 0:
            # The cut fell between two records: nothing is cut short (the file's wall-clock metadata
            # moves its records by a few bytes from run to run).  One byte on, it cuts one.
            cut.write_bytes(data[:size + 1])
            part = read_recording(cut)
        assert not part.complete and 0 < part.truncated_bytes < len(data)
        assert [m.log_time for m in part.messages] == [m.log_time for m in full.messages[:len(part.messages)]]
        recovered.append(part.end_ns)
        assert run(replay_args(cut, verify=True)) == 0, "what was recovered re-simulates exactly"
        err = capsys.readouterr().err
        assert err == f"recovered {len(part.messages)} messages up to t = {part.end_ns / 1e9:.6f} s; " \
                      "the file has no footer (writer killed?)\n"
    assert recovered == sorted(recovered) and recovered[0] < recovered[-1] < full.end_ns


# -- a writer that is killed or stopped --------------------------------------------------


CHILD = r"""
import os, signal, sys, time
from friction_sim.core.model.commands import Command
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.io.recorder import Recorder, plant_parameters, recording_metadata
from friction_sim.io.sinks import CommandRecord, ParametersRecord, deliver_tick

path, mode, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
params, inputs = SliderParams(), Inputs()

def stop(signum, frame):
    raise KeyboardInterrupt
signal.signal(signal.SIGTERM, stop)
# Ctrl-C raises KeyboardInterrupt, as in a terminal, even when this child was started with SIGINT
# ignored (Python then leaves it ignored: a test run from a background job of a shell hung here).
signal.signal(signal.SIGINT, signal.default_int_handler)

rt = RealtimeSlider(params, inputs, wall_ns=time.monotonic_ns(), log_rate=1000.0)
try:
    with Recorder(path, recording_metadata(params, inputs, log_rate=1000.0)) as recorder:
        recorder.write(ParametersRecord({**plant_parameters(params, inputs), "log_rate": 1000.0}, 0.0, False))
        started, n, announced = time.monotonic(), 0, False
        while True:
            now = time.monotonic_ns()
            if rt.slider.t >= 0.075 + 0.15 * n:  # a command every 0.15 s of simulation time
                command = Command(0.0, "drive_force", {"drive_force": 0.55 + 0.03 * (n % 7)})
                recorder.write(CommandRecord(rt.command(command, now), ""))
                n += 1
            deliver_tick([recorder], rt.tick(now), "slideway")
            if not announced and time.monotonic() - started >= seconds:
                print(repr(rt.slider.t), flush=True)  # once: a signal must not cut a second print
                announced = True
                if mode == "kill":
                    os.kill(os.getpid(), signal.SIGKILL)
            time.sleep(0.001)  # the child's pace until the signal comes
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
