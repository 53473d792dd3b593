"""The single slider's bookkeeping: its logs and counts, refusals, sampling against
advancing point by point, and the no-progress guard of the stepper."""

import math

import numpy as np
import pytest

from friction_sim.core.engine.single import EventKind, Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.errors import FrictionSimError, ParameterError

from helpers import paper_slider

TWO_PI = 2.0 * math.pi


def test_event_log_is_bounded_but_counts_keep_counting():
    bounded = paper_slider(event_log_size=10)
    full = paper_slider(event_log_size=None)
    returned = bounded.advance_to(1.0)  # 50 periods: 50 slips
    full.advance_to(1.0)
    assert len(returned) == 100  # the call itself returns them all
    assert len(bounded.events) == 10
    assert bounded.events == full.events[-10:]
    assert bounded.event_counts == {EventKind.SLIP_START: 50, EventKind.STICK: 50, EventKind.REVERSAL: 0,
                                    EventKind.LIFT_OFF: 0, EventKind.LANDING: 0}
    assert full.event_counts == bounded.event_counts
    assert len(full.events) == 100


def test_advance_to_backwards_is_refused():
    slider = paper_slider()
    slider.advance_to(0.05)
    state = slider.state()
    with pytest.raises(ParameterError) as excinfo:
        slider.advance_to(0.049)
    err = excinfo.value
    assert isinstance(err, ValueError) and isinstance(err, FrictionSimError)
    assert err.field == "t" and "0.049" in str(err)
    assert slider.state() == state
    assert slider.advance_to(0.05) == []  # the same time is fine


def test_sample_equals_per_point_advance_and_state():
    rng = np.random.default_rng(7)
    t_end = 0.3
    probe = paper_slider(event_log_size=None)
    probe.set_inputs(drive_force=0.75, excitation_amplitude=4.0)
    probe.advance_to(t_end)
    event_times = [e.t for e in probe.events]
    times = np.sort(np.concatenate([rng.uniform(0, t_end, 400), event_times, [0.0, t_end]]))

    def make():
        s = paper_slider()
        s.set_inputs(drive_force=0.75, excitation_amplitude=4.0)
        return s

    tr = make().sample(times)
    point = make()
    states = []
    for t in times:
        point.advance_to(t)
        states.append(point.state())
    for name in ("x", "v", "acceleration", "friction_force", "normal_force"):
        got = getattr(tr, name)
        want = np.array([getattr(s, name) for s in states])
        scale = max(np.max(np.abs(want)), 1e-300)
        assert np.max(np.abs(got - want)) <= 1e-12 * scale, name
    want_phase = np.array([s.phase for s in states])
    assert np.max(np.abs(tr.phase - want_phase)) <= 1e-12 * TWO_PI
    assert np.array_equal(tr.mode, np.array([int(s.mode) for s in states]))
    assert np.array_equal(tr.t, times)
    assert np.any(tr.mode == 0) and np.any(tr.mode == 1)


def test_a_general_model_that_makes_no_progress_fails_loudly(monkeypatch):
    """Should a rounding case ever slip past the general model's progress guards
    (zero-length events at one instant, for ever), advance_to raises a
    SimulationFault naming the instant instead of hanging, and the slider is
    left at its last good state."""
    from friction_sim.core.physics import stepper
    from friction_sim.core.physics.segment import FLIGHT, LANDING, Step
    from friction_sim.errors import SimulationFault

    slider = Slider(SliderParams(excitation_angle=60.0), Inputs())
    slider.advance_to(0.01)
    before = slider.state()

    def stuck_in_place(plant, mode, phase0, v0, vz0, z0, closing, grounded):
        return Step(0.0, False, phase0, 0, 0.0, 0.0, 0.0, LANDING, FLIGHT, 0.0, 0.0, 0, False)

    monkeypatch.setattr(stepper, "next_step", stuck_in_place)
    slider.set_inputs(drive_force=0.5)  # a new segment: its step comes from the stand-in
    with pytest.raises(SimulationFault, match=r"no progress: more than 1000 events at t = 0\.01 s"):
        slider.advance_to(0.02)
    assert slider.t == before.t and slider.state().x == before.x
