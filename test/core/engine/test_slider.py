"""Closed-form and invariant tests of the exact event-driven core.

Expected values are derived here from the model, not copied from the code:

    R = m*g + Fz - Pa*sin(theta),  theta' = omega = 2*pi*f,  Ft = Fd + Fx
    stuck while |Ft| <= mu*R;  slipping m*dv/dt = Ft - mu*R*sign(v).

With phi = Fd/(mu*m*g) and a = Pa/(m*g) a slip from rest at theta_A has, in
units of mu*g/omega, the speed w(psi) = (phi-1)*psi + a*(cos thA - cos(thA+psi))
after a phase advance psi (integrate dv/dtheta = (mu*g/omega)*(phi-1+a*sin)),
and it travels (mu*g/omega**2) * integral(w) until w returns to zero.
"""

import bisect
import copy
import math
from fractions import Fraction

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from friction_sim.core.engine.single import EventKind, Mode, Slider
from friction_sim.core.model.commands import Command
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.simulation import random_schedule, run_schedule
from friction_sim.errors import FrictionSimError, ParameterError

from helpers import EndlessLoop, grouped, mirrored, time_limit

TWO_PI = 2.0 * math.pi
PAPER = dict(m=1.0, mu=0.1, g=10.0, fd=0.7, pa=5.0, f=50.0)
THETA_A = math.asin(0.6)  # (1 - phi)/a = 0.3/0.5 for the paper case
OMEGA = TWO_PI * 50.0
PERIOD = 1.0 / 50.0


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------




def w_units(psi, phi, a, theta_a):
    """Slip speed from rest in units of mu*g/omega after a phase advance psi."""
    return (phi - 1.0) * psi + a * (math.cos(theta_a) - math.cos(theta_a + psi))


def periodic_slip(phi, a):
    """(theta_A, psi_B, psi_C, D): slip start phase, advance to the velocity
    peak and to the stop, and the travel per period in units of mu*g/omega**2,
    computed independently of friction_sim (brentq + closed-form integral)."""
    theta_a = math.asin((1.0 - phi) / a)
    psi_b = math.pi - 2.0 * theta_a  # dw/dpsi = phi - 1 + a*sin(thA + psi) = 0 again
    psi_c = brentq(w_units, psi_b, TWO_PI, args=(phi, a, theta_a), xtol=1e-16, rtol=1e-15)
    d = (phi - 1.0) * psi_c**2 / 2.0 + a * (
        psi_c * math.cos(theta_a) - math.sin(theta_a + psi_c) + math.sin(theta_a)
    )
    return theta_a, psi_b, psi_c, d


def paper_slider(**kw):
    return Slider(SliderParams(), Inputs(), **kw)


def max_acceleration(params, inputs):
    """An upper bound of |dv/dt| under these inputs."""
    return (abs(inputs.tangential_force)
            + params.mu * (params.weight - inputs.external_force_z + inputs.excitation_amplitude)
            ) / params.mass


def rel_close(actual, expected, rel):
    return abs(actual - expected) <= rel * abs(expected)


def assert_states_close(a, b, rel=1e-12):
    scale_x = max(abs(a.x), abs(b.x), 1e-300)
    scale_v = max(abs(a.v), abs(b.v), 1e-300)
    assert abs(a.x - b.x) <= rel * scale_x, (a, b)
    assert abs(a.v - b.v) <= rel * scale_v, (a, b)
    assert a.mode == b.mode


def assert_events_close(ev_a, ev_b, rel=1e-12):
    assert [(e.kind, e.before, e.after) for e in ev_a] == [(e.kind, e.before, e.after) for e in ev_b]
    ta = np.array([e.t for e in ev_a])
    tb = np.array([e.t for e in ev_b])
    assert np.all(np.abs(ta - tb) <= rel * np.maximum(np.abs(tb), 1e-300))


# --------------------------------------------------------------------------
# the paper's Fig. 2 case in closed form
# --------------------------------------------------------------------------


def test_slip_starts_at_asin_0_6():
    slider = paper_slider()
    events = slider.advance_to(PERIOD)
    assert [e.kind for e in events] == [EventKind.SLIP_START, EventKind.STICK]
    start = events[0]
    assert abs(start.phase - THETA_A) <= 1e-12
    assert abs(start.t - THETA_A / OMEGA) <= 1e-12 * (THETA_A / OMEGA) + 1e-18
    assert start.x == 0.0
    assert (start.before, start.after) == (Mode.STUCK, Mode.FORWARD)
    # and in every later period at the same phase
    later = slider.advance_to(10 * PERIOD)
    starts = [e for e in later if e.kind is EventKind.SLIP_START]
    assert len(starts) == 9
    for k, e in enumerate(starts, start=1):
        assert abs(e.phase - THETA_A) <= 1e-12
        assert abs(e.t - (k * PERIOD + THETA_A / OMEGA)) <= 1e-12 * e.t


