"""Recording faults: a path that cannot be written is one error at start; a
disk that fills during a run (for real: RLIMIT_FSIZE in a child process,
/dev/full, a file that fails after N bytes) stops the recording with one
accurate message, never blocks the producer afterwards, never raises from
finish(), and leaves a file that reads and verifies up to its last chunk."""

from __future__ import annotations

import dataclasses
import errno
import json
import logging
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from friction_sim.core.model.events import Mode, SliderState
from friction_sim.errors import RecordingPathError
from friction_sim.io.reader import read_recording
from friction_sim.io.recorder import Recorder
from friction_sim.io.sinks import StatesRecord

STATE = SliderState(t=0.0, x=1.5e-4, v=-2.5e-3, acceleration=0.3, friction_force=-0.95, normal_force=9.5,
                    phase=1.0, mode=Mode.BACKWARD)
FAILED = re.compile(r"^recording failed: \[Errno (\d+)\] ([^\[\]]+) writing (\S+) after (\d+) messages"
                    r"(?: \(t = (\d+\.\d{3}) s\))?; the run goes on unrecorded$")


def states(first: int, n: int) -> list[SliderState]:
    return [dataclasses.replace(STATE, t=k * 1e-3) for k in range(first, first + n)]


def writer_threads() -> int:
    return sum(thread.name == "mcap_writer" for thread in threading.enumerate())


def assert_not_chained(error: BaseException) -> None:
    chained = error.__cause__ or (None if error.__suppress_context__ else error.__context__)
    assert chained is None, "nothing chained: a traceback would show it"


# -- at start -------------------------------------------------------------------------------


def test_dev_full_is_one_error_at_start(capfd: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture) -> None:
    before = writer_threads()
    with pytest.raises(RecordingPathError) as error:
        Recorder("/dev/full", metadata={"mass": 1.0})
    assert str(error.value) == "log_path = '/dev/full' rejected: cannot write there: [Errno 28] No space left on device"
    assert (error.value.field, error.value.value) == ("log_path", "/dev/full")
    assert_not_chained(error.value)
    assert capfd.readouterr() == ("", ""), "nothing printed"
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING], "nothing logged: the caller reports it"
    assert writer_threads() == before, "no thread left behind"


