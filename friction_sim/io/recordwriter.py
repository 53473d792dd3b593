"""The recorder's writer thread side: sink records -> ROS 2 messages -> the MCAP file.

:class:`RecordWriter` takes the records a :class:`~friction_sim.io.recorder.Recorder`
queued (states, events, period means, commands, parameters, messages,
metadata) and writes them to a :class:`~friction_sim.io.bagfile.BagFile`
in order.  The state topics (pose, velocity, friction_force) and
mean_velocity are fixed-layout messages: consecutive states are written
many at a time, as rows of numbers in the bytes rosbags serialized for a
template (:func:`~friction_sim.io.cdr.fixed_layouts`, checked against
rosbags), and so are the accelerometer's sensor_msgs/Imu samples (a
thousand a second: one rosbags serialization each would cost the recording
more than the simulation); everything else is built by :mod:`friction_sim.io.messages` and
serialized one message at a time.  Topics are stored fully qualified in the
node's namespace, as rosbag2 names them.

A record no message can hold (a topic reused with another type, a time no
ROS stamp holds, a value of no parameter type) is dropped, counted in
:attr:`RecordWriter.bad` and warned about once per kind; an ``OSError``
(the disk) is raised to the caller, which ends the recording.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus

from friction_sim.core.model.events import Event, Mode, SliderState
from friction_sim.core.model.records import Acceleration, PeriodSummary
from friction_sim.errors import one_line
from friction_sim.io.bagfile import MAX_STAMP_NS, BagFile, EncodedRows, RowGroup
from friction_sim.io.cdr import FixedLayout, diagnostic_status, fixed_layouts
from friction_sim.io.messages import (
    ACCELEROMETER,
    STATE_TOPICS,
    TOPIC_TYPES,
    command_message,
    command_topic,
    event_fields,
    event_message,
    fill_state_messages,
    imu_message,
    mean_velocity_message,
    message_class,
    parameters_message,
    rejection_message,
    seconds_to_ns,
    state_messages,
    time_msg,
)
from friction_sim.io.sinks import (
    AccelerationsRecord,
    ClockRecord,
    CommandRecord,
    EventRecord,
    MessageRecord,
    ParametersRecord,
    PeriodRecord,
    Record,
    StatesRecord,
    record_size,
)
from friction_sim.io.typesupport import message_type_name

#: An event's message type and level (:func:`~friction_sim.io.messages.event_message`'s), for its direct serialization.
_EVENT_TYPE = TOPIC_TYPES["events"]
_EVENT_LEVEL = ord(DiagnosticStatus.OK)

_log = logging.getLogger("friction_sim.io.recorder")


class Metadata(NamedTuple):
    """An MCAP metadata record for the file (the recorder's own, not a sink record)."""

    name: str
    data: Mapping[str, str]


#: What the recorder queues: a sink record, or metadata.
Item = Record | Metadata
#: States encoded per numpy pass (bounds how long the writer holds the GIL at once).
ROWS_PER_PASS = 2048


#: The numbers of a state the three state messages carry, in the order of a row
#: of :meth:`BagFile.add_rows` (pose x and z, velocity v and vz, friction force and R).
STATE_VALUES = ("x", "z", "v", "vz", "friction_force", "normal_force")


def state_row(state: SliderState) -> tuple[float, ...]:
    """The :data:`STATE_VALUES` of ``state``."""
    return state.x, state.z, state.v, state.vz, state.friction_force, state.normal_force


def state_row_builder(frame_id: str) -> Callable[[int, Sequence[float]], Sequence[Any]]:
    """The three state messages in ``frame_id`` from a log time [ns] and a row
    of :data:`STATE_VALUES`: what :func:`~friction_sim.io.cdr.fixed_layouts`
    probes to find where each number sits (the recorder and the live view)."""
    def make(ns: int, values: Sequence[float]) -> Sequence[Any]:
        x, z, v, vz, friction, normal = values
        return state_messages(SliderState(ns / 1e9, x, v, 0.0, friction, normal, 0.0, Mode.STUCK, z, vz), frame_id)

    return make


def imu_row_builder(frame_id: str, noise: float) -> Callable[[int, Sequence[float]], Sequence[Any]]:
    """The accelerometer's Imu message in ``frame_id`` (covariance from ``noise``) from a
    stamp [ns] and a row (x, y, z): what :func:`~friction_sim.io.cdr.fixed_layouts` probes
    (the recorder, and the slider's publisher of the topic)."""
    def make(ns: int, values: Sequence[float]) -> Sequence[Any]:
        return [imu_message(Acceleration(ns / 1e9, *values), frame_id, noise)]

    return make


def _state_table(states: Sequence[SliderState]) -> np.ndarray:
    """A row (t, :data:`STATE_VALUES`...) per state."""
    return np.array([(s.t, *state_row(s)) for s in states], dtype=np.float64)


def _sample_table(samples: Sequence[Acceleration]) -> np.ndarray:
    """A row (t, x, y, z) per accelerometer sample."""
    return np.array([(s.t, s.x, s.y, s.z) for s in samples], dtype=np.float64)


class _RowKind(NamedTuple):
    """What the records of a row group are: a row (t, values...) per record, the messages
    a record makes, and what a dropped one is counted as (and why, for a time no stamp holds)."""

    table: Callable[[Sequence[Any]], np.ndarray]
    messages: int
    what: str
    unstamped: str


_STATES = _RowKind(_state_table, 3, "state", "a state time no ROS stamp holds")
_SAMPLES = _RowKind(_sample_table, 1, "accelerations", "a sample time no ROS stamp holds")


class _Piece(NamedTuple):
    """A pass of a batch's rows: its first record's index in the batch, the rows built
    (None: the pass failed), and how many were kept before each record (and after the last)."""

    first: int
    rows: EncodedRows | None
    kept: list[int]


class _Encoded:
    """The records of one group of a batch (a frame's states, or its samples at one noise),
    built at once (:meth:`RecordWriter._append`) and written a run at a time, in the order
    queued (:meth:`RecordWriter.write`)."""

    def __init__(self) -> None:
        self.records: list[Any] = []
        self.pieces: list[_Piece] | None = None  # (None: not built yet)
        self.written = 0  # records written (or dropped) so far

    def append(self, file: BagFile, count: int) -> None:
        """Write the next ``count`` records' rows (those kept)."""
        start, stop = self.written, self.written + count
        self.written = stop  # (first: a run that fails is dropped, and the next ones keep their rows)
        for first, rows, kept in self.pieces or ():
            low, high = max(start, first), min(stop, first + len(kept) - 1)
            if rows is not None and low < high:
                file.append_rows(rows, kept[low - first], kept[high - first])


def qualified_topic(namespace: str, topic: str) -> str:
    """``topic`` as rosbag2 names it: absolute names stay, relative ones are
    resolved in ``namespace`` (``pose`` in ``/`` is ``/pose``, in ``/feeder1``
    it is ``/feeder1/pose``)."""
    if topic.startswith("/"):
        return topic
    return f"{namespace.rstrip('/')}/{topic}"


class RecordWriter:
    """Writes queued sink records to ``file`` (see the module docstring); one thread only."""

    def __init__(self, file: BagFile, namespace: str, path: Path, node: str) -> None:
        self.file = file
        self.namespace = namespace
        self.node = node
        self.path = path
        #: Messages dropped because no message could hold their record.
        self.bad = 0
        self._warned: set[tuple[str, str]] = set()
        self._topics: dict[str, str] = {}
        self._state_groups: dict[str, RowGroup | None] = {}
        self._period_layouts: dict[str, FixedLayout | None] = {}
        self._imu_groups: dict[tuple[str, float], RowGroup | None] = {}
        self._templates: tuple[Any, Any, Any] | None = None  # pose, twist, wrench: the one-at-a-time path
        # The batch being written: its states by frame and samples by (frame, noise), built (see write).
        self._state_rows: dict[str, _Encoded] = {}
        self._sample_rows: dict[tuple[str, float], _Encoded] = {}

    def write(self, batch: Sequence[Item]) -> None:
        """Write the records of ``batch``.  The states of consecutive ticks
        (of one frame) go together, then those ticks' events and period means,
        then their accelerometer samples together; any other record (a command,
        parameters, a message, metadata) keeps its place: everything queued
        before it is written before it (a file cut short holds the commands
        the states it holds followed, and no later ones).  Each topic stays in
        time order.  The states and samples of the whole batch are built at
        once, before it is written (:meth:`_encode`): a controller that answers
        every period puts a command between each period's, and building them a
        run at a time took half the writer's work."""
        self._encode(batch)
        try:
            self._write_in_place(batch)
        finally:
            self._state_rows, self._sample_rows = {}, {}

    def _write_in_place(self, batch: Sequence[Item]) -> None:
        states: list[SliderState] = []
        frame_id = ""
        later: list[Item] = []  # events, periods and samples of the ticks whose states are in ``states``
        for item in batch:
            if isinstance(item, StatesRecord):
                if states and item.frame_id != frame_id:
                    self._write_run(states, frame_id, later)
                    states, later = [], []
                states.extend(item.states)
                frame_id = item.frame_id
            elif isinstance(item, (EventRecord, PeriodRecord, AccelerationsRecord)):
                later.append(item)
            else:
                self._write_run(states, frame_id, later)
                states, later = [], []
                self._write_safely(item)
        self._write_run(states, frame_id, later)

    def _write_run(self, states: list[SliderState], frame_id: str, later: list[Item]) -> None:
        if states:
            self._write_states(states, frame_id)
        samples: list[AccelerationsRecord] = []
        for item in later:
            if isinstance(item, AccelerationsRecord):
                if samples and (item.frame_id, item.noise) != (samples[-1].frame_id, samples[-1].noise):
                    self._write_samples(samples)
                    samples = []
                samples.append(item)
            else:
                self._write_safely(item)
        self._write_samples(samples)

    def _write_samples(self, records: list[AccelerationsRecord]) -> None:
        """Write consecutive accelerometer records of one frame and noise in one pass."""
        if len(records) <= 1:
            for record in records:
                self._write_safely(record)
            return
        first = records[0]
        self._write_safely(AccelerationsRecord(tuple(sample for record in records for sample in record.samples),
                                               first.frame_id, first.noise))

    def topic(self, topic: str) -> str:
        """The fully qualified name of ``topic`` (cached)."""
        name = self._topics.get(topic)
        if name is None:
            name = self._topics[topic] = qualified_topic(self.namespace, topic)
        return name

    # -- states and periods, many at a time ---------------------------------------------

    def _encode(self, batch: Sequence[Item]) -> None:
        """Gather the states (by frame) and accelerometer samples (by frame and noise) of
        ``batch``, in the order queued: each group is built at its first run (once
        what was queued before it is written, so channels are made in the order queued)
        and written a run at a time."""
        for item in batch:
            if isinstance(item, StatesRecord):
                self._state_rows.setdefault(item.frame_id, _Encoded()).records.extend(item.states)
            elif isinstance(item, AccelerationsRecord):
                self._sample_rows.setdefault((item.frame_id, item.noise), _Encoded()).records.extend(item.samples)

    def _append(self, encoded: _Encoded, count: int, group: RowGroup, kind: _RowKind) -> None:
        """Write the next ``count`` records of ``encoded`` as rows of ``group``, building all
        its records the first time (in passes of :data:`ROWS_PER_PASS`); a record whose time no
        ROS stamp holds is dropped and counted, as is a pass that fails."""
        if encoded.pieces is None:
            encoded.pieces = []
            records = encoded.records
            for first in range(0, len(records), ROWS_PER_PASS):
                encoded.pieces.append(self._piece(first, records[first:first + ROWS_PER_PASS], group, kind))
        encoded.append(self.file, count)

    def _piece(self, first: int, part: Sequence[Any], group: RowGroup, kind: _RowKind) -> _Piece:
        """One pass of :meth:`_append`: the rows of ``part``, whose first record is ``first``."""
        try:
            table = kind.table(part)
            ns = np.rint(table[:, 0] * 1e9)  # = seconds_to_ns(t): round half to even, as round()
            ok = (ns >= 0.0) & (ns <= MAX_STAMP_NS)  # False for NaN too
            if not ok.all():
                self._count_bad(kind.messages * int((~ok).sum()), kind.what, kind.unstamped)
                ns, table = ns[ok], table[ok]
            rows = self.file.encode_rows(group, ns.astype(np.int64), table[:, 1:])
            return _Piece(first, rows, [0, *np.cumsum(ok).tolist()])
        except OSError:
            raise
        except Exception as error:  # noqa: BLE001 - bad records must not end the recording
            self._count_bad(kind.messages * len(part), kind.what, one_line(error, with_type=True))
            return _Piece(first, None, [0] * (len(part) + 1))

    def _write_states(self, states: Sequence[SliderState], frame_id: str) -> None:
        """Write states as pose, velocity and friction_force: many at a time
        when the three messages are fixed-layout (they are), else one by one."""
        group = self._state_group(frame_id)
        if group is None:
            for state in states:
                self._write_safely(StatesRecord((state,), frame_id))
            return
        self._append(self._state_rows[frame_id], len(states), group, _STATES)

    def _state_group(self, frame_id: str) -> RowGroup | None:
        """The fixed layouts of a state's three messages in ``frame_id`` (cached)."""
        if frame_id not in self._state_groups:
            topics = [self.topic(topic) for topic in STATE_TOPICS]
            self._state_groups[frame_id] = self.file.row_group(topics, state_row_builder(frame_id), len(STATE_VALUES))
        return self._state_groups[frame_id]

    def _write_period(self, period: PeriodSummary, frame_id: str) -> None:
        """Write a period's mean velocity (from its fixed layout when it has one)."""
        if frame_id not in self._period_layouts:
            layouts = fixed_layouts(lambda ns, values: [mean_velocity_message(
                PeriodSummary(n=0, t=ns / 1e9, mean_velocity=values[0], window_periods=1, stick_fraction=0.0),
                frame_id)], 1)
            self._period_layouts[frame_id] = layouts[0] if layouts else None
        layout = self._period_layouts[frame_id]
        ns = seconds_to_ns(period.t)
        topic = self.topic("mean_velocity")
        if layout is not None and 0 <= ns <= MAX_STAMP_NS:
            self.file.add_serialized(topic, layout.type_name, layout.encode_one(ns, (period.mean_velocity,)), ns)
        else:
            self._add(topic, mean_velocity_message(period, frame_id), ns)

    def _imu_group(self, frame_id: str, noise: float) -> RowGroup | None:
        """The fixed layout of the accelerometer's Imu message in ``frame_id`` at ``noise`` (cached)."""
        key = (frame_id, noise)
        if key not in self._imu_groups:
            self._imu_groups[key] = self.file.row_group([self.topic(ACCELEROMETER)],
                                                        imu_row_builder(frame_id, noise), 3)
        return self._imu_groups[key]

    def _write_accelerations(self, samples: Sequence[Acceleration], frame_id: str, noise: float) -> None:
        """Write accelerometer samples as sensor_msgs/Imu, many at a time (one by one if
        the message has no fixed layout)."""
        group = self._imu_group(frame_id, noise)
        if group is None:
            topic = self.topic(ACCELEROMETER)
            for sample in samples:
                self._add(topic, imu_message(sample, frame_id, noise), seconds_to_ns(sample.t))
            return
        self._append(self._sample_rows[(frame_id, noise)], len(samples), group, _SAMPLES)

    # -- one record at a time --------------------------------------------------------

    def _write_safely(self, item: Item) -> None:
        """Write one record; a bad one is dropped and counted, an OSError raised."""
        try:
            self._write_one(item)
        except OSError:
            raise
        except Exception as error:  # noqa: BLE001 - one bad record must not end the recording
            self._count_bad(1 if isinstance(item, Metadata) else record_size(item), record_kind(item),
                            one_line(error, with_type=True))

    def _write_one(self, item: Item) -> None:
        """Build the messages of one queued record and write them."""
        if isinstance(item, MessageRecord):
            self._add(self.topic(item.topic), item.msg, item.log_time_ns)
        elif isinstance(item, Metadata):
            self.file.add_metadata(item.name, dict(item.data))
        elif isinstance(item, PeriodRecord):
            self._write_period(item.period, item.frame_id)
        elif isinstance(item, AccelerationsRecord):
            self._write_accelerations(item.samples, item.frame_id, item.noise)
        elif isinstance(item, EventRecord):
            self._write_event(item.event)
        elif isinstance(item, StatesRecord):  # (one by one: the states' messages have no fixed layout)
            for state in item.states:
                self._add_state(state, item.frame_id)
        else:
            for topic, msg, log_time_ns in record_messages(item, self.node):
                self._add(self.topic(topic), msg, log_time_ns)

    def _write_event(self, event: Event) -> None:
        """Write an event as the DiagnosticStatus :func:`event_message` builds, serialized directly."""
        name, message, values = event_fields(event)
        data = diagnostic_status(_EVENT_LEVEL, name, message, "", values)
        log_time_ns = seconds_to_ns(event.t)
        if not self.file.add_serialized(self.topic("events"), _EVENT_TYPE, data, log_time_ns):
            self._count_outside(_EVENT_TYPE, log_time_ns)

    def _add_state(self, state: SliderState, frame_id: str) -> None:
        """Write a state one message at a time (messages reused: serialized at once)."""
        if self._templates is None:
            self._templates = state_messages(state, frame_id)
        else:
            fill_state_messages(state, frame_id, *self._templates)
        ns = seconds_to_ns(state.t)
        for topic, msg in zip(STATE_TOPICS, self._templates):
            self._add(self.topic(topic), msg, ns)

    def _add(self, topic: str, msg: Any, log_time_ns: int) -> None:
        """Write one message; a log time no ROS stamp holds is dropped and counted."""
        if not self.file.add(topic, msg, log_time_ns):
            self._count_outside(message_type_name(type(msg)), log_time_ns)

    def _count_outside(self, type_name: str, log_time_ns: int) -> None:
        """Count a message dropped because its log time is one no ROS stamp holds."""
        self._count_bad(1, type_name, f"log time {log_time_ns} ns is outside ROS time")

    def _count_bad(self, messages: int, what: str, why: str) -> None:
        """Count ``messages`` dropped because no message could hold them (warn once per kind)."""
        self.bad += messages
        if (what, why) not in self._warned:
            self._warned.add((what, why))
            _log.warning("recording %s: dropped a %s record: %s", self.path, what, why)


def record_kind(item: Item) -> str:
    """What ``item`` is, for a warning: a message's topic, else its kind (``states``, ``event``, ...)."""
    if isinstance(item, MessageRecord):
        return str(item.topic)[:40]
    return type(item).__name__.removesuffix("Record").lower()


def record_topics(record: Record) -> tuple[str, ...]:
    """The topics (relative names, or absolute ones) the messages of ``record`` go on."""
    if isinstance(record, StatesRecord):
        return STATE_TOPICS
    if isinstance(record, MessageRecord):
        return (record.topic,)
    if isinstance(record, CommandRecord):
        return (command_topic(record.outcome.name) if record.outcome.accepted else "rejected_commands",)
    return _TOPICS[type(record)]


#: The one topic of each kind of record that has one whatever it holds.
_TOPICS: dict[type, tuple[str]] = {EventRecord: ("events",), PeriodRecord: ("mean_velocity",),
                                   AccelerationsRecord: (ACCELEROMETER,), ParametersRecord: ("parameters",),
                                   ClockRecord: ("/clock",)}


def record_messages(record: Record, node: str) -> list[tuple[str, Any, int]]:
    """(topic, message, log time [ns]) of a sink record other than states, as a
    recording holds them (the live view serves the same); parameter events
    name ``node``, the slider's fully qualified name."""
    if isinstance(record, StatesRecord):
        raise ValueError("states are written many at a time, not as single messages")
    (topic,) = record_topics(record)
    if isinstance(record, AccelerationsRecord):
        return [(topic, imu_message(sample, record.frame_id, record.noise), seconds_to_ns(sample.t))
                for sample in record.samples]
    if isinstance(record, MessageRecord):
        return [(topic, record.msg, int(record.log_time_ns))]
    if isinstance(record, PeriodRecord):
        return [(topic, mean_velocity_message(record.period, record.frame_id), seconds_to_ns(record.period.t))]
    if isinstance(record, EventRecord):
        return [(topic, event_message(record.event), seconds_to_ns(record.event.t))]
    if isinstance(record, CommandRecord):
        outcome = record.outcome
        message = command_message(outcome.command, record.frame_id, node) if outcome.accepted \
            else rejection_message(outcome)
        return [(topic, message, seconds_to_ns(outcome.t))]
    if isinstance(record, ParametersRecord):
        return [(topic, parameters_message(record.values, record.t, changed=record.changed, node=node),
                 seconds_to_ns(record.t))]
    return [(topic, message_class("rosgraph_msgs/msg/Clock")(clock=time_msg(record.t_ns)), record.t_ns)]


__all__ = ["ROWS_PER_PASS", "STATE_VALUES", "Item", "Metadata", "RecordWriter", "imu_row_builder", "qualified_topic",
           "record_kind", "record_messages", "record_topics", "state_row_builder", "state_row"]
