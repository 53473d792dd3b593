"""Reading and replaying recordings: ``friction-sim replay run.mcap``.

* :func:`read_recording` reads a recording written by
  :mod:`friction_sim.io.recording`.  It does not need the summary: it walks the
  file record by record, so a file whose writer was killed (no footer) is read
  up to its last complete record, and :meth:`Recording.recovery_note` says how
  much was recovered.
* :func:`verify` rebuilds the simulation with the exact core from the
  recorded parameters and accepted commands (applied at their recorded
  simulation times) and compares it with every recorded pose and velocity
  sample; it passes when both differ by at most 1e-9 relative to the largest
  recorded |x| and |v|.
* :func:`publish` republishes the recorded messages on their topics with the
  recorded timing scaled by ``rate``, like ``ros2 bag play``.
* :func:`export_csv` writes one CSV per topic; :func:`plot` draws position,
  velocity, friction force and R against time with the commands marked.

:func:`add_arguments` and :func:`run` are the CLI subcommand.  Errors (missing
file, not MCAP, not a friction_sim recording) raise
:class:`~friction_sim.errors.RecordingError` with one line.
"""

from __future__ import annotations

import argparse
import csv
import gc
import io
import json
import math
import struct
import sys
import threading
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence, TextIO

import numpy as np

from friction_sim.errors import FrictionSimError, ParameterError, RecordingError
from friction_sim.io.messages import NS_PER_S, ns_to_seconds, parameter_event_values
from friction_sim.io.recording import (
    INPUT_FIELDS, METADATA_NAME, PLANT_FIELDS, SUMMARY_METADATA_NAME, message_class,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

MCAP_MAGIC = b"\x89MCAP0\r\n"
EXIT_OK, EXIT_MISMATCH, EXIT_ERROR = 0, 1, 2
DEFAULT_TOLERANCE = 1e-9
_INPUT_TOPICS = ("drive_force", "excitation_amplitude", "excitation_frequency")


# --------------------------------------------------------------------------
# Reading.
# --------------------------------------------------------------------------


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
    _classes: dict[str, type] = field(default_factory=dict, repr=False)

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

    def message_type(self, topic: str) -> type:
        """The message class of ``topic``, imported from its schema name."""
        cls = self._classes.get(topic)
        if cls is None:
            channel = self.topics.get(topic)
            if channel is None:
                raise RecordingError(f"{self.path}: no topic {topic!r}")
            cls = self._classes[topic] = message_class(channel.type_name)
        return cls

    def decode(self, raw: RawMessage) -> Any:
        """Deserialize one message with its type resolved from the schema name."""
        from rclpy.serialization import deserialize_message

        return deserialize_message(raw.data, self.message_type(raw.topic))

    def decoded(self, topic: str) -> list[tuple[int, Any]]:
        """(log time [ns], message) of every message on ``topic``."""
        return [(raw.log_time, self.decode(raw)) for raw in self.messages_on(topic)]

    # -- times and notes -------------------------------------------------------------

    @property
    def start_ns(self) -> int:
        return min((m.log_time for m in self.messages), default=0)

    @property
    def end_ns(self) -> int:
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


def read_recording(path: str | Path, *, require_friction_sim: bool = True) -> Recording:
    """Read a recording as far as it holds complete records.

    Raises :class:`RecordingError` for a missing file, a file that is not
    MCAP, and (with ``require_friction_sim``) an MCAP file that has no
    ``friction_sim`` metadata record or no ``pose`` topic.
    """
    from mcap.data_stream import ReadDataStream
    from mcap.opcode import Opcode
    from mcap.records import Channel as McapChannel
    from mcap.records import Chunk, Header, Message, Metadata, Schema, Statistics
    from mcap.stream_reader import breakup_chunk

    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise RecordingError(f"no such file: {path}") from None
    except IsADirectoryError:
        raise RecordingError(f"is a directory, not a recording: {path}") from None
    except OSError as error:
        raise RecordingError(f"cannot read {path}: {error.strerror or error}") from None
    if len(data) < len(MCAP_MAGIC) or data[:8] != MCAP_MAGIC:
        raise RecordingError(f"not an MCAP file: {path}")
    recording = Recording(path, file_size=len(data))
    size = len(data)
    position = len(MCAP_MAGIC)
    in_summary = False

    def stream(start: int, length: int) -> ReadDataStream:
        return ReadDataStream(io.BytesIO(data[start:start + length]))

    def add(record: Any) -> None:
        if isinstance(record, Schema):
            recording.schemas.setdefault(record.id, (record.name, record.encoding, bytes(record.data)))
        elif isinstance(record, McapChannel):
            if record.id not in recording.channels:
                schema = recording.schemas.get(record.schema_id, ("", "", b""))
                recording.channels[record.id] = Channel(record.id, record.topic, schema[0],
                                                        record.message_encoding, dict(record.metadata))
        elif isinstance(record, Message):
            channel = recording.channels.get(record.channel_id)
            if channel is not None:
                recording.messages.append(RawMessage(channel.topic, record.log_time, bytes(record.data)))

    while position < size:
        if position + 9 > size:
            recording.truncated_bytes = size - position
            break
        opcode = data[position]
        (length,) = struct.unpack_from("<Q", data, position + 1)
        start = position + 9
        if start + length > size:
            recording.truncated_bytes = size - position
            break
        try:
            if opcode == Opcode.HEADER:
                header = Header.read(stream(start, length))
                recording.profile, recording.library = header.profile, header.library
            elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE) and not in_summary:
                reader = {Opcode.SCHEMA: Schema.read, Opcode.CHANNEL: McapChannel.read}.get(opcode)
                add(reader(stream(start, length)) if reader else Message.read(stream(start, length), length))
            elif opcode == Opcode.CHUNK:
                records = breakup_chunk(Chunk.read(stream(start, length)), validate_crc=True)
                for record in records:
                    add(record)
                recording.chunks += 1
            elif opcode == Opcode.METADATA:
                metadata = Metadata.read(stream(start, length))
                recording.metadata[metadata.name] = dict(metadata.metadata)
            elif opcode == Opcode.STATISTICS:
                recording.statistics = Statistics.read(stream(start, length))
            elif opcode == Opcode.DATA_END:
                in_summary = True
            elif opcode == Opcode.FOOTER:
                recording.complete = data[start + length:start + length + 8] == MCAP_MAGIC
                break
        except Exception:  # noqa: BLE001 - a damaged record ends what can be recovered
            recording.truncated_bytes = size - position
            break
        position = start + length
    if require_friction_sim and not recording.is_friction_sim():
        missing = "no friction_sim metadata record" if METADATA_NAME not in recording.metadata else "no pose topic"
        raise RecordingError(f"not a friction_sim recording ({missing}): {path}")
    return recording


