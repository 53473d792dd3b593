"""Analytic checks of the general core (issue 11): flight, landing, energy.

* Lift-off: on a level track with no external force the contact force
  R = m*g - Pa*sin(theta) first falls below zero at sin(theta) = 1/Gamma.
* The completely inelastic bouncing ball: lifting off at sin(theta0) = 1/Gamma,
  the height relative to the track is (g/omega^2)*(Gamma*cos(theta0)*u
  - Gamma*(sin(theta0 + u) - sin(theta0)) - u^2/2), u = theta - theta0; it is
  zero again at u = 2*pi exactly when Gamma*cos(theta0) = pi, i.e. at
  Gamma = sqrt(1 + pi^2); the landing speed is then 2*pi*g/omega.
* Energy: between events the kinetic energy changes by the work of the
  applied forces (Ft*v, -R*vz in flight, -mu*R*|v| in a slip); at a landing it
  drops by the impact loss, which the impact law fixes and which is >= 0.
* With every new parameter at its default the core is Kostek's model: slip
  starts and displacements against the textbook closed form in mpmath.
* How time is cut into advance_to calls does not change a flight.
* Restitution near 1 ends in finitely many bounces (the plastic floor).
"""

from __future__ import annotations

import itertools
import math
from typing import Any

import numpy as np
import pytest

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.events import EventKind
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import is_kostek

import reference_exact

GAMMA_ONE_PERIOD = math.sqrt(1.0 + math.pi**2)


