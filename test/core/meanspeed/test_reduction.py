"""The friction-reduction curve (issue 22, item 4): the apparent friction
mu_app/mu = phi a slider needs to move at a mean speed under vibration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.reduction import (
    BISECTIONS,
    LOMAKIN,
    LOMAKIN_FREQUENCY,
    apparent_friction_ratio,
    reduction_curves,
    runaway_ratio,
)
from friction_sim.core.meanspeed.urelation import u_map
from friction_sim.core.model.params import Inputs
from friction_sim.errors import ParameterError


def test_lomakin_s_conditions_give_the_exact_inverse_and_its_ends() -> None:
    """mu 0.156, f 100 Hz: at V -> 0 the breakaway 1 - a; at the fastest periodic
    stick-slip, a g mu/(2 pi f), the full friction 1; in between the speed the
    forward relation gives for that phi is the speed asked for."""
    curves = reduction_curves(points=41)
    assert curves.closed_form and curves.params == LOMAKIN and curves.frequency == LOMAKIN_FREQUENCY
    assert np.array_equal(curves.by_speed[:, 0], 1.0 - curves.ratios), "breakaway under the vibration"
    assert np.array_equal(curves.by_speed[:, -1], np.ones(curves.ratios.size)), \
        "each ratio's fastest stick-slip needs the full friction: every curve reaches 1"
    g, mu, f = LOMAKIN.gravity, LOMAKIN.mu, LOMAKIN_FREQUENCY
    for ratio, speeds, row in zip(curves.ratios, curves.speeds, curves.by_speed):
        assert np.all(np.isfinite(row)), "no point dropped: each curve ends at its own fastest speed"
        assert np.all(np.diff(row) > 0.0), "faster needs more drive: the friction seems larger"
        assert speeds[0] == 0.0 and speeds[-1] == pytest.approx(ratio * g * mu / (2 * math.pi * f), rel=1e-15)
        forward = np.asarray(u_map(row, ratio)) * g * mu / f
        assert forward == pytest.approx(speeds, rel=1e-11, abs=1e-18)
    for speed, ratios, row in zip(curves.marked_speeds, curves.amplitudes, curves.by_amplitude):
        assert np.all(np.isfinite(row)), "each speed's curve starts at the least ratio that reaches it"
        assert row[0] == 1.0 and ratios[0] == pytest.approx(2 * math.pi * speed * f / (g * mu), rel=1e-15)
        assert ratios[-1] == np.max(curves.ratios)
        assert np.all(np.diff(row) < 0.0), "more vibration, less apparent friction at the same speed"


def test_the_simulated_path_agrees_with_the_closed_form_on_kostek_s_model() -> None:
    """Bisection on the exact general mean speed (the path beyond Kostek's model)
    finds the closed form's phi to the bisection's resolution: the bracket
    [-top, top) halved BISECTIONS times, plus the mean speed's own rounding."""
    speeds = np.array([0.0, 1e-4, 4e-4, 8e-4])
    exact = apparent_friction_ratio(speeds, 0.5, LOMAKIN, LOMAKIN_FREQUENCY)
    simulated = apparent_friction_ratio(speeds, 0.5, LOMAKIN, LOMAKIN_FREQUENCY, simulated=True)
    resolution = 2.0 * runaway_ratio(LOMAKIN) * 2.0**-BISECTIONS
    assert simulated == pytest.approx(exact, rel=0.0, abs=4.0 * resolution + 1e-14)


def test_beyond_kostek_s_model_the_phi_found_gives_the_speed_asked_for() -> None:
    """A vibration at 60 degrees to the track (the part hops at the larger
    ratios): each phi found, driven on the single slider (not the population
    engine the bisection used), gives the mean speed asked for, as closely as
    the bisection's resolution times the local slope allows."""
    params = LOMAKIN.replace(excitation_angle=60.0)
    curves = reduction_curves(params, ratios=(0.3, 1.2), marked_speeds=(5e-4,), points=9)
    assert not curves.closed_form
    assert np.any(curves.by_speed < 0.0), "a tilted vibration conveys by itself: a braking force holds the speed"
    for ratio, row in zip(curves.ratios, curves.by_speed):
        for speed, phi in zip(curves.speeds[0][1::3], row[1::3]):
            if not math.isfinite(phi):
                continue
            weight = params.weight
            slider = Slider(params, Inputs(drive_force=phi * params.mu * weight, excitation_amplitude=ratio * weight,
                                           excitation_frequency=LOMAKIN_FREQUENCY), cycle_log_size=None)
            slider.advance_to(400 / LOMAKIN_FREQUENCY + 0.001)
            marks = slider.cycle_marks
            measured = (marks[400].x - marks[200].x) / (200 / LOMAKIN_FREQUENCY)
            assert measured == pytest.approx(speed, rel=1e-6, abs=1e-9), (ratio, speed, phi)


def test_bad_inputs_are_refused_naming_them() -> None:
    with pytest.raises(ParameterError, match="mean_speed"):
        apparent_friction_ratio(math.nan, 0.5, LOMAKIN, 100.0)
    with pytest.raises(ParameterError, match="excitation_frequency"):
        apparent_friction_ratio(1e-4, 0.5, LOMAKIN, 0.0)
    with pytest.raises(ParameterError, match="points"):
        reduction_curves(points=1)


@pytest.mark.parametrize("ratio", [0.2, 0.6, 0.8])
def test_the_rise_from_breakaway_is_drawn_not_jumped(ratio: float) -> None:
    """phi rises as the square root of the speed from breakaway (1 - a), vertically
    at V = 0: the first step of a curve must be a small part of its whole rise, as
    small as the later steps (on an even grid in V, a = 0.8 jumped 0.2 -> 0.29 at
    once, 11 % of the rise to 1, in the first of 100 steps)."""
    curves = reduction_curves(ratios=(ratio,), points=101)
    row = curves.by_speed[0]
    steps = np.diff(row) / (row[-1] - row[0])
    assert steps[0] < 0.02 and steps[0] <= 2.0 * np.median(steps)