# -- fast access to the state samples ------------------------------------------------


def _stamped_float64s(raw: RawMessage, count: int) -> tuple[float, ...] | None:
    """The first ``count`` float64 after the std_msgs/Header of a CDR
    little-endian *Stamped message (pose.position, twist.linear, wrench.force),
    or None if the message is not laid out that way."""
    data = raw.data
    if len(data) < 16 or data[0:2] != b"\x00\x01":
        return None
    (length,) = struct.unpack_from("<I", data, 12)
    offset = (12 + length + 7) & ~7
    if 4 + offset + 8 * count > len(data):
        return None
    return struct.unpack_from(f"<{count}d", data, 4 + offset)


def state_series(recording: Recording, topic: str, fields: Callable[[Any], tuple[float, ...]],
                 count: int) -> tuple[np.ndarray, np.ndarray]:
    """(log times [ns], values [n, count]) of a stamped state topic, read from
    the CDR directly when its layout is the expected one (checked on the
    first message against a full deserialization), else deserialized."""
    raws = recording.messages_on(topic)
    times = np.fromiter((r.log_time for r in raws), dtype=np.int64, count=len(raws))
    values = np.empty((len(raws), count))
    fast = bool(raws) and _stamped_float64s(raws[0], count) == tuple(fields(recording.decode(raws[0])))
    for i, raw in enumerate(raws):
        quick = _stamped_float64s(raw, count) if fast else None
        values[i] = quick if quick is not None else fields(recording.decode(raw))
    return times, values


