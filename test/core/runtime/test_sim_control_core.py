"""Pause, step and reset in the core, without ROS: the clock stands still
exactly, stepping gives the trajectory running gives, and a restart is the
start again, shifted in time, in every regime."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.core.runtime.simclock import SimClock

MS = 1_000_000
#: The paper's case, a hopping tilted vibration, and mu_s > mu on a slope.
REGIMES = {
    "kostek": (SliderParams(), Inputs()),
    "hopping": (SliderParams(mu=0.5, excitation_angle=30.0), Inputs(excitation_amplitude=20.0, drive_force=0.0)),
    "static_slope": (SliderParams(static_ratio=1.5, track_inclination=3.0), Inputs(excitation_amplitude=7.0)),
}


def test_a_paused_clock_stands_still_and_resumes_without_a_jump() -> None:
    clock = SimClock(2.0, wall_ns=0)
    assert clock.now_ns(10 * MS) == 20 * MS
    clock.pause(10 * MS)
    assert clock.now_ns(10_000 * MS) == 20 * MS
    clock.step(5 * MS)
    assert clock.now_ns(20_000 * MS) == 25 * MS
    clock.resume(30_000 * MS)
    assert clock.now_ns(30_001 * MS) == 27 * MS
    with pytest.raises(ValueError, match="only while paused"):
        clock.step(1)


@pytest.mark.parametrize("regime", REGIMES)
def test_restart_is_the_start_again_shifted_in_time(regime: str) -> None:
    params, inputs = REGIMES[regime]
    slider = Slider(params, inputs, cycle_log_size=None)
    slider.advance_to(0.3137)
    at = slider.t
    slider.restart()
    assert (slider.state().x, slider.state().v, slider.state().z) == (0.0, 0.0, 0.0)
    taus = np.linspace(0.0, 0.4, 801)
    again, fresh = slider.sample(at + taus), Slider(params, inputs).sample(taus)
    for name in ("x", "v", "z"):
        a, b = getattr(again, name), getattr(fresh, name)
        assert np.max(np.abs(a - b)) <= 1e-12 * max(np.max(np.abs(b)), 1e-300), name
    marks = slider.cycle_marks
    assert [m.n for m in marks] == sorted({m.n for m in marks}), "period numbers go on, never repeat"
    assert any(m.t == at and m.x == 0.0 for m in marks), "a new period starts at the reset"


def _realtime(params: SliderParams, inputs: Inputs) -> RealtimeSlider:
    return RealtimeSlider(params, inputs, wall_ns=0, log_rate=1000.0)


@settings(max_examples=25, deadline=None)
@given(regime=st.sampled_from(sorted(REGIMES)), pause_ms=st.integers(1, 400),
       steps=st.lists(st.integers(1, 60_000_000), min_size=1, max_size=12))
def test_stepping_a_paused_slider_gives_the_run_exactly(regime: str, pause_ms: int, steps: list[int]) -> None:
    """Whatever the pause time and the step lengths (ns), the states logged on
    the way are the ones a slider running without a stop logs, to 1e-12."""
    params, inputs = REGIMES[regime]
    stepped = _realtime(params, inputs)
    samples = list(stepped.tick(pause_ms * MS).samples)
    assert stepped.pause(pause_ms * MS).accepted
    wall = pause_ms * MS
    for length in steps:
        wall += 7 * MS  # wall time passes between the calls; simulation time must not
        assert stepped.step(length / 1e9, wall).accepted
        samples.extend(stepped.tick(wall).samples)
    end = stepped.slider.t
    assert end == pytest.approx(pause_ms / 1e3 + sum(steps) / 1e9, abs=1e-9)
    running = _realtime(params, inputs)
    reference = list(running.tick(round(end * 1e9)).samples)
    assert [s.t for s in samples] == [s.t for s in reference]
    for name in ("x", "v", "z", "vz", "friction_force", "normal_force"):
        a = np.array([getattr(s, name) for s in samples])
        b = np.array([getattr(s, name) for s in reference])
        assert np.max(np.abs(a - b), initial=0.0) <= 1e-12 * max(np.max(np.abs(b), initial=0.0), 1e-300), name


def test_step_is_refused_while_running_and_beyond_the_sample_limit() -> None:
    rt = _realtime(SliderParams(), Inputs())
    refused = rt.step(0.02, 5 * MS)
    assert not refused.accepted and "running" in refused.reason
    assert rt.pause(5 * MS).accepted and not rt.pause(6 * MS).accepted
    too_long = rt.step(1e3, 7 * MS)
    assert not too_long.accepted and "duration = 1000.0 s" in too_long.reason and "at most" in too_long.reason
    fast = _realtime(SliderParams(), Inputs(excitation_frequency=20_000.0))
    assert fast.pause(0).accepted
    too_many = fast.step(100.0, MS)
    assert not too_many.accepted and "2e+06 excitation periods, at most 100000" in too_many.reason
    assert rt.rejected == 3 and rt.slider.t == pytest.approx(0.005)
    assert rt.step_length(3, 0.0) == pytest.approx(0.06) and rt.step_length(3, 0.25) == 0.25
