"""Reading a recording: :func:`read_recording` -> :class:`Recording`.

The file is read with ``mcap``'s :class:`~mcap.stream_reader.StreamReader`,
record by record from the start: no summary is needed, so a file whose
writer was killed (no footer) is read up to its last complete record, and
:meth:`Recording.recovery_note` says how much was recovered.  Messages stay
serialized (:class:`RawMessage`); :meth:`Recording.decode` decodes one with
rosbags (:mod:`friction_sim.io.cdr`), without ROS.

Errors (missing file, not MCAP, not a friction_sim recording) raise
:class:`~friction_sim.errors.RecordingError` with one line.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from friction_sim.errors import RecordingError
from friction_sim.io import cdr
from friction_sim.io.messages import message_class, ns_to_seconds
from friction_sim.io.recorder import METADATA_NAME, SUMMARY_METADATA_NAME

MCAP_MAGIC = b"\x89MCAP0\r\n"


@dataclass(frozen=True)
class Channel:
    """One recorded topic."""

    id: int
    topic: str
    type_name: str
    encoding: str
    metadata: dict[str, str]


@dataclass(frozen=True)
class RawMessage:
    """One recorded message, still serialized (CDR)."""

    topic: str
    log_time: int
    data: bytes


@dataclass
class Recording:
    """Everything read from a recording, in file order.

    ``complete`` is False when the file has no footer (its writer was
    killed); then ``messages`` holds what was flushed before, and
    ``truncated_bytes`` how many bytes at the end were incomplete.
    """

    path: Path
    profile: str = ""
    library: str = ""
    schemas: dict[int, tuple[str, str, bytes]] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    messages: list[RawMessage] = field(default_factory=list)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    statistics: Any = None
    complete: bool = False
    truncated_bytes: int = 0
    file_size: int = 0
    chunks: int = 0
    _by_topic: dict[str, list[RawMessage]] | None = field(default=None, repr=False)

    # -- topics and messages -----------------------------------------------------

    @property
    def topics(self) -> dict[str, Channel]:
        """topic -> channel, in order of first appearance."""
        return {channel.topic: channel for channel in self.channels.values()}

    def messages_on(self, topic: str) -> list[RawMessage]:
        """The messages of one topic, in file order."""
        if self._by_topic is None:
            by_topic: dict[str, list[RawMessage]] = {}
            for raw in self.messages:
                by_topic.setdefault(raw.topic, []).append(raw)
            self._by_topic = by_topic
        return self._by_topic.get(topic, [])

    def type_name(self, topic: str) -> str:
        """The message type name of ``topic`` (its schema name)."""
        channel = self.topics.get(topic)
        if channel is None:
            raise RecordingError(f"{self.path}: no topic {topic!r}")
        return channel.type_name

    def message_type(self, topic: str) -> type:
        """The generated ROS 2 message class of ``topic`` (to publish or subscribe to it)."""
        return message_class(self.type_name(topic))

    def decode(self, raw: RawMessage) -> Any:
        """Deserialize one message (a rosbags dataclass: same fields as the ROS class)."""
        return cdr.deserialize(raw.data, self.type_name(raw.topic))

    def decoded(self, topic: str) -> list[tuple[int, Any]]:
        """(log time [ns], message) of every message on ``topic``."""
        return [(raw.log_time, self.decode(raw)) for raw in self.messages_on(topic)]

    # -- times and notes -------------------------------------------------------------

    @property
    def start_ns(self) -> int:
        """The earliest log time [ns] (0 without messages)."""
        return min((m.log_time for m in self.messages), default=0)

    @property
    def end_ns(self) -> int:
        """The latest log time [ns] (0 without messages)."""
        return max((m.log_time for m in self.messages), default=0)

    @property
    def dropped(self) -> int | None:
        """Messages the recorder dropped (None: not known, e.g. not finished)."""
        summary = self.metadata.get(SUMMARY_METADATA_NAME)
        try:
            return int(summary["dropped"]) if summary else None
        except (KeyError, ValueError):
            return None

    def recovery_note(self) -> str | None:
        """The one line that says what was recovered from an unfinished file."""
        if self.complete:
            return None
        return (f"recovered {len(self.messages)} messages up to t = {ns_to_seconds(self.end_ns):.6f} s; "
                f"the file has no footer (writer killed?)")

    def is_friction_sim(self) -> bool:
        """Whether the file is a friction_sim recording (its metadata record and a pose topic)."""
        return METADATA_NAME in self.metadata and "pose" in self.topics

    def info_lines(self) -> list[str]:
        """A ``ros2 bag info``-like summary."""
        lines = [
            f"File:       {self.path} ({_size(self.file_size)}, {self.chunks} chunks)",
            f"Profile:    {self.profile}   library: {self.library}",
            f"Time:       {ns_to_seconds(self.start_ns):.6f} .. {ns_to_seconds(self.end_ns):.6f} s "
            f"(simulation time)",
            f"Messages:   {len(self.messages)}",
        ]
        if self.dropped:
            lines.append(f"Dropped:    {self.dropped} messages (the recorder fell behind)")
        width = max((len(t) for t in self.topics), default=0)
        for number, (topic, channel) in enumerate(self.topics.items()):
            label = "Topics:" if number == 0 else ""
            lines.append(f"{label:<12}{topic:<{width}}  {channel.type_name:<38} {len(self.messages_on(topic))}")
        meta = self.metadata.get(METADATA_NAME, {})
        if meta:
            lines.append("Parameters: " + ", ".join(f"{k} = {v}" for k, v in meta.items() if k != "format"))
        return lines

    # -- filling it in ------------------------------------------------------------

    def add(self, record: Any) -> None:
        """Take one record read from the file (others than these are ignored)."""
        from mcap.records import Channel as McapChannel
        from mcap.records import Message, Metadata, Schema, Statistics

        if isinstance(record, Message):
            channel = self.channels.get(record.channel_id)
            if channel is not None:
                self.messages.append(RawMessage(channel.topic, record.log_time, bytes(record.data)))
        elif isinstance(record, Schema):
            self.schemas.setdefault(record.id, (record.name, record.encoding, bytes(record.data)))
        elif isinstance(record, McapChannel) and record.id not in self.channels:
            schema = self.schemas.get(record.schema_id, ("", "", b""))
            self.channels[record.id] = Channel(record.id, record.topic, schema[0], record.message_encoding,
                                               dict(record.metadata))
        elif isinstance(record, Metadata):
            self.metadata[record.name] = dict(record.metadata)
        elif isinstance(record, Statistics):
            self.statistics = record


def read_recording(path: str | Path, *, require_friction_sim: bool = True) -> Recording:
    """Read a recording as far as it holds complete records.

    Raises :class:`RecordingError` for a missing file, a file that is not
    MCAP, and (with ``require_friction_sim``) an MCAP file that has no
    ``friction_sim`` metadata record or no ``pose`` topic.
    """
    path = Path(path)
    with _open(path) as stream:
        if stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise RecordingError(f"not an MCAP file: {path}")
        stream.seek(0)
        recording = Recording(path, file_size=path.stat().st_size)
        _read_records(stream, recording)
    if require_friction_sim and not recording.is_friction_sim():
        missing = "no friction_sim metadata record" if METADATA_NAME not in recording.metadata else "no pose topic"
        raise RecordingError(f"not a friction_sim recording ({missing}): {path}")
    return recording


def _open(path: Path) -> IO[bytes]:
    """The file opened for reading; a one-line RecordingError if it cannot be."""
    try:
        return path.open("rb")
    except FileNotFoundError:
        raise RecordingError(f"no such file: {path}") from None
    except IsADirectoryError:
        raise RecordingError(f"is a directory, not a recording: {path}") from None
    except OSError as error:
        raise RecordingError(f"cannot read {path}: {error.strerror or error}") from None


class _Truncated(EOFError):
    """A read came back shorter than asked: the file ends inside a record."""


class _ExactReads:
    """A file for StreamReader that counts the bytes read and raises
    :class:`_Truncated` on a short read (StreamReader returns short reads
    silently).  Deliberately not an io.RawIOBase, which StreamReader would
    wrap in a buffer, hiding the position."""

    def __init__(self, raw: IO[bytes]) -> None:
        self._raw = raw
        self.position = 0

    def read(self, n: int = -1) -> bytes:
        """``n`` bytes (all with -1); _Truncated if the file has fewer."""
        data = self._raw.read(n)
        self.position += len(data)
        if n >= 0 and len(data) < n:
            raise _Truncated(f"wanted {n} bytes at {self.position - len(data)}, the file has {len(data)}")
        return data


def _read_records(stream: IO[bytes], recording: Recording) -> None:
    """Fill ``recording`` from ``stream`` up to the end of the last complete record.

    StreamReader yields a record only once it is read whole (a chunk: read,
    CRC-checked and decompressed), so the position at each yield is the end
    of what can be kept.  Damage of any kind ends the reading: a short read,
    struct.error in a cut header, EndOfFile, a bad CRC (a ValueError), a zstd
    error, a garbage length, a bad closing magic.
    """
    exact = _ExactReads(stream)
    end = 0
    try:
        for records in _records(exact, recording):
            for record in records:
                recording.add(record)
            end = exact.position
        recording.complete = True
        end = exact.position
    except Exception:  # noqa: BLE001 - damage ends what can be recovered (see the docstring)
        end = max(end, len(MCAP_MAGIC))
    recording.truncated_bytes = recording.file_size - end


def _records(stream: _ExactReads, recording: Recording) -> Iterator[list[Any]]:
    """For each record of the file, in file order, the records to keep: those
    inside a chunk, a data section's record, the summary's metadata and
    statistics (not its repeated schemas, channels and indexes).  Sets the
    header fields and counts chunks."""
    from mcap.records import Chunk, DataEnd, Header, Metadata, Statistics
    from mcap.stream_reader import StreamReader, breakup_chunk

    reader = StreamReader(stream, emit_chunks=True,  # type: ignore[arg-type]  # any object with read()
                          record_size_limit=max(recording.file_size, 1024))
    in_summary = False
    for record in reader.records:
        if isinstance(record, Header):
            recording.profile, recording.library = record.profile, record.library
            yield []
        elif isinstance(record, Chunk):
            yield breakup_chunk(record, validate_crc=True)
            recording.chunks += 1
        else:
            in_summary = in_summary or isinstance(record, DataEnd)
            yield [record] if not in_summary or isinstance(record, (Metadata, Statistics)) else []


def _size(n: float) -> str:
    """A byte count for people (``12.3 KiB``)."""
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n} B"


__all__ = ["MCAP_MAGIC", "Channel", "RawMessage", "Recording", "read_recording"]
