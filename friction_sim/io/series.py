"""The recorded state samples as numpy arrays, fast, chunk by chunk.

Decoding every message with rosbags costs ~4-7 s per million samples, which
makes ``--verify`` and plots of a long recording slow; all messages of a
stamped state topic share one CDR layout, so reading the floats with numpy
views takes ~0.2 s.  That is why this hand-written reader exists; messages
that are not laid out alike are decoded message by message.

:func:`state_blocks` yields the arrays of one chunk at a time (memory
bounded whatever the length); :func:`thinned_series` keeps, for a figure,
the smallest and largest value of every run of samples.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from friction_sim.io.cdr import FRAME_ID_OFFSET, STAMP_OFFSET, deserialize, header_end, stamped_body_offset, stamps_ns
from friction_sim.io.reader import RawMessage, Recording

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
#: How to read a state topic: the fields of a decoded message, and how many.
Fields = tuple[Callable[[Any], tuple[float, ...]], int]
Series = tuple[IntArray, FloatArray]

POSITION: Fields = (lambda m: (m.pose.position.x,), 1)
VELOCITY: Fields = (lambda m: (m.twist.linear.x,), 1)
#: Position x, y, z and velocity x, y, z: columns 0 and 2 are (x, z) and (v, vz).
POSITION_XZ: Fields = (lambda m: (m.pose.position.x, m.pose.position.y, m.pose.position.z), 3)
VELOCITY_XZ: Fields = (lambda m: (m.twist.linear.x, m.twist.linear.y, m.twist.linear.z), 3)
FORCE: Fields = (lambda m: (m.wrench.force.x, m.wrench.force.y, m.wrench.force.z), 3)


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
    offset = stamped_body_offset(first)
    if offset is None or offset + 8 * count > length:
        return None
    joined = b"".join(datas)
    if len(joined) != n * length:
        return None
    rows = np.frombuffer(joined, dtype=np.uint8).reshape(n, length)
    head = rows[:, 0:header_end(first)]  # encapsulation, stamp, frame_id: all but the stamp must match
    if not ((head[:, :STAMP_OFFSET] == head[0, :STAMP_OFFSET]).all()
            and (head[:, FRAME_ID_OFFSET:] == head[0, FRAME_ID_OFFSET:]).all()):
        return None
    values: FloatArray = rows[:, offset:offset + 8 * count].copy().view("<f8").astype(np.float64)
    return values


#: sensor_msgs/Imu: linear_acceleration.z is float64 number 27 after the header (orientation 4,
#: its covariance 9, angular_velocity 3, its covariance 9, linear_acceleration x, y, z).
IMU_NORMAL = 27
IMU_TYPE = "sensor_msgs/msg/Imu"


def imu_normals(datas: Sequence[bytes]) -> list[tuple[int, float]]:
    """(stamp [ns], linear_acceleration.z) of serialized sensor_msgs/Imu messages, in order:
    read from the CDR at numpy speed (checked on the first against a full decoding), else
    decoded one by one.  The controller takes a thousand readings a simulated second: rclpy's
    conversion of each into a Python Imu message costs more than the inner loop's use of it."""
    if not datas:
        return []
    values = stamped_floats(datas, IMU_NORMAL + 1)
    first = deserialize(datas[0], IMU_TYPE)
    if values is not None and float(values[0, IMU_NORMAL]) != first.linear_acceleration.z:
        values = None
    if values is None:
        decoded = [deserialize(data, IMU_TYPE) for data in datas]
        return [(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec, msg.linear_acceleration.z)
                for msg in decoded]
    return list(zip(stamps_ns(datas).tolist(), values[:, IMU_NORMAL].tolist()))


def state_values(recording: Recording, raws: Sequence[RawMessage], fields: Fields) -> Series:
    """(log times [ns], values [n, count]) of messages of one stamped state
    topic: read from the CDR directly when the layout allows it (checked on
    the first message against a full decoding), else decoded one by one."""
    read, count = fields
    times = np.fromiter((r.log_time for r in raws), dtype=np.int64, count=len(raws))
    values = stamped_floats([r.data for r in raws], count)
    if values is not None and raws and tuple(values[0]) != tuple(read(recording.decode(raws[0]))):
        values = None
    if values is None:
        values = np.array([read(recording.decode(raw)) for raw in raws], dtype=np.float64).reshape(-1, count)
    return times, values


