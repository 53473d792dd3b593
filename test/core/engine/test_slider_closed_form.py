"""Closed-form tests of the exact event-driven core: the paper's Fig. 2 case, and
slips, stops and reversals without excitation.

Expected values are derived here from the model, not copied from the code:

    R = m*g + Fz - Pa*sin(theta),  theta' = omega = 2*pi*f,  Ft = Fd + Fx
    stuck while |Ft| <= mu*R;  slipping m*dv/dt = Ft - mu*R*sign(v).

With phi = Fd/(mu*m*g) and a = Pa/(m*g) a slip from rest at theta_A has, in
units of mu*g/omega, the speed w(psi) = (phi-1)*psi + a*(cos thA - cos(thA+psi))
after a phase advance psi (integrate dv/dtheta = (mu*g/omega)*(phi-1+a*sin)),
and it travels (mu*g/omega**2) * integral(w) until w returns to zero.
"""

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from friction_sim.core.engine.single import EventKind, Mode, Slider
from friction_sim.core.model.commands import Command
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.simulation import run_schedule

from helpers import paper_slider, rel_close

TWO_PI = 2.0 * math.pi
PAPER = dict(m=1.0, mu=0.1, g=10.0, fd=0.7, pa=5.0, f=50.0)
THETA_A = math.asin(0.6)  # (1 - phi)/a = 0.3/0.5 for the paper case
OMEGA = TWO_PI * 50.0
PERIOD = 1.0 / 50.0


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



def test_stuck_time_and_events_of_one_period():
    slider = paper_slider()
    events = slider.advance_to(PERIOD)
    _, _, psi_c, _ = periodic_slip(0.7, 0.5)
    assert rel_close(slider.stuck_time, PERIOD - psi_c / OMEGA, 1e-12)
    assert all(e.x == slider.state().x for e in events[1:])


# --------------------------------------------------------------------------
# slips, stops and reversals
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

