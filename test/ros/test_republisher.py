"""--publish: the recorded messages on real topics with the recorded timing."""

from __future__ import annotations

import io
import itertools
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor

from friction_sim.cli.progress import TerminalProgress
from friction_sim.core.model.commands import Command
from friction_sim.errors import RecordingError
from friction_sim.experiment.offline import record_offline
from friction_sim.io.reader import read_recording
from friction_sim.io.sinks import StatesRecord
from friction_sim.ros.republisher import publish

from recording_helpers import plain


def test_publish_keeps_the_recorded_timing(ros: None, tmp_path: Path) -> None:
    path = tmp_path / "short.mcap"
    record_offline(path, schedule=[Command(0.3, "drive_force", {"drive_force": 0.9}),
                                   Command(0.62, "drive_force", {"drive_force": 0.6})],
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
            assert plain(received) == plain(sent), topic  # an rclpy message received, a rosbags one decoded
            pairs.append((log_time / 1e9, arrived))
    pairs.sort()
    # Real time, without asserting this machine's speed (bench/replay.py measures the
    # timing error): no message goes out before its time, so the arrivals span at
    # least the recorded second, less the lateness of the first one.
    assert pairs[-1][0] - pairs[0][0] == pytest.approx(1.0)
    assert pairs[-1][1] - pairs[0][1] >= 1.0 - outcome["result"].max_late - 0.001


def spy_on_publishers(monkeypatch: pytest.MonkeyPatch, before_each: Callable[[], None]) -> None:
    """Call ``before_each()`` before every message the republisher publishes (on its real publishers)."""
    from friction_sim.ros import republisher

    made = republisher._publishers  # noqa: SLF001 - the spy wraps what it makes

    class Spy:
        def __init__(self, publisher: Any) -> None:
            self.publisher = publisher

        def publish(self, data: Any) -> None:
            before_each()
            self.publisher.publish(data)

    monkeypatch.setattr(republisher, "_publishers",
                        lambda *args, **kw: {k: Spy(v) for k, v in made(*args, **kw).items()})


class VirtualTime:
    """A stand-in for the ``time`` module on a clock of its own: ``sleep`` moves
    it on by what was asked plus an oversleep drawn in [0, ``oversleep``),
    as a busy machine would."""

    def __init__(self, oversleep: float, seed: int = 1) -> None:
        self.now, self.oversleep = 1000.0, oversleep
        self.rng = np.random.default_rng(seed)

    def monotonic(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += max(seconds, 0.0) + self.oversleep * float(self.rng.random())


@pytest.mark.parametrize("rate", [1.0, 2.5])
def test_publish_keeps_the_recorded_timing_on_its_clock(ros: None, tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch, rate: float) -> None:
    """Exactly, on a virtual clock that oversleeps up to 2 ms at every sleep: each
    message goes out at the start plus its recorded time / rate, late by no more
    than one oversleep, and lateness never adds up (absolute deadlines)."""
    from friction_sim.ros import republisher

    path = tmp_path / "short.mcap"
    record_offline(path, schedule=[Command(0.3, "drive_force", {"drive_force": 0.9})], duration=1.0, log_rate=100.0)
    recording = read_recording(path)
    clock = VirtualTime(oversleep=0.002)
    monkeypatch.setattr(republisher, "time", clock)
    sent: list[float] = []
    spy_on_publishers(monkeypatch, lambda: sent.append(clock.now))
    topics = ["pose", "velocity", "events", "drive_force"]
    result = publish(recording, rate=rate, topics=topics)
    recorded = sorted(log / 1e9 for topic in topics for log, _ in recording.decoded(topic))
    assert result.messages == len(recorded) == len(sent)
    late = np.array(sent) - sent[0] - (np.array(recorded) - recorded[0]) / rate
    assert late.min() >= -0.002 and late.max() < 0.002 + 1e-9, (late.min(), late.max())
    half = len(late) // 2
    assert abs(float(np.median(late[half:]) - np.median(late[:half]))) < 0.002, "no drift"
    assert result.max_late < 0.002 + 1e-9


def test_publish_loops_at_a_faster_rate_and_reports_progress(ros: None, tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """Looped, it starts over until stopped: stopped during its fourth pass (the
    stop counted in messages, not in seconds), it reports four passes, interrupted."""
    path = tmp_path / "short.mcap"
    record_offline(path, duration=0.5, log_rate=100.0)
    recording = read_recording(path)
    per_loop = len(recording.decoded("pose"))
    stop = threading.Event()
    count = itertools.count(1)
    spy_on_publishers(monkeypatch, lambda: stop.set() if next(count) == 3 * per_loop + 10 else None)
    progress = io.StringIO()
    result = publish(recording, rate=5.0, loop=True, topics=["/pose"], stop=stop,
                     progress=TerminalProgress(progress, interval=0.0))
    assert result.loops == 4 and result.messages == 3 * per_loop + 10 and result.interrupted
    assert "replay:" in progress.getvalue() and "x5 " in progress.getvalue()
    with pytest.raises(RecordingError, match="no topic warp"):
        publish(recording, topics=["warp"])


def test_publish_moves_a_namespaced_recording_and_streams_it(ros: None, tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """A recording made in /feeder1 (topics stored /feeder1/pose, as rosbag2 stores them)
    replays on its stored names, or moved into another namespace; and it is streamed:
    the whole-file list of messages is never asked for."""
    from friction_sim.core.engine.single import Slider
    from friction_sim.core.model.params import Inputs, SliderParams
    from friction_sim.io.reader import Recording
    from friction_sim.io.recorder import Recorder, recording_metadata

    path = tmp_path / "feeder1.mcap"
    slider = Slider(SliderParams(), Inputs())
    states = []
    for k in range(1, 41):
        slider.advance_to(k / 100)
        states.append(slider.state())
    with Recorder(path, recording_metadata(SliderParams(), Inputs(), log_rate=100.0), namespace="/feeder1") as rec:
        rec.write(StatesRecord(tuple(states), "slideway"))
    recording = read_recording(path)
    assert "/feeder1/pose" in recording.topics
    monkeypatch.setattr(Recording, "messages", property(lambda self: pytest.fail("read the whole file")))
    target = f"/replay_{uuid.uuid4().hex[:8]}"
    listener = rclpy.create_node("listener", namespace="/")
    received: dict[str, list[Any]] = {f"{target}/pose": [], "/feeder1/pose": []}
    for topic, log in received.items():
        listener.create_subscription(recording.message_type("pose"), topic, log.append, 100)
    executor = SingleThreadedExecutor()
    executor.add_node(listener)
    try:
        for namespace in (target, ""):
            player = threading.Thread(target=lambda ns=namespace: publish(
                recording, topics=["pose"], namespace=ns, wait_for_subscribers=1, wait_timeout=10.0, delay=0.3))
            player.start()
            deadline = time.monotonic() + 15.0
            expected = f"{namespace or '/feeder1'}/pose"
            while len(received[expected]) < 40 and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.01)
            player.join(timeout=10.0)
    finally:
        executor.shutdown(timeout_sec=0.0)
        listener.destroy_node()
    assert len(received[f"{target}/pose"]) == 40 and len(received["/feeder1/pose"]) == 40
    assert [m.pose.position.x for m in received[f"{target}/pose"]] == [s.x for s in states]


def test_in_time_order_merges_chunks_with_about_one_chunk_held() -> None:
    from friction_sim.io.reader import RawMessage
    from friction_sim.ros.republisher import in_time_order

    chunks = [[RawMessage("a", t, b"") for t in (0, 2, 1, 5)], [RawMessage("b", t, b"") for t in (4, 6, 5)],
              [RawMessage("a", t, b"") for t in (7, 9, 8)]]
    consumed: list[int] = []

    def feed() -> Any:
        for k, chunk in enumerate(chunks):
            consumed.append(k)
            yield chunk

    merged = in_time_order(feed())
    first = [next(merged) for _ in range(3)]
    assert [m.log_time for m in first] == [0, 1, 2] and consumed == [0, 1], "out before the third chunk is read"
    rest = list(merged)
    assert [m.log_time for m in first + rest] == [0, 1, 2, 4, 5, 5, 6, 7, 8, 9]
    assert [m.topic for m in first + rest if m.log_time == 5] == ["a", "b"], "ties keep file order"


def test_prefetched_reads_ahead_passes_errors_on_and_stops_with_its_consumer() -> None:
    from friction_sim.ros.republisher import prefetched

    def failing() -> Any:
        yield from range(3)
        raise OSError("[Errno 5] Input/output error")

    got: list[Any] = []
    with pytest.raises(OSError, match="Input/output"):
        for item in prefetched(failing()):
            got.append(item)
    assert got == [0, 1, 2]
    produced: list[int] = []

    def endless() -> Any:
        for k in itertools.count():
            produced.append(k)
            yield k

    running = set(threading.enumerate())
    ahead = prefetched(endless(), size=5)
    assert next(ahead) == 0
    (reader,) = [t for t in threading.enumerate() if t not in running and t.name == "replay_reader"]
    ahead.close()  # the consumer is done (a stop, Ctrl-C): the reader thread stops too
    reader.join(timeout=10.0)  # (the timeout only guards a hang)
    assert not reader.is_alive(), "the reader thread ended with its consumer: no reading after the end"
    assert len(produced) < 20, "bounded read-ahead"


def _pressing_run(tmp_path: Path) -> tuple[Path, Path]:
    """A run whose external force presses the slider on the track (force.z < 0 today),
    and the same run as written before the convention was marked (force.z > 0 then)."""
    from friction_sim.io.recorder import CONVENTION_KEY

    from recording_helpers import rewrite

    today = tmp_path / "today.mcap"
    record_offline(today, schedule=[Command(0.1, "external_wrench", {"external_force_x": 0.02,
                                                                      "external_force_z": -3.0}),
                                    Command(0.2, "drive_force", {"drive_force": 0.8})], duration=0.3, log_rate=100.0)

    def old_sign(topic: str, t: int, msg: Any) -> Any:
        if topic.lstrip("/") == "external_wrench":
            msg.wrench.force.z = -msg.wrench.force.z
        return msg

    def unmarked(data: dict[str, str]) -> dict[str, str]:
        data.pop(CONVENTION_KEY)
        return data

    old = rewrite(today, tmp_path / "old.mcap", old_sign, metadata=unmarked, external_force_z_convention=None)
    return today, old


def test_an_old_files_external_wrench_is_republished_in_todays_convention(ros: None, tmp_path: Path) -> None:
    """A slider of today that takes a republished old recording must feel the force the
    recorded slider felt: the old file's force.z (> 0 loaded the contact) goes out turned
    round; a file of today, and every other topic, go out as recorded."""
    from friction_sim.ros.republisher import in_todays_convention

    today, old = _pressing_run(tmp_path)
    for path in (today, old):
        recording = read_recording(path)
        raws = list(in_todays_convention(recording, recording.iter_messages()))
        assert [(r.topic, r.log_time) for r in raws] == [(r.topic, r.log_time) for r in recording.iter_messages()]
        (wrench,) = [recording.decode(r) for r in raws if r.topic.lstrip("/") == "external_wrench"]
        assert (wrench.wrench.force.x, wrench.wrench.force.z) == (0.02, -3.0)  # today's convention, both files
        others = [r.data for r in raws if r.topic.lstrip("/") != "external_wrench"]
        assert others == [r.data for r in recording.iter_messages() if r.topic.lstrip("/") != "external_wrench"]

    namespace = f"/replay_{uuid.uuid4().hex[:8]}"
    listener = rclpy.create_node("listener", namespace=namespace)
    received: list[Any] = []
    recording = read_recording(old)
    listener.create_subscription(recording.message_type("external_wrench"), "external_wrench", received.append, 10)
    executor = SingleThreadedExecutor()
    executor.add_node(listener)
    player = threading.Thread(target=lambda: publish(recording, topics=["external_wrench"], namespace=namespace,
                                                     wait_for_subscribers=1, wait_timeout=10.0, delay=0.3))
    try:
        player.start()
        deadline = time.monotonic() + 15.0
        while not received and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.01)
        player.join(timeout=10.0)
    finally:
        executor.shutdown(timeout_sec=0.0)
        listener.destroy_node()
    assert [(m.wrench.force.x, m.wrench.force.z) for m in received] == [(0.02, -3.0)]
