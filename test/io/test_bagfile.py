"""The MCAP file BagFile writes: valid for mcap's own reader (CRCs checked),
every index pointing where it says, sequence numbers per channel, the
summary agreeing with the data, and the same records mcap's Writer makes."""

from __future__ import annotations

import struct
import tracemalloc
from pathlib import Path
from typing import Any

import zstandard
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, ChunkIndex, Message, MessageIndex, Metadata, MetadataIndex, Schema, Statistics
from mcap.stream_reader import StreamReader, breakup_chunk

from friction_sim.experiment.offline import record_offline
from friction_sim.io.bagfile import BagFile, RecordingStats
from friction_sim.io.typesupport import DEFAULT_QOS

from recording_helpers import varied_schedule

OPCODES = {0x03: Schema, 0x04: Channel, 0x05: Message, 0x06: Chunk, 0x07: MessageIndex, 0x08: ChunkIndex,
           0x0B: Statistics, 0x0C: Metadata, 0x0D: MetadataIndex}


def recorded(tmp_path: Path, chunk_size: int) -> tuple[Path, Any]:
    path = tmp_path / f"run{chunk_size}.mcap"
    stats = record_offline(path, schedule=varied_schedule(), duration=1.5, log_rate=1000.0,
                           recorder_options={"chunk_size": chunk_size})
    return path, stats


def record_at(data: bytes, offset: int) -> tuple[int, int]:
    """(opcode, length) of the record at ``offset``."""
    opcode, length = struct.unpack_from("<BQ", data, offset)
    return opcode, length


def test_mcaps_reader_reads_it_all_with_crcs_checked(tmp_path: Path) -> None:
    for chunk_size in (4096, 4 * 1024 * 1024):  # many chunks, and one per flush
        path, stats = recorded(tmp_path, chunk_size)
        with path.open("rb") as stream:
            reader = make_reader(stream, validate_crcs=True)
            summary = reader.get_summary()
            messages = list(reader.iter_messages(log_time_order=True))
        assert summary is not None
        assert len(messages) == stats.messages == summary.statistics.message_count
        assert [m.log_time for _, _, m in messages] == sorted(m.log_time for _, _, m in messages)
        per_topic: dict[str, int] = {}
        for _, channel, _ in messages:
            per_topic[channel.topic] = per_topic.get(channel.topic, 0) + 1
        assert per_topic == stats.per_topic
        assert {summary.channels[c].topic: n for c, n in summary.statistics.channel_message_counts.items()} == per_topic
        assert summary.statistics.message_start_time == stats.first_ns == 0
        assert summary.statistics.message_end_time == stats.last_ns
        assert summary.statistics.chunk_count == len(summary.chunk_indexes)
        assert summary.statistics.metadata_count == 3  # friction_sim, friction_sim_summary, rosbag2


def test_every_index_points_where_it_says(tmp_path: Path) -> None:
    path, stats = recorded(tmp_path, 4096)
    data = path.read_bytes()
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and len(summary.chunk_indexes) > 5
    sequences: dict[int, list[int]] = {}
    for index in summary.chunk_indexes:
        assert record_at(data, index.chunk_start_offset) == (0x06, index.chunk_length - 9)
        chunk = next(iter(StreamReader(_Reader(data[index.chunk_start_offset:]), skip_magic=True,
                                       emit_chunks=True).records))
        assert isinstance(chunk, Chunk)
        raw = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
        assert chunk.compression == index.compression == "zstd" and len(chunk.data) == index.compressed_size
        # Where each message of the chunk really is:
        actual: dict[int, list[tuple[int, int]]] = {}
        offset = 0
        while offset < len(raw):
            opcode, length = record_at(raw, offset)
            if opcode == 0x05:
                channel, sequence, log_time, publish_time = struct.unpack_from("<HIQQ", raw, offset + 9)
                assert publish_time == log_time
                actual.setdefault(channel, []).append((log_time, offset))
                sequences.setdefault(channel, []).append(sequence)
            offset += 9 + length
        assert offset == len(raw) == index.uncompressed_size
        times = [t for entries in actual.values() for t, _ in entries]
        assert (index.message_start_time, index.message_end_time) == (min(times), max(times))
        # ... and what the message indexes after the chunk say:
        assert sorted(index.message_index_offsets) == sorted(actual)
        for channel, at in index.message_index_offsets.items():
            opcode, length = record_at(data, at)
            assert opcode == 0x07
            channel_id, size = struct.unpack_from("<HI", data, at + 9)
            entries = list(struct.iter_unpack("<QQ", data[at + 15:at + 15 + size]))
            assert channel_id == channel and 6 + size == length and entries == actual[channel]
        lengths = [9 + record_at(data, at)[1] for at in index.message_index_offsets.values()]
        assert index.message_index_length == sum(lengths)
    for channel, numbers in sequences.items():
        assert numbers == list(range(len(numbers))), f"channel {channel}: sequence numbers count its messages"
    assert sum(len(n) for n in sequences.values()) == stats.messages
    for index in summary.metadata_indexes:
        assert record_at(data, index.offset) == (0x0C, index.length - 9)


