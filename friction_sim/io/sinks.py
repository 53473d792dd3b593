"""What consumes a run: the sink interface, and the records it takes.

The slider node (and the offline recorder,
:func:`friction_sim.experiment.offline.record_offline`) hands everything it
records or serves to a list of sinks through one call, :meth:`Sink.write`,
one record at a time: the exact states, the events, the period means, the
accelerometer's samples, every command with its outcome, the parameters,
``/clock`` and any other ROS message (diagnostics, target_speed).  A record
is an immutable tuple that says what it is by its type; a sink takes the
records it holds and passes over the rest.  The MCAP recorder is one sink; a
live view is another; a new consumer (a metric, a probe) is a class with
``write`` and ``close``.

A sink must be cheap to call (the tick thread calls it): queue the work, do
it elsewhere.  A sink that must not lose anything may make the caller wait
when it falls behind (the recorder does, for as long as its writer makes
progress, and says how long in
:attr:`~friction_sim.io.recordqueue.RecordQueue.wait_seconds`).  A record is read
later, on the sink's own thread: what it holds (a message, a dict of
parameters) must not be changed once written.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple, Protocol

from friction_sim.core.model.commands import Outcome
from friction_sim.core.model.events import Event, SliderState
from friction_sim.core.model.records import Acceleration, PeriodSummary, Tick


class StatesRecord(NamedTuple):
    """Exact states in time order, as ``pose``, ``velocity`` and ``friction_force`` in ``frame_id``."""

    states: tuple[SliderState, ...]
    frame_id: str


class EventRecord(NamedTuple):
    """A transition of the motion (slip start, stick, reversal, lift-off, landing), on ``events``."""

    event: Event


class PeriodRecord(NamedTuple):
    """The mean velocity of the window ending with a completed period, on ``mean_velocity``."""

    period: PeriodSummary
    frame_id: str


class AccelerationsRecord(NamedTuple):
    """The accelerometer's samples (noise included) in time order, on ``accelerometer``;
    ``noise`` is the standard deviation [m/s^2] the messages state as their covariance."""

    samples: tuple[Acceleration, ...]
    frame_id: str
    noise: float


class CommandRecord(NamedTuple):
    """A command as handled: accepted (on its own topic), or refused with the reason
    (on ``rejected_commands``)."""

    outcome: Outcome
    frame_id: str


class ParametersRecord(NamedTuple):
    """Parameter values at simulation time ``t`` [s], on ``parameters``: the set at
    start (``changed`` False) or a later change."""

    values: Mapping[str, Any]
    t: float
    changed: bool


class ClockRecord(NamedTuple):
    """Simulation time ``t_ns`` [ns] as the node publishes it on ``/clock`` (while
    ``publish_clock`` is true): a sink that serves it builds the message."""

    t_ns: int


class MessageRecord(NamedTuple):
    """Any ROS 2 message ``msg`` on ``topic`` (relative names are the node's
    namespace's) at ``log_time_ns`` (simulation time, ns): diagnostics, target_speed."""

    topic: str
    msg: Any
    log_time_ns: int


#: Everything a sink is handed.
Record = (StatesRecord | EventRecord | PeriodRecord | AccelerationsRecord | CommandRecord | ParametersRecord
          | ClockRecord | MessageRecord)


class Sink(Protocol):
    """A consumer of a run: takes :data:`Record` s.  A sink that sets
    ``published_states = True`` (the live view) is handed the states the node
    published, one per tick, instead of the recording's log grid."""

    def write(self, record: Record) -> bool:
        """Take ``record`` (or pass over it); False if it was lost (dropped, counted)."""

    def close(self) -> None:
        """The run is over: finish whatever was written (idempotent)."""


def record_size(record: Record) -> int:
    """How many messages ``record`` stands for: three a state, one a sample, one for the rest."""
    if isinstance(record, StatesRecord):
        return 3 * len(record.states)
    if isinstance(record, AccelerationsRecord):
        return len(record.samples)
    return 1


def deliver(sinks: Sequence[Sink], record: Record) -> None:
    """Hand ``record`` to every sink."""
    for sink in sinks:
        sink.write(record)


def deliver_tick(sinks: Sequence[Sink], tick: Tick, frame_id: str, noise: float = 0.0) -> None:
    """Hand what a real-time tick passed to every sink: the accelerometer's
    samples (``noise``: its standard deviation), the states on the log grid (a
    sink whose ``published_states`` is true, a live view, gets the state the
    tick published instead), the events and the period means.  Each record is
    made once, for all the sinks, and only if some sink gets it (the tick
    thread calls this a thousand times a second)."""
    samples = AccelerationsRecord(tuple(tick.accelerations), frame_id, noise) if tick.accelerations else None
    logged: StatesRecord | None = None
    published: StatesRecord | None = None
    later: list[Record] | None = None
    for sink in sinks:
        if samples is not None:
            sink.write(samples)
        if getattr(sink, "published_states", False):
            if published is None:
                published = StatesRecord((tick.state,), frame_id)
            sink.write(published)
        elif tick.samples:
            if logged is None:
                logged = StatesRecord(tuple(tick.samples), frame_id)
            sink.write(logged)
        if tick.events or tick.periods:
            if later is None:
                later = [*map(EventRecord, tick.events), *(PeriodRecord(period, frame_id) for period in tick.periods)]
            for record in later:
                sink.write(record)


__all__ = ["AccelerationsRecord", "ClockRecord", "CommandRecord", "EventRecord", "MessageRecord", "ParametersRecord",
           "PeriodRecord", "Record", "Sink", "StatesRecord", "deliver", "deliver_tick", "record_size"]
