"""Offline jobs on the exact core: run_schedule and simulate (issue 10, item 16)."""

from __future__ import annotations

import numpy as np
import pytest

from friction_sim.core.commands import Command
from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.simulation import random_schedule, run_schedule
from friction_sim.core.slider import Slider


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
