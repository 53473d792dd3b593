"""Recording: every record round-trips through the file, the MCAP layout
rosbag2 and Foxglove expect (fully qualified topic names), data on disk
within the flush interval, the queue (waiting, or dropping and counting),
and the log grid whatever the tick times."""

from __future__ import annotations

import dataclasses
import itertools
import json
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

from friction_sim.core.model.commands import Command, Outcome
from friction_sim.core.model.events import Event, EventKind, Mode, SliderState
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.model.records import Acceleration, PeriodSummary
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.errors import ParameterError, RecordingPathError
from friction_sim.experiment.offline import record_offline
from friction_sim.io import messages as M
from friction_sim.io.cdr import serialize
from friction_sim.io.reader import read_recording
from friction_sim.io.recorder import METADATA_NAME, Recorder, qualified_topic
from friction_sim.io.sinks import (
    AccelerationsRecord,
    CommandRecord,
    EventRecord,
    MessageRecord,
    ParametersRecord,
    PeriodRecord,
    StatesRecord,
    deliver_tick,
)
from friction_sim.io.typesupport import (
    PLAIN_DUMPERS,
    message_definition,
    message_type_name,
    plain_yaml,
    share_directory,
    type_hash,
)

from recording_helpers import plain, varied_schedule

STATE = SliderState(t=1.2345678901, x=1.5e-4, v=-2.5e-3, acceleration=0.3, friction_force=-0.95,
                    normal_force=9.5, phase=1.0, mode=Mode.BACKWARD)
FLOAT_COMMANDS = ("drive_force", "excitation_amplitude", "excitation_frequency", "target_speed")


# -- round trip through the file ------------------------------------------------------


def every_record() -> dict[str, Any]:
    return {
        "state": STATE,
        "event": Event(1.0, EventKind.STICK, 2e-4, 3.0, Mode.FORWARD, Mode.STUCK),
        "period": PeriodSummary(n=7, t=0.14, mean_velocity=2.1e-3, window_periods=1, stick_fraction=0.4),
        "commands": [Outcome(Command(0.3 + 0.01 * k, topic, {topic: 0.5 + k}))
                     for k, topic in enumerate(FLOAT_COMMANDS)]
        + [Outcome(Command(0.4, "external_wrench", {"external_force_x": 0.05, "external_force_z": 1.5})),
           Outcome(Command(0.45, "parameters", {"mu": 0.12})),
           Outcome(Command(0.5, "excitation_amplitude", {"excitation_amplitude": 20.0}), "too large")],
        "parameters": {"mass": 1.0, "mu": 0.1, "gravity": 10.0, "drive_force": 0.7, "excitation_amplitude": 5.0,
                       "excitation_frequency": 50.0, "frame_id": "slideway", "mean_window_periods": 2},
    }


def test_every_message_type_round_trips_through_the_file(tmp_path: Path) -> None:
    records = every_record()
    path = tmp_path / "all.mcap"
    from std_msgs.msg import String

    with Recorder(path, metadata={"mass": 1.0}) as recorder:
        recorder.write(ParametersRecord(records["parameters"], 0.0, False))
        recorder.write(StatesRecord((records["state"],), "rail"))
        recorder.write(EventRecord(records["event"]))
        recorder.write(PeriodRecord(records["period"], "rail"))
        for outcome in records["commands"]:
            recorder.write(CommandRecord(outcome, "rail"))
        assert recorder.write(MessageRecord("notes", String(data="hello"), 42))
        assert recorder.dropped == 0, "every record was queued"
    expected: list[tuple[str, int, Any]] = [("parameters", 0, M.parameters_message(records["parameters"], 0.0))]
    ns = M.seconds_to_ns(STATE.t)
    expected += [(topic, ns, msg) for topic, msg in zip(M.STATE_TOPICS, M.state_messages(STATE, "rail"))]
    expected.append(("events", 1_000_000_000, M.event_message(records["event"])))
    expected.append(("mean_velocity", 140_000_000, M.mean_velocity_message(records["period"], "rail")))
    for outcome in records["commands"]:
        topic = outcome.name if outcome.accepted else "rejected_commands"
        msg = M.command_message(outcome.command, "rail") if outcome.accepted else M.rejection_message(outcome)
        expected.append((topic, M.seconds_to_ns(outcome.t), msg))
    expected.append(("notes", 42, String(data="hello")))
    expected = [("/" + topic, t, msg) for topic, t, msg in expected]  # stored fully qualified, as rosbag2 does

    recording = read_recording(path)
    assert recording.complete and recording.profile == "ros2"
    got = [(raw.topic, raw.log_time, recording.decode(raw)) for raw in recording.messages]
    assert [(topic, t) for topic, t, _ in got] == [(topic, t) for topic, t, _ in expected]
    for (topic, _, msg), (_, _, want) in zip(got, expected):
        # Decoded with rosbags: the same type (by name) and the same field values as the message written.
        assert message_type_name(type(msg)) == message_type_name(type(want)) and plain(msg) == plain(want), topic
    assert recording.topics["/parameters"].type_name == "rcl_interfaces/msg/ParameterEvent"
    assert recording.topics["/rejected_commands"].type_name == "diagnostic_msgs/msg/DiagnosticStatus"


