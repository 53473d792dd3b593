"""Invariants of the exact core: how the time axis is cut does not change the
result, energy balances, the mirror image of a schedule gives the mirror image of
the motion bit for bit, and the phase and the motion stay continuous across
input changes and events."""

import bisect
import copy
import math

import numpy as np
import pytest
from scipy.integrate import quad

from friction_sim.core.engine.single import EventKind, Mode, Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.simulation import random_schedule, run_schedule

from helpers import assert_events_close, assert_states_close, grouped, mirrored, paper_slider, rel_close

TWO_PI = 2.0 * math.pi
THETA_A = math.asin(0.6)  # (1 - phi)/a = 0.3/0.5 for the paper case
OMEGA = TWO_PI * 50.0


def max_acceleration(params, inputs):
    """An upper bound of |dv/dt| under these inputs."""
    return (abs(inputs.tangential_force)
            + params.mu * (params.weight - inputs.external_force_z + inputs.excitation_amplitude)
            ) / params.mass


# --------------------------------------------------------------------------
# how time is cut does not matter
# --------------------------------------------------------------------------


def _cuts(rng, t_end, n):
    return np.sort(rng.uniform(0.0, t_end, n))


def test_cut_invariance_constant_inputs():
    rng = np.random.default_rng(1)
    t_end = 1.0  # 50 periods
    one = paper_slider(event_log_size=None)
    one.advance_to(t_end)

    cut = paper_slider(event_log_size=None)
    collected = []
    for t in _cuts(rng, t_end, 3000):
        collected.extend(cut.advance_to(t))
    collected.extend(cut.advance_to(t_end))

    grid = paper_slider(event_log_size=None)
    tr = grid.sample(np.linspace(0.0, t_end, 5001))

    assert_states_close(cut.state(), one.state())
    assert_states_close(grid.state(), one.state())
    assert rel_close(tr.x[-1], one.state().x, 1e-12) and tr.v[-1] == one.state().v
    assert len(one.events) == 100
    assert_events_close(collected, one.events)
    assert_events_close(cut.events, one.events)
    assert_events_close(grid.events, one.events)
    assert rel_close(cut.stuck_time, one.stuck_time, 1e-12)


@pytest.mark.parametrize("seed, external", [(3, False), (4, True), (5, True)])
def test_cut_invariance_random_schedule(seed, external):
    rng = np.random.default_rng(seed)
    t_end = 0.6
    schedule = random_schedule(rng, t_end, external=external)
    assert len(schedule) >= 3

    ref = paper_slider(event_log_size=None)
    run_schedule(ref, schedule, np.array([t_end]))

    grid = paper_slider(event_log_size=None)
    tr = run_schedule(grid, schedule, np.linspace(0.0, t_end, 3001))

    cut = paper_slider(event_log_size=None)
    cuts = list(_cuts(rng, t_end, 4000))
    for command in grouped(schedule):
        for t in [c for c in cuts if c < command.t]:
            cut.advance_to(t)
        cuts = [c for c in cuts if c >= command.t]
        cut.advance_to(command.t)
        cut.set_inputs(**command.values)
    for t in cuts:
        cut.advance_to(t)
    cut.advance_to(t_end)

    assert_states_close(grid.state(), ref.state())
    assert_states_close(cut.state(), ref.state())
    assert rel_close(tr.x[-1], ref.state().x, 1e-12)
    assert len(ref.events) > 10
    assert_events_close(grid.events, ref.events)
    assert_events_close(cut.events, ref.events)



# --------------------------------------------------------------------------
# energy balance
# --------------------------------------------------------------------------


class _Oracle:
    """Random-access v(t) of a finished run, from deep copies of the slider
    taken at every event and command (a copy advances only forward)."""

    def __init__(self):
        self.times, self.copies = [], []

    def keep(self, slider):
        self.times.append(slider.t)
        self.copies.append(copy.deepcopy(slider))

    def state(self, t):
        i = bisect.bisect_right(self.times, t) - 1
        probe = copy.deepcopy(self.copies[i])
        probe.advance_to(t)
        return probe.state()


def test_energy_balance():
    params = SliderParams()
    m, mu, g = params.mass, params.mu, params.gravity
    pieces = [
        (0.0, Inputs()),
        (0.0305, Inputs(0.85, 4.0, 40.0, 0.05, -0.5)),
        (0.071, Inputs(-0.8, 6.0, 60.0, 0.0, 0.0)),
    ]
    t_end = 0.11
    slider = Slider(params, pieces[0][1], event_log_size=None)
    oracle = _Oracle()
    work_in, events, _bounds = 0.0, [], []
    theta0 = 0.0  # my own phase bookkeeping
    friction_work = 0.0
    for i, (t0, inputs) in enumerate(pieces):
        t1 = pieces[i + 1][0] if i + 1 < len(pieces) else t_end
        if i:
            assert not slider.state().stuck  # the commands act during a slip
            slider.set_inputs(inputs)
        x0 = slider.state().x
        oracle.keep(slider)
        inside = []
        while slider.next_event_time <= t1:
            inside.extend(slider.advance_to(slider.next_event_time))
            oracle.keep(slider)
        slider.advance_to(t1)
        work_in += inputs.tangential_force * (slider.state().x - x0)
        events.extend(inside)

        omega, load, pa = TWO_PI * inputs.excitation_frequency, m * g - inputs.external_force_z, \
            inputs.excitation_amplitude

        def power(t, theta0=theta0, t0=t0, omega=omega, load=load, pa=pa):
            reaction = load - pa * math.sin(theta0 + omega * (t - t0))
            return mu * reaction * abs(oracle.state(t).v)

        points = sorted({e.t for e in inside if t0 < e.t < t1})
        value, _err = quad(power, t0, t1, points=points or None, limit=400, epsabs=0.0, epsrel=1e-12)
        friction_work += value
        theta0 += omega * (t1 - t0)

    end = slider.state()
    assert not end.stuck and abs(end.v) > 1e-4  # kinetic energy is part of the balance
    kinds = {e.kind for e in events}
    assert {EventKind.SLIP_START, EventKind.STICK, EventKind.REVERSAL} <= kinds
    kinetic = 0.5 * m * end.v**2
    assert friction_work > 0.0
    assert abs(work_in - (kinetic + friction_work)) <= 1e-8 * max(abs(work_in), friction_work)