def test_the_records_are_those_mcaps_writer_makes(tmp_path: Path) -> None:
    """Same schemas, channels and statistics as mcap's Writer writing the same messages."""
    from mcap.writer import CompressionType, IndexType, Writer

    path, _ = recorded(tmp_path, 4 * 1024 * 1024)
    with path.open("rb") as stream:
        reader = make_reader(stream)
        ours = reader.get_summary()
        header = reader.get_header()
        messages = list(reader.iter_messages(log_time_order=False))
    assert ours is not None
    again = tmp_path / "again.mcap"
    with again.open("wb") as stream:
        writer = Writer(stream, chunk_size=4 * 1024 * 1024, compression=CompressionType.ZSTD, index_types=IndexType.ALL)
        writer.start(profile=header.profile, library=header.library)
        for schema in ours.schemas.values():
            writer.register_schema(schema.name, schema.encoding, schema.data)
        for channel in ours.channels.values():
            writer.register_channel(channel.topic, channel.message_encoding, channel.schema_id, channel.metadata)
        for _, _, message in messages:
            writer.add_message(message.channel_id, message.log_time, message.data, message.publish_time,
                               message.sequence)
        writer.finish()
    with again.open("rb") as stream:
        theirs = make_reader(stream).get_summary()
    assert theirs is not None
    assert ours.schemas == theirs.schemas and ours.channels == theirs.channels
    ours.statistics.metadata_count = theirs.statistics.metadata_count = 0
    ours.statistics.chunk_count = theirs.statistics.chunk_count = 0
    assert ours.statistics == theirs.statistics


class _Reader:
    """A file-like view of bytes for StreamReader."""

    def __init__(self, data: bytes) -> None:
        self._data, self._at = data, 0

    def read(self, n: int = -1) -> bytes:
        end = len(self._data) if n < 0 else self._at + n
        chunk, self._at = self._data[self._at:end], min(end, len(self._data))
        return chunk


def test_breakup_chunk_sees_the_same_messages(tmp_path: Path) -> None:
    path, stats = recorded(tmp_path, 4096)
    count = 0
    for record in StreamReader(_Reader(path.read_bytes()), emit_chunks=True, validate_crcs=True).records:
        if isinstance(record, Chunk):
            count += sum(isinstance(r, Message) for r in breakup_chunk(record, validate_crc=True))
    assert count == stats.messages


def test_rosbags_opens_it_as_a_rosbag2_bag(tmp_path: Path) -> None:
    """A second, independent reader of MCAP and of rosbag2's metadata."""
    from rosbags.rosbag2 import Reader

    from friction_sim.io.cdr import deserialize

    path, stats = recorded(tmp_path, 4096)
    with Reader(path) as bag:
        assert bag.message_count == stats.messages
        assert {c.topic: c.msgcount for c in bag.connections} == stats.per_topic
        poses = [(c, t, data) for c, t, data in bag.messages() if c.topic == "/pose"]
    assert len(poses) == stats.per_topic["/pose"] and poses[0][0].msgtype == "geometry_msgs/msg/PoseStamped"
    assert [t for _, t, _ in poses] == [round(k * 1e6) for k in range(len(poses))]
    last = deserialize(poses[-1][2], "geometry_msgs/msg/PoseStamped")
    assert (last.header.stamp.sec, last.header.stamp.nanosec) == (1, 500_000_000) and last.header.frame_id == "slideway"