@pytest.mark.parametrize("noise", [0.0, 0.05])
def test_accelerometer_samples_are_written_as_the_imu_messages_rosbags_serializes(tmp_path: Path, noise: float) -> None:
    """The accelerometer's samples go many at a time into a fixed layout: each message's bytes
    are those of rosbags' serialization of the Imu message built one at a time, at its own stamp
    and log time; a sample at a time no ROS stamp holds is dropped and counted, the rest kept."""
    rng = np.random.default_rng(5)
    samples = [Acceleration(round(0.001 * k + 2.0, 9), *rng.normal(0.0, 30.0, 3)) for k in range(50)]
    samples.append(Acceleration(-1.0, 1.0, 2.0, 3.0))  # before time 0: no ROS stamp holds it
    path = tmp_path / "imu.mcap"
    with Recorder(path, metadata={"mass": 1.0}) as recorder:
        recorder.write(AccelerationsRecord(tuple(samples[:20]), "rail", noise))
        recorder.write(StatesRecord((STATE,), "rail"))  # (between two batches: each topic stays in time order)
        recorder.write(AccelerationsRecord(tuple(samples[20:]), "rail", noise))
    assert recorder.stats.dropped == 1 and recorder.stats.error is None
    recording = read_recording(path)
    raws = recording.messages_on("accelerometer")
    assert recording.topics["/accelerometer"].type_name == "sensor_msgs/msg/Imu"
    assert [raw.log_time for raw in raws] == [M.seconds_to_ns(sample.t) for sample in samples[:-1]]
    assert [bytes(raw.data) for raw in raws] == [serialize(M.imu_message(sample, "rail", noise))
                                                 for sample in samples[:-1]]
    assert len(recording.messages_on("pose")) == 1


def test_topics_are_stored_fully_qualified_in_the_namespace(tmp_path: Path) -> None:
    from std_msgs.msg import String

    path = tmp_path / "ns.mcap"
    with Recorder(path, metadata={"mass": 1.0}, namespace="/feeder1") as recorder:
        recorder.write(StatesRecord((STATE,), "slideway"))
        recorder.write(EventRecord(every_record()["event"]))
        recorder.write(MessageRecord("/tf_note", String(data="absolute names stay"), 5))
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    assert sorted(channel.topic for channel in summary.channels.values()) == [
        "/feeder1/events", "/feeder1/friction_force", "/feeder1/pose", "/feeder1/velocity", "/tf_note"]
    assert set(recorder.stats.per_topic) == {channel.topic for channel in summary.channels.values()}
    assert qualified_topic("/", "pose") == "/pose" and qualified_topic("/a/b/", "pose") == "/a/b/pose"
    with pytest.raises(ParameterError, match="namespace = 'feeder1' rejected"):
        Recorder(tmp_path / "bad.mcap", namespace="feeder1")
    assert not (tmp_path / "bad.mcap").exists()


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
    for dumper in PLAIN_DUMPERS.values():  # (libyaml's emitter where PyYAML has it: the same text as its own)
        assert plain_yaml(bag, dumper) == metadata["rosbag2"]["serialized_metadata"]
    assert bag["version"] == 9 and bag["storage_identifier"] == "mcap" and bag["ros_distro"] == "jazzy"
    assert bag["message_count"] == stats.messages
    assert bag["duration"]["nanoseconds"] == stats.last_ns - stats.first_ns == 1_000_000_000
    assert bag["relative_file_paths"] == [path.name] and bag["files"][0]["message_count"] == stats.messages
    counts = {topic["topic_metadata"]["name"]: topic["message_count"] for topic in bag["topics_with_message_count"]}
    assert counts == stats.per_topic and "/pose" in counts
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
        recorder.write(StatesRecord((STATE,), "slideway"))
        while time.monotonic() - written < 60.0:  # a hang guard only
            live = read_recording(path, require_friction_sim=False)
            if live.messages:
                break
            time.sleep(0.02)  # poll interval: waiting for the first chunk
        # Without the periodic flush nothing reaches the disk before finish(): the
        # writer's own count shows that its flush (not a buffer filling) put it there.
        assert recorder.stats.chunks_flushed >= 1 and recorder.stats.last_flush >= written
        assert not live.complete and len(live.messages) == 3
        assert "no footer" in (live.recovery_note() or "")
    finally:
        recorder.finish()
    assert read_recording(path).complete


