"""MCAP records for :mod:`friction_sim.io.reader`, read chunk by chunk.

The records are walked here with :mod:`struct` rather than with ``mcap``'s
:class:`~mcap.stream_reader.StreamReader`, because that builds a Python
object per message and per message-index entry (``breakup_chunk``: about 6
us a message, 170,000 messages/s; the message indexes after each chunk cost
as much again), which would set the read rate of a long recording; the walk
takes about 1 us a message.  Only three fixed layouts of the MCAP spec are
read by hand: a record's opcode and length, a Chunk's fields, a Message's
channel id, sequence, log and publish time; a message index is only
attributed to its channel.  Every other record is parsed by ``mcap``.

:func:`read_summary` reads what describes a finished file (header, schemas,
channels, statistics, metadata) through its footer, summary offsets and
metadata index, without touching the data: a few KiB whatever the length.
"""

from __future__ import annotations

import io
import struct
import zlib
from collections.abc import Callable, Iterator
from itertools import islice
from typing import IO, Any

from mcap.opcode import Opcode
from mcap.records import Channel as McapChannel
from mcap.records import Chunk, Footer, Header, Metadata, MetadataIndex, Schema, Statistics, SummaryOffset
from mcap.stream_reader import StreamReader

MCAP_MAGIC = b"\x89MCAP0\r\n"
RECORD = struct.Struct("<BQ")  # opcode, length: every MCAP record starts so
MESSAGE = struct.Struct("<HIQ")  # a Message record's channel id, sequence, log time
MESSAGE_DATA = RECORD.size + 22  # where its data starts: after those and the publish time
FOOTER = struct.Struct("<BQQQI")  # opcode, length, summary start, summary offset start, summary CRC
_SUMMARY_GROUPS = (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.STATISTICS, Opcode.METADATA_INDEX)


class Truncated(EOFError):
    """A read came back shorter than asked: the file ends inside a record."""


class ExactReads:
    """A file read exactly: counts the bytes read (the end of the last whole
    record) and raises :class:`Truncated` on a short read."""

    def __init__(self, raw: IO[bytes]) -> None:
        self._raw = raw
        self.position = 0

    def read(self, n: int = -1) -> bytes:
        """``n`` bytes (all with -1); Truncated if the file has fewer."""
        data = self._raw.read(n)
        self.position += len(data)
        if n >= 0 and len(data) < n:
            raise Truncated(f"wanted {n} bytes at {self.position - len(data)}, the file has {len(data)}")
        return data


CHUNK_HEAD = struct.Struct("<QQQI")  # a Chunk's start and end time, uncompressed size and CRC
#: A record :func:`data_records` yields for damage: (DAMAGED, the exception).
DAMAGED = -1


def data_records(stream: ExactReads, file_size: int) -> Iterator[tuple[int, Any]]:
    """(opcode, record) of the file's top-level records from its start, up to
    the footer and closing magic: chunks as mcap ``Chunk`` records, unopened;
    a message index as the id of the channel it indexes (which channels a
    chunk holds), without reading its entries; the others parsed by mcap.
    Damage (a short read, a length longer than the file, a bad magic) raises."""
    if stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
        raise ValueError("no MCAP magic at the start")
    while True:
        opcode, length = RECORD.unpack(stream.read(RECORD.size))
        if length > file_size:
            raise ValueError(f"a record of {length} bytes in a file of {file_size}")
        body = stream.read(length)
        if opcode == Opcode.CHUNK:
            yield opcode, _chunk(body)
        elif opcode == Opcode.MESSAGE_INDEX:
            yield opcode, int.from_bytes(body[:2], "little")
        elif opcode in _PARSED:
            record = parse_records(RECORD.pack(opcode, length) + body)[0]
            yield opcode, record
            if isinstance(record, Footer):
                if stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
                    raise ValueError("no MCAP magic after the footer")
                return


def until_damaged(records: Iterator[tuple[int, Any]]) -> Iterator[tuple[int, Any]]:
    """``records``, then (DAMAGED, the exception) if reading them raised."""
    try:
        yield from records
    except Exception as error:  # noqa: BLE001 - any damage ends the records; the caller decides
        yield DAMAGED, error


def _chunk(body: bytes) -> Chunk:
    """A Chunk record's fields (the MCAP spec's layout)."""
    start, end, size, crc = CHUNK_HEAD.unpack_from(body)
    pos = CHUNK_HEAD.size
    name_length = int.from_bytes(body[pos:pos + 4], "little")
    compression = body[pos + 4:pos + 4 + name_length].decode("utf-8")
    pos += 4 + name_length
    data_length = int.from_bytes(body[pos:pos + 8], "little")
    data = body[pos + 8:pos + 8 + data_length]
    if len(data) != data_length:
        raise ValueError("a chunk's records run past its end")
    return Chunk(compression=compression, data=data, message_end_time=end, message_start_time=start,
                 uncompressed_crc=crc, uncompressed_size=size)


_PARSED = frozenset(int(o) for o in Opcode) - {Opcode.CHUNK, Opcode.MESSAGE_INDEX}


def chunk_data(chunk: Chunk) -> bytes:
    """The records of a chunk, decompressed and CRC-checked (ValueError if damaged)."""
    if chunk.compression == "zstd":
        import zstandard

        data = zstandard.decompress(chunk.data, max_output_size=chunk.uncompressed_size)
    elif chunk.compression == "lz4":
        import lz4.frame  # type: ignore[import-untyped]  # no type information

        data = lz4.frame.decompress(chunk.data)
    elif chunk.compression == "":
        data = bytes(chunk.data)
    else:
        raise ValueError(f"chunk compression {chunk.compression!r} is not supported")
    if len(data) != chunk.uncompressed_size:
        raise ValueError(f"chunk holds {len(data)} bytes, its record says {chunk.uncompressed_size}")
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        raise ValueError("chunk CRC mismatch")
    return data


