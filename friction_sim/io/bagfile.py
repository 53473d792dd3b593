"""The MCAP file of a recording, laid out as rosbag2's MCAP storage plugin (Jazzy) writes it.

:class:`BagFile` writes, from one thread (the recorder's writer thread):
zstd chunks holding the schemas, channels and messages, each followed by
its message indexes; metadata records between chunks; and on
:meth:`BagFile.finish` the data end, the summary (schemas, channels,
statistics, chunk and metadata indexes, summary offsets, CRC) and the
footer: what ``mcap.writer.Writer`` writes with the options rosbag2 uses.
Every record except Message and MessageIndex is written by ``mcap``'s own
record classes; those two are hand-written, many at a time, with numpy,
because ``Writer`` costs about 3.6 us per message (a dataclass, struct calls
and a seek per message, two more per index entry) and a run recorded 100
times faster than real time produces 300,000 messages a second.
:meth:`BagFile.add_rows` writes a whole group of fixed-layout messages
(:class:`~friction_sim.io.cdr.FixedLayout`) per row in one numpy pass.

The stream must be unbuffered (or a BytesIO): a chunk is written with one
``write`` loop, nothing stays in a Python buffer that a later ``close``
would try (and fail) to write again, and after a failed write the file
holds every record before the failing one whole.  :class:`RecordingStats`
counts what is in the file: messages of chunks written whole.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

from friction_sim.errors import RecordingError
from friction_sim.io import cdr
from friction_sim.io.chunks import MCAP_MAGIC
from friction_sim.io.messages import ns_to_seconds
from friction_sim.io.typesupport import message_definition, message_type_name, plain_yaml, qos_yaml, type_hash

#: rosbag2 bag metadata version written in the ``rosbag2`` record (Jazzy).
ROSBAG2_METADATA_VERSION = 9
ROS_DISTRO = "jazzy"
#: A Message record up to its data: opcode, record length, channel id, sequence, log time, publish time.
_MESSAGE = struct.Struct("<BQHIQQ")
#: A MessageIndex record up to its entries: opcode, record length, channel id, entries' length.
_MESSAGE_INDEX = struct.Struct("<BQHI")
_SEQUENCE_MOD = 1 << 32  # the sequence field is a uint32: it wraps
#: Largest log time [ns] whose header stamp fits (builtin_interfaces/Time.sec is an int32).
MAX_STAMP_NS = (2**31 - 1) * 1_000_000_000 + 999_999_999


@dataclass
class RecordingStats:
    """What a recording holds: per-topic counts and the log-time range [ns]
    of the messages in the file (in chunks written whole), and what it lacks:
    messages ``dropped`` (the writer fell behind a producer that does not
    wait, a record no message could hold, or handed over after finish) and
    messages ``unrecorded`` because the recording had failed (``error``).
    ``waited`` [s] and ``waits`` say how long producers waited for the writer."""

    path: Path
    messages: int = 0
    dropped: int = 0
    unrecorded: int = 0
    per_topic: dict[str, int] = field(default_factory=dict)
    first_ns: int | None = None
    last_ns: int | None = None
    chunks_flushed: int = 0
    last_flush: float | None = None  # time.monotonic() of the last flush
    bytes: int = 0
    waited: float = 0.0
    waits: int = 0
    error: str | None = None

    @property
    def duration(self) -> float:
        """Seconds between the first and the last log time."""
        if self.first_ns is None or self.last_ns is None:
            return 0.0
        return ns_to_seconds(self.last_ns - self.first_ns)

    def count(self, topic: str, n: int, first_ns: int, last_ns: int) -> None:
        """Count ``n`` messages on ``topic`` with log times in [first_ns, last_ns]."""
        self.messages += n
        self.per_topic[topic] = self.per_topic.get(topic, 0) + n
        if self.first_ns is None or first_ns < self.first_ns:
            self.first_ns = first_ns
        if self.last_ns is None or last_ns > self.last_ns:
            self.last_ns = last_ns


@dataclass
class _ChannelChunk:
    """One channel's messages in the open chunk: index entries (log time,
    offset in the chunk) as pairs of arrays and a list of single ones, count, time range."""

    arrays: list[tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]] = field(default_factory=list)
    singles: list[int] = field(default_factory=list)  # log time, offset, log time, offset, ...
    count: int = 0
    first: int = 2**64
    last: int = -1

    def add(self, log_time: int, offset: int) -> None:
        self.singles += (log_time, offset)
        self.count += 1
        self.first, self.last = min(self.first, log_time), max(self.last, log_time)

    def add_many(self, log_times: np.ndarray[Any, np.dtype[np.int64]], offsets: np.ndarray[Any, np.dtype[np.int64]],
                 first: int, last: int) -> None:
        """Entries for messages at ``log_times`` (from ``first`` to ``last``) and ``offsets``."""
        self._keep_singles()
        self.arrays.append((log_times, offsets))
        self.count += len(log_times)
        self.first, self.last = min(self.first, first), max(self.last, last)

    def _keep_singles(self) -> None:
        if self.singles:
            pairs = np.array(self.singles, dtype=np.int64).reshape(-1, 2)
            self.arrays.append((pairs[:, 0], pairs[:, 1]))
            self.singles = []

    def entries(self) -> bytes:
        """The index entries, little-endian (log time, offset) pairs in the order written
        (built once per chunk: a run of rows adds its arrays as they are)."""
        self._keep_singles()
        if not self.arrays:
            return b""
        table = np.empty((self.count, 2), dtype="<u8")
        table[:, 0] = np.concatenate([times for times, _ in self.arrays])
        table[:, 1] = np.concatenate([offsets for _, offsets in self.arrays])
        return table.tobytes()


@dataclass(frozen=True)
class RowGroup:
    """A group of fixed-layout messages written together, one group per row
    (e.g. pose, velocity, friction_force of one state): the channels and
    layouts, and each message's offset in a row of ``row_size`` bytes."""

    topics: tuple[str, ...]
    layouts: tuple[cdr.FixedLayout, ...]
    starts: tuple[int, ...]
    row_size: int


