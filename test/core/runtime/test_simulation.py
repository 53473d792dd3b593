"""Offline jobs on the exact core: run_schedule and simulate (issue 10, item 16)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.urelation import u_map
from friction_sim.core.model.commands import Command
from friction_sim.core.model.events import EventKind
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.simulation import random_schedule, run_schedule, simulate


def driven(schedule: list[Command], until: float) -> Slider:
    """The same schedule applied with advance_to and set_inputs alone (the
    commands of one instant merged, as run_schedule takes them together)."""
    slider = Slider(event_log_size=None)
    merged: dict[float, dict[str, float]] = {}
    for command in schedule:
        merged.setdefault(command.t, {}).update(command.values)
    for t, values in sorted(merged.items()):
        slider.advance_to(t)
        slider.set_inputs(**values)
    slider.advance_to(max(until, slider.t))
    return slider


def test_an_event_between_the_last_sample_and_a_command_is_kept() -> None:
    # The first slip starts at asin(0.6)/(2*pi*50) = 2.05 ms: after the sample at
    # 1 ms, before the command at 5 ms.
    schedule = [Command(0.005, "drive_force", {"drive_force": 0.72})]
    trajectory = run_schedule(Slider(), schedule, np.array([0.0, 0.001, 0.1]))
    assert [e.t for e in trajectory.events] == [e.t for e in driven(schedule, 0.1).events]
    assert any(0.001 < e.t < 0.005 for e in trajectory.events)


@pytest.mark.parametrize("seed", range(6))
def test_the_events_of_a_run_are_all_the_events_whatever_the_sampling(seed: int) -> None:
    rng = np.random.default_rng(seed)
    duration = 0.6
    schedule = random_schedule(rng, duration, external=bool(seed % 2))
    # sparse samples (fewer than commands), some commands after the last sample
    times = np.sort(rng.uniform(0.0, 0.8 * duration, 5))
    slider = Slider(event_log_size=None)
    trajectory = run_schedule(slider, schedule, times)
    reference = driven(schedule, times[-1])
    assert len(trajectory.events) > 10
    assert list(trajectory.events) == slider.events == reference.events
    assert all(a.t <= b.t for a, b in zip(trajectory.events, trajectory.events[1:]))


def test_one_piece_and_many_pieces_give_the_same_samples() -> None:
    schedule = [Command(0.013, "excitation_amplitude", {"excitation_amplitude": 6.0}),
                Command(0.031, "excitation_frequency", {"excitation_frequency": 70.0})]
    times = np.linspace(0.0, 0.1, 101)
    pieces = run_schedule(Slider(SliderParams(), Inputs()), schedule, times)
    assert pieces.t.size == 101 and np.array_equal(pieces.t, times)
    assert np.all(np.isfinite(pieces.x))


def test_a_schedule_into_flight_carries_z_and_vz() -> None:
    """Raising Pa past the weight mid-run: the joined samples carry the height and
    its rate, equal to a slider driven by hand to each sample time."""
    schedule = [Command(0.013, "excitation_amplitude", {"excitation_amplitude": 20.0})]
    times = np.linspace(0.0, 0.06, 61)
    pieces = run_schedule(Slider(), schedule, times)
    assert pieces.z.max() > 0.0 and np.any(pieces.vz < 0.0)
    assert np.all(pieces.z[times < 0.013] == 0.0)
    reference = Slider()
    for k, t in enumerate(times):
        if t >= 0.013 and reference.inputs.excitation_amplitude != 20.0:
            reference.advance_to(0.013)
            reference.set_inputs(excitation_amplitude=20.0)
        reference.advance_to(float(t))
        state = reference.state()
        assert (pieces.z[k], pieces.vz[k], pieces.x[k]) == pytest.approx((state.z, state.vz, state.x), rel=1e-12,
                                                                        abs=1e-15)


def test_simulate_flight_fraction_is_the_time_between_lift_offs_and_landings() -> None:
    """The flight fraction over the measured window, against the event list: the sum of
    landing - lift-off times (clipped to the window) over its length."""
    params = SliderParams(mu=0.5, excitation_angle=30.0, track_inclination=3.0)
    inputs = Inputs(drive_force=0.0, excitation_amplitude=22.0)
    result = simulate(params, inputs, 0.41, settle=0.1, sample_rate=1000.0)
    start, end = 0.1, 0.1 + result.periods / 50.0
    assert result.periods == 15
    flying, since = 0.0, None
    for event in result.events:
        if event.kind is EventKind.LIFT_OFF:
            since = event.t
        elif event.kind is EventKind.LANDING and since is not None:
            flying += max(0.0, min(event.t, end) - max(since, start))
            since = None
    assert flying > 0.0
    assert result.flight_fraction == pytest.approx(flying / (end - start), rel=1e-12)
    counts = {kind.value: sum(e.kind is kind for e in result.events) for kind in EventKind}
    assert result.event_counts == counts and counts["lift_off"] >= 20
    assert result.as_dict()["events"] == counts and result.as_dict()["flight_fraction"] == result.flight_fraction
    assert not result.u_closed_form and result.throw_number == pytest.approx(22.0 / (10.0 * math.cos(math.radians(3))))


def test_simulate_in_kostek_s_model_keeps_its_closed_form() -> None:
    result = simulate(SliderParams(), Inputs(), 1.0, settle=0.1)
    assert result.u_closed_form and result.flight_fraction == 0.0
    assert result.u_exact == u_map(0.7, 0.5) and result.u_measured == pytest.approx(result.u_exact, rel=1e-9)
    assert result.event_counts["lift_off"] == result.event_counts["landing"] == 0