# --------------------------------------------------------------------------
# Verify.
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class VerifyResult:
    """How a re-simulation compares with the recorded states.

    ``max_dx``/``max_dv`` are the largest absolute differences (at
    ``worst_dx_t``/``worst_dv_t`` s), ``rel_dx``/``rel_dv`` the same relative
    to the largest recorded |x| and |v|.  ``passed`` when both are within
    ``tolerance`` and nothing went wrong (``problems``).
    """

    samples: int
    commands: int
    max_dx: float
    max_dv: float
    x_scale: float
    v_scale: float
    rel_dx: float
    rel_dv: float
    worst_dx_t: float
    worst_dv_t: float
    tolerance: float
    problems: tuple[str, ...] = ()

    @property
    def passed(self) -> bool:
        return (not self.problems and self.samples > 0
                and self.rel_dx <= self.tolerance and self.rel_dv <= self.tolerance)

    def lines(self) -> list[str]:
        verdict = "reproducible" if self.passed else "NOT reproducible"
        lines = [
            f"re-simulated {self.samples} samples with {self.commands} recorded commands",
            f"largest position difference: {self.max_dx:.3e} m at t = {self.worst_dx_t:.6f} s "
            f"({self.rel_dx:.3e} of max|x| = {self.x_scale:.6g} m)",
            f"largest velocity difference: {self.max_dv:.3e} m/s at t = {self.worst_dv_t:.6f} s "
            f"({self.rel_dv:.3e} of max|v| = {self.v_scale:.6g} m/s)",
        ]
        lines += [f"problem: {problem}" for problem in self.problems]
        lines.append(f"{verdict} (tolerance {self.tolerance:.0e} relative)")
        return lines


@dataclass(frozen=True)
class RecordedChange:
    """An accepted change of the physics, as recorded: when [ns], in which
    order it was written, on which topic, and the plant and input fields."""

    t_ns: int
    order: int
    topic: str
    plant: dict[str, float]
    inputs: dict[str, float]


def initial_parameters(recording: Recording) -> dict[str, Any]:
    """The parameters at start: the first ParameterEvent's new_parameters on
    ``parameters``, else the ``friction_sim`` metadata record."""
    for raw in recording.messages_on("parameters"):
        new, _ = parameter_event_values(recording.decode(raw))
        if new:
            return new
    meta = recording.metadata.get(METADATA_NAME, {})
    values: dict[str, Any] = {}
    for name in (*PLANT_FIELDS, *INPUT_FIELDS):
        if name in meta:
            try:
                values[name] = float(meta[name])
            except ValueError:
                pass
    return values