@dataclass(frozen=True)
class _RowFrame:
    """A row of a :class:`RowGroup` on its channels as one numpy structured type: the
    bytes every row shares (each message's opcode, length and channel, its layout's
    template) and a named field for each number that varies (the message record's
    sequence and times, and its layout's :meth:`~friction_sim.io.cdr.FixedLayout.fields`
    under the prefix ``m<index>_``), so a row group is filled in a numpy call per field."""

    dtype: np.dtype[Any]
    template: np.ndarray[Any, np.dtype[np.uint8]]
    prefixes: tuple[str, ...]

    @classmethod
    def of(cls, group: RowGroup, channels: tuple[int, ...]) -> _RowFrame:
        fields: dict[str, tuple[str, int]] = {}
        template = bytearray(group.row_size)
        prefixes = tuple(f"m{index}_" for index in range(len(channels)))
        for prefix, channel, layout, start in zip(prefixes, channels, group.layouts, group.starts):
            _MESSAGE.pack_into(template, start, Opcode.MESSAGE, 22 + layout.size, channel, 0, 0, 0)
            body = start + _MESSAGE.size
            template[body:body + layout.size] = layout.template
            fields.update({f"{prefix}sequence": ("<u4", start + 11), f"{prefix}log_time": ("<u8", start + 15),
                           f"{prefix}publish_time": ("<u8", start + 23), **layout.fields(prefix, body)})
        return cls(cdr.structured(fields, group.row_size), np.frombuffer(bytes(template), dtype=np.uint8), prefixes)


@dataclass(frozen=True)
class EncodedRows:
    """Rows of a :class:`RowGroup` built by :meth:`BagFile.encode_rows`, on its
    ``channels``, at ``log_times``, written by :meth:`BagFile.append_rows`."""

    group: RowGroup
    channels: tuple[int, ...]
    rows: np.ndarray[Any, np.dtype[Any]]
    log_times: np.ndarray[Any, np.dtype[np.int64]]
    #: What :meth:`BagFile.append_rows` does to every slice, done once: each channel's
    #: sequence numbers in ``rows`` (views), the rows' bytes, and whether the log times
    #: ascend (then a slice's first and last are its range).
    sequences: tuple[np.ndarray[Any, np.dtype[np.uint32]], ...]
    data: memoryview
    ascending: bool


