"""Property tests of the exact core on random plants, inputs and schedules.

Parameters are drawn as (mass, mu, gravity, f) plus the nondimensional
phi = Fd/(mu*m*g) in (0, 1.2) and a = Pa/(m*g) in [0, 0.95).  Points within
1e-9 of the motion boundary phi = 1 - a are avoided in the tests that are not
about it: there, the binary rounding of the inputs decides whether the slider
moves at all (see test_core.py::test_no_motion_exactly_on_the_boundary).
"""

import math
from fractions import Fraction

import numpy as np
from hypothesis import HealthCheck, Phase, assume, given, settings
from hypothesis import strategies as st

from friction_sim.core.engine.single import EventKind, Mode, Slider
from friction_sim.core.meanspeed.urelation import u_map
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.simulation import random_schedule, run_schedule

from helpers import grouped, mirrored, rescaled_drive, time_limit

TWO_PI = 2.0 * math.pi
BOUNDARY_MARGIN = 1e-9

PROPERTY = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])




masses = st.floats(0.1, 10.0)
mus = st.floats(0.02, 1.0)
gravities = st.floats(1.0, 20.0)
frequencies = st.floats(1.0, 500.0)
phis = st.floats(0.0, 1.2, exclude_min=True, exclude_max=True)
ratios = st.floats(0.0, 0.95, exclude_max=True)
seeds = st.integers(0, 2**32 - 1)


def make(mass, mu, g, f, phi, a, sign=1.0):
    params = SliderParams(mass=mass, mu=mu, gravity=g)
    inputs = Inputs(drive_force=sign * phi * mu * mass * g, excitation_amplitude=a * mass * g,
                    excitation_frequency=f)
    return params, inputs


def away_from_boundary(phi, a):
    assume(abs(phi - (1.0 - a)) > BOUNDARY_MARGIN)


def schedule_for(seed, params, f, periods, external):
    """random_schedule scaled to this plant (it assumes mu ~ 0.1)."""
    rng = np.random.default_rng(seed)
    duration = periods / f
    commands = random_schedule(rng, duration, frequency=f, weight=params.weight, external=external)
    return rescaled_drive(commands, params.mu / 0.1), duration


# --------------------------------------------------------------------------


@PROPERTY
@given(masses, mus, gravities, frequencies, phis, ratios, seeds, st.booleans())
def test_mirror_symmetry(mass, mu, g, f, phi, a, seed, external):
    away_from_boundary(phi, a)
    params, inputs = make(mass, mu, g, f, phi, a)
    schedule, duration = schedule_for(seed, params, f, 20, external)
    times = np.linspace(0.0, duration, 801)
    a_slider = Slider(params, inputs, event_log_size=None)
    b_slider = Slider(params, inputs.replace(drive_force=-inputs.drive_force), event_log_size=None)
    with time_limit(10.0, "run_schedule"):
        ta = run_schedule(a_slider, schedule, times)
        tb = run_schedule(b_slider, mirrored(schedule), times)
    assert np.array_equal(tb.x, -ta.x)
    assert np.array_equal(tb.v, -ta.v)
    assert np.array_equal(tb.friction_force, -ta.friction_force)
    assert np.array_equal(tb.acceleration, -ta.acceleration)
    assert np.array_equal(tb.normal_force, ta.normal_force)
    assert np.array_equal(tb.mode, -ta.mode)
    ea, eb = a_slider.events, b_slider.events
    assert [(e.t, e.kind, e.phase) for e in eb] == [(e.t, e.kind, e.phase) for e in ea]
    assert [(-e.x, Mode(-e.before), Mode(-e.after)) for e in ea] == [(e.x, e.before, e.after) for e in eb]


@PROPERTY
@given(masses, mus, gravities, frequencies, ratios,
       st.floats(0.0, 1.0 - BOUNDARY_MARGIN), st.sampled_from([-1.0, 1.0]),
       st.floats(0.0, 0.5), st.floats(0.0, 1.0), st.floats(0.0, TWO_PI, exclude_max=True),
       st.floats(-10.0, 10.0))
def test_zero_creep_below_the_boundary(mass, mu, g, f, a, u, sign, fz_frac, split, phase0, x0):
    """|Ft| <= mu*min(R) (with a relative margin of 1e-9): x stays x0 exactly."""
    params = SliderParams(mass=mass, mu=mu, gravity=g)
    fz = -fz_frac * params.weight  # pressing on the contact (Fz > 0 lifts)
    load = params.weight - fz
    pa = a * load
    ft = sign * u * mu * (load - pa)
    inputs = Inputs(drive_force=split * ft, excitation_amplitude=pa, excitation_frequency=f,
                    external_force_x=ft - split * ft, external_force_z=fz)
    slider = Slider(params, inputs, x0=x0, phase0=phase0, event_log_size=None)
    periods = 200
    with time_limit(5.0, "sample"):
        tr = slider.sample(np.linspace(0.0, periods / f, 4001))
    assert np.all(tr.x == x0)
    assert np.all(tr.v == 0.0)
    assert np.all(tr.mode == Mode.STUCK)
    assert slider.events == [] and sum(slider.event_counts.values()) == 0
    assert slider.next_event_time == math.inf


