"""What two recordings of the same run must share: :func:`recording_digest`.

A lockstep run (:mod:`friction_sim.core.runtime.lockstep`) gives the same
messages every time.  What may differ between two recordings of it is what the
wall clock says: the MCAP log times, and the health figures of the diagnostics
(how fast it ran, how long the recorder or a participant made it wait).  The
digest leaves exactly those out: per topic, every message's payload in order of
its header stamp (messages of one stamp from two publishers have no order of
their own), diagnostics with their wall-clock figures blanked, and the
recording's metadata.  Two recordings are the same run when their digests are
equal; :func:`differences` says where they are not.
"""

from __future__ import annotations

import hashlib
import os
from collections import defaultdict
from collections.abc import Iterator

#: The diagnostics values that tell the wall clock's story (how fast, how long something waited, how
#: often a sample went out again while the slider waited, how far ahead of the slider the scheduler's
#: promises had come), or name the file: blanked in a digest.
WALL_CLOCK_KEYS = frozenset({
    "achieved_real_time_factor", "tick_rate", "late_ticks", "late_ticks_total", "ticks_behind_in_interval",
    "stalls", "time_slipped", "recording_waited_s", "recording_waited_in_interval_s", "lockstep_waited_s",
    "lockstep_stale_answers", "lockstep_join_waits", "lockstep_promise", "messages_lost", "live_view_clients",
    "live_view_sent", "live_view_dropped", "recording",
})
#: Metadata written from the wall clock or the file system (left out).
_WALL_METADATA = frozenset({"log_path", "recorded_at", "started_at", "wall_time"})


def _messages(path: str | os.PathLike[str]) -> Iterator[tuple[str, str, bytes]]:
    from mcap.reader import make_reader

    with open(path, "rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            yield channel.topic, schema.name if schema is not None else "", message.data


def _stamp_and_payload(type_name: str, data: bytes) -> tuple[int, bytes]:
    """(header stamp [ns] or -1, the payload as compared: diagnostics, which other nodes' publishers
    encoded (their padding bytes are not their content), by their content, with their wall-clock
    figures blanked)."""
    from friction_sim.io import cdr

    if not type_name.endswith("DiagnosticArray"):
        stamped = cdr.fields(type_name)[0][0] == "header"
        return (int(cdr.stamps_ns([data])[0]) if stamped else -1), data
    msg = cdr.deserialize(data, type_name)
    content = [(status.level, status.name, status.message, status.hardware_id,
                [(value.key, "" if value.key in WALL_CLOCK_KEYS else value.value) for value in status.values])
               for status in msg.status]
    return _stamp(msg), repr((msg.header.frame_id, content)).encode()


def _stamp(msg: object) -> int:
    header = getattr(msg, "header", None)
    return -1 if header is None else int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def recording_digest(path: str | os.PathLike[str]) -> dict[str, str]:
    """topic -> a SHA-256 of its messages (payloads in stamp order, wall-clock figures
    blanked), and ``metadata`` -> one of the recording's metadata (see the module)."""
    per_topic: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    for topic, type_name, data in _messages(path):
        per_topic[topic].append(_stamp_and_payload(type_name, data))
    digest = {}
    for topic, entries in sorted(per_topic.items()):
        if all(stamp >= 0 for stamp, _ in entries):  # (unstamped ones, commands, keep the order they were taken in)
            entries.sort()
        h = hashlib.sha256()
        for stamp, payload in entries:
            h.update(stamp.to_bytes(8, "little", signed=True) + len(payload).to_bytes(8, "little") + payload)
        digest[topic] = f"{len(entries)}:{h.hexdigest()}"
    digest["metadata"] = hashlib.sha256(repr(_metadata(path)).encode()).hexdigest()
    return digest


def _metadata(path: str | os.PathLike[str]) -> list[tuple[str, list[tuple[str, str]]]]:
    from mcap.reader import make_reader

    with open(path, "rb") as stream:
        records = make_reader(stream).iter_metadata()
        name = os.path.basename(path)  # (the file's own name, in rosbag2's metadata)
        return sorted((record.name, sorted((k, _in_order(v.replace(name, "<file>"))) for k, v in record.metadata.items()
                                           if k not in _WALL_METADATA))
                      for record in records)


def _in_order(text: str) -> str:
    """rosbag2's metadata with its topics in name order (their order is that of the first message of
    each, which threads of the nodes write in either order); any other text as it is."""
    import yaml

    if "topics_with_message_count" not in text:
        return text
    info = yaml.safe_load(text)
    info = info.get("rosbag2_bagfile_information", info)
    info["topics_with_message_count"].sort(key=lambda entry: entry["topic_metadata"]["name"])
    return str(yaml.safe_dump(info, sort_keys=True))


def differences(first: dict[str, str], second: dict[str, str]) -> list[str]:
    """The topics (or ``metadata``) whose digests differ, with both digests."""
    return [f"{key}: {first.get(key)} != {second.get(key)}" for key in sorted({*first, *second})
            if first.get(key) != second.get(key)]


def run_digest(path: str | os.PathLike[str]) -> str:
    """One SHA-256 of the whole :func:`recording_digest` (the figure a closing note quotes)."""
    return hashlib.sha256(repr(sorted(recording_digest(path).items())).encode()).hexdigest()


__all__ = ["WALL_CLOCK_KEYS", "differences", "recording_digest", "run_digest"]