def test_a_directory_or_a_path_ending_in_a_slash_is_refused_not_made_a_file(tmp_path: Path) -> None:
    for bad in (f"{tmp_path}/new/", f"{tmp_path}/new.mcap/", str(tmp_path), f"{tmp_path}/"):
        with pytest.raises(RecordingPathError) as error:
            Recorder(bad, setting="path")
        assert str(error.value).startswith(f"path = '{bad}' rejected: names a directory, not a file (e.g. ")
        assert_not_chained(error.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == [], "nothing made"
    with pytest.raises(RecordingPathError, match=r"^log_path = '' rejected: give a file name"):
        Recorder("")
    missing = tmp_path / "no" / "run.mcap"
    with pytest.raises(RecordingPathError, match=re.escape(
            f"log_path = '{missing}' rejected: cannot write there: [Errno 2] No such file or directory")):
        Recorder(missing)


# -- a disk that fills: a child process with a file size limit -------------------------------

CHILD = r"""
import json, logging, resource, signal, sys, time
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit then fails with EFBIG
path, limit, ticks = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
records = []
handler = logging.Handler()
handler.emit = records.append
logging.getLogger("friction_sim").addHandler(handler)
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.errors import RecordingPathError
from friction_sim.io.recorder import Recorder, plant_parameters, recording_metadata
from friction_sim.io.sinks import ParametersRecord, deliver_tick
params, inputs = SliderParams(), Inputs()
try:
    recorder = Recorder(path, recording_metadata(params, inputs, log_rate=1000.0), flush_interval=0.02,
                        chunk_size=8192, queue_size=3000)
except RecordingPathError as error:
    print(json.dumps({"start_error": str(error)}))
    sys.exit(0)
recorder.write(ParametersRecord({**plant_parameters(params, inputs), "log_rate": 1000.0, "frame_id": "slideway",
                                 "mean_window_periods": 1}, 0.0, False))
rt = RealtimeSlider(params, inputs, wall_ns=0, real_time_factor=10.0, log_rate=1000.0)
waits_after, puts_after, failed_at = 0, 0, None
for k in range(1, ticks + 1):
    tick = rt.tick(k * 1_000_000)
    failed = recorder.queue.failed
    waits = recorder.queue.waits
    deliver_tick([recorder], tick, "slideway")
    if failed:
        waits_after += recorder.queue.waits - waits
        puts_after += 1
        failed_at = k if failed_at is None else failed_at
    if k % 20 == 0:
        time.sleep(0.005)  # let the writer write (and fail) while the run goes on
try:
    stats = recorder.finish()
    raised = None
except BaseException as error:
    raised = repr(error)
print(json.dumps({
    "error": recorder.error, "raised": raised, "stats_error": stats.error, "messages": stats.messages,
    "unrecorded": stats.unrecorded, "dropped": stats.dropped, "last_ns": stats.last_ns,
    "waits_after": waits_after, "puts_after": puts_after, "failed_at": failed_at, "ticks": ticks,
    "logged": [[r.levelname, r.getMessage()] for r in records],
}))
"""


def run_child(path: Path, limit: int, ticks: int) -> dict[str, Any]:
    done = subprocess.run([sys.executable, "-c", CHILD, str(path), str(limit), str(ticks)], capture_output=True,
                          text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def test_a_file_limit_at_start_is_one_error_and_leaves_no_file(tmp_path: Path) -> None:
    path = tmp_path / "small.mcap"
    result = run_child(path, 100, 10)  # not even the header fits
    assert result == {"start_error": f"log_path = '{path}' rejected: cannot write there: [Errno 27] File too large"}
    assert not path.exists(), "a file that holds nothing usable is removed"


def test_disk_full_during_a_run_one_message_no_blocking_and_the_part_written_verifies(tmp_path: Path) -> None:
    path = tmp_path / "full.mcap"
    result = run_child(path, 120_000, 1500)  # ~120 kB: fills after about a simulated second
    error = result["error"]
    match = FAILED.match(error or "")
    assert match, error
    assert match.group(1) == str(errno.EFBIG) and match.group(2) == "File too large" and match.group(3) == str(path)
    assert result["raised"] is None and result["stats_error"] == error, "finish() returns the error, never raises"
    assert result["logged"] == [["ERROR", error]], "one message, logged once; never 'falls behind'"
    assert result["failed_at"] is not None and result["failed_at"] < result["ticks"] - 100, "it failed mid-run"
    assert result["puts_after"] > 100 and result["unrecorded"] > 0 and result["dropped"] == 0
    assert result["waits_after"] == 0, "a failed recording never makes the producer wait (the recorder counts waits)"
    assert path.stat().st_size <= 120_000

    # The message tells the truth about the file: that many messages, up to that time.
    recording = read_recording(path)
    assert not recording.complete
    assert recording.message_count == result["messages"] == int(match.group(4)) > 1000
    last_pose = max(raw.log_time for raw in recording.iter_messages(["pose"]))
    assert match.group(5) == f"{result['last_ns'] / 1e9:.3f}" and last_pose <= result["last_ns"]
    done = subprocess.run([sys.executable, "-m", "friction_sim.cli.main", "replay", str(path), "--verify"],
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0 and "reproducible" in done.stdout, done.stdout + done.stderr


# -- a file that fails after N bytes, in process -------------------------------------------


class FailingFile:
    """An unbuffered file that takes ``room`` bytes, part of a write if need
    be, then fails every write with ``code`` (a disk that fills)."""

    def __init__(self, path: Path, room: int, code: int) -> None:
        self._file = path.open("wb", buffering=0)
        self.room = room
        self.code = code

    def write(self, data: Any) -> int:
        if self.room <= 0:
            raise OSError(self.code, os.strerror(self.code))
        taken = self._file.write(bytes(data[:self.room]))
        self.room -= taken
        return taken

    def fileno(self) -> int:
        return self._file.fileno()

    def close(self) -> None:
        self._file.close()


class FillingRecorder(Recorder):
    room = 60_000
    code = errno.ENOSPC

    def _open(self) -> Any:
        return FailingFile(self.path, self.room, self.code)


def test_a_disk_that_fills_wakes_a_waiting_producer_and_later_puts_are_counted_no_ops(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    path = tmp_path / "enospc.mcap"
    recorder = FillingRecorder(path, metadata={"mass": 1.0}, queue_size=300, chunk_size=4096, flush_interval=0.02)
    produced = threading.Event()

    def produce() -> None:
        for first in range(0, 40_000, 100):
            # 300 messages: the queue holds one such put
            recorder.write(StatesRecord(tuple(states(first, 100)), "slideway"))
        produced.set()

    producer = threading.Thread(target=produce)
    producer.start()
    assert produced.wait(30.0), "the producer is never stuck behind a failed writer"
    producer.join()
    assert recorder.queue.failed and recorder.queue.waits >= 1, "it did wait while the writer worked"
    match = FAILED.match(recorder.error or "")
    assert match and match.group(1) == str(errno.ENOSPC) and match.group(2) == "No space left on device", recorder.error
    written = int(match.group(4))
    assert written > 0 and recorder.dropped == 0
    assert written + recorder.queue.unrecorded == 120_000, "every message is in the file or counted"
    before, waits = recorder.queue.unrecorded, recorder.queue.waits
    recorder.write(StatesRecord(tuple(states(50_000, 1000)), "slideway"))
    assert recorder.queue.waits == waits and recorder.queue.unrecorded == before + 3000, "refused at once, counted"
    stats = recorder.finish()
    assert stats.error == recorder.error and stats.messages == written and recorder.finish() is stats
    errors = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert [r.getMessage() for r in errors] == [recorder.error], "one message; never 'falls behind'"
    recording = read_recording(path)
    assert recording.message_count == written and not recording.complete
    assert len(recording.messages_on("pose")) == written // 3


class CrashingRecorder(Recorder):
    """A writer thread that waits for ``gate`` and then fails with a bug, not an OSError."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.gate = threading.Event()
        super().__init__(*args, **kwargs)

    def _write_batch(self, batch: Any) -> None:
        self.gate.wait(10.0)
        raise RuntimeError("a bug in the writer")


def test_a_writer_that_crashes_releases_the_waiting_producer(tmp_path: Path) -> None:
    recorder = CrashingRecorder(tmp_path / "crash.mcap", metadata={"mass": 1.0}, queue_size=9)
    done = threading.Event()
    producer = threading.Thread(target=lambda: (
        recorder.write(StatesRecord(tuple(states(0, 100)), "slideway")),
        [recorder.write(StatesRecord((s,), "slideway")) for s in states(100, 50)], done.set()))
    producer.start()
    assert not done.wait(0.5), "the producer waits while the writer works"
    recorder.gate.set()
    assert done.wait(10.0), "a failed writer releases the producer"
    producer.join()
    assert recorder.error is not None and recorder.error.startswith(
        "recording failed: RuntimeError: a bug in the writer writing ")
    stats = recorder.finish()
    assert stats.error == recorder.error and stats.messages == 0 and stats.unrecorded >= 3
    assert read_recording(tmp_path / "crash.mcap", require_friction_sim=False).message_count == 0


class GoneRecorder(Recorder):
    """A writer thread that ends at once without a word (what _run never does)."""

    def _run(self) -> None:
        return


def test_a_producer_never_waits_for_a_writer_thread_that_is_gone(tmp_path: Path) -> None:
    recorder = GoneRecorder(tmp_path / "gone.mcap", metadata={"mass": 1.0}, queue_size=9)
    while recorder.writer_alive:
        time.sleep(0.01)  # poll interval: waiting for the writer to go
    for state in states(0, 10):  # a wait on a full queue nobody empties would never end
        recorder.write(StatesRecord((state,), "slideway"))
    assert recorder.dropped == 3 * 7, "3 states fit in the queue; the rest is counted"
    assert recorder.finish().dropped == 30, "and the 3 states no writer took are counted at finish"


def test_a_disk_that_fills_at_finish_is_reported_by_finish_not_raised(tmp_path: Path) -> None:
    path = tmp_path / "late.mcap"

    probe = Recorder(tmp_path / "probe.mcap", metadata={"mass": 1.0})
    start = (tmp_path / "probe.mcap").stat().st_size  # the header and the metadata, written at once
    probe.finish()

    class LateRecorder(FillingRecorder):
        room = start + 10  # what is written at start fits, the first chunk does not

    recorder = LateRecorder(path, metadata={"mass": 1.0}, flush_interval=3600.0)  # nothing written before finish
    recorder.write(StatesRecord(tuple(states(0, 10)), "slideway"))
    assert recorder.error is None
    stats = recorder.finish()
    assert stats.error == recorder.error and stats.error is not None
    match = FAILED.match(stats.error)
    assert match and match.group(4) == "0" and match.group(5) is None, stats.error
    assert stats.unrecorded == 30 and stats.messages == 0
    recording = read_recording(path, require_friction_sim=False)
    assert recording.message_count == 0 and not recording.complete and "mass" in recording.metadata["friction_sim"]