def chunk_messages(data: bytes, wanted: dict[int, str],
                   make: Callable[[str, int, bytes], Any]) -> list[Any]:
    """``make(topic, log time, data)`` of each message of a chunk whose channel
    is in ``wanted`` (channel id -> topic), in chunk order."""
    out: list[Any] = []
    append = out.append
    record, message = RECORD.unpack_from, MESSAGE.unpack_from
    pos, end = 0, len(data)
    while pos < end:
        opcode, length = record(data, pos)
        if opcode == 0x05:  # Opcode.MESSAGE (a literal: this loop runs per message)
            channel, _, log_time = message(data, pos + RECORD.size)
            topic = wanted.get(channel)
            if topic is not None:
                append(make(topic, log_time, data[pos + MESSAGE_DATA:pos + RECORD.size + length]))
        pos += RECORD.size + length
    return out


def chunk_counts(data: bytes) -> tuple[dict[int, int], int | None, int | None, list[Any]]:
    """Of one chunk: messages per channel id, the earliest and latest log
    times (None without messages) and its schema and channel records."""
    counts: dict[int, int] = {}
    first: int | None = None
    last: int | None = None
    others: list[Any] = []
    record, message = RECORD.unpack_from, MESSAGE.unpack_from
    pos, end = 0, len(data)
    while pos < end:
        opcode, length = record(data, pos)
        stop = pos + RECORD.size + length
        if stop > end:
            raise ValueError("a record runs past the end of its chunk")
        if opcode == 0x05:
            channel, _, log_time = message(data, pos + RECORD.size)
            counts[channel] = counts.get(channel, 0) + 1
            first = log_time if first is None or log_time < first else first
            last = log_time if last is None or log_time > last else last
        elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
            others.extend(parse_records(data[pos:stop]))
        pos = stop
    return counts, first, last, others


def parse_records(data: bytes) -> list[Any]:
    """The whole records in ``data`` (no magic), parsed by mcap."""
    count, pos = 0, 0
    while pos < len(data):
        pos += RECORD.size + RECORD.unpack_from(data, pos)[1]
        count += 1
    if pos != len(data):
        raise ValueError("the last record runs past the end")
    return list(islice(StreamReader(io.BytesIO(data), skip_magic=True).records, count))


def _read_at(stream: IO[bytes], offset: int, length: int) -> bytes:
    """``length`` bytes at ``offset`` (Truncated if the file has fewer)."""
    stream.seek(offset)
    data = stream.read(length)
    if len(data) != length:
        raise Truncated(f"wanted {length} bytes at {offset}, the file has {len(data)}")
    return data


class Summary:
    """What describes a finished file, without its data."""

    def __init__(self) -> None:
        self.header: Header | None = None
        self.schemas: list[Schema] = []
        self.channels: list[McapChannel] = []
        self.statistics: Statistics | None = None
        self.metadata: list[Metadata] = []


def read_summary(stream: IO[bytes], file_size: int) -> Summary | None:
    """The summary of a finished file (footer, summary and statistics present),
    else None: then only a pass over the data can say what the file holds.
    Damage in what is read raises (ValueError, Truncated, mcap's errors)."""
    footer_at = file_size - len(MCAP_MAGIC) - FOOTER.size
    if footer_at < len(MCAP_MAGIC):
        return None
    tail = _read_at(stream, footer_at, FOOTER.size + len(MCAP_MAGIC))
    opcode, length, summary_start, offsets_start, _ = FOOTER.unpack_from(tail)
    if tail[FOOTER.size:] != MCAP_MAGIC or opcode != Opcode.FOOTER or length != 20 or summary_start == 0:
        return None
    summary = Summary()
    head = _read_at(stream, len(MCAP_MAGIC), RECORD.size)
    header = parse_records(head + _read_at(stream, len(MCAP_MAGIC) + RECORD.size, RECORD.unpack(head)[1]))
    summary.header = header[0] if header and isinstance(header[0], Header) else None
    for record in _summary_records(stream, summary_start, offsets_start, footer_at):
        if isinstance(record, Schema):
            summary.schemas.append(record)
        elif isinstance(record, McapChannel):
            summary.channels.append(record)
        elif isinstance(record, Statistics):
            summary.statistics = record
        elif isinstance(record, MetadataIndex):
            summary.metadata.extend(r for r in parse_records(_read_at(stream, record.offset, record.length))
                                    if isinstance(r, Metadata))
    return summary if summary.statistics is not None and summary.header is not None else None


def _summary_records(stream: IO[bytes], summary_start: int, offsets_start: int, footer_at: int) -> list[Any]:
    """The summary's schemas, channels, statistics and metadata indexes: only
    their groups when the file has summary offsets (so that the chunk
    indexes of a long file are never read), else the whole summary."""
    if offsets_start == 0:
        return [r for r in parse_records(_read_at(stream, summary_start, footer_at - summary_start))
                if not isinstance(r, Footer)]
    records: list[Any] = []
    for offset in parse_records(_read_at(stream, offsets_start, footer_at - offsets_start)):
        if isinstance(offset, SummaryOffset) and offset.group_opcode in _SUMMARY_GROUPS:
            records += parse_records(_read_at(stream, offset.group_start, offset.group_length))
    return records


__all__ = [
    "DAMAGED", "FOOTER", "MCAP_MAGIC", "MESSAGE", "MESSAGE_DATA", "RECORD", "ExactReads", "Summary", "Truncated",
    "chunk_counts", "chunk_data", "chunk_messages", "data_records", "parse_records", "read_summary",
    "until_damaged",
]