@settings(max_examples=60, deadline=None, phases=[Phase.explicit, Phase.generate],
          suppress_health_check=[HealthCheck.too_slow])
@given(masses, mus, gravities, frequencies, st.floats(0.01, 0.95), st.sampled_from([-1.0, 1.0]))
def test_exactly_on_the_boundary(mass, mu, g, f, a, sign):
    """phi = 1 - a in floating point: the binary inputs are then a rounding
    error above, on or below the boundary.  At or below (decided exactly, in
    rational arithmetic) nothing may move; above, the motion must at least be
    in the drive's direction.  Either way advance_to must return."""
    params = SliderParams(mass=mass, mu=mu, gravity=g)
    pa = a * params.weight
    fd = sign * mu * (params.weight - pa)
    inputs = Inputs(drive_force=fd, excitation_amplitude=pa, excitation_frequency=f)
    exact_excess = abs(Fraction(fd)) - Fraction(mu) * (Fraction(mass) * Fraction(g) - Fraction(pa))
    slider = Slider(params, inputs, event_log_size=None)
    with time_limit(0.5, "advance_to on the motion boundary"):
        slider.advance_to(5.0 / f)
    x = slider.state().x
    if exact_excess <= 0:
        assert x == 0.0 and slider.events == []
    else:
        assert sign * x >= 0.0
        assert slider.event_counts[EventKind.SLIP_START] <= 6


@PROPERTY
@given(masses, mus, gravities, frequencies, phis, ratios, seeds, st.booleans(),
       st.lists(st.floats(0.0, 1.0), min_size=1, max_size=300))
def test_cut_invariance(mass, mu, g, f, phi, a, seed, external, cuts):
    away_from_boundary(phi, a)
    params, inputs = make(mass, mu, g, f, phi, a)
    schedule, duration = schedule_for(seed, params, f, 15, external)

    one = Slider(params, inputs, event_log_size=None)
    many = Slider(params, inputs, event_log_size=None)
    grid = Slider(params, inputs, event_log_size=None)
    with time_limit(10.0, "advance_to"):
        run_schedule(one, schedule, np.array([duration]))
        run_schedule(grid, schedule, np.linspace(0.0, duration, 1001))
        times = sorted(c * duration for c in cuts)
        for command in grouped(schedule):
            while times and times[0] < command.t:
                many.advance_to(times.pop(0))
            many.advance_to(command.t)
            many.set_inputs(**command.values)
        for t in times:
            many.advance_to(t)
        many.advance_to(duration)

    ref = one.state()
    for other in (many, grid):
        s = other.state()
        assert abs(s.x - ref.x) <= 1e-12 * max(abs(ref.x), 1e-300)
        assert abs(s.v - ref.v) <= 1e-12 * max(abs(ref.v), 1e-300)
        assert s.mode == ref.mode
        assert [(e.kind, e.before, e.after) for e in other.events] == \
            [(e.kind, e.before, e.after) for e in one.events]
        for e1, e2 in zip(one.events, other.events):
            assert abs(e1.t - e2.t) <= 1e-12 * e1.t


@PROPERTY
@given(masses, mus, gravities, frequencies,
       st.floats(0.1, 1.0, exclude_max=True), st.floats(0.0, 1.0),
       st.sampled_from([-1.0, 1.0]), st.integers(1, 12))
def test_mean_speed_over_whole_periods_is_u(mass, mu, g, f, phi, a_fraction, sign, periods):
    # a drawn inside the motion region (1 - phi + margin, 0.95), not filtered into it
    lowest = 1.0 - phi + BOUNDARY_MARGIN
    a = lowest + a_fraction * (0.95 - lowest)
    assume(phi > 1.0 - a + BOUNDARY_MARGIN)
    u = u_map(sign * phi, a)
    assume(abs(u) >= 1e-6)
    params, inputs = make(mass, mu, g, f, phi, a, sign)
    slider = Slider(params, inputs, event_log_size=None)
    with time_limit(5.0, "advance_to"):
        slider.advance_to(periods / f)
    measured = slider.state().x / (periods / f) * f / (g * mu)
    assert abs(measured - u) <= 1e-8 * abs(u)
    # one slip per period (from theta_A = asin((1-phi)/a) until before the
    # period ends, as w(2*pi - theta_A) = (phi-1)*(2*pi-theta_A) + a*(cos thA - 1)
    # < 0), none open at a whole period -- unless theta_A is within rounding
    # of the period start (phi -> 1), where the next slip may already count.
    if 1.0 - phi > 1e-6:
        assert slider.event_counts[EventKind.SLIP_START] == periods
        assert slider.event_counts[EventKind.STICK] == periods
        assert slider.state().v == 0.0