# -- the queue --------------------------------------------------------------------------


class StalledRecorder(Recorder):
    """A recorder whose writer thread is stuck (a slow disk) until ``gate`` opens."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.gate = threading.Event()
        super().__init__(*args, **kwargs)

    def _write_batch(self, batch: Any) -> None:
        self.gate.wait(10.0)
        super()._write_batch(batch)


def states(n: int) -> list[SliderState]:
    return [dataclasses.replace(STATE, t=k * 1e-3) for k in range(n)]


def test_a_full_queue_drops_and_counts_without_blocking_a_caller_that_does_not_wait(tmp_path: Path) -> None:
    path = tmp_path / "stalled.mcap"
    recorder = StalledRecorder(path, metadata={"mass": 1.0}, queue_size=10, block_when_full=False)
    accepted = 0
    for state in states(100):
        before = recorder.dropped
        recorder.write(StatesRecord((state,), "slideway"))
        accepted += recorder.dropped == before
    # The writer is stalled until the gate opens: a call that waited for it would
    # never have returned, and the recorder counts every wait (none, below).
    # 3 states (9 messages) fit in the queue, and up to 3 more if the writer took them before it stalled.
    assert 3 <= accepted <= 6 and recorder.dropped == 3 * (100 - accepted), "drops count messages"
    assert recorder.queue.waits == 0
    recorder.gate.set()
    stats = recorder.finish()
    assert stats.dropped == 3 * (100 - accepted) and stats.per_topic["/pose"] == accepted and stats.error is None
    recording = read_recording(path, require_friction_sim=False)
    assert recording.dropped == 3 * (100 - accepted), "the file says how many messages it lacks"
    assert len(recording.messages_on("pose")) == accepted
    before = recorder.dropped
    recorder.write(StatesRecord((STATE,), "slideway"))
    assert recorder.dropped == before + 3, "after finish nothing is written, and that is counted"


def test_a_producer_that_waits_loses_nothing_and_resumes_when_the_writer_moves(tmp_path: Path) -> None:
    path = tmp_path / "waits.mcap"
    recorder = StalledRecorder(path, metadata={"mass": 1.0}, queue_size=10)  # waiting is the default
    done = threading.Event()
    returned_at: list[float] = []

    def produce() -> None:
        for state in states(50):
            recorder.write(StatesRecord((state,), "slideway"))
        returned_at.append(time.monotonic())
        done.set()

    producer = threading.Thread(target=produce)
    producer.start()
    assert not done.wait(0.5), "the producer waits while the writer is stuck"
    assert recorder.dropped == 0 and recorder.queue.waits >= 1
    opened = time.monotonic()
    recorder.gate.set()
    assert done.wait(10.0), "the producer goes on once the writer moves"
    producer.join()
    stats = recorder.finish()
    assert stats.dropped == 0 and stats.unrecorded == 0 and stats.error is None
    assert stats.per_topic["/pose"] == 50 and stats.waits >= 1
    # The wait lasted about as long as the writer was stuck: it ended when the writer moved.
    assert 0.4 < stats.waited < returned_at[0] - opened + 0.6
    recording = read_recording(path, require_friction_sim=False)
    assert recording.dropped == 0 and len(recording.messages_on("pose")) == 50


def test_a_command_never_waits_behind_a_queue_full_of_states(tmp_path: Path) -> None:
    """States fill the queue and would make their producer wait; a command or
    parameter change (also sent from the node's parameter-service thread) has
    headroom beyond the capacity, so a parameter set is answered at once."""
    recorder = StalledRecorder(tmp_path / "urgent.mcap", metadata={"mass": 1.0}, queue_size=30)
    recorder.write(StatesRecord(tuple(states(10)), "slideway"))  # 30 messages: the queue is full
    recorder.write(CommandRecord(Outcome(Command(0.001, "drive_force", {"drive_force": 0.8})), "slideway"))
    recorder.write(ParametersRecord({"publish_rate": 500.0}, 0.001, True))
    assert recorder.queue.waits == 0  # the writer is stalled: a wait would never have ended
    recorder.gate.set()
    stats = recorder.finish()
    assert stats.dropped == 0 and stats.per_topic["/drive_force"] == 1


def test_finish_is_idempotent_and_unwritable_paths_are_one_line_errors(tmp_path: Path) -> None:
    recorder = Recorder(tmp_path / "a.mcap")
    first = recorder.finish()
    assert recorder.finish() is first and recorder.finished
    for bad, reason in ((tmp_path / "missing" / "run.mcap", "[Errno 2] No such file or directory"),
                        (tmp_path, "names a directory, not a file")):
        with pytest.raises(RecordingPathError) as error:
            Recorder(bad)
        message = str(error.value)
        assert message.startswith(f"log_path = '{bad}' rejected: ") and reason in message and "\n" not in message
        chained = error.value.__cause__ or (None if error.value.__suppress_context__ else error.value.__context__)
        assert chained is None, "nothing chained: a traceback would show it"


def test_a_bad_message_is_dropped_without_ending_the_recording(tmp_path: Path) -> None:
    from std_msgs.msg import Float64, String

    path = tmp_path / "bad.mcap"
    with Recorder(path, metadata={"mass": 1.0}) as recorder:
        recorder.write(MessageRecord("drive_force", Float64(data=0.5), 1))
        recorder.write(MessageRecord("drive_force", String(data="not a force"), 2))  # another type on the same topic
        recorder.write(ParametersRecord({"odd": object()}, 0.0, False))  # no ROS parameter type holds this
        recorder.write(StatesRecord((STATE,), "slideway"))
    assert recorder.stats.dropped == 2 and recorder.stats.error is None
    recording = read_recording(path)
    assert recording.complete and len(recording.messages_on("drive_force")) == 1 and recording.dropped == 2
    assert len(recording.messages_on("pose")) == 1


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
                command = Command(0.0, "drive_force", {"drive_force": float(rng.uniform(-1, 1))})
                recorder.write(CommandRecord(rt.command(command, when), ""))
            deliver_tick([recorder], rt.tick(wall), "slideway")
    recording = read_recording(path, require_friction_sim=False)
    times = np.array([raw.log_time for raw in recording.messages_on("pose")])
    assert np.array_equal(times, np.round(np.arange(1001) / 2000.0 * 1e9).astype(np.int64))
    events = recording.decoded("events")
    assert len(events) == sum(rt.slider.event_counts.values())
    assert [float({kv.key: kv.value for kv in m.values}["t"]) for _, m in events] == [e.t for e in rt.slider.events]
    assert all(a <= b for (a, _), (b, _) in itertools.pairwise(events))


# -- a batch of states and commands --------------------------------------------------------


@pytest.mark.parametrize("rows_per_pass", [2048, 3])
def test_in_a_batch_of_states_and_commands_each_record_keeps_its_place(tmp_path: Path, rows_per_pass: int,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """A controller that answers every period puts a command between each period's
    states and samples.  The writer builds a batch's rows at once but writes them a
    run at a time: each command stays between the states it followed and those that
    follow it (a file cut short holds the commands the states it holds followed, and
    no later ones; a copy of the file message by message keeps that), each channel
    numbered in order.  Chunks of one byte: each run ends one.  In passes of 3 rows
    too, with a state whose time no stamp holds (dropped, counted, the rest in place)."""
    from mcap.records import Channel, Message
    from mcap.stream_reader import StreamReader

    from friction_sim.io import recordwriter
    from friction_sim.io.bagfile import BagFile, RecordingStats
    from friction_sim.io.recordwriter import RecordWriter
    from friction_sim.io.typesupport import DEFAULT_QOS

    monkeypatch.setattr(recordwriter, "ROWS_PER_PASS", rows_per_pass)

    path = tmp_path / "run.mcap"
    expected = []
    with path.open("wb") as stream:
        file = BagFile(stream, DEFAULT_QOS, 1, RecordingStats(path))
        file.start("ros2", "test")
        writer = RecordWriter(file, "/", path, "slider")
        for batch in range(3):
            items: list[Any] = []
            for tick in range(4):
                t = batch + 0.1 * tick
                bad = dataclasses.replace(STATE, t=-1.0)  # (no stamp holds it)
                items += [StatesRecord((dataclasses.replace(STATE, t=t), *[bad][:tick == 2]), "slideway"),
                          AccelerationsRecord((Acceleration(t, 0.1, 0.0, 9.8),), "slideway", 0.0),
                          CommandRecord(Outcome(Command(t + 0.05, "drive_force", {"drive_force": 0.1 * tick})),
                                        "slideway")]
                ns, command_ns = round(t * 1e9), round((t + 0.05) * 1e9)
                expected += [("/pose", ns), ("/velocity", ns), ("/friction_force", ns), ("/accelerometer", ns),
                             ("/drive_force", command_ns)]
            writer.write(items)
            assert writer.bad == 3 * (batch + 1)
        file.finish()
    topics: dict[int, str] = {}
    written, sequences = [], {}
    with path.open("rb") as stream:
        for record in StreamReader(stream).records:
            if isinstance(record, Channel):
                topics[record.id] = record.topic
            elif isinstance(record, Message):
                written.append((topics[record.channel_id], record.log_time))
                sequences.setdefault(record.channel_id, []).append(record.sequence)
    assert written == expected
    assert all(numbers == list(range(len(numbers))) for numbers in sequences.values())