def forces(params: SliderParams, inputs: Inputs, t: np.ndarray, phase0: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(Ft, R) at times t, from the model's definition (independent of the core)."""
    theta = phase0 + 2.0 * math.pi * inputs.excitation_frequency * t
    beta, alpha = math.radians(params.excitation_angle), math.radians(params.track_inclination)
    pt = 0.0 if params.excitation_angle == 90.0 else inputs.excitation_amplitude / math.tan(beta)
    weight = params.mass * params.gravity
    ft = (inputs.drive_force + inputs.external_force_x - weight * math.sin(alpha)
          + pt * np.sin(theta + math.radians(params.excitation_phase)))
    r = weight * math.cos(alpha) - inputs.external_force_z - inputs.excitation_amplitude * np.sin(theta)
    return ft, r


def hopping(gamma: float, *, beta: float = 90.0, e: float = 0.0, landing: str = "impulsive", mu: float = 0.5,
            drive: float = 0.0, frequency: float = 50.0) -> tuple[SliderParams, Inputs]:
    params = SliderParams(mass=1.0, mu=mu, gravity=10.0, excitation_angle=beta, restitution=e,
                          landing_friction=landing)
    return params, Inputs(drive_force=drive, excitation_amplitude=gamma * params.normal_weight,
                          excitation_frequency=frequency)


# ---------------------------------------------------------------------------- lift-off and one-period flight


@pytest.mark.parametrize("gamma", [1.05, 1.5, 2.0, 3.0])
@pytest.mark.parametrize("beta", [90.0, 30.0])
def test_lift_off_phase_is_asin_of_one_over_gamma(gamma: float, beta: float) -> None:
    params, inputs = hopping(gamma, beta=beta, drive=0.1)
    slider = Slider(params, inputs, event_log_size=None)
    slider.advance_to(10.0 / inputs.excitation_frequency)
    lifts = [e for e in slider.events if e.kind is EventKind.LIFT_OFF]
    assert len(lifts) == 10  # one per period below Gamma = 3.30 with plastic landings
    expected = math.asin(1.0 / gamma)
    omega = 2.0 * math.pi * inputs.excitation_frequency
    for n, event in enumerate(lifts):
        assert abs(event.phase - expected) <= 1e-12, (n, event.phase, expected)
        assert abs(event.t - (expected + 2.0 * math.pi * n) / omega) <= 1e-12 * (n + 1) / inputs.excitation_frequency
        assert event.vz_before == 0.0 and event.vz_after == 0.0 and event.v_before == event.v_after
    assert lifts[0].t == pytest.approx(expected / omega, rel=1e-13)


def test_one_period_flight_at_gamma_sqrt_one_plus_pi_squared() -> None:
    params, inputs = hopping(GAMMA_ONE_PERIOD)
    period = 1.0 / inputs.excitation_frequency
    slider = Slider(params, inputs, event_log_size=None)
    slider.advance_to(8.5 * period)
    lifts = [e.t for e in slider.events if e.kind is EventKind.LIFT_OFF]
    landings = [e for e in slider.events if e.kind is EventKind.LANDING]
    assert len(landings) >= 7
    for lift, landing in zip(lifts, landings):
        assert abs((landing.t - lift) / period - 1.0) <= 1e-12, (lift, landing.t)
        assert landing.vz_before == pytest.approx(-2.0 * math.pi * params.gravity / (2.0 * math.pi * 50.0), rel=1e-12)
        assert landing.vz_after == 0.0
    # R = 0 at the landing phase: it leaves again at once, every period
    assert np.allclose(np.diff(lifts) / period, 1.0, rtol=0.0, atol=1e-12)


def test_flight_shorter_or_longer_than_a_period_either_side() -> None:
    for factor, longer in ((0.999, False), (1.001, True)):
        params, inputs = hopping(GAMMA_ONE_PERIOD * factor)
        slider = Slider(params, inputs, event_log_size=None)
        slider.advance_to(2.5 / inputs.excitation_frequency)
        lift = next(e.t for e in slider.events if e.kind is EventKind.LIFT_OFF)
        land = next(e.t for e in slider.events if e.kind is EventKind.LANDING)
        assert ((land - lift) * inputs.excitation_frequency > 1.0) is longer


# ---------------------------------------------------------------------------- energy


def energy_balance(params: SliderParams, inputs: Inputs, periods: float) -> tuple[float, float, float, int]:
    """Run the core; return (kinetic energy change, work of the forces minus
    impact losses, sum of |terms| as scale, number of landings).  The work is
    integrated segment by segment (between events, the motion is smooth) with
    48-point Gauss-Legendre, at the core's exact sampled velocities."""
    t_end = periods / inputs.excitation_frequency
    first = Slider(params, inputs, event_log_size=None)
    first.advance_to(t_end)
    events = first.events
    bounds = [0.0] + [e.t for e in events] + [t_end]
    modes = [0] + [int(e.after) for e in events]
    x, w = np.polynomial.legendre.leggauss(48)
    pieces = [(a, b, mode) for a, b, mode in zip(bounds[:-1], bounds[1:], modes) if b > a]
    nodes = np.concatenate([0.5 * (b - a) * x + 0.5 * (b + a) for a, b, _ in pieces])
    order = np.argsort(nodes, kind="stable")
    second = Slider(params, inputs, event_log_size=None)
    trajectory = second.sample(nodes[order])
    v = np.empty_like(nodes)
    vz = np.empty_like(nodes)
    v[order], vz[order] = trajectory.v, trajectory.vz
    ft, r = forces(params, inputs, nodes)
    work = 0.0
    scale = 0.0
    for k, (a, b, mode) in enumerate(pieces):
        sl = slice(48 * k, 48 * (k + 1))
        if mode == 2:
            power = ft[sl] * v[sl] - r[sl] * vz[sl]
        elif mode in (1, -1):
            power = (ft[sl] - mode * params.mu * r[sl]) * v[sl]
        else:
            power = np.zeros(48)
        piece = 0.5 * (b - a) * float(np.dot(w, power))
        work += piece
        scale += 0.5 * (b - a) * float(np.dot(w, np.abs(power)))
    losses = 0.0
    landings = 0
    for e in events:
        if e.kind is EventKind.LANDING:
            landings += 1
            loss = 0.5 * params.mass * (e.v_before**2 + e.vz_before**2 - e.v_after**2 - e.vz_after**2)
            assert loss >= -1e-15 * params.mass * (e.v_before**2 + e.vz_before**2)
            losses += loss
            scale += abs(loss)
    end = first.state()
    kinetic = 0.5 * params.mass * (end.v**2 + end.vz**2)
    return kinetic, work - losses, scale, landings


@pytest.mark.parametrize(("gamma", "beta", "e", "landing"), [
    (2.0, 30.0, 0.0, "impulsive"), (2.0, 30.0, 0.0, "none"), (2.5, 45.0, 0.5, "impulsive"),
    (2.5, 45.0, 0.5, "none"), (4.2, 60.0, 0.0, "impulsive"), (1.5, 20.0, 0.3, "impulsive"),
])
def test_energy_bookkeeping(gamma: float, beta: float, e: float, landing: str) -> None:
    params, inputs = hopping(gamma, beta=beta, e=e, landing=landing, drive=0.5)
    kinetic, balance, scale, landings = energy_balance(params, inputs, 6.0)
    assert landings >= 3
    assert abs(kinetic - balance) <= 1e-11 * scale, (kinetic, balance, scale)


def test_work_over_each_flight_is_the_kinetic_energy_change() -> None:
    """Lift-off to landing: 1/2 m (v^2 + vz^2) changes by the work of Ft along x
    and of -R along z, and the landing obeys the impact law with loss >= 0."""
    params, inputs = hopping(2.0, beta=30.0, e=0.4, drive=0.3)
    slider = Slider(params, inputs, event_log_size=None)
    slider.advance_to(5.0 / inputs.excitation_frequency)
    events = slider.events
    x, w = np.polynomial.legendre.leggauss(64)
    flights = 0
    for start, end in itertools.pairwise(events):
        if start.after != 2 or end.kind is not EventKind.LANDING:
            continue
        flights += 1
        nodes = 0.5 * (end.t - start.t) * x + 0.5 * (end.t + start.t)
        probe = Slider(params, inputs, event_log_size=None)
        trajectory = probe.sample(nodes)
        ft, r = forces(params, inputs, nodes)
        power = ft * trajectory.v - r * trajectory.vz
        work = 0.5 * (end.t - start.t) * float(np.dot(w, power))
        scale = 0.5 * (end.t - start.t) * float(np.dot(w, np.abs(power)))
        change = 0.5 * params.mass * (end.v_before**2 + end.vz_before**2 - start.v_after**2 - start.vz_after**2)
        assert abs(change - work) <= 1e-11 * scale, (start, end, change, work)
        # the impact law (normal restitution, Coulomb impulse bounded by mu*(1+e)*|vz|)
        impulse = (1.0 + params.restitution) * abs(end.vz_before) if end.vz_after > 0.0 else abs(end.vz_before)
        if end.vz_after > 0.0:
            assert end.vz_after == pytest.approx(params.restitution * abs(end.vz_before), rel=1e-15)
        bound = params.mu * impulse
        expected_v = 0.0 if abs(end.v_before) <= bound else end.v_before - math.copysign(bound, end.v_before)
        assert end.v_after == pytest.approx(expected_v, rel=1e-14, abs=1e-15 * bound)
        loss = 0.5 * params.mass * (end.v_before**2 + end.vz_before**2 - end.v_after**2 - end.vz_after**2)
        assert loss >= 0.0
    assert flights >= 4


# ---------------------------------------------------------------------------- Kostek's model at the defaults


@pytest.mark.parametrize(("phi", "a"), [(0.7, 0.5), (0.35, 0.9), (0.95, 0.1), (0.5, 0.75), (0.82, 0.3)])
def test_defaults_reduce_to_kostek_exactly(phi: float, a: float) -> None:
    """Slip starts at t_n = (n + theta_A/(2 pi))/f and x(t_n) = n*D, theta_A and D
    from the textbook closed form in mpmath (test/reference_exact.py), to 1e-12."""
    params = SliderParams(mass=1.0, mu=0.1, gravity=10.0)
    assert is_kostek(params) and params.restitution == 0.0 and params.landing_friction == "impulsive"
    inputs = Inputs(drive_force=phi * params.mu * params.weight, excitation_amplitude=a * params.weight,
                    excitation_frequency=50.0)
    (fraction_hi, fraction_lo), _, travel = reference_exact.paper_case_slip(
        params.mass, params.mu, params.gravity, inputs.drive_force, inputs.excitation_amplitude,
        inputs.excitation_frequency)
    slider = Slider(params, inputs, event_log_size=None)
    slider.advance_to(40.0 / inputs.excitation_frequency)
    starts = [e for e in slider.events if e.kind is EventKind.SLIP_START]
    assert len(starts) == 40
    assert slider.event_counts[EventKind.LIFT_OFF] == 0 and slider.event_counts[EventKind.LANDING] == 0
    for n, event in enumerate(starts):
        exact_t = (n + fraction_hi + fraction_lo) / inputs.excitation_frequency
        assert abs(event.t - exact_t) <= 1e-12 * exact_t, (n, event.t, exact_t)
        if n:
            assert abs(event.x - n * travel) <= 1e-12 * n * travel, (n, event.x, n * travel)
    state = slider.state()
    assert state.z == 0.0 and state.vz == 0.0 and slider.flight_time == 0.0


# ---------------------------------------------------------------------------- cutting time


@pytest.mark.parametrize(("gamma", "beta", "e", "landing"), [
    (2.0, 30.0, 0.0, "impulsive"), (2.5, 45.0, 0.6, "impulsive"), (4.3, 50.0, 0.0, "none"), (1.8, 25.0, 0.5, "none"),
])
def test_cutting_time_does_not_change_a_flight(gamma: float, beta: float, e: float, landing: str) -> None:
    params, inputs = hopping(gamma, beta=beta, e=e, landing=landing, drive=0.4)
    t_end = 12.0 / inputs.excitation_frequency
    one = Slider(params, inputs, event_log_size=None)
    one.advance_to(t_end)
    rng = np.random.default_rng(int(gamma * 100))
    cut = Slider(params, inputs, event_log_size=None)
    collected = []
    for t in np.sort(rng.uniform(0.0, t_end, 2000)):
        collected.extend(cut.advance_to(float(t)))
    collected.extend(cut.advance_to(t_end))
    grid = Slider(params, inputs, event_log_size=None)
    trajectory = grid.sample(np.linspace(0.0, t_end, 3001))
    assert one.event_counts[EventKind.LANDING] >= 5
    for events in (collected, cut.events, list(trajectory.events)):
        assert [(e.kind, e.before, e.after) for e in events] == [(e.kind, e.before, e.after) for e in one.events]
        for mine, theirs in zip(events, one.events):
            assert abs(mine.t - theirs.t) <= 1e-12 * theirs.t
            assert abs(mine.x - theirs.x) <= 1e-12 * max(abs(theirs.x), 1e-300)
            assert abs(mine.vz_before - theirs.vz_before) <= 1e-12 * abs(theirs.vz_before)
    a, b = cut.state(), one.state()
    for name in ("x", "v", "z", "vz"):
        assert abs(getattr(a, name) - getattr(b, name)) <= 1e-12 * max(abs(getattr(b, name)), 1e-300), name
    assert a.mode == b.mode
    assert cut.flight_time == pytest.approx(one.flight_time, rel=1e-12)
    assert trajectory.x[-1] == pytest.approx(b.x, rel=1e-12)


# ---------------------------------------------------------------------------- no Zeno loop


@pytest.mark.parametrize(("gamma", "chatters"), [(1.01, True), (1.2, False)])
def test_restitution_near_one_ends_in_finitely_many_bounces(gamma: float, chatters: bool) -> None:
    """e = 0.99.  At Gamma = 1.01 every flight ends in a chatter of ~1000 ever
    smaller bounces that stops at the plastic floor (a rebound below 1e-6 of
    the excitation's speed scale), so the slider lands for good and lifts off
    again next period; there are at most ln(u_max/floor)/ln(1/e) bounces per
    chatter.  At Gamma = 1.2 the track keeps it bouncing.  Either way the run
    finishes quickly with a bounded number of events."""
    params, inputs = hopping(gamma, beta=90.0, e=0.99, drive=0.0)
    periods = 8
    duration = periods / inputs.excitation_frequency
    slider = Slider(params, inputs, event_log_size=None)
    slider.advance_to(duration)
    omega = 2.0 * math.pi * inputs.excitation_frequency
    floor = 1e-6 * params.normal_weight / params.mass / omega
    fastest = (params.normal_weight + inputs.excitation_amplitude) / params.mass * duration  # |vz| bound
    per_chatter = math.log(fastest / floor) / math.log(1.0 / 0.99) + 2.0
    landings = slider.event_counts[EventKind.LANDING]
    lift_offs = slider.event_counts[EventKind.LIFT_OFF]
    assert slider.t == duration
    assert 1 <= landings <= lift_offs * per_chatter, (landings, lift_offs, per_chatter)
    if chatters:
        assert lift_offs == periods and landings >= 100 * periods
        plastic = [e for e in slider.events if e.kind is EventKind.LANDING and e.vz_after == 0.0]
        assert len(plastic) == periods
        assert all(0.99 * abs(e.vz_before) <= floor for e in plastic)


# ---------------------------------------------------------------------------- a grazing landing


def rebound_height(gamma: float) -> tuple[float, float, Any, Any]:
    """Level track, Fd = 0: the first flight from lift-off at sin(theta0) = 1/Gamma
    lands at phase theta_L with speed w_L (units g/omega); a rebound with
    restitution e then has the height (units g/omega^2, u = theta - theta_L)
    z2(u, e) = e*w_L*u - u^2/2 + Gamma*(cos(theta_L)*u - sin(theta_L + u) + sin(theta_L))."""
    from scipy.optimize import brentq

    theta0 = math.asin(1.0 / gamma)

    def z1(u: float) -> float:
        return gamma * math.cos(theta0) * u - gamma * (math.sin(theta0 + u) - math.sin(theta0)) - u * u / 2

    u_land = brentq(z1, math.pi, 2 * math.pi, xtol=1e-16)
    theta_l = theta0 + u_land
    w_l = -(gamma * math.cos(theta0) - gamma * math.cos(theta_l) - u_land)

    def z2(u: float, e: float) -> float:
        return e * w_l * u - u * u / 2 + gamma * (math.cos(theta_l) * u - (math.sin(theta_l + u) - math.sin(theta_l)))

    def dz2(u: float, e: float) -> float:
        return e * w_l - u + gamma * (math.cos(theta_l) - math.cos(theta_l + u))

    return theta_l, w_l, z2, dz2


def first_turn(dz: Any, e: float, lo: float, hi: float, rising: bool) -> float:
    """Where dz(., e) first changes sign on (lo, hi): from + to - (apex) or - to + (a minimum)."""
    from scipy.optimize import brentq

    grid = np.linspace(lo, hi, 2001)
    values = [dz(u, e) for u in grid]
    for k in range(1, grid.size):
        if (values[k - 1] > 0.0 >= values[k]) if not rising else (values[k - 1] <= 0.0 < values[k]):
            return float(brentq(dz, grid[k - 1], grid[k], args=(e,), xtol=1e-16))
    raise AssertionError("no turn")


def test_grazing_landing_is_not_missed() -> None:
    """Gamma = 2: the rebound after the first landing dips towards the track
    while the track accelerates up, and at e = e* (~0.482) its lowest point
    just touches z = 0.  Slightly below e* the slider lands at that dip (a
    near-tangent root, depth 5e-6 and 5e-9 of g/omega^2); slightly above it
    passes over and lands ~0.38 periods later.  The core must find either
    landing, at the analytic time."""
    from scipy.optimize import brentq

    gamma, frequency = 2.0, 50.0
    omega = 2.0 * math.pi * frequency
    theta_l, _, z2, dz2 = rebound_height(gamma)

    def lowest(e: float) -> float:
        return z2(first_turn(dz2, e, 1e-9, 2 * math.pi, rising=True), e)

    e_star = brentq(lowest, 0.4, 0.5, xtol=1e-16)
    for rel in (-1e-6, -1e-9, 1e-9, 1e-6):
        e = e_star * (1.0 + rel)
        dip = first_turn(dz2, e, 1e-9, 2 * math.pi, rising=True)
        if rel < 0:
            apex = first_turn(dz2, e, 1e-9, dip, rising=False)
            u2 = brentq(z2, apex, dip, args=(e,), xtol=1e-16)
        else:
            u2 = brentq(z2, dip, dip + 2 * math.pi, args=(e,), xtol=1e-16)
        expected = (theta_l + u2) / omega
        params = SliderParams(mass=1.0, mu=0.5, gravity=10.0, restitution=e)
        inputs = Inputs(drive_force=0.0, excitation_amplitude=gamma * params.weight, excitation_frequency=frequency)
        slider = Slider(params, inputs, event_log_size=None)
        slider.advance_to(3.0 / frequency)
        landings = [event for event in slider.events if event.kind is EventKind.LANDING]
        assert landings[0].t == pytest.approx(theta_l / omega, rel=1e-13)
        assert abs(landings[1].t - expected) <= 1e-9 * expected, (rel, landings[1].t, expected)
        assert (landings[1].t < (theta_l + dip) / omega) is (rel < 0)