@PROPERTY
@given(masses, mus, gravities, frequencies, phis, ratios, seeds, st.booleans(),
       st.lists(st.floats(0.0, 1.0), min_size=5, max_size=60))
def test_time_only_forward_and_stuck_means_still(mass, mu, g, f, phi, a, seed, external, cuts):
    away_from_boundary(phi, a)
    params, inputs = make(mass, mu, g, f, phi, a)
    schedule, duration = schedule_for(seed, params, f, 15, external)

    # advance in random steps, applying the schedule
    slider = Slider(params, inputs, event_log_size=None)
    steps = sorted({c * duration for c in cuts} | {c.t for c in schedule} | {duration})
    pending = grouped(schedule)
    last_t, last_stuck_time, last_event_t = 0.0, 0.0, -math.inf
    with time_limit(10.0, "advance_to"):
        for t in steps:
            events = slider.advance_to(t)
            assert slider.t == t >= last_t
            for e in events:
                assert last_event_t <= e.t <= t
                assert e.t >= last_t  # not before the previous call's time
                last_event_t = e.t
            assert last_stuck_time <= slider.stuck_time <= slider.t + 1e-15
            last_t, last_stuck_time = t, slider.stuck_time
            while pending and pending[0].t == t:
                slider.set_inputs(**pending.pop(0).values)
    assert not pending
    times = [e.t for e in slider.events]
    assert times == sorted(times)

    # the same motion sampled: stuck samples have v == 0 exactly and, within
    # one stuck stretch, the same x
    sampled = Slider(params, inputs, event_log_size=None)
    grid = np.linspace(0.0, duration, 1501)
    with time_limit(10.0, "run_schedule"):
        tr = run_schedule(sampled, schedule, grid)
    stuck = tr.mode == Mode.STUCK
    assert np.all(tr.v[stuck] == 0.0)
    assert np.all(tr.acceleration[stuck] == 0.0)
    event_times = np.array(times + [math.inf])
    for i in range(grid.size - 1):
        if stuck[i] and stuck[i + 1]:
            no_event = not np.any((event_times > grid[i]) & (event_times <= grid[i + 1]))
            if no_event:
                assert tr.x[i + 1] == tr.x[i], (grid[i], grid[i + 1])
    # x is continuous: |v| <= |v(t_i)| + amax*(t - t_i) on each sample
    # interval, with amax >= |dv/dt| = |Ft -+ mu*R|/m under every input in force
    current, amax = inputs, 0.0
    for command in [None] + sorted(schedule, key=lambda c: c.t):
        if command is not None:
            current = current.replace(**command.values)
        load = params.weight - current.external_force_z + current.excitation_amplitude
        amax = max(amax, (abs(current.tangential_force) + params.mu * load) / params.mass)
    dt = np.diff(grid)
    bound = np.abs(tr.v[:-1]) * dt + 0.5 * amax * dt**2
    assert np.all(np.abs(np.diff(tr.x)) <= bound * (1 + 1e-9) + 1e-15 * np.max(np.abs(tr.x)))


@settings(max_examples=60, deadline=None, phases=[Phase.explicit, Phase.generate],
          suppress_health_check=[HealthCheck.too_slow])
@given(masses, mus, gravities, frequencies, phis, st.floats(0.05, 0.95), st.sampled_from([-1.0, 1.0]),
       st.sampled_from(["start", "end"]), st.integers(-4, 4))
def test_starting_on_a_slip_window_edge_terminates(mass, mu, g, f, phi, a, sign, which, ulps):
    """A stuck slider whose phase is within a few ulps of either edge of the
    slip window (where |Ft| = mu*R) must not loop on zero-length slips.
    (No shrinking: a failing example costs the time limit each run.)"""
    edge = (1.0 - phi) / a
    assume(-1.0 < edge < 1.0)
    theta_a = math.asin(edge)
    center = theta_a if which == "start" else math.pi - theta_a
    phase0 = center + ulps * math.ulp(center)
    params, inputs = make(mass, mu, g, f, phi, a, sign)
    slider = Slider(params, inputs, phase0=phase0, event_log_size=None)
    with time_limit(0.5, f"advance_to from phase0={phase0!r} ({which} of the slip window)"):
        slider.advance_to(2.0 / f)
    times = [e.t for e in slider.events]
    assert all(times.count(t) <= 2 for t in times)
    assert len(times) <= 8
