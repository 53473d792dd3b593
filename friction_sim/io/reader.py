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

What describes the file (topics, counts, the ``external_wrench``
convention, notes) is :class:`~friction_sim.io.recordinfo.RecordingInfo`'s,
which :class:`Recording` extends with the file's messages; every method that
takes a topic takes the stored name or the name relative to the recorded
node (``pose``).

Errors (missing file, not MCAP, not a friction_sim recording, a finished
file damaged in its middle, a file with dropped messages where the tool
needs all of them) raise :class:`~friction_sim.errors.RecordingError` with
one line.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
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
from friction_sim.io.recorder import METADATA_NAME
from friction_sim.io.recordinfo import POSE, Channel, RecordingInfo


class RawMessage(NamedTuple):
    """One recorded message, still serialized (CDR); ``topic`` as stored."""

    topic: str
    log_time: int
    data: bytes


@dataclass
class Recording(RecordingInfo):
    """A recording: what describes it (:class:`~friction_sim.io.recordinfo.RecordingInfo`)
    and its messages, read on demand, streamed chunk by chunk, and decoded
    when asked for.  Its fields are RecordingInfo's; of an unfinished file
    (``complete`` False) the messages are those its writer flushed.
    """

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


__all__ = ["MCAP_MAGIC", "POSE", "Channel", "RawMessage", "Recording", "read_recording"]