def state_blocks(recording: Recording, topics: Mapping[str, Fields]) -> Iterator[dict[str, Series]]:
    """For each chunk, the samples of ``topics`` (name -> fields) it holds,
    by the names asked for (topics absent from the chunk: empty arrays)."""
    names = {recording.topic_name(name): name for name in topics}
    names.pop(None, None)
    for block in recording.iter_chunks(topics):
        by_topic: dict[str, list[RawMessage]] = {name: [] for name in topics}
        for raw in block:
            by_topic[names[raw.topic]].append(raw)
        yield {name: state_values(recording, raws, topics[name]) for name, raws in by_topic.items()}


def status_names(recording: Recording, raws: Sequence[RawMessage]) -> list[str]:
    """The ``name`` of diagnostic_msgs/DiagnosticStatus messages (the stick/slip
    events).  Decoding one with rosbags costs ~100 us (its key/values), so
    the name is read where CDR puts it (level, then the string's length and
    bytes), checked on the first message against a full decoding."""
    names = []
    for raw in raws:
        data = raw.data
        length = int.from_bytes(data[8:12], "little")
        names.append(data[12:11 + length].decode("utf-8", "replace") if data[:2] == b"\x00\x01" else "")
    if raws and names[0] != recording.decode(raws[0]).name:
        names = [recording.decode(raw).name for raw in raws]
    return names


class Thinner:
    """Keeps, of every run of ``step`` samples, the ones with the smallest and
    the largest value of each column: what a figure of ``points`` points
    shows of a series too long to draw (every sample when it is short)."""

    def __init__(self, total: int, columns: int, points: int) -> None:
        self.step = max(1, math.ceil(total / max(1, points // 2)))
        self.columns = columns
        self._times: list[IntArray] = []
        self._values: list[FloatArray] = []
        self._pending: list[Series] = []
        self._pending_n = 0

    def add(self, times: IntArray, values: FloatArray) -> None:
        """Take the next samples (in time order)."""
        if times.size:
            self._pending.append((times, values))
            self._pending_n += times.size
        if self._pending_n >= self.step:
            self._thin(final=False)

    def _thin(self, *, final: bool) -> None:
        """Thin the whole steps pending (and, when ``final``, the last partial one)."""
        times = np.concatenate([t for t, _ in self._pending]) if self._pending else np.empty(0, np.int64)
        values = np.concatenate([v for _, v in self._pending]) if self._pending else np.empty((0, self.columns))
        whole = times.size - times.size % self.step
        found = [self._extremes(values[:whole], self.step)] if whole else []
        if final and whole < times.size:
            found.append(whole + self._extremes(values[whole:], times.size - whole))
        upto = times.size if final else whole
        self._pending = [(times[upto:], values[upto:])] if upto < times.size else []
        self._pending_n = times.size - upto
        if found:
            keep = np.unique(np.concatenate(found))
            self._times.append(times[keep])
            self._values.append(values[keep])

    def _extremes(self, values: FloatArray, step: int) -> IntArray:
        """Indexes of the smallest and largest value of each column in each ``step`` samples."""
        shaped = values.reshape(-1, step, self.columns)
        base = np.arange(shaped.shape[0])[:, None] * step
        found: IntArray = np.concatenate([(base + shaped.argmin(axis=1)).ravel(),
                                          (base + shaped.argmax(axis=1)).ravel()])
        return found

    def result(self) -> Series:
        """(log times [ns], values) kept, in time order."""
        self._thin(final=True)
        if not self._times:
            return np.empty(0, np.int64), np.empty((0, self.columns))
        return np.concatenate(self._times), np.concatenate(self._values)


def thinned_series(recording: Recording, topics: Mapping[str, Fields], points: int = 4000) -> dict[str, Series]:
    """Every topic of ``topics`` read in one pass, thinned to about ``points``
    samples (the extremes of each run, :class:`Thinner`)."""
    thinners = {name: Thinner(recording.count(name), count, points) for name, (_, count) in topics.items()}
    for block in state_blocks(recording, topics):
        for name, (times, values) in block.items():
            thinners[name].add(times, values)
    return {name: thinner.result() for name, thinner in thinners.items()}


__all__ = ["FORCE", "IMU_NORMAL", "POSITION", "POSITION_XZ", "VELOCITY", "VELOCITY_XZ", "Fields", "Thinner",
           "imu_normals", "stamped_floats",
           "state_blocks", "state_values", "status_names", "thinned_series"]