def verify(recording: Recording, tolerance: float = DEFAULT_TOLERANCE) -> VerifyResult:
    """Re-simulate the recording with the exact core and compare it with the
    recorded pose and velocity samples (see :class:`VerifyResult`)."""
    from friction_sim.core.slider import Slider
    from friction_sim.core.params import Inputs, SliderParams

    problems: list[str] = []
    values = initial_parameters(recording)
    missing = [name for name in (*PLANT_FIELDS, *INPUT_FIELDS[:3]) if name not in values]
    if missing:
        raise RecordingError(f"{recording.path}: no initial value of {', '.join(missing)} "
                             f"(neither on 'parameters' nor in the friction_sim metadata)")
    try:
        params = SliderParams(**{name: float(values[name]) for name in PLANT_FIELDS})
        inputs = Inputs(**{name: float(values.get(name, 0.0)) for name in INPUT_FIELDS})
        slider = Slider(params, inputs, event_log_size=0)
    except ParameterError as error:
        raise RecordingError(f"{recording.path}: recorded initial parameters are invalid: {error}") from None
    changes = recorded_changes(recording)
    pose_ns, pose = state_series(recording, "pose", lambda m: (m.pose.position.x,), 1)
    vel_ns, vel = state_series(recording, "velocity", lambda m: (m.twist.linear.x,), 1)
    times_ns = np.unique(np.concatenate([pose_ns, vel_ns]))
    times = sample_times(times_ns, _log_rate(recording, values))
    x_sim = np.empty(times_ns.size)
    v_sim = np.empty(times_ns.size)
    first = 0
    for change in changes:
        last = int(np.searchsorted(times_ns, change.t_ns, side="right"))
        if last > first:
            trajectory = slider.sample(np.maximum(times[first:last], slider.t))
            x_sim[first:last], v_sim[first:last] = trajectory.x, trajectory.v
            first = last
        t = ns_to_seconds(change.t_ns)
        try:
            slider.advance_to(max(t, slider.t))
            if change.plant:
                slider.set_params(slider.params.replace(**change.plant))
            if change.inputs:
                slider.set_inputs(**change.inputs)
        except ParameterError as error:
            problems.append(f"the command recorded at t = {t:.9f} s cannot be applied: {error}")
    if first < times_ns.size:
        trajectory = slider.sample(np.maximum(times[first:], slider.t))
        x_sim[first:], v_sim[first:] = trajectory.x, trajectory.v
    dx, dx_t = _largest_difference(times_ns, x_sim, pose_ns, pose[:, 0])
    dv, dv_t = _largest_difference(times_ns, v_sim, vel_ns, vel[:, 0])
    x_scale = float(np.max(np.abs(pose[:, 0]))) if pose.size else 0.0
    v_scale = float(np.max(np.abs(vel[:, 0]))) if vel.size else 0.0
    if recording.dropped:
        problems.append(f"the recorder dropped {recording.dropped} messages")
    return VerifyResult(
        samples=int(pose_ns.size), commands=len(changes), max_dx=dx, max_dv=dv, x_scale=x_scale, v_scale=v_scale,
        rel_dx=_relative(dx, x_scale), rel_dv=_relative(dv, v_scale), worst_dx_t=dx_t, worst_dv_t=dv_t,
        tolerance=tolerance, problems=tuple(problems),
    )


def _log_rate(recording: Recording, initial: dict[str, Any]) -> float | None:
    for source in (initial, recording.metadata.get(METADATA_NAME, {})):
        try:
            rate = float(source["log_rate"])
        except (KeyError, TypeError, ValueError):
            continue
        if math.isfinite(rate) and rate > 0.0:
            return rate
    return None


def sample_times(times_ns: np.ndarray, log_rate: float | None) -> np.ndarray:
    """Simulation times [s] of recorded samples: the grid time k / log_rate
    where the log time [ns] is that grid point rounded (the exact time the
    state was computed for), else log time / 1e9."""
    seconds = times_ns / NS_PER_S
    if log_rate is None or times_ns.size == 0:
        return seconds
    grid = np.rint(times_ns * (log_rate / NS_PER_S)) / log_rate
    on_grid = np.rint(grid * NS_PER_S).astype(np.int64) == times_ns
    return np.where(on_grid, grid, seconds)


def recorded_changes(recording: Recording) -> list[RecordedChange]:
    """Accepted physics changes: inputs topics, external_wrench, and every
    ParameterEvent on ``parameters`` after the initial one; sorted by time,
    ties in the order they were written."""
    index = {id(raw): i for i, raw in enumerate(recording.messages)}
    changes: list[RecordedChange] = []
    for topic in _INPUT_TOPICS:
        for raw in recording.messages_on(topic):
            changes.append(RecordedChange(raw.log_time, index[id(raw)], topic, {},
                                          {topic: float(recording.decode(raw).data)}))
    for raw in recording.messages_on("external_wrench"):
        force = recording.decode(raw).wrench.force
        changes.append(RecordedChange(raw.log_time, index[id(raw)], "external_wrench", {},
                                      {"external_force_x": float(force.x), "external_force_z": float(force.z)}))
    initial_seen = False
    for raw in recording.messages_on("parameters"):
        new, changed = parameter_event_values(recording.decode(raw))
        if new and not initial_seen:
            initial_seen = True
            new = {}
        values = {**new, **changed}
        plant = {k: float(v) for k, v in values.items() if k in PLANT_FIELDS}
        inputs = {k: float(v) for k, v in values.items() if k in INPUT_FIELDS}
        if plant or inputs:
            changes.append(RecordedChange(raw.log_time, index[id(raw)], "parameters", plant, inputs))
    return sorted(changes, key=lambda c: (c.t_ns, c.order))