def test_still_before_slip_start():
    slider = paper_slider()
    tr = slider.sample(np.linspace(0.0, THETA_A / OMEGA * (1 - 1e-9), 101))
    assert np.all(tr.x == 0.0) and np.all(tr.v == 0.0)
    assert np.all(tr.mode == Mode.STUCK)
    # stuck friction balances the drive force exactly
    assert np.all(tr.friction_force == -0.7)


def test_one_period_closed_form():
    _m, mu, g = PAPER["m"], PAPER["mu"], PAPER["g"]
    theta_a, _psi_b, psi_c, d = periodic_slip(0.7, 0.5)
    # two asin(0.6) (one libm call each, <= 1 ulp apart on any libm): 1e-15 is 9 ulp of 0.64
    assert abs(theta_a - THETA_A) < 1e-15
    # sanity of the closed-form integral against quadrature of w
    d_quad, _ = quad(w_units, 0.0, psi_c, args=(0.7, 0.5, theta_a), epsabs=0, epsrel=1e-13)
    assert rel_close(d_quad, d, 1e-12)

    x_period = d * mu * g / OMEGA**2
    slider = paper_slider()
    events = slider.advance_to(PERIOD)
    assert rel_close(slider.state().x, x_period, 1e-12)
    stick = events[1]
    assert stick.kind is EventKind.STICK
    assert rel_close(stick.x, x_period, 1e-12)
    assert abs(stick.phase - (theta_a + psi_c)) <= 1e-12
    assert abs(stick.t - (theta_a + psi_c) / OMEGA) <= 1e-12 * stick.t

    # periodic: N periods travel N*D
    slider.advance_to(37 * PERIOD)
    assert rel_close(slider.state().x, 37 * x_period, 1e-12)


def test_velocity_is_exactly_zero_at_the_stick_and_peaks_at_point_b():
    mu, g = PAPER["mu"], PAPER["g"]
    theta_a, psi_b, _psi_c, _ = periodic_slip(0.7, 0.5)
    slider = paper_slider()
    events = slider.advance_to(PERIOD)
    stick = events[1]

    probe = paper_slider()
    probe.advance_to(stick.t)
    at_stick = probe.state()
    assert at_stick.v == 0.0
    assert at_stick.mode is Mode.STUCK

    # the peak (B) is where the friction limit mu*R rises back above Fd:
    # theta_B = pi - theta_A
    t_b = (math.pi - theta_a) / OMEGA
    # pi - 2*theta_a rounds twice, psi_b carries one asin's ulp: within 4 ulp of pi (1.8e-15)
    assert abs(psi_b - (math.pi - theta_a - theta_a)) <= 4 * math.ulp(math.pi)
    t_a, t_c = events[0].t, stick.t
    grid = np.linspace(t_a, t_c, 20001)
    tr = paper_slider().sample(np.sort(np.append(grid, t_b)))
    i_b = int(np.searchsorted(tr.t, t_b))
    assert tr.t[i_b] == t_b
    assert np.argmax(tr.v) == i_b or tr.v[i_b] >= tr.v.max() * (1 - 1e-15)
    v_peak = mu * g / OMEGA * w_units(psi_b, 0.7, 0.5, theta_a)
    assert rel_close(tr.v[i_b], v_peak, 1e-12)
    assert abs(tr.acceleration[i_b]) <= 1e-12 * mu * g
    # rises before B, falls after B
    assert np.all(np.diff(tr.v[1:i_b]) > 0.0)
    assert np.all(np.diff(tr.v[i_b + 1:-1]) < 0.0)
    assert np.all(tr.v[1:-1] > 0.0)


