"""The MCAP file of a recording, laid out as rosbag2's MCAP storage plugin (Jazzy) writes it.

:class:`BagFile` wraps ``mcap.writer.Writer`` (``mcap_ros2``'s writer takes no
channel metadata, which rosbag2 needs): zstd chunks with indexes,
statistics and summary; a ``ros2msg`` schema per type with the full
definition; per channel the QoS and type hash; and, on close, the
``rosbag2`` metadata record.  It is used from one thread only (the
recorder's writer thread).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from friction_sim.errors import RecordingError
from friction_sim.io import cdr
from friction_sim.io.messages import ns_to_seconds
from friction_sim.io.typesupport import message_definition, message_type_name, plain_yaml, qos_yaml, type_hash

#: rosbag2 bag metadata version written in the ``rosbag2`` record (Jazzy).
ROSBAG2_METADATA_VERSION = 9
ROS_DISTRO = "jazzy"


@dataclass
class RecordingStats:
    """What a recorder wrote: per-topic counts, log-time range [ns], messages
    dropped because the writer fell behind (or arrived after finish)."""

    path: Path
    messages: int = 0
    dropped: int = 0
    per_topic: dict[str, int] = field(default_factory=dict)
    first_ns: int | None = None
    last_ns: int | None = None
    chunks_flushed: int = 0
    last_flush: float | None = None  # time.monotonic() of the last flush
    bytes: int = 0
    error: str | None = None

    @property
    def duration(self) -> float:
        """Seconds between the first and the last log time."""
        if self.first_ns is None or self.last_ns is None:
            return 0.0
        return ns_to_seconds(self.last_ns - self.first_ns)

    def count(self, topic: str, log_time_ns: int) -> None:
        """Count one message written on ``topic`` at ``log_time_ns``."""
        self.messages += 1
        self.per_topic[topic] = self.per_topic.get(topic, 0) + 1
        if self.first_ns is None or log_time_ns < self.first_ns:
            self.first_ns = log_time_ns
        if self.last_ns is None or log_time_ns > self.last_ns:
            self.last_ns = log_time_ns



class BagFile:
    """The MCAP writer of a recorder, used by its writer thread only: channels
    and schemas registered on a topic's first message, sequence numbers,
    counts, the rosbag2 metadata record."""

    def __init__(self, stream: IO[bytes], qos_profiles: list[dict[str, Any]], chunk_size: int,
                 stats: RecordingStats) -> None:
        from mcap.writer import CompressionType, IndexType, Writer

        self.writer = Writer(
            stream, chunk_size=chunk_size, compression=CompressionType.ZSTD,
            index_types=IndexType.ALL, use_chunking=True, use_statistics=True,
            use_summary_offsets=True, repeat_channels=True, repeat_schemas=True, enable_crcs=True,
        )
        self.qos_profiles = qos_profiles
        self.qos_yaml = qos_yaml(qos_profiles)
        self.stats = stats
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, tuple[int, str]] = {}  # topic -> (channel id, type name)
        self.sequence: dict[int, int] = {}

    def add(self, topic: str, msg: Any, log_time_ns: int) -> bool:
        """Write ``msg`` on ``topic``; False (nothing written) for a negative log time."""
        log_time_ns = int(log_time_ns)
        if log_time_ns < 0:
            return False
        type_name = message_type_name(type(msg))
        channel = self.channels.get(topic)
        if channel is None:
            channel = self.channels[topic] = (self._register(topic, type_name), type_name)
        elif channel[1] != type_name:
            raise RecordingError(f"topic {topic!r} has type {channel[1]}, not {type_name}")
        sequence = self.sequence.get(channel[0], 0)
        self.sequence[channel[0]] = sequence + 1
        self.writer.add_message(channel[0], log_time_ns, cdr.serialize(msg), log_time_ns, sequence)
        self.stats.count(topic, log_time_ns)
        return True

    def _register(self, topic: str, type_name: str) -> int:
        """The channel of a new topic (and its type's schema, once)."""
        schema_id = self.schemas.get(type_name)
        if schema_id is None:
            schema_id = self.schemas[type_name] = self.writer.register_schema(
                name=type_name, encoding="ros2msg", data=message_definition(type_name).encode("utf-8"))
        return self.writer.register_channel(
            topic=topic, message_encoding="cdr", schema_id=schema_id,
            metadata={"offered_qos_profiles": self.qos_yaml, "topic_type_hash": type_hash(type_name)},
        )

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


__all__ = ["ROS_DISTRO", "ROSBAG2_METADATA_VERSION", "BagFile", "RecordingStats"]