def _largest_difference(sim_ns: np.ndarray, sim: np.ndarray, rec_ns: np.ndarray,
                        rec: np.ndarray) -> tuple[float, float]:
    if rec_ns.size == 0:
        return 0.0, 0.0
    diff = np.abs(sim[np.searchsorted(sim_ns, rec_ns)] - rec)
    worst = int(np.argmax(diff))
    return float(diff[worst]), ns_to_seconds(int(rec_ns[worst]))


def _relative(difference: float, scale: float) -> float:
    if difference == 0.0:
        return 0.0
    return difference / scale if scale > 0.0 else math.inf


# --------------------------------------------------------------------------
# Publish.
# --------------------------------------------------------------------------


@dataclass
class PublishResult:
    """What :func:`publish` sent: messages, loops, and the largest lateness
    of a publish call behind its scheduled wall time [s]."""

    messages: int = 0
    loops: int = 0
    max_late: float = 0.0
    interrupted: bool = False


def _qos(channel: Channel) -> Any:
    import yaml
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    profile = QoSProfile(depth=10)
    try:
        offered = yaml.safe_load(channel.metadata.get("offered_qos_profiles", "") or "[]") or []
        first = offered[0] if offered else {}
    except (yaml.YAMLError, IndexError, TypeError, KeyError):
        first = {}
    reliability, durability = first.get("reliability"), first.get("durability")
    if reliability in ("best_effort", 2):
        profile.reliability = ReliabilityPolicy.BEST_EFFORT
    if durability in ("transient_local", 1):
        profile.durability = DurabilityPolicy.TRANSIENT_LOCAL
    return profile


def _select_topics(recording: Recording, topics: Sequence[str] | None) -> list[str]:
    available = list(recording.topics)
    if not topics:
        return available
    wanted = [t.lstrip("/") for t in topics]
    unknown = [t for t in wanted if t not in recording.topics]
    if unknown:
        raise RecordingError(f"no topic {', '.join(unknown)} in {recording.path}; topics: {', '.join(available)}")
    return wanted


def publish(
    recording: Recording, *, rate: float = 1.0, loop: bool = False, topics: Sequence[str] | None = None,
    namespace: str = "", wait_for_subscribers: int = 0, wait_timeout: float = 5.0, delay: float = 0.0,
    progress: TextIO | None = None, stop: threading.Event | None = None, node_name: str | None = None,
) -> PublishResult:
    """Republish the recorded messages (as recorded, serialized) on their
    topics, the recorded log times scaled by 1/``rate``; with ``loop`` start
    over until ``stop`` is set or Ctrl-C.  Topic names are the recorded
    (relative) names, resolved in ``namespace``.  With
    ``wait_for_subscribers`` it first waits (up to ``wait_timeout`` s) until
    every publisher has that many subscriptions, then waits ``delay`` s
    (discovery may need a moment to match both ends).  Progress goes to
    ``progress`` (a one-line bar when it is a TTY, else a line a second).
    rclpy is initialised here if the caller has not done so.
    """
    import rclpy

    if not (isinstance(rate, (int, float)) and math.isfinite(rate) and rate > 0.0):
        raise ParameterError("rate", rate, "must be a finite factor > 0")
    selected = _select_topics(recording, topics)
    messages = sorted((m for m in recording.messages if m.topic in set(selected)), key=lambda m: m.log_time)
    result = PublishResult()
    own_context = not rclpy.ok()
    if own_context:
        rclpy.init()
    node = None
    try:
        node = rclpy.create_node(node_name or f"friction_sim_replay_{uuid.uuid4().hex[:8]}",
                                 namespace=namespace or "/")
        publishers = {topic: node.create_publisher(recording.message_type(topic), topic,
                                                   _qos(recording.topics[topic])) for topic in selected}
        if wait_for_subscribers > 0:
            deadline = time.monotonic() + wait_timeout
            while time.monotonic() < deadline and not (stop is not None and stop.is_set()):
                if all(p.get_subscription_count() >= wait_for_subscribers for p in publishers.values()):
                    break
                time.sleep(0.01)
        if delay > 0.0:
            time.sleep(delay)
        if not messages:
            return result
        bar = _Progress(progress, ns_to_seconds(messages[-1].log_time - messages[0].log_time), rate)
        # A full garbage collection of a large heap can stall this thread for
        # ~100 ms; leave the objects that exist now out of collections while
        # playing, so the recorded timing holds.
        gc.freeze()
        try:
            while True:
                _play_once(messages, publishers, rate, result, bar, stop)
                result.loops += 1
                if not loop or (stop is not None and stop.is_set()):
                    break
        except KeyboardInterrupt:
            result.interrupted = True
        finally:
            gc.unfreeze()
        bar.close(result)
    finally:
        if node is not None:
            node.destroy_node()
        if own_context:
            rclpy.try_shutdown()
    return result


