"""The resonant exciter (issue 21): the slideway against the analytic resonance
curve and the closed form of its step response, the part against an
independent reference (solve_ivp on the coupled equations), continuity at
every change, and the force actuator untouched."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference_exciter import random_case, solve

from friction_sim.core.engine.population import run_batch
from friction_sim.core.engine.single import Slider
from friction_sim.core.model.events import EventKind
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.exciter import response
from friction_sim.core.physics.transient import Signal, first_time, value

from helpers import exciter_states

RESONANT = SliderParams(actuator="resonant")


def _exact_response(r: float, zeta: float) -> tuple[float, float]:
    """G and the lag from the complex transfer function, in 50 digits."""
    mpmath.mp.dps = 50
    r_, z_ = mpmath.mpf(r), mpmath.mpf(zeta)
    h = 2 * z_ * r_**2 / mpmath.mpc(1 - r_**2, 2 * z_ * r_)
    return float(abs(h)), float(-mpmath.arg(h) % (2 * mpmath.pi))


@pytest.mark.parametrize("zeta", [1e-4, 0.02, 0.1, 0.7])
def test_the_steady_response_is_the_analytic_resonance_curve(zeta: float) -> None:
    # response() takes a dozen roundings (the ratio, (1 - r)(1 + r), hypot, atan2): ~1e-15
    # relative, and 1e-12 is the target; near resonance 1 - r**2 has the condition
    # 1/|1 - r**2| in r, which (1 - r)(1 + r) avoids.
    for f in np.concatenate([np.linspace(1.0, 150.0, 301), [49.999999, 50.0, 50.000001]]):
        gain, lag = response(float(f), 50.0, zeta)
        exact_gain, exact_lag = _exact_response(float(f) / 50.0, zeta)
        assert gain == pytest.approx(exact_gain, rel=1e-12, abs=0.0)
        assert lag == pytest.approx(exact_lag, rel=0.0, abs=1e-12)
    assert response(50.0, 50.0, zeta) == (1.0, math.pi / 2)  # at resonance, exactly


def _linear_solution(params: SliderParams, u0: float, u1: float, f: float, t0: float,
                     times: np.ndarray) -> np.ndarray:
    """(q, q', q'') of the slideway stepped from u0 to u1 at t0, from the state
    matrix's exponential (scipy.linalg.expm) and the complex steady amplitude:
    no formula of the core's."""
    from scipy.linalg import expm

    wn, zeta, a = 2 * math.pi * params.natural_frequency, params.damping_ratio, params.full_drive_acceleration
    w = 2 * math.pi * f
    matrix = np.array([[0.0, 1.0], [-wn * wn, -2 * zeta * wn]])

    def steady(u: float, t: float) -> np.ndarray:
        amplitude = 2 * zeta * a * u / complex(wn * wn - w * w, 2 * zeta * wn * w)
        e = np.exp(1j * w * t)
        return np.array([(amplitude * e).imag, (1j * w * amplitude * e).imag])

    start = steady(u0, t0) - steady(u1, t0)
    rows = []
    for t in times:
        q, qd = steady(u1, t) + expm(matrix * (t - t0)) @ start
        qdd = 2 * zeta * a * u1 * math.sin(w * t) - 2 * zeta * wn * qd - wn * wn * q
        rows.append((q, qd, qdd))
    return np.array(rows)


@pytest.mark.parametrize(("fn", "f"), [(50.0, 50.0), (52.0, 50.0), (47.0, 50.0)])
def test_the_slideway_after_a_step_of_drive_is_the_linear_solution(fn: float, f: float) -> None:
    params = RESONANT.replace(natural_frequency=fn)
    slider = Slider(params, Inputs(excitation_frequency=f, drive_level=0.3))
    t0 = 0.1234567
    slider.advance_to(t0)
    slider.set_inputs(drive_level=0.9)
    times = t0 + np.linspace(0.0, 1.5, 61)[1:]
    expected = _linear_solution(params, 0.3, 0.9, f, t0, times)
    scale = np.max(np.abs(expected), axis=0)
    for t, row in zip(times, expected):
        slider.advance_to(float(t))
        state = slider.exciter
        assert state is not None
        # expm and the steady amplitude are good to ~1e-15 of the scale; the sine of a phase
        # omega*t ~ 500 rad carries ~500 ulps of it: 1e-12 of the scale bounds both.
        error = np.abs(np.array([state.q, state.qd, state.qdd]) - row) / scale
        assert np.all(error <= 1e-12), (t, error)


def test_the_envelope_after_a_step_decays_at_zeta_omega_n() -> None:
    # The transient force is Re(c exp(lambda t)): its size falls exactly as exp(-zeta omega_n t).
    params = RESONANT.replace(natural_frequency=52.0)
    slider = Slider(params, Inputs(drive_level=0.2))
    slider.advance_to(0.05)
    slider.set_inputs(drive_level=1.0)
    steady = params.mass * 1.0 * params.full_drive_acceleration * response(50.0, 52.0, 0.02).gain
    sigma = params.damping_ratio * 2 * math.pi * params.natural_frequency
    sizes = []
    for k in range(8):
        slider.advance_to(0.05 + 0.1 * k)
        state = slider.exciter
        assert state is not None and state.amplitude > steady
        sizes.append(state.amplitude - steady)
    ratios = np.array(sizes[1:]) / np.array(sizes[:-1])
    # the subtraction loses log10(steady/size) digits at most (size > 2 % of steady here)
    assert ratios == pytest.approx(math.exp(-sigma * 0.1), rel=1e-12)


def test_a_change_at_any_instant_keeps_the_slideway_and_the_phase_continuous() -> None:
    rng = np.random.default_rng(21)
    slider = Slider(RESONANT.replace(natural_frequency=51.0, excitation_angle=60.0), Inputs(drive_level=0.7))
    t = 0.0
    for _ in range(40):
        t += float(rng.uniform(0.001, 0.03))
        slider.advance_to(t)
        before, phase = slider.exciter, slider.state().phase
        assert before is not None
        change = rng.integers(3)
        if change == 0:
            slider.set_inputs(drive_level=float(rng.uniform(0.0, 1.0)))
        elif change == 1:
            slider.set_inputs(excitation_frequency=float(rng.uniform(40.0, 60.0)))
        else:
            slider.set_params(slider.params.replace(natural_frequency=float(rng.uniform(45.0, 55.0)),
                                                    damping_ratio=float(rng.uniform(0.01, 0.1))))
        after = slider.exciter
        assert after is not None
        # q and q' are re-derived through the new steady response: a few roundings of their size
        assert after.q == pytest.approx(before.q, rel=0.0, abs=1e-13 * abs(before.q) + 1e-20)
        assert after.qd == pytest.approx(before.qd, rel=0.0, abs=1e-13 * abs(before.qd) + 1e-18)
        assert slider.state().phase == phase
        if change == 0:  # the drive force jumps with u: q'' by exactly 2 zeta A du sin(theta)
            du = after.drive_level - before.drive_level
            jump = 2 * slider.params.damping_ratio * 10.0 * du * math.sin(phase)
            assert after.qdd - before.qdd == pytest.approx(jump, abs=1e-12 * (abs(before.qdd) + 1.0))


@pytest.mark.parametrize("seed", range(12))
def test_the_part_agrees_with_the_coupled_reference(seed: int) -> None:
    case = random_case(np.random.default_rng(seed))
    reference = solve(case, 0.4)
    times = np.linspace(0.0, 0.4, 81)[1:]
    ours, slider = exciter_states(case, times)
    theirs = np.array([reference.at(float(t))[2:6] for t in times])
    # The reference integrates at rtol 1e-12 over ~1000 steps of T/40 (and polishes events to
    # 4 eps): its own error is below ~1e-9 of each quantity's range, the target.
    scale = np.max(np.abs(theirs), axis=0)
    assert np.all(np.abs(ours - theirs) <= 1e-9 * scale + 1e-300)
    kinds = [kind if not kind.startswith("slip_start") else EventKind.SLIP_START.value for _, kind in reference.events]
    assert [event.kind.value for event in slider.events] == kinds
    # event times to 1e-9 of a period (the same reference error, in time)
    assert np.all(np.abs(np.array([event.t for event in slider.events]) - [t for t, _ in reference.events])
                  <= 1e-9 * 0.02)


def test_the_reference_cases_include_flight_and_motion() -> None:
    # (the agreement above is not vacuous: the drawn cases slip, and some hop)
    kinds = set()
    for seed in range(12):
        kinds |= {kind for _, kind in solve(random_case(np.random.default_rng(seed)), 0.4).events}
    assert {"stick", "lift_off", "landing"} <= kinds


def test_how_time_is_cut_does_not_change_the_transient_motion() -> None:
    def run(stops: np.ndarray) -> tuple[float, float, int]:
        slider = Slider(RESONANT.replace(natural_frequency=52.0, excitation_angle=45.0), Inputs(drive_level=0.5))
        slider.advance_to(0.05)
        slider.set_inputs(drive_level=1.0)
        for t in stops:
            slider.advance_to(float(t))
        state = slider.state()
        return state.x, state.v, sum(slider.event_counts.values())

    rng = np.random.default_rng(5)
    assert run(np.array([1.0])) == run(np.sort(rng.uniform(0.05, 1.0, 200)).tolist() + [1.0])


def test_the_transient_settles_and_the_motion_is_the_steady_one_again() -> None:
    params = RESONANT.replace(natural_frequency=52.0)
    stepped = Slider(params, Inputs(drive_level=0.3), cycle_log_size=None)
    stepped.advance_to(0.2)
    stepped.set_inputs(drive_level=0.9)
    steady = Slider(params, Inputs(drive_level=0.9), cycle_log_size=None)
    stepped.advance_to(12.0)
    steady.advance_to(12.0)
    assert stepped._transient.c == 0j  # noqa: SLF001 - dropped below rounding, so the steady memo serves again
    late = [mark for mark in stepped.cycle_marks if mark.n >= 500]
    reference = [mark for mark in steady.cycle_marks if mark.n >= 500]
    ours = np.diff([mark.x for mark in late])
    theirs = np.diff([mark.x for mark in reference])
    # the same periodic motion: each period's travel, to the rounding of x (~1e-16 m on 5e-3 m)
    assert ours == pytest.approx(theirs, rel=1e-9)


def test_the_force_actuator_ignores_the_exciter_settings_bit_for_bit() -> None:
    plain = Slider()
    other = Slider(SliderParams(natural_frequency=30.0, damping_ratio=0.3, full_drive_acceleration=1.0),
                   Inputs(drive_level=0.0))
    assert plain.advance_to(1.0) == other.advance_to(1.0)
    assert plain.state() == other.state()


def test_at_resonance_the_steady_exciter_conveys_as_the_force_actuator() -> None:
    # Defaults: u A G m = 0.5 * 10 * 1 * 1 = 5 N exactly, a quarter period behind the drive.
    force, resonant = Slider(cycle_log_size=None), Slider(RESONANT, cycle_log_size=None)
    force.advance_to(1.0)
    resonant.advance_to(1.0)
    travel = [np.diff([m.x for m in slider.cycle_marks])[10:] for slider in (force, resonant)]
    assert travel[1] == pytest.approx(travel[0], rel=1e-12)


def test_the_population_engine_runs_the_steady_exciter_as_the_single_slider() -> None:
    columns = {
        "actuator": ["resonant"] * 6 + ["force"],
        "natural_frequency": [45.0, 48.0, 50.0, 52.0, 55.0, 50.0, 50.0],
        "damping_ratio": [0.02, 0.05, 0.02, 0.02, 0.1, 0.01, 0.02],
        "drive_level": [1.0, 0.8, 0.5, 0.9, 1.0, 0.7, 0.5],
        "excitation_angle": [90.0, 30.0, 90.0, 60.0, 45.0, 20.0, 90.0],
        "full_drive_acceleration": [10.0, 20.0, 10.0, 15.0, 40.0, 25.0, 10.0],
        "restitution": [0.0, 0.3, 0.0, 0.0, 0.5, 0.2, 0.0],
    }
    # (every event computed: the periodic shortcut's extrapolation may differ in the last bits)
    compiled = run_batch(columns, settle_periods=5, periods=20, periodic_shortcut=False)
    scalar = run_batch(columns, settle_periods=5, periods=20, engine="scalar")
    assert np.array_equal(compiled.mean_velocity, scalar.mean_velocity)
    assert all(np.array_equal(compiled.event_counts[kind], scalar.event_counts[kind]) for kind in scalar.event_counts)
    # the paper's case at resonance (index 2) conveys as the force actuator's (index 6)
    assert compiled.mean_velocity[2] == pytest.approx(compiled.mean_velocity[6], rel=1e-12)
    assert np.any(compiled.flight_fraction > 0.0)


@settings(max_examples=200, deadline=None)
@given(b0=st.floats(-3.0, 1.0), b1=st.floats(0.0, 2.0), phase=st.floats(0.0, 6.28), re=st.floats(-3.0, 3.0),
       im=st.floats(-3.0, 3.0), sigma=st.floats(1.0, 50.0), omega_d=st.floats(100.0, 500.0),
       level=st.sampled_from([0, 1, 2]), positive=st.booleans())
def test_first_time_misses_no_root(b0: float, b1: float, phase: float, re: float, im: float, sigma: float,
                                   omega_d: float, level: int, positive: bool) -> None:
    s = Signal(level, 1e-6 if level == 2 else 0.0, 0.01 if level else 0.0, b0, b1, phase, 2 * math.pi * 50.0,
               complex(re, im), complex(-sigma, omega_d))
    horizon = 0.06
    found = first_time(s, 0.0, horizon, positive, np.zeros(1, np.int64))
    grid = np.linspace(0.0, horizon, 30001)
    holds = [(value(s, float(t)) > 0.0) if positive else (value(s, float(t)) <= 0.0) for t in grid]
    first_on_grid = grid[holds.index(True)] if True in holds else math.inf
    assert found <= first_on_grid  # a root the grid sees is never missed
    if found != math.inf:
        at = value(s, found)
        assert (at > 0.0) if positive else (at <= 0.0)  # the condition holds where it is reported
        earlier = grid[grid < found * (1 - 1e-9) - 1e-15]
        # no grid point before it satisfies the condition by more than rounding
        assert all(((value(s, float(t)) <= 1e-12) if positive else (value(s, float(t)) > -1e-12)) for t in earlier)
        if found > 0.0:  # found to the last bit: the condition fails at the float before (whatever narrowed it)
            before = value(s, math.nextafter(found, -math.inf))
            assert not (before > 0.0) if positive else not (before <= 0.0)