def test_no_excitation_constant_acceleration():
    m, mu, g, fd = 2.0, 0.1, 10.0, 3.0  # mu*m*g = 2 N < Fd
    slider = Slider(SliderParams(mass=m, mu=mu, gravity=g),
                    Inputs(drive_force=fd, excitation_amplitude=0.0))
    times = np.array([0.0, 1e-6, 0.013, 0.5, 1.0, 7.25, 100.0])
    tr = slider.sample(times)
    acc = (fd - mu * m * g) / m
    expected = acc * times**2 / 2.0
    assert np.all(np.abs(tr.x - expected) <= 1e-12 * expected)
    assert np.all(np.abs(tr.v - acc * times) <= 1e-12 * acc * times)
    assert np.all(tr.acceleration == acc)
    assert slider.next_event_time == math.inf
    assert slider.event_counts[EventKind.STICK] == 0
    # per-point advance_to agrees
    other = Slider(SliderParams(mass=m, mu=mu, gravity=g),
                   Inputs(drive_force=fd, excitation_amplitude=0.0))
    other.advance_to(7.25)
    assert rel_close(other.state().x, acc * 7.25**2 / 2, 1e-12)


@pytest.mark.parametrize("fd", [0.0, 0.3, 0.999, 1.0, -1.0, -0.5])
def test_no_excitation_below_friction_never_moves(fd):
    slider = Slider(SliderParams(), Inputs(drive_force=fd, excitation_amplitude=0.0))
    assert slider.next_event_time == math.inf
    tr = slider.sample(np.linspace(0.0, 100.0, 1001))
    assert np.all(tr.x == 0.0) and np.all(tr.v == 0.0)
    assert np.all(tr.friction_force == -fd)
    assert slider.events == []


# --------------------------------------------------------------------------
# zero creep
# --------------------------------------------------------------------------


@pytest.mark.parametrize("fd, pa", [(0.4, 5.0), (0.5, 5.0), (-0.5, 5.0), (0.0, 9.0), (0.1, 9.0), (0.05, 9.5)])
def test_zero_creep_below_and_on_the_motion_boundary(fd, pa):
    slider = paper_slider(event_log_size=None)
    slider.set_inputs(drive_force=fd, excitation_amplitude=pa)
    periods = 10_000
    with time_limit(5.0, "advance_to"):
        events = slider.advance_to(periods * PERIOD)
    state = slider.state()
    assert state.x == 0.0 and state.v == 0.0
    assert events == [] and slider.events == []
    assert sum(slider.event_counts.values()) == 0
    assert slider.stuck_time == periods * PERIOD
    slider = paper_slider()
    slider.set_inputs(drive_force=fd, excitation_amplitude=pa)
    tr = slider.sample(np.linspace(0.0, periods * PERIOD, 200_001))
    assert np.all(tr.x == 0.0) and np.all(tr.v == 0.0)
    assert np.all(tr.mode == Mode.STUCK)


def _on_or_below_boundary(mu, m, g, fd, pa):
    """Exactly, on the binary values given: |Fd| <= mu*(m*g - Pa)."""
    F = Fraction
    return abs(F(fd)) <= F(mu) * (F(m) * F(g) - F(pa))


# Decimal inputs on the boundary phi = 1 - a whose binary values are (by exact
# rational arithmetic) at or below it: the slider must never move.  Rounding in
# next_slip_start's edge = (load - |Ft|/mu)/Pa lets it find a slip window of
# width ~1e-8 rad anyway, and slip_stop_delay then returns 0: STICK and
# SLIP_START alternate forever at the same instant (advance_to never returns).
BOUNDARY_CASES = [
    (0.1, 0.93, 0.7),
    (0.1, 0.89, 1.1),
    (0.3, 2.82, 0.6),
    (0.1, 0.5, 5.0),
    (0.1, 0.3, 7.0),
    (0.1, 0.4, 6.0),
]


@pytest.mark.parametrize("mu, fd, pa", BOUNDARY_CASES)
def test_no_motion_exactly_on_the_boundary(mu, fd, pa):
    assert _on_or_below_boundary(mu, 1.0, 10.0, fd, pa)
    slider = Slider(SliderParams(mu=mu), Inputs(drive_force=fd, excitation_amplitude=pa),
                    event_log_size=8)
    with time_limit(0.5, f"advance_to(1.0) with mu={mu}, Fd={fd}, Pa={pa}"):
        slider.advance_to(1.0)
    assert slider.state().x == 0.0
    assert sum(slider.event_counts.values()) == 0