def _play_once(messages: list[RawMessage], publishers: dict[str, Any], rate: float, result: PublishResult,
               bar: _Progress, stop: threading.Event | None) -> None:
    first = messages[0].log_time
    start = time.monotonic() + 0.01
    for raw in messages:
        if stop is not None and stop.is_set():
            result.interrupted = True
            return
        target = start + (raw.log_time - first) / NS_PER_S / rate
        _sleep_until(target)
        publishers[raw.topic].publish(raw.data)
        result.messages += 1
        result.max_late = max(result.max_late, time.monotonic() - target)
        bar.update(ns_to_seconds(raw.log_time - first), result.messages)


def _sleep_until(target: float) -> None:
    """Sleep until monotonic time ``target``: coarse sleep, then a short
    GIL-releasing spin for the last millisecond."""
    while True:
        remaining = target - time.monotonic()
        if remaining <= 0.0:
            return
        time.sleep(remaining - 0.001 if remaining > 0.002 else 0)


class _Progress:
    """``[#####.....]  12.3/60.0 s  x1.0  1234 msgs`` on a TTY (redrawn in
    place), or one plain line per second of wall time otherwise."""

    def __init__(self, stream: TextIO | None, total: float, rate: float) -> None:
        self.stream, self.total, self.rate = stream, total, rate
        self.tty = bool(stream is not None and getattr(stream, "isatty", lambda: False)())
        self.last = 0.0

    def update(self, t: float, count: int, *, force: bool = False) -> None:
        if self.stream is None:
            return
        now = time.monotonic()
        if not force and now - self.last < (0.1 if self.tty else 1.0):
            return
        self.last = now
        fraction = t / self.total if self.total > 0 else 1.0
        text = f"{t:9.3f}/{self.total:.3f} s  x{self.rate:g}  {count} msgs"
        if self.tty:
            filled = int(round(30 * fraction))
            self.stream.write(f"\r[{'#' * filled}{'.' * (30 - filled)}] {text}")
        else:
            self.stream.write(f"replay: {100 * fraction:5.1f}%  {text}\n")
        self.stream.flush()

    def close(self, result: PublishResult) -> None:
        if self.stream is None:
            return
        self.update(self.total, result.messages, force=True)
        if self.tty:
            self.stream.write("\n")
        self.stream.flush()


# --------------------------------------------------------------------------
# CSV and plot.
# --------------------------------------------------------------------------


def flatten(msg: Any, prefix: str = "") -> dict[str, Any]:
    """A message as {dotted.field: value}: nested messages flattened, byte
    fields as integers, sequences as a JSON list (of flattened messages)."""
    row: dict[str, Any] = {}
    for name in msg.get_fields_and_field_types():
        value = getattr(msg, name)
        key = f"{prefix}{name}"
        if hasattr(value, "get_fields_and_field_types"):
            row.update(flatten(value, key + "."))
        else:
            row[key] = _cell(value)
    return row


def _cell(value: Any) -> Any:
    if isinstance(value, bytes):
        return value[0] if len(value) == 1 else value.hex()
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)) or (hasattr(value, "__len__") and hasattr(value, "tolist")
                                            and not isinstance(value, str)):
        items = value.tolist() if hasattr(value, "tolist") else list(value)
        return json.dumps([flatten(v) if hasattr(v, "get_fields_and_field_types") else _json_item(v)
                           for v in items])
    return value


def _json_item(value: Any) -> Any:
    if isinstance(value, bytes):
        return value[0] if len(value) == 1 else value.hex()
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)
    return value