class BagFile:
    """The MCAP writer of a recorder (see the module docstring)."""

    def __init__(self, stream: IO[bytes], qos_profiles: list[dict[str, Any]], chunk_size: int,
                 stats: RecordingStats) -> None:
        self._stream = stream
        self._chunk_size = chunk_size
        self.qos_profiles = qos_profiles
        self.qos_yaml = qos_yaml(qos_profiles)
        self.stats = stats
        self.position = 0
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, tuple[int, str]] = {}  # topic -> (channel id, type name)
        self._schema_records: list[Schema] = []
        self._channel_records: list[Channel] = []
        self._sequence: dict[int, int] = {}
        self._chunk = bytearray()
        self._in_chunk: dict[int, _ChannelChunk] = {}
        #: The summary's ChunkIndex records, serialized as written: a record of 77 bytes + 10 per channel
        #: per chunk, where a ChunkIndex object (its dict of offsets, the ints) cost ~1 KB.  A run ends a
        #: chunk every flush_interval of wall time, so an hour holds thousands of them.
        self._chunk_index_records = bytearray()
        self._chunk_count = 0
        self._metadata_indexes: list[MetadataIndex] = []
        self._zstd = zstandard.ZstdCompressor()
        self._frames: dict[tuple[RowGroup, tuple[int, ...]], _RowFrame] = {}

    # -- records outside chunks ---------------------------------------------------

    def start(self, profile: str, library: str) -> None:
        """The magic and the header."""
        self._write(MCAP_MAGIC + _record(Header(profile, library)))

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """A metadata record, written at once (the open chunk stays open)."""
        record = _record(Metadata(name=name, metadata=data))
        offset = self.position
        self._write(record)
        self._metadata_indexes.append(MetadataIndex(offset=offset, length=len(record), name=name))

    # -- messages -------------------------------------------------------------------

    def add(self, topic: str, msg: Any, log_time_ns: int) -> bool:
        """Write ``msg`` on ``topic``; False (nothing written) for a log time
        whose stamp no ROS time holds (< 0 or beyond the int32 seconds)."""
        if not 0 <= log_time_ns <= MAX_STAMP_NS:
            return False
        self._channel(topic, message_type_name(type(msg)))  # a topic keeps its type: checked before the work
        return self.add_serialized(topic, message_type_name(type(msg)), cdr.serialize(msg), log_time_ns)

    def add_serialized(self, topic: str, type_name: str, data: bytes, log_time_ns: int) -> bool:
        """Write a message given as CDR ``data`` on ``topic`` (see :meth:`add`)."""
        log_time_ns = int(log_time_ns)
        if not 0 <= log_time_ns <= MAX_STAMP_NS:
            return False
        channel = self._channel(topic, type_name)
        sequence = self._sequence[channel]
        self._sequence[channel] = (sequence + 1) % _SEQUENCE_MOD
        self._channel_chunk(channel).add(log_time_ns, len(self._chunk))
        self._chunk += _MESSAGE.pack(Opcode.MESSAGE, 22 + len(data), channel, sequence, log_time_ns, log_time_ns)
        self._chunk += data
        self._maybe_end_chunk()
        return True

    def row_group(self, topics: Sequence[str], make: Callable[[int, Sequence[float]], Sequence[Any]],
                  n_values: int) -> RowGroup | None:
        """The group of messages ``make(ns, values)`` builds, one per topic, if
        they are fixed-layout (None: write them one at a time)."""
        layouts = cdr.fixed_layouts(make, n_values)
        if layouts is None or len(layouts) != len(topics):
            return None
        starts, size = [], 0
        for layout in layouts:
            starts.append(size)
            size += _MESSAGE.size + layout.size
        return RowGroup(tuple(topics), layouts, tuple(starts), size)

    def add_rows(self, group: RowGroup, log_times: np.ndarray[Any, np.dtype[np.int64]],
                 values: np.ndarray[Any, np.dtype[np.float64]]) -> None:
        """Write the group's messages for each row: stamped and logged at
        ``log_times[i]`` (each within 0..MAX_STAMP_NS), carrying ``values[i]``;
        in row order, the group's topics in order within a row."""
        encoded = self.encode_rows(group, log_times, values)
        self.append_rows(encoded, 0, len(log_times))

    def encode_rows(self, group: RowGroup, log_times: np.ndarray[Any, np.dtype[np.int64]],
                    values: np.ndarray[Any, np.dtype[np.float64]]) -> EncodedRows:
        """The group's messages for each row (see :meth:`add_rows`), built in one
        pass and written later, a slice at a time (:meth:`append_rows`): a writer
        that keeps other records in their place between the rows of one batch
        builds them once, not once per slice."""
        channels = tuple(self._channel(topic, layout.type_name) for topic, layout in zip(group.topics, group.layouts))
        frame = self._frames.get((group, channels))
        if frame is None:
            frame = self._frames[(group, channels)] = _RowFrame.of(group, channels)
        n = len(log_times)
        rows = np.empty(n, dtype=frame.dtype)
        rows.view(np.uint8).reshape(n, group.row_size)[:] = frame.template  # the bytes every row shares
        for prefix, layout in zip(frame.prefixes, group.layouts):
            rows[f"{prefix}log_time"] = rows[f"{prefix}publish_time"] = log_times
            layout.fill(rows, prefix, log_times, values)
        sequences = tuple(rows[f"{prefix}sequence"] for prefix in frame.prefixes)
        ascending = bool(np.all(log_times[1:] >= log_times[:-1]))
        return EncodedRows(group, channels, rows, log_times, sequences,
                           rows.view(np.uint8).reshape(-1).data, ascending)

    def append_rows(self, encoded: EncodedRows, start: int, stop: int) -> None:
        """Write rows ``start`` to ``stop`` of ``encoded``, numbered on each channel
        from where it stands (slices of one encoding are written in order)."""
        n = stop - start
        if n <= 0:
            return
        group, log_times = encoded.group, encoded.log_times[start:stop]
        counter = np.arange(n, dtype=np.int64)
        for sequences, channel in zip(encoded.sequences, encoded.channels):
            number = self._sequence[channel]
            if number + n <= _SEQUENCE_MOD:  # (no wrap: the numbers go straight into the rows)
                np.add(counter, number, out=sequences[start:stop], casting="unsafe")
            else:
                sequences[start:stop] = (number + counter) % _SEQUENCE_MOD
        # Built whole: only now change the chunk, its indexes and the sequence numbers.
        if encoded.ascending:
            low, high = int(log_times[0]), int(log_times[-1])
        else:
            low, high = int(log_times.min()), int(log_times.max())
        rows_at = len(self._chunk) + group.row_size * counter  # (where each row starts in the chunk)
        for channel, offset in zip(encoded.channels, group.starts):
            self._sequence[channel] = (self._sequence[channel] + n) % _SEQUENCE_MOD
            self._channel_chunk(channel).add_many(log_times, rows_at + offset, low, high)
        self._chunk += encoded.data[start * group.row_size:stop * group.row_size]
        self._maybe_end_chunk()

    # -- chunks ---------------------------------------------------------------------

    def flush(self) -> None:
        """End the open chunk and write it (if it holds a message)."""
        if not self._in_chunk:
            return
        data = self._chunk  # compressed and checksummed in place, not copied
        compressed = self._zstd.compress(data)
        start = min(c.first for c in self._in_chunk.values())
        end = max(c.last for c in self._in_chunk.values())
        chunk = _record(Chunk(compression="zstd", data=compressed, message_start_time=start, message_end_time=end,
                              uncompressed_crc=zlib.crc32(data), uncompressed_size=len(data)))
        indexes, offsets = [], {}
        position = self.position + len(chunk)
        for channel, content in self._in_chunk.items():
            entries = content.entries()
            offsets[channel] = position
            indexes.append(_MESSAGE_INDEX.pack(Opcode.MESSAGE_INDEX, 6 + len(entries), channel, len(entries)))
            indexes.append(entries)
            position += _MESSAGE_INDEX.size + len(entries)
        chunk_start = self.position
        self._write(chunk)
        # The chunk is in the file (a reader recovers it even if its indexes fail to follow): count it.
        topics = {channel: topic for topic, (channel, _) in self.channels.items()}
        for channel, content in self._in_chunk.items():
            self.stats.count(topics[channel], content.count, content.first, content.last)
        self._chunk = bytearray()
        self._in_chunk = {}
        self._write(b"".join(indexes))
        self._chunk_index_records += _record(ChunkIndex(
            message_start_time=start, message_end_time=end, chunk_start_offset=chunk_start, chunk_length=len(chunk),
            message_index_offsets=offsets, message_index_length=position - chunk_start - len(chunk),
            compression="zstd", compressed_size=len(compressed), uncompressed_size=len(data)))
        self._chunk_count += 1

    def _maybe_end_chunk(self) -> None:
        if len(self._chunk) > self._chunk_size:
            self.flush()

    def _channel_chunk(self, channel: int) -> _ChannelChunk:
        content = self._in_chunk.get(channel)
        if content is None:
            content = self._in_chunk[channel] = _ChannelChunk()
        return content

    def _channel(self, topic: str, type_name: str) -> int:
        """The channel id of ``topic`` (registered, with its schema, on first use)."""
        channel = self.channels.get(topic)
        if channel is None:
            channel = self.channels[topic] = (self._register(topic, type_name), type_name)
        elif channel[1] != type_name:
            raise RecordingError(f"topic {topic!r} has type {channel[1]}, not {type_name}")
        return channel[0]

    def _register(self, topic: str, type_name: str) -> int:
        """A new channel (and its type's schema, once), recorded in the open chunk."""
        schema_id = self.schemas.get(type_name)
        if schema_id is None:
            schema_id = self.schemas[type_name] = len(self._schema_records) + 1
            schema = Schema(id=schema_id, name=type_name, encoding="ros2msg",
                            data=message_definition(type_name).encode("utf-8"))
            self._schema_records.append(schema)
            self._chunk += _record(schema)
        channel = Channel(id=len(self._channel_records) + 1, topic=topic, message_encoding="cdr", schema_id=schema_id,
                          metadata={"offered_qos_profiles": self.qos_yaml, "topic_type_hash": type_hash(type_name)})
        self._channel_records.append(channel)
        self._chunk += _record(channel)
        self._sequence[channel.id] = 0
        return channel.id

    # -- the end --------------------------------------------------------------------

    def finish(self) -> None:
        """The last chunk, the data end, the summary, the footer and the magic."""
        self.flush()
        self._write(_record(DataEnd(data_section_crc=0)))
        summary_start = self.position
        summary = RecordBuilder()
        offsets = []
        stats = self.stats
        ids = {topic: channel for topic, (channel, _) in self.channels.items()}
        groups: list[tuple[Opcode, bytes | bytearray]] = [
            (Opcode.SCHEMA, _records(self._schema_records)),
            (Opcode.CHANNEL, _records(self._channel_records)),
            (Opcode.STATISTICS, _record(Statistics(
                message_count=stats.messages, schema_count=len(self._schema_records),
                channel_count=len(self._channel_records), attachment_count=0,
                metadata_count=len(self._metadata_indexes), chunk_count=self._chunk_count,
                message_start_time=stats.first_ns or 0, message_end_time=stats.last_ns or 0,
                channel_message_counts={ids[topic]: count for topic, count in stats.per_topic.items()}))),
            (Opcode.CHUNK_INDEX, self._chunk_index_records),
            (Opcode.ATTACHMENT_INDEX, b""),
            (Opcode.METADATA_INDEX, _records(self._metadata_indexes)),
        ]
        for opcode, records in groups:
            group_start = summary.count
            summary.write(records)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + group_start,
                                         group_length=summary.count - group_start))
        offset_start = summary_start + summary.count
        for offset in offsets:
            offset.write(summary)
        data: bytes = summary.end()  # type: ignore[no-untyped-call]  # mcap.data_stream has no annotations
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, offset_start), zlib.crc32(data))
        footer = _record(Footer(summary_start=summary_start, summary_offset_start=offset_start, summary_crc=crc))
        self._write(data + footer + MCAP_MAGIC)

    def _write(self, data: bytes | bytearray) -> None:
        """Write all of ``data`` (an unbuffered file may take part of it per call)."""
        view = memoryview(data)
        while view:
            written = self._stream.write(view)
            if written is None:  # a non-blocking file with no room: never ours
                raise BlockingIOError(f"the recording file took no data at offset {self.position}")
            self.position += written
            view = view[written:]

    # -- rosbag2 -----------------------------------------------------------------------

    def rosbag2_metadata(self, file_name: str) -> str:
        """rosbag2's BagMetadata (version 9) for this file, complete, as YAML."""
        stats = self.stats
        start = stats.first_ns or 0
        duration = (stats.last_ns - start) if stats.last_ns is not None else 0
        info = {
            "version": ROSBAG2_METADATA_VERSION,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": stats.messages,
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": topic, "type": type_name, "serialization_format": "cdr",
                        "offered_qos_profiles": self.qos_profiles,
                        "type_description_hash": type_hash(type_name),
                    },
                    "message_count": stats.per_topic.get(topic, 0),
                }
                for topic, (_, type_name) in self.channels.items()
            ],
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [file_name],
            "files": [{
                "path": file_name, "starting_time": {"nanoseconds_since_epoch": start},
                "duration": {"nanoseconds": duration}, "message_count": stats.messages,
            }],
            "custom_data": None,
            "ros_distro": ROS_DISTRO,
        }
        return plain_yaml(info)


def _record(record: McapRecord) -> bytes:
    """One record as bytes, written by mcap's record class."""
    builder = RecordBuilder()
    record.write(builder)
    data: bytes = builder.end()  # type: ignore[no-untyped-call]  # mcap.data_stream has no annotations
    return data


def _records(records: Sequence[McapRecord]) -> bytes:
    """Records one after the other, as bytes (a summary group)."""
    return b"".join(_record(record) for record in records)


__all__ = ["MAX_STAMP_NS", "ROSBAG2_METADATA_VERSION", "ROS_DISTRO", "BagFile", "EncodedRows", "RecordingStats",
           "RowGroup"]