def test_no_motion_on_the_boundary_sweep():
    """Every Pa = 0.1..9.9 N with Fd = mu*(m*g - Pa) rounded to decimals, for
    mu in (0.1, 0.3), that is exactly at or below the boundary."""
    failures = []
    for mu in (0.1, 0.3):
        for k in range(1, 100):
            pa = k / 10
            fd = round(mu * (10.0 - pa), 12)
            if not _on_or_below_boundary(mu, 1.0, 10.0, fd, pa):
                continue
            slider = Slider(SliderParams(mu=mu), Inputs(drive_force=fd, excitation_amplitude=pa),
                            event_log_size=8)
            try:
                with time_limit(0.2, "advance_to"):
                    slider.advance_to(1.0)
            except EndlessLoop:
                failures.append((mu, fd, pa, "hangs"))
                continue
            if slider.state().x != 0.0 or sum(slider.event_counts.values()):
                failures.append((mu, fd, pa, slider.state().x))
    assert failures == []


# A stuck slider whose phase is (to rounding) at the END of the slip window,
# theta = pi - asin(edge), edge = (m*g + Fz - |Ft|/mu)/Pa: there dw/dt = 0 and
# then < 0, so nothing may move.  next_slip_start's direct test
# |Ft| > mu*R(phase) can say "slip now" while slip_stop_delay, which recomputes
# the edge as asin(-b0/b1), finds the slip already decelerating and returns 0:
# STICK and SLIP_START then alternate forever at one instant.
EDGE_FD, EDGE_PA = 0.92, 2.0  # edge = (10 - 9.2)/2 = 0.4
WINDOW_END = math.pi - math.asin(0.4)


def _check_no_motion_until_next_window(slider, t_start):
    next_window = t_start + (TWO_PI + math.asin(0.4) - WINDOW_END) / OMEGA
    with time_limit(0.5, "advance_to from the end of the slip window"):
        events = slider.advance_to(next_window - 1e-6)
    assert abs(slider.state().x) <= 1e-18
    assert len(events) <= 2  # at most one zero-length slip
    with time_limit(0.5, "advance_to"):
        events = slider.advance_to(next_window + 1e-6)
    assert [e.kind for e in events] == [EventKind.SLIP_START]
    assert abs(events[0].phase - math.asin(0.4)) < 1e-9


def test_start_at_the_end_of_the_slip_window_via_phase0():
    slider = Slider(SliderParams(), Inputs(drive_force=EDGE_FD, excitation_amplitude=EDGE_PA),
                    phase0=WINDOW_END, event_log_size=8)
    _check_no_motion_until_next_window(slider, 0.0)


def test_set_inputs_at_the_end_of_the_slip_window():
    # A stuck slider (Fd = 0) whose drive force is switched on at the instant
    # the excitation phase reaches the end of the slip window.
    t = 0.008690101195655437  # = (pi - asin(0.4))/(2*pi*50) to rounding
    assert abs(OMEGA * t - WINDOW_END) < 1e-14
    slider = Slider(SliderParams(), Inputs(drive_force=0.0, excitation_amplitude=EDGE_PA),
                    event_log_size=8)
    slider.advance_to(t)
    slider.set_inputs(drive_force=EDGE_FD)
    _check_no_motion_until_next_window(slider, t)


@pytest.mark.parametrize("phase0", [-1e-300, -1e-17])
@pytest.mark.parametrize("fd", [0.9999999999999999, 0.7, 1.0])
def test_tiny_negative_phase0_is_phase_zero(phase0, fd):
    # phase0 = -1e-300 is phase 0 to every digit (though -1e-300 % (2*pi)
    # rounds to exactly 2*pi, outside [0, 2*pi)).  With phi a rounding error
    # below 1 the slip's speed minima fall by only ~1e-15*T per period.
    inputs = Inputs(drive_force=fd, excitation_amplitude=5.0)
    t_end = 0.105  # mid-period: away from the v = 0 tangency of phi = 1
    reference = Slider(SliderParams(), inputs, phase0=0.0, event_log_size=None)
    reference.advance_to(t_end)
    slider = Slider(SliderParams(), inputs, phase0=phase0, event_log_size=None)
    with time_limit(0.5, f"advance_to with phase0={phase0!r}, Fd={fd!r}"):
        slider.advance_to(t_end)
    assert_states_close(slider.state(), reference.state(), rel=1e-9)


@pytest.mark.parametrize("fd, pa", [(0.7, 5.0), (0.95, 1.0), (0.28, 7.2)])
def test_forward_slips_never_move_backwards(fd, pa):
    # Fd > 0 and no reversal: x(t) is non-decreasing and never below x0 = 0.
    # (0.28, 7.2) sits a rounding error above the motion boundary: its slips
    # are ~1e-8 rad long and travel ~1e-29 m, which must still be >= 0.
    slider = paper_slider(event_log_size=None)
    slider.set_inputs(drive_force=fd, excitation_amplitude=pa)
    with time_limit(2.0, "sample"):
        tr = slider.sample(np.linspace(0.0, 0.2, 20001))
    assert slider.event_counts[EventKind.REVERSAL] == 0
    assert np.all(tr.v >= 0.0)
    assert np.all(np.diff(tr.x) >= 0.0)
    assert np.all(tr.x >= 0.0)
    assert all(e.x >= 0.0 for e in slider.events)


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
# reversal
# --------------------------------------------------------------------------