def export_csv(recording: Recording, directory: str | Path, topics: Sequence[str] | None = None) -> list[Path]:
    """One CSV per topic in ``directory`` (``<topic>.csv``): columns
    log_time_ns, t (s), then the flattened message fields."""
    directory = Path(directory)
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise RecordingError(f"cannot create {directory}: {error.strerror or error}") from None
    written = []
    for topic in _select_topics(recording, topics):
        path = directory / (topic.strip("/").replace("/", "__") + ".csv")
        rows = [(raw, flatten(recording.decode(raw))) for raw in recording.messages_on(topic)]
        columns: list[str] = []
        for _, row in rows:
            for key in row:
                if key not in columns:
                    columns.append(key)
        try:
            with path.open("w", newline="") as stream:
                writer = csv.writer(stream)
                writer.writerow(["log_time_ns", "t", *columns])
                for raw, row in rows:
                    writer.writerow([raw.log_time, repr(ns_to_seconds(raw.log_time)),
                                     *(row.get(c, "") for c in columns)])
        except OSError as error:
            raise RecordingError(f"cannot write {path}: {error.strerror or error}") from None
        written.append(path)
    return written


def command_marks(recording: Recording) -> list[tuple[float, str, bool]]:
    """(t [s], label, accepted) of every command in the recording."""
    marks: list[tuple[float, str, bool]] = []
    for topic in _INPUT_TOPICS + ("target_speed",):
        for t_ns, msg in recording.decoded(topic):
            marks.append((ns_to_seconds(t_ns), f"{topic} = {msg.data:g}", True))
    for t_ns, msg in recording.decoded("external_wrench"):
        f = msg.wrench.force
        marks.append((ns_to_seconds(t_ns), f"external force = ({f.x:g}, {f.z:g})", True))
    initial_seen = False
    for t_ns, msg in recording.decoded("parameters"):
        new, changed = parameter_event_values(msg)
        if new and not initial_seen:
            initial_seen = True
            continue
        values = {**new, **changed}
        if values:
            marks.append((ns_to_seconds(t_ns), ", ".join(f"{k} = {v}" for k, v in values.items()), True))
    for t_ns, msg in recording.decoded("rejected_commands"):
        marks.append((ns_to_seconds(t_ns), f"refused {msg.name}", False))
    return sorted(marks)


def plot(recording: Recording) -> Figure:
    """Position, velocity, friction force and normal force R against time,
    with every command marked (refused ones dotted red).  matplotlib is
    imported here; the Figure is not registered with pyplot."""
    from matplotlib.figure import Figure

    pose_ns, pose = state_series(recording, "pose", lambda m: (m.pose.position.x,), 1)
    vel_ns, vel = state_series(recording, "velocity", lambda m: (m.twist.linear.x,), 1)
    force_ns, force = state_series(recording, "friction_force",
                                   lambda m: (m.wrench.force.x, m.wrench.force.y, m.wrench.force.z), 3)
    figure = Figure(figsize=(10, 9), layout="constrained")
    axes = figure.subplots(4, 1, sharex=True)
    axes[0].plot(pose_ns / NS_PER_S, pose[:, 0] * 1e3, lw=0.8)
    axes[0].set_ylabel("position x [mm]")
    axes[1].plot(vel_ns / NS_PER_S, vel[:, 0] * 1e3, lw=0.8, label="v")
    mean = recording.decoded("mean_velocity")
    if mean:
        axes[1].step([ns_to_seconds(t) for t, _ in mean], [m.twist.linear.x * 1e3 for _, m in mean],
                     where="pre", lw=1.2, label="mean over window")
        axes[1].legend(loc="upper right", fontsize="small")
    axes[1].set_ylabel("velocity v [mm/s]")
    axes[2].plot(force_ns / NS_PER_S, force[:, 0], lw=0.8, color="tab:red")
    axes[2].set_ylabel("friction force [N]")
    axes[3].plot(force_ns / NS_PER_S, force[:, 2], lw=0.8, color="tab:green")
    axes[3].set_ylabel("normal force R [N]")
    axes[3].set_xlabel("simulation time t [s]")
    marks = command_marks(recording)
    for number, (t, label, accepted) in enumerate(marks):
        for ax in axes:
            ax.axvline(t, color="0.35" if accepted else "tab:red", ls="--" if accepted else ":", lw=0.8)
        if number < 40:
            axes[0].annotate(label, (t, 1.0), xycoords=("data", "axes fraction"), rotation=90, va="top",
                             ha="right", fontsize=6, color="0.25" if accepted else "tab:red")
    for ax in axes:
        ax.grid(True, lw=0.3)
    figure.suptitle(f"{recording.path.name}: {len(marks)} commands")
    return figure


