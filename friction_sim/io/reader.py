"""Reading a recording: :func:`read_recording` -> :class:`Recording`, streamed.

:func:`read_recording` reads only what describes the file.  A finished
file (footer, summary, statistics) is described by its summary and metadata
records, found through the summary offsets and the metadata index: a few
KiB read, whatever the length.  A file whose writer was killed or failed
(a full disk: no footer) is read once from the start, record by record with
``mcap``'s :class:`~mcap.stream_reader.StreamReader`, keeping counts, never
messages, up to the end of its last complete record;
:meth:`Recording.recovery_note` says how much was recovered.

Messages are read when asked for, chunk by chunk (:meth:`Recording.iter_chunks`,
:meth:`Recording.iter_messages`, see :mod:`friction_sim.io.chunks`): memory
holds one chunk at a time whatever the length of the file.  They stay
serialized (:class:`RawMessage`); :meth:`Recording.decode` decodes one with
rosbags (:mod:`friction_sim.io.cdr`), without ROS.  ``messages``,
``messages_on`` and ``decoded`` collect lists, for short files and tests.

Topic names: recordings store fully qualified names the way rosbag2 does
(``/pose``, ``/feeder1/pose``); older friction_sim recordings stored them
relative (``pose``).  Every method that takes a topic takes either the
stored name or the name relative to the recorded node (``pose``,
``events``): :meth:`Recording.topic_name` resolves it.

The ``external_wrench`` convention: a file records in its ``friction_sim``
metadata record which way ``external_force_z`` points
(``external_force_z_convention: lifts``, z away from the track).  A file
without the key was written before, when positive force.z pressed the
slider on the track; :attr:`Recording.external_force_z_sign` (-1 for such a
file) turns its commands and parameters into today's convention
(:func:`friction_sim.experiment.verify.recorded_commands` and
:func:`~friction_sim.experiment.verify.initial_parameters` apply it).

Errors (missing file, not MCAP, not a friction_sim recording, a finished
file damaged in its middle, a file with dropped messages where the tool
needs all of them) raise :class:`~friction_sim.errors.RecordingError` with
one line.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, NamedTuple

from mcap.opcode import Opcode

from friction_sim.errors import RecordingError
from friction_sim.io import cdr
from friction_sim.io.chunks import (
    DAMAGED,
    MCAP_MAGIC,
    ExactReads,
    chunk_counts,
    chunk_data,
    chunk_messages,
    data_records,
    read_summary,
    until_damaged,
)
from friction_sim.io.messages import message_class, ns_to_seconds
from friction_sim.io.recorder import CONVENTION_KEY, LIFTS, LOADS, METADATA_NAME, SUMMARY_METADATA_NAME

#: The topic every friction_sim recording has; its namespace is the recording's.
POSE = "pose"


@dataclass(frozen=True)
class Channel:
    """One recorded topic (``topic`` as stored in the file)."""

    id: int
    topic: str
    type_name: str
    encoding: str
    metadata: dict[str, str]


class RawMessage(NamedTuple):
    """One recorded message, still serialized (CDR); ``topic`` as stored."""

    topic: str
    log_time: int
    data: bytes


@dataclass
class Recording:
    """What describes a recording; its messages are read on demand.

    ``complete`` is False when the file has no footer (its writer was killed,
    or failed); then the messages are those flushed before, and
    ``truncated_bytes`` counts the bytes at the end that were incomplete.
    ``counts`` is messages per channel id, ``start_ns``/``end_ns`` the log
    time range [ns] (0 without messages).
    """

    path: Path
    profile: str = ""
    library: str = ""
    schemas: dict[int, tuple[str, str, bytes]] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    statistics: Any = None
    complete: bool = False
    truncated_bytes: int = 0
    file_size: int = 0
    chunks: int = 0
    counts: dict[int, int] = field(default_factory=dict)
    start_ns: int = 0
    end_ns: int = 0

    # -- topics --------------------------------------------------------------------

    @property
    def topics(self) -> dict[str, Channel]:
        """stored topic -> channel, in order of first appearance."""
        return {channel.topic: channel for channel in self.channels.values()}

    @property
    def namespace_prefix(self) -> str:
        """What the recorded node's topics start with: ``""`` for an old file
        (``pose``), ``"/"`` at the root (``/pose``), ``"/feeder1/"``.  Taken
        from the pose topic (the one with most messages if several)."""
        candidates = [c for c in self.channels.values()
                      if c.topic.lstrip("/") == POSE or c.topic.endswith("/" + POSE)]
        if not candidates:
            return ""
        best = max(candidates, key=lambda c: self.counts.get(c.id, 0))
        return best.topic[:-len(POSE)]

    def topic_name(self, name: str) -> str | None:
        """The stored name of topic ``name`` (stored, absolute or relative to
        the recorded node), or None if the file has no such topic."""
        topics = self.topics
        if name in topics:
            return name
        relative = name.lstrip("/")
        for candidate in (self.namespace_prefix + relative, relative, "/" + relative):
            if candidate in topics:
                return candidate
        matches = [topic for topic in topics if topic.endswith("/" + relative)]
        return matches[0] if len(matches) == 1 else None

    def relative_name(self, topic: str) -> str:
        """A stored name relative to the recorded node (``/feeder1/pose`` -> ``pose``)."""
        prefix = self.namespace_prefix
        return topic[len(prefix):] if prefix and topic.startswith(prefix) else topic.lstrip("/")

    def count(self, topic: str) -> int:
        """Messages on ``topic`` (0 if the file has no such topic)."""
        stored = self.topic_name(topic)
        return sum(n for cid, n in self.counts.items()
                   if cid in self.channels and self.channels[cid].topic == stored) if stored else 0

    @property
    def message_count(self) -> int:
        """Messages in the file (the readable part of an unfinished one)."""
        return sum(self.counts.values())

    def type_name(self, topic: str) -> str:
        """The message type name of ``topic`` (its schema name)."""
        stored = self.topic_name(topic)
        if stored is None:
            raise RecordingError(f"{self.path}: no topic {topic!r}")
        return self.topics[stored].type_name

    def message_type(self, topic: str) -> type:
        """The generated ROS 2 message class of ``topic`` (to publish or subscribe to it)."""
        return message_class(self.type_name(topic))

    # -- messages, streamed ------------------------------------------------------

    def iter_chunks(self, topics: Iterable[str] | None = None) -> Iterator[list[RawMessage]]:
        """The messages of ``topics`` (default: all), a list per chunk, in file
        order; only one chunk is in memory at a time, and a chunk whose
        message indexes show none of ``topics`` is not even decompressed.  A
        topic the file does not have is simply not there."""
        wanted = self._wanted(topics)
        if not wanted:
            return
        with _open(self.path) as stream:
            exact = ExactReads(stream)
            pending: Any = None  # the last chunk, opened once the indexes after it are known
            present: set[int] = set()
            for opcode, record in until_damaged(data_records(exact, self.file_size)):
                if opcode == Opcode.MESSAGE_INDEX:
                    present.add(record)
                    continue
                if pending is not None and (not present or not present.isdisjoint(wanted)):
                    block = self._open_chunk(pending, wanted, exact.position)
                    if block:
                        yield block
                pending = None
                if opcode == Opcode.CHUNK:
                    pending, present = record, set()
                elif opcode == Opcode.MESSAGE and record.channel_id in wanted:
                    yield [RawMessage(wanted[record.channel_id], record.log_time, bytes(record.data))]
                elif opcode == DAMAGED:
                    self._damaged(exact.position, record)
                    return
                elif opcode == Opcode.DATA_END:
                    return

    def _open_chunk(self, chunk: Any, wanted: dict[int, str], position: int) -> list[RawMessage]:
        """The wanted messages of a chunk; damage inside it as :meth:`_damaged`."""
        try:
            return chunk_messages(chunk_data(chunk), wanted, RawMessage)
        except Exception as error:  # noqa: BLE001 - a bad CRC, zstd error, garbage inside
            self._damaged(position, error)
            return []

    def _damaged(self, position: int, error: BaseException) -> None:
        """Damage while reading messages: the end of an unfinished file (its
        scan stopped at the same place), an error in a finished one."""
        if not self.complete:
            return
        raise RecordingError(f"{self.path} is damaged near byte {position} "
                             f"({type(error).__name__}: {' '.join(str(error).split())})")

    def _wanted(self, topics: Iterable[str] | None) -> dict[int, str]:
        """channel id -> stored topic of the channels to read."""
        if topics is None:
            return {cid: channel.topic for cid, channel in self.channels.items()}
        stored = {self.topic_name(topic) for topic in topics} - {None}
        return {cid: channel.topic for cid, channel in self.channels.items() if channel.topic in stored}

    def iter_messages(self, topics: Iterable[str] | None = None) -> Iterator[RawMessage]:
        """The messages of ``topics`` (default: all), one by one in file order, streamed."""
        for block in self.iter_chunks(topics):
            yield from block

    def iter_decoded(self, topic: str) -> Iterator[tuple[int, Any]]:
        """(log time [ns], message) of every message on ``topic``, streamed."""
        for raw in self.iter_messages([topic]):
            yield raw.log_time, self.decode(raw)

    def decode(self, raw: RawMessage) -> Any:
        """Deserialize one message (a rosbags dataclass: same fields as the ROS class)."""
        return cdr.deserialize(raw.data, self.type_name(raw.topic))

    @property
    def messages(self) -> list[RawMessage]:
        """Every message, in file order: the whole file in memory (short files
        and tests; the tools stream with :meth:`iter_chunks`)."""
        return list(self.iter_messages())

    def messages_on(self, topic: str) -> list[RawMessage]:
        """The messages of one topic, in file order (a list: that topic in memory)."""
        return list(self.iter_messages([topic]))

    def decoded(self, topic: str) -> list[tuple[int, Any]]:
        """(log time [ns], message) of every message on ``topic`` (a list)."""
        return list(self.iter_decoded(topic))

    # -- conventions -------------------------------------------------------------------

    @property
    def external_force_z_convention(self) -> str:
        """Which way the file's ``external_force_z`` (``external_wrench`` force.z)
        points: ``lifts`` (away from the track: written since the key exists)
        or ``loads`` (a file without the key: > 0 pressed the slider on the track)."""
        return self.metadata.get(METADATA_NAME, {}).get(CONVENTION_KEY, LOADS)

    @property
    def external_force_z_sign(self) -> float:
        """What the file's ``external_force_z`` values are multiplied by to mean
        what they mean today (z away from the track): 1.0, or -1.0 for a file
        in the old ``loads`` convention.  RecordingError for a convention this
        version does not know."""
        convention = self.external_force_z_convention
        if convention == LIFTS:
            return 1.0
        if convention == LOADS:
            return -1.0
        raise RecordingError(f"{self.path}: {CONVENTION_KEY} = {convention!r} is not known "
                             f"(known: {LIFTS}, {LOADS})")

    # -- notes -------------------------------------------------------------------------

    @property
    def dropped(self) -> int | None:
        """Messages the recorder dropped (None: not known, e.g. not finished)."""
        summary = self.metadata.get(SUMMARY_METADATA_NAME)
        try:
            return int(summary["dropped"]) if summary else None
        except (KeyError, ValueError):
            return None

    def refuse_dropped(self, what: str) -> None:
        """RecordingError (one line, with the count) if the recorder dropped
        messages: then no summary or re-simulation of the file can be right."""
        if self.dropped:
            raise RecordingError(f"{self.path}: {self.dropped} messages were dropped while recording; "
                                 f"the file cannot be {what}")

    def recovery_note(self) -> str | None:
        """The one line that says what was recovered from an unfinished file."""
        if self.complete:
            return None
        return (f"recovered {self.message_count} messages up to t = {ns_to_seconds(self.end_ns):.6f} s; "
                f"the file has no footer (writer killed?)")

    def is_friction_sim(self) -> bool:
        """Whether the file is a friction_sim recording (its metadata record and a pose topic)."""
        return METADATA_NAME in self.metadata and self.topic_name(POSE) is not None

    def info_lines(self) -> list[str]:
        """A ``ros2 bag info``-like summary."""
        lines = [
            f"File:       {self.path} ({_size(self.file_size)}, {self.chunks} chunks)",
            f"Profile:    {self.profile}   library: {self.library}",
            f"Time:       {ns_to_seconds(self.start_ns):.6f} .. {ns_to_seconds(self.end_ns):.6f} s "
            f"(simulation time)",
            f"Messages:   {self.message_count}",
        ]
        if self.dropped:
            lines.append(f"Dropped:    {self.dropped} messages while recording")
        width = max((len(t) for t in self.topics), default=0)
        for number, (topic, channel) in enumerate(self.topics.items()):
            label = "Topics:" if number == 0 else ""
            lines.append(f"{label:<12}{topic:<{width}}  {channel.type_name:<38} {self.counts.get(channel.id, 0)}")
        meta = self.metadata.get(METADATA_NAME, {})
        if meta:
            lines.append("Parameters: " + ", ".join(f"{k} = {v}" for k, v in meta.items()
                                                    if k not in ("format", CONVENTION_KEY)))
            words = _CONVENTION_WORDS.get(self.external_force_z_convention, self.external_force_z_convention)
            lines.append(f"Convention: external_wrench force.z > 0 {words}"
                         + ("" if CONVENTION_KEY in meta else " (a file written before the convention was marked)"))
        return lines

    # -- filling it in ------------------------------------------------------------

    def take(self, record: Any) -> None:
        """Take one descriptive record (schema, channel, metadata, statistics, header)."""
        from mcap.records import Channel as McapChannel
        from mcap.records import Header, Metadata, Schema, Statistics

        if isinstance(record, Schema):
            self.schemas.setdefault(record.id, (record.name, record.encoding, bytes(record.data)))
        elif isinstance(record, McapChannel) and record.id not in self.channels:
            schema = self.schemas.get(record.schema_id, ("", "", b""))
            self.channels[record.id] = Channel(record.id, record.topic, schema[0], record.message_encoding,
                                               dict(record.metadata))
        elif isinstance(record, Metadata):
            self.metadata[record.name] = dict(record.metadata)
        elif isinstance(record, Statistics):
            self.statistics = record
        elif isinstance(record, Header):
            self.profile, self.library = record.profile, record.library

    def add_counts(self, counts: dict[int, int], first: int | None, last: int | None) -> None:
        """Add the messages of one chunk (or one message) to the counts and the time range."""
        had = bool(self.counts)
        for cid, n in counts.items():
            self.counts[cid] = self.counts.get(cid, 0) + n
        if first is not None and last is not None:
            self.start_ns = first if not had else min(self.start_ns, first)
            self.end_ns = last if not had else max(self.end_ns, last)


_CONVENTION_WORDS = {LIFTS: "lifts (z away from the track)", LOADS: "loads the contact (the old convention)"}


def read_recording(path: str | Path, *, require_friction_sim: bool = True) -> Recording:
    """Describe a recording (its messages are read later, streamed).

    Raises :class:`RecordingError` for a missing file, a file that is not
    MCAP, and (with ``require_friction_sim``) an MCAP file that has no
    ``friction_sim`` metadata record or no ``pose`` topic.
    """
    path = Path(path)
    with _open(path) as stream:
        if stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise RecordingError(f"not an MCAP file: {path}")
        size = path.stat().st_size
        recording = _from_summary(stream, path, size)
        if recording is None:
            recording = Recording(path, file_size=size)
            stream.seek(0)
            _scan(stream, recording)
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


def _from_summary(stream: IO[bytes], path: Path, size: int) -> Recording | None:
    """A finished file described from its summary; None if it has none (or a damaged one)."""
    try:
        summary = read_summary(stream, size)
    except Exception:  # noqa: BLE001 - a damaged summary: the scan reads what the data holds
        return None
    if summary is None or summary.statistics is None:
        return None
    recording = Recording(path, file_size=size, complete=True)
    for record in [summary.header, *summary.schemas, *summary.channels, *summary.metadata]:
        recording.take(record)
    stats = summary.statistics
    recording.statistics = stats
    recording.chunks = stats.chunk_count
    recording.counts = {cid: n for cid, n in stats.channel_message_counts.items() if n}
    if stats.message_count:
        recording.start_ns, recording.end_ns = stats.message_start_time, stats.message_end_time
    return recording


def _scan(stream: IO[bytes], recording: Recording) -> None:
    """Describe ``recording`` from its data, up to the end of the last complete record.

    A record is taken only once it is read whole (a chunk: read, CRC-checked
    and decompressed), so the position after each is the end of what can be
    kept.  Damage of any kind ends the reading: a short read, a cut header,
    a bad CRC, a zstd error, a garbage length, a bad closing magic.
    """
    exact = ExactReads(stream)
    end = 0
    in_summary = False
    for opcode, record in until_damaged(data_records(exact, recording.file_size)):
        if opcode == DAMAGED:
            break
        if opcode == Opcode.CHUNK:
            try:
                counts, first, last, others = chunk_counts(chunk_data(record))
            except Exception:  # noqa: BLE001 - a damaged chunk ends what can be recovered
                break
            for other in others:
                recording.take(other)
            recording.add_counts(counts, first, last)
            recording.chunks += 1
        elif opcode == Opcode.MESSAGE and not in_summary:
            recording.add_counts({record.channel_id: 1}, record.log_time, record.log_time)
        elif opcode != Opcode.MESSAGE_INDEX:
            in_summary = in_summary or opcode == Opcode.DATA_END
            if not in_summary or opcode in (Opcode.METADATA, Opcode.STATISTICS):
                recording.take(record)
        end = exact.position
    else:
        recording.complete = True  # data_records ends only after the footer and the closing magic
    recording.truncated_bytes = recording.file_size - max(end, len(MCAP_MAGIC))


def _size(n: float) -> str:
    """A byte count for people (``12.3 KiB``)."""
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n} B"


__all__ = ["MCAP_MAGIC", "POSE", "Channel", "RawMessage", "Recording", "read_recording"]
