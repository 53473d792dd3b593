"""What describes a recording: its topics, counts, conventions and notes (:class:`RecordingInfo`).

The description of an MCAP file as :func:`friction_sim.io.reader.read_recording`
finds it (from the summary of a finished file, or by a scan of an unfinished
one): schemas, channels, metadata, statistics, the message counts per
channel and the log time range.  No messages: reading them, streamed, is
:class:`friction_sim.io.reader.Recording`'s, which is a RecordingInfo with
the file's messages to read.

Topic names: recordings store fully qualified names the way rosbag2 does
(``/pose``, ``/feeder1/pose``); older friction_sim recordings stored them
relative (``pose``).  Every method that takes a topic takes either the
stored name or the name relative to the recorded node (``pose``,
``events``): :meth:`RecordingInfo.topic_name` resolves it.

The ``external_wrench`` convention: a file records in its ``friction_sim``
metadata record which way ``external_force_z`` points
(``external_force_z_convention: lifts``, z away from the track).  A file
without the key was written before, when positive force.z pressed the
slider on the track; :attr:`RecordingInfo.external_force_z_sign` (-1 for
such a file) turns its commands and parameters into today's convention
(:func:`friction_sim.experiment.verify.recorded_commands` and
:func:`~friction_sim.experiment.verify.initial_parameters` apply it).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from friction_sim.errors import RecordingError
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


@dataclass
class RecordingInfo:
    """What describes a recording (its messages are :class:`~friction_sim.io.reader.Recording`'s to read).

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


def _size(n: float) -> str:
    """A byte count for people (``12.3 KiB``)."""
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n} B"


__all__ = ["POSE", "Channel", "RecordingInfo"]