# --------------------------------------------------------------------------
# The command line.
# --------------------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``friction-sim replay FILE ...``."""
    parser.add_argument("file", type=Path, help="the recording (.mcap)")
    parser.add_argument("--verify", action="store_true",
                        help="re-simulate from the recorded parameters and commands and compare with the "
                             "recorded states (exit 1 if they differ by more than --tolerance)")
    parser.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE,
                        help=f"relative tolerance of --verify ({DEFAULT_TOLERANCE:g})")
    parser.add_argument("--publish", action="store_true", help="republish the messages on their topics")
    parser.add_argument("--rate", type=float, default=1.0, help="playback rate factor for --publish (1.0)")
    parser.add_argument("--loop", action="store_true", help="with --publish: start over at the end")
    parser.add_argument("--topics", nargs="+", metavar="TOPIC", help="with --publish/--csv: only these topics")
    parser.add_argument("--namespace", default="", help="with --publish: namespace of the published topics")
    parser.add_argument("--delay", type=float, default=0.0, help="with --publish: seconds to wait before playing")
    parser.add_argument("--csv", type=Path, metavar="DIR", help="write one CSV per topic into DIR")
    parser.add_argument("--plot", type=Path, metavar="PNG",
                        help="draw position, velocity, friction force and R with the commands marked")


def run(args: argparse.Namespace) -> int:
    """Run the replay subcommand; 0 ok, 1 when --verify finds a difference.
    Raises RecordingError for a file that cannot be used."""
    recording = read_recording(args.file)
    note = recording.recovery_note()
    if note:
        print(note, file=sys.stderr)
    code = EXIT_OK
    acted = False
    if args.verify:
        acted = True
        result = verify(recording, args.tolerance)
        for line in result.lines():
            print(line)
        if not result.passed:
            code = EXIT_MISMATCH
    if args.csv is not None:
        acted = True
        paths = export_csv(recording, args.csv, getattr(args, "topics", None))
        print(f"wrote {len(paths)} CSV files to {args.csv}")
    if args.plot is not None:
        acted = True
        figure = plot(recording)
        try:
            args.plot.parent.mkdir(parents=True, exist_ok=True)
            figure.savefig(args.plot, dpi=120)
        except OSError as error:
            raise RecordingError(f"cannot write {args.plot}: {error.strerror or error}") from None
        print(f"wrote {args.plot}")
    if args.publish:
        acted = True
        result_pub = publish(recording, rate=args.rate, loop=args.loop, topics=args.topics,
                             namespace=args.namespace, delay=getattr(args, "delay", 0.0), progress=sys.stderr)
        print(f"published {result_pub.messages} messages"
              + (f" in {result_pub.loops} loops" if args.loop else "")
              + (" (interrupted)" if result_pub.interrupted else ""))
    if not acted:
        for line in recording.info_lines():
            print(line)
    return code


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m friction_sim.io.replay FILE ...``: errors are one line, exit 2."""
    parser = argparse.ArgumentParser(prog="friction-sim replay",
                                     description="Verify, republish, export or plot a friction_sim recording.")
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except FrictionSimError as error:
        print(f"friction-sim replay: error: {error}", file=sys.stderr)
    except KeyboardInterrupt:
        return EXIT_OK
    return EXIT_ERROR


def _size(n: int) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n} B"


if __name__ == "__main__":
    raise SystemExit(main())


__all__ = [
    "Channel", "PublishResult", "RawMessage", "Recording", "VerifyResult", "add_arguments", "export_csv",
    "flatten", "initial_parameters", "main", "plot", "publish", "read_recording", "run", "verify",
]
