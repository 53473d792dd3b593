"""The sink interface: one entry, ``write(record)``, and what a tick hands each sink."""

from __future__ import annotations

from pathlib import Path

from friction_sim.core.model.events import Event, EventKind, Mode, SliderState
from friction_sim.core.model.records import Acceleration, PeriodSummary, Tick
from friction_sim.io.reader import read_recording
from friction_sim.io.recorder import Recorder
from friction_sim.io.sinks import (
    AccelerationsRecord,
    ClockRecord,
    EventRecord,
    MessageRecord,
    PeriodRecord,
    Record,
    StatesRecord,
    deliver,
    deliver_tick,
    record_size,
)


def state(t: float) -> SliderState:
    return SliderState(t, 1e-3 * t, 0.01, 0.0, -0.3, 10.0, 0.0, Mode.STUCK)


class Log:
    """A sink that keeps what it is handed."""

    def __init__(self, published_states: bool = False) -> None:
        self.published_states = published_states
        self.records: list[Record] = []

    def write(self, record: Record) -> bool:
        self.records.append(record)
        return True

    def close(self) -> None: ...


TICK = Tick(state(0.004), [Event(0.0035, EventKind.SLIP_START, 4e-6, 0.3, Mode.STUCK, Mode.FORWARD)],
            [PeriodSummary(n=1, t=0.004, mean_velocity=0.02, window_periods=1, stick_fraction=0.5)],
            samples=(state(0.002), state(0.003)), accelerations=(Acceleration(0.003, 0.1, 0.0, 9.8),))


def test_a_tick_reaches_each_sink_as_records_in_one_order() -> None:
    """The accelerometer's samples, the states, the events, the period means: the log grid's
    states for a recording, the published state for a sink that serves what was published."""
    recording, live = Log(), Log(published_states=True)
    deliver_tick([recording, live], TICK, "rail", noise=0.05)
    later = [EventRecord(TICK.events[0]), PeriodRecord(TICK.periods[0], "rail")]
    samples = AccelerationsRecord(TICK.accelerations, "rail", 0.05)
    assert recording.records == [samples, StatesRecord(TICK.samples, "rail"), *later]
    assert live.records == [samples, StatesRecord((TICK.state,), "rail"), *later]


def test_a_quiet_tick_hands_a_recording_nothing_and_a_live_view_its_state() -> None:
    recording, live = Log(), Log(published_states=True)
    deliver_tick([recording, live], Tick(state(0.5), [], []), "rail")
    assert recording.records == [] and live.records == [StatesRecord((state(0.5),), "rail")]


def test_deliver_hands_one_record_to_every_sink_and_sizes_count_messages() -> None:
    sinks = [Log(), Log(published_states=True)]
    record = MessageRecord("diagnostics", object(), 7)
    deliver(sinks, record)
    assert [sink.records for sink in sinks] == [[record], [record]]
    assert record_size(StatesRecord((state(0.1), state(0.2)), "rail")) == 6  # pose, velocity, friction_force
    assert record_size(AccelerationsRecord(TICK.accelerations * 3, "rail", 0.0)) == 3
    assert record_size(ClockRecord(5)) == record_size(record) == 1


def test_a_recording_keeps_no_clock(tmp_path: Path) -> None:
    """/clock would only repeat the log times: the recorder takes the record and writes nothing."""
    path = tmp_path / "run.mcap"
    with Recorder(path, metadata={"mass": 1.0}) as recorder:
        assert recorder.write(ClockRecord(1_000_000))
        assert recorder.write(StatesRecord((state(0.001),), "rail"))
    recording = read_recording(path, require_friction_sim=False)
    assert recording.topic_name("/clock") is None and recording.message_count == 3
    assert recorder.stats.dropped == 0
