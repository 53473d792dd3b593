"""The real-time loop of a hopping slider (core/realtime.py): amplitudes above
the weight are taken, not refused; each period's summary carries the fraction
spent in flight and diagnostics the lift-offs, landings and flight fraction of
the interval, all checked against the events the loop handed out; the
general model's parameters, text included, go through the one gate."""

from __future__ import annotations

import math

import pytest

from friction_sim.core.model.commands import Command
from friction_sim.core.model.events import CycleMark, Event, EventKind, Mode
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.model.records import PeriodSummary
from friction_sim.core.runtime.realtime import NS_PER_S, RealtimeSlider

HOP = Inputs(excitation_amplitude=15.0, drive_force=0.3)  # Gamma = 1.5: a flight every period
TICK = NS_PER_S // 1000


def _run(rt: RealtimeSlider, start: int, end: int) -> tuple[list[Event], list[PeriodSummary]]:
    events: list[Event] = []
    periods: list[PeriodSummary] = []
    for wall in range(start, end + 1, TICK):
        tick = rt.tick(wall)
        events += tick.events
        periods += tick.periods
    return events, periods


def _flights(events: list[Event]) -> list[tuple[float, float]]:
    """(lift-off, landing) time of every flight, from the mode each event leaves and enters."""
    flights, up = [], None
    for event in events:
        if event.after is Mode.FLIGHT and event.before is not Mode.FLIGHT:
            up = event.t
        elif event.before is Mode.FLIGHT and event.after is not Mode.FLIGHT:
            assert up is not None
            flights.append((up, event.t))
            up = None
    return flights


def _flight_time(flights: list[tuple[float, float]], start: float, end: float) -> float:
    return sum(max(0.0, min(b, end) - max(a, start)) for a, b in flights)