# --------------------------------------------------------------------------
# mirror symmetry
# --------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [0, 11])
def test_mirror_symmetry(seed):
    rng = np.random.default_rng(seed)
    t_end = 0.6
    schedule = random_schedule(rng, t_end, external=True)
    times = np.sort(np.concatenate([np.linspace(0.0, t_end, 2001), rng.uniform(0, t_end, 500)]))
    start = Inputs(drive_force=0.7, external_force_x=0.04, external_force_z=-0.3)
    mirror_start = Inputs(drive_force=-0.7, external_force_x=-0.04, external_force_z=-0.3)

    a = Slider(SliderParams(), start, event_log_size=None)
    b = Slider(SliderParams(), mirror_start, event_log_size=None)
    ta = run_schedule(a, schedule, times)
    tb = run_schedule(b, mirrored(schedule), times)

    assert np.max(np.abs(ta.x)) > 0.0
    assert np.array_equal(tb.x, -ta.x)
    assert np.array_equal(tb.v, -ta.v)
    assert np.array_equal(tb.acceleration, -ta.acceleration)
    assert np.array_equal(tb.friction_force, -ta.friction_force)
    assert np.array_equal(tb.normal_force, ta.normal_force)
    assert np.array_equal(tb.phase, ta.phase)
    assert np.array_equal(tb.mode, -ta.mode)

    assert len(a.events) == len(b.events) > 5
    for ea, eb in zip(a.events, b.events):
        assert eb.t == ea.t and eb.kind == ea.kind and eb.phase == ea.phase
        assert eb.x == -ea.x
        assert eb.before == Mode(-ea.before) and eb.after == Mode(-ea.after)



# --------------------------------------------------------------------------
# phase continuity, event continuity
# --------------------------------------------------------------------------


def _angle_diff(a, b):
    return abs((a - b + math.pi) % TWO_PI - math.pi)


@pytest.mark.parametrize("t1", [0.0123, 0.005])  # stuck / slipping
def test_frequency_change_keeps_phase_continuous(t1):
    slider = paper_slider()
    slider.advance_to(t1)
    before = slider.state()
    assert _angle_diff(before.phase, OMEGA * t1) < 1e-12
    slider.set_inputs(excitation_frequency=80.0)
    after = slider.state()
    assert after.phase == before.phase
    assert after.normal_force == before.normal_force
    assert after.x == before.x and after.v == before.v
    t2 = t1 + 0.0371
    slider.advance_to(t2)
    expected = OMEGA * t1 + TWO_PI * 80.0 * (t2 - t1)
    assert _angle_diff(slider.state().phase, expected) < 1e-11
    assert rel_close(slider.state().normal_force, 10.0 - 5.0 * math.sin(expected), 1e-12)
    # the slip windows follow the new frequency: theta_A + 2*pi*k
    for e in slider.advance_to(0.5):
        if e.kind is EventKind.SLIP_START:
            assert abs(e.phase - THETA_A) < 1e-12


@pytest.mark.parametrize("seed", [21, 22])
def test_continuity_at_events(seed):
    rng = np.random.default_rng(seed)
    t_end = 0.5
    schedule = random_schedule(rng, t_end, external=True)
    first = paper_slider(event_log_size=None)
    run_schedule(first, schedule, np.array([t_end]))
    events = [e for e in first.events if 1e-6 < e.t < t_end - 1e-6]
    assert len(events) > 10

    params = SliderParams()
    inputs, amax = Inputs(), max_acceleration(params, Inputs())
    for c in schedule:
        inputs = inputs.replace(**c.values)
        amax = max(amax, max_acceleration(params, inputs))

    dt = 1e-9
    te = np.array([e.t for e in events])
    times = np.unique(np.concatenate([te - dt, te, te + dt]))
    second = paper_slider(event_log_size=None)
    tr = run_schedule(second, schedule, times)
    for e in events:
        i = int(np.searchsorted(times, e.t))
        j, k = int(np.searchsorted(times, e.t - dt)), int(np.searchsorted(times, e.t + dt))
        assert times[i] == e.t
        assert tr.v[i] == 0.0, e
        assert tr.x[i] == e.x, e
        for n in (j, k):
            assert abs(tr.v[n]) <= amax * dt * (1 + 1e-9), e
            assert abs(tr.x[n] - e.x) <= 0.5 * amax * dt**2 * (1 + 1e-6) + 4e-16 * abs(e.x), e