def test_reversal_without_excitation_closed_form():
    # Fd = 1.5 N > mu*m*g = 1 N: a = 0.5 m/s^2 from rest; at t1 = 0.1 s flip
    # to Fd = -1.5 N: decelerate at 2.5 m/s^2 from v = 0.05 m/s, stop at
    # t1 + 0.02 s after 0.0005 m, then |Ft| > mu*R: slip back at 0.5 m/s^2.
    slider = Slider(SliderParams(), Inputs(drive_force=1.5, excitation_amplitude=0.0),
                    event_log_size=None)
    first = slider.advance_to(0.1)
    assert [e.kind for e in first] == [EventKind.SLIP_START] and first[0].t == 0.0
    assert rel_close(slider.state().v, 0.05, 1e-12)
    slider.set_inputs(drive_force=-1.5)
    events = slider.advance_to(0.2)
    assert [e.kind for e in events] == [EventKind.REVERSAL]
    rev = events[0]
    assert (rev.before, rev.after) == (Mode.FORWARD, Mode.BACKWARD)
    assert rel_close(rev.t, 0.12, 1e-12)
    assert rel_close(rev.x, 0.003, 1e-12)
    state = slider.state()
    assert rel_close(state.x, 0.003 - 0.25 * 0.08**2, 1e-12)
    assert rel_close(state.v, -0.5 * 0.08, 1e-12)
    assert state.mode is Mode.BACKWARD


def test_stick_without_excitation_closed_form():
    # flip to Fd = -0.5 N, |Ft| < mu*m*g: decelerate at 1.5 m/s^2 and stick.
    slider = Slider(SliderParams(), Inputs(drive_force=1.5, excitation_amplitude=0.0))
    slider.advance_to(0.1)
    slider.set_inputs(drive_force=-0.5)
    events = slider.advance_to(1.0)
    assert [e.kind for e in events] == [EventKind.STICK]
    assert rel_close(events[0].t, 0.1 + 0.05 / 1.5, 1e-12)
    assert rel_close(events[0].x, 0.0025 + 0.05**2 / 3.0, 1e-12)
    assert slider.state().v == 0.0 and slider.state().friction_force == 0.5


@pytest.mark.parametrize("fd", [-0.9, -0.8, -0.6, -1.2])
def test_reversal_under_excitation_agrees_with_reference(fd):
    import reference
    t_flip, t_end = 0.006, 0.1  # the flip happens during the first slip
    slider = paper_slider(event_log_size=None)
    times = np.linspace(0.0, t_end, 1001)
    tr = run_schedule(slider, [Command(t_flip, "drive_force", {"drive_force": fd})], times)
    kinds = [e.kind for e in slider.events]
    assert kinds[:2] == [EventKind.SLIP_START, EventKind.REVERSAL]
    assert slider.events[1].before is Mode.FORWARD and slider.events[1].after is Mode.BACKWARD

    ref = reference.reference_solution(
        1.0, 0.1, 10.0,
        [(0.0, reference.ReferenceInputs()), (t_flip, reference.ReferenceInputs(drive_force=fd))],
        times,
    )
    assert tuple(k.value for k in kinds) == ref.event_kinds
    assert np.max(np.abs(np.array([e.t for e in slider.events]) - ref.event_times)) < 1e-9
    assert np.max(np.abs(tr.x - ref.x)) <= 1e-8 * np.max(np.abs(ref.x))
    assert np.max(np.abs(tr.v - ref.v)) <= 1e-8 * np.max(np.abs(ref.v))


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


# --------------------------------------------------------------------------
# bookkeeping
# --------------------------------------------------------------------------


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


def test_stuck_time_and_events_of_one_period():
    slider = paper_slider()
    events = slider.advance_to(PERIOD)
    _, _, psi_c, _ = periodic_slip(0.7, 0.5)
    assert rel_close(slider.stuck_time, PERIOD - psi_c / OMEGA, 1e-12)
    assert all(e.x == slider.state().x for e in events[1:])


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