def test_what_it_keeps_for_the_summary_is_bytes_per_chunk_not_objects(tmp_path: Path) -> None:
    """Each chunk leaves its ChunkIndex for the summary, and a recorder ends a
    chunk every flush_interval of wall time (an hour in real time: 14,400).
    Kept as the serialized record (77 bytes + 10 per channel), not as a
    ChunkIndex object with its dict of offsets (~1 KB with 7 channels: a
    simulated hour grew a lockstep run by megabytes).  Counted by tracemalloc,
    so the same on any machine; the summary still indexes every chunk."""
    from std_msgs.msg import Float64

    path = tmp_path / "many_chunks.mcap"
    topics = [f"/topic{i}" for i in range(7)]
    warm, chunks = 20, 2000
    with path.open("wb", buffering=0) as stream:
        bag = BagFile(stream, DEFAULT_QOS, 4 * 1024 * 1024, RecordingStats(path))
        bag.start("ros2", "test")

        def one_chunk(k: int) -> None:
            for topic in topics:
                bag.add(topic, Float64(data=float(k)), 1_000_000 + k)
            bag.flush()

        for k in range(warm):  # the channels registered, the counts' dict filled
            one_chunk(k)
        started = not tracemalloc.is_tracing()
        if started:
            tracemalloc.start()
        before = tracemalloc.get_traced_memory()[0]
        for k in range(warm, warm + chunks):
            one_chunk(k)
        held = tracemalloc.get_traced_memory()[0] - before
        if started:
            tracemalloc.stop()
        bag.finish()
    assert held / chunks < 1.25 * (77 + 10 * len(topics)), f"{held / chunks:.0f} bytes kept per chunk"
    with path.open("rb") as stream:
        summary = make_reader(stream, validate_crcs=True).get_summary()
    assert summary is not None and len(summary.chunk_indexes) == summary.statistics.chunk_count == warm + chunks
    assert all(len(index.message_index_offsets) == len(topics) for index in summary.chunk_indexes)


def test_rows_appended_a_slice_at_a_time_number_wrap_and_range_as_one_message_at_a_time(tmp_path: Path) -> None:
    """Rows of a group written in slices: each message's sequence number follows its channel's
    (wrapping at 2**32 within a slice), and the chunk's index and time range hold whether the
    log times ascend or not (a reset sends time back)."""
    import numpy as np

    from friction_sim.io.recordwriter import state_row_builder

    path = tmp_path / "rows.mcap"
    log_times = {"ascending": np.array([5, 6, 7, 9, 12], dtype=np.int64) * 10**6,
                 "not": np.array([9, 3, 7, 1, 12], dtype=np.int64) * 10**6}
    with path.open("wb") as stream:
        file = BagFile(stream, DEFAULT_QOS, 1 << 20, RecordingStats(path))
        file.start("ros2", "test")
        group = file.row_group(["/pose", "/velocity", "/friction_force"], state_row_builder("rail"), 6)
        assert group is not None
        for times in log_times.values():
            encoded = file.encode_rows(group, times, np.arange(30, dtype=float).reshape(5, 6))
            channel, _ = file.channels["/velocity"]
            file._sequence[channel] = 2**32 - 3  # noqa: SLF001 (three numbers before the wrap)
            file.append_rows(encoded, 0, 2)
            file.append_rows(encoded, 2, 5)
            file.flush()
        file.finish()
    with path.open("rb") as stream:
        reader = make_reader(stream, validate_crcs=True)
        summary = reader.get_summary()
        messages = [(channel.topic, message.sequence, message.log_time)
                    for _, channel, message in reader.iter_messages(log_time_order=False)]
    assert summary is not None and len(summary.chunk_indexes) == 2
    for index, times in zip(summary.chunk_indexes, log_times.values(), strict=True):
        assert (index.message_start_time, index.message_end_time) == (int(times.min()), int(times.max()))
    velocity = [(sequence, log_time) for topic, sequence, log_time in messages if topic == "/velocity"]
    wrapped = [2**32 - 3, 2**32 - 2, 2**32 - 1, 0, 1]
    assert velocity == [*zip(wrapped, log_times["ascending"].tolist()), *zip(wrapped, log_times["not"].tolist())]
    assert [sequence for topic, sequence, _ in messages if topic == "/pose"] == [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]