def test_each_period_summary_carries_the_flight_fraction_the_events_give() -> None:
    rt = RealtimeSlider(SliderParams(), HOP, wall_ns=0)
    events, periods = _run(rt, 0, NS_PER_S // 2)
    flights = _flights(events)
    assert len(flights) >= 20 and all(b > a for a, b in flights)
    assert len(periods) >= 20
    for period in periods:
        start = period.t - 1.0 / 50.0
        expected = _flight_time(flights, start, period.t) / (period.t - start)
        assert 0.0 < period.flight_fraction < 1.0
        assert period.flight_fraction == pytest.approx(expected, rel=1e-9, abs=1e-12)
        assert period.stick_fraction + period.flight_fraction <= 1.0 + 1e-12


def test_fractions_are_clamped_to_0_1_where_rounding_pushes_them_out(monkeypatch: pytest.MonkeyPatch) -> None:
    """Stuck and flight times are accumulated apart from the period marks' times,
    so a period spent wholly in flight can come out a few ulp above 1 (a hopping
    run showed flight_fraction 1.0000000000003553): summaries say 1, never more,
    and never below 0."""
    t0, t1 = 1000.0, 1000.02
    over = (t1 - t0) * (1.0 + 2 ** -42)  # a whole period of flight, accumulated a few ulp long
    marks = [CycleMark(50_000, t0, 0.0, 0.0, 5.0), CycleMark(50_001, t1, 0.0, -1e-18, 5.0 + over)]
    assert (marks[1].flight_time - marks[0].flight_time) / (t1 - t0) > 1.0  # what the division gave
    rt = RealtimeSlider(SliderParams(), HOP, wall_ns=0)
    monkeypatch.setattr(rt.slider, "cycle_marks_after", lambda n: [m for m in marks if m.n > n])
    (summary,) = rt.period_means.new(rt.slider, rt.marks_before)  # the summaries straight from the marks
    assert summary.flight_fraction == 1.0 and summary.stick_fraction == 0.0


def test_diagnostics_count_lift_offs_and_landings_and_the_flight_fraction_per_interval() -> None:
    rt = RealtimeSlider(SliderParams(), HOP, wall_ns=0)
    first_events, _ = _run(rt, 0, 3 * NS_PER_S // 10)
    first = rt.diagnostics(3 * NS_PER_S // 10)
    lift_offs = sum(e.kind is EventKind.LIFT_OFF for e in first_events)
    landings = sum(e.kind is EventKind.LANDING for e in first_events)
    assert lift_offs >= 10 and landings >= 10
    assert (first["lift_offs"], first["landings"]) == (lift_offs, landings)
    assert (first["lift_offs_in_interval"], first["landings_in_interval"]) == (lift_offs, landings)
    flights = _flights(first_events)
    t1 = rt.slider.t
    assert first["flight_fraction_in_interval"] == pytest.approx(_flight_time(flights, 0.0, t1) / t1, rel=1e-9)
    assert first["throw_number"] == 1.5 and 0.0 < first["flight_fraction"] < 1.0

    more, _ = _run(rt, 3 * NS_PER_S // 10 + TICK, 5 * NS_PER_S // 10)
    second = rt.diagnostics(5 * NS_PER_S // 10)
    assert second["lift_offs_in_interval"] == sum(e.kind is EventKind.LIFT_OFF for e in more) > 0
    assert second["lift_offs"] == lift_offs + second["lift_offs_in_interval"]
    everything = _flights(first_events + more)
    t2 = rt.slider.t
    assert second["flight_fraction_in_interval"] == pytest.approx(
        _flight_time(everything, t1, t2) / (t2 - t1), rel=1e-9)


def test_on_the_track_there_is_no_flight_to_report() -> None:
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0)
    _, periods = _run(rt, 0, NS_PER_S // 10)
    report = rt.diagnostics(NS_PER_S // 10)
    assert periods and all(p.flight_fraction == 0.0 for p in periods)
    assert (report["lift_offs"], report["landings"], report["flight_fraction"]) == (0, 0, 0.0)
    assert report["flight_fraction_in_interval"] == 0.0 and report["throw_number"] == 0.5


@pytest.mark.parametrize("command", [
    Command(0.0, "excitation_amplitude", {"excitation_amplitude": 12.0}),
    Command(0.0, "external_wrench", {"external_force_x": 0.0, "external_force_z": 7.0}),  # lifts: m g - Fz < Pa
    Command(0.0, "parameters", {"mass": 0.3}),
])
def test_a_command_that_throws_the_slider_off_is_taken_and_it_hops(command: Command) -> None:
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0)
    rt.tick(NS_PER_S // 100)
    outcome = rt.command(command, NS_PER_S // 100)
    assert outcome.accepted, outcome.reason
    events, _ = _run(rt, NS_PER_S // 100 + TICK, NS_PER_S // 10)
    assert any(e.kind is EventKind.LIFT_OFF for e in events)
    assert rt.rejected == 0


def test_the_general_models_parameters_go_through_configure_text_included() -> None:
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0)
    refused = rt.configure({"landing_friction": "glue", "restitution": 0.5}, NS_PER_S // 100)
    assert refused.reason == "landing_friction = 'glue' rejected: must be one of impulsive, none"
    assert rt.slider.params == SliderParams() and rt.rejected == 1 and rt.last_rejection == refused.reason
    taken = rt.configure({"landing_friction": "none", "restitution": 0.5, "excitation_angle": 30.0,
                          "track_inclination": 5.0, "static_ratio": 1.2, "excitation_phase": 90.0}, NS_PER_S // 50)
    assert taken.accepted and taken.values["landing_friction"] == "none"
    assert rt.slider.params == SliderParams(landing_friction="none", restitution=0.5, excitation_angle=30.0,
                                            track_inclination=5.0, static_ratio=1.2, excitation_phase=90.0)
    state = rt.tick(NS_PER_S // 10).state
    assert all(math.isfinite(value) for value in (state.x, state.v, state.z, state.vz))
    # A topic command is checked against the plant in force, one field at a time.
    outcome = rt.command(Command(0.0, "parameters", {"restitution": 1.0}), NS_PER_S // 10)
    assert not outcome.accepted and "restitution = 1.0" in outcome.reason


def test_a_prediction_made_outside_the_lock_is_the_one_reported(monkeypatch: pytest.MonkeyPatch) -> None:
    """The node computes the prediction (a simulation outside Kostek's model)
    before it takes the tick's lock and hands it to diagnostics, which then
    does not simulate; a prediction that fails is NaN, not an exception."""
    from friction_sim.core.runtime import diagnostics

    params = SliderParams(excitation_angle=60.0)
    rt = RealtimeSlider(params, HOP, wall_ns=0)
    made = rt.prediction(params, HOP)
    assert math.isfinite(made.u) and made.u > 0.0

    def no_simulation(*_: object) -> None:
        raise AssertionError("diagnostics simulated under the lock")

    monkeypatch.setattr(diagnostics, "predict", no_simulation)
    report = rt.diagnostics(NS_PER_S, made)
    assert report["predicted_U"] == made.u
    rt.slider.set_inputs(drive_force=0.4)  # a change: the cached prediction no longer applies
    assert math.isnan(rt.prediction().u)  # and the failing predict gives NaN, not a traceback
