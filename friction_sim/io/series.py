"""The recorded state samples as numpy arrays, fast.

Decoding every message with rosbags costs ~4-7 s per million samples, which
makes ``--verify`` and plots of a long recording slow; all messages of a
stamped state topic share one CDR layout, so reading the floats with numpy
views takes ~0.2 s.  That is why this hand-written reader exists; a topic
whose messages are not laid out alike is decoded message by message.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from friction_sim.io.reader import Recording

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def stamped_floats(datas: Sequence[bytes], count: int) -> FloatArray | None:
    """The first ``count`` float64 after the std_msgs/Header of CDR
    little-endian *Stamped messages (pose.position, twist.linear,
    wrench.force) as an [n, count] array, or None unless every message has
    the layout of the first (same length, encapsulation and frame_id)."""
    n = len(datas)
    if n == 0:
        return np.empty((0, count))
    first = datas[0]
    length = len(first)
    if length < 16 or first[:2] != b"\x00\x01":  # CDR little endian
        return None
    frame_length = int.from_bytes(first[12:16], "little")  # with its NUL
    offset = 4 + ((12 + frame_length + 7) & ~7)  # body offsets count from byte 4
    if offset + 8 * count > length:
        return None
    joined = b"".join(datas)
    if len(joined) != n * length:
        return None
    rows = np.frombuffer(joined, dtype=np.uint8).reshape(n, length)
    head = rows[:, 0:16 + frame_length]  # encapsulation, stamp, frame_id: all but the stamp must match
    if not ((head[:, :4] == head[0, :4]).all() and (head[:, 12:] == head[0, 12:]).all()):
        return None
    values: FloatArray = rows[:, offset:offset + 8 * count].copy().view("<f8").astype(np.float64)
    return values


def state_series(recording: Recording, topic: str, fields: Callable[[Any], tuple[float, ...]],
                 count: int) -> tuple[IntArray, FloatArray]:
    """(log times [ns], values [n, count]) of a stamped state topic: read from
    the CDR directly when the layout allows it (checked on the first message
    against a full decoding), else decoded message by message."""
    raws = recording.messages_on(topic)
    times = np.fromiter((r.log_time for r in raws), dtype=np.int64, count=len(raws))
    values = stamped_floats([r.data for r in raws], count)
    if values is not None and raws and tuple(values[0]) != tuple(fields(recording.decode(raws[0]))):
        values = None
    if values is None:
        values = np.array([fields(recording.decode(raw)) for raw in raws], dtype=np.float64).reshape(-1, count)
    return times, values


__all__ = ["state_series", "stamped_floats"]
