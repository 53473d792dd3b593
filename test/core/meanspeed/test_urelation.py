"""The nondimensional mean-speed relation U(phi, a) and its inverse.

Independent expectations: the periodic slip from rest at theta_A =
asin((1 - phi)/a) has the speed w(psi) = (phi-1)*psi + a*(cos thA -
cos(thA+psi)) (units mu*g/omega); it stops at the root psi_C of w on
(pi - 2*thA, 2*pi] (found here with brentq), travels D = integral of w (units
mu*g/omega**2) per period, hence U = V*f/(g*mu) = D/(4*pi**2).
"""

import math
from fractions import Fraction
from typing import Any

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from friction_sim.core.meanspeed.urelation import (
    amplitude_ratio_for,
    motion_boundary,
    moves,
    slip_start_phase,
    stop_phase_advance,
    u_map,
)
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.simulation import simulate
from friction_sim.errors import FrictionSimError, ParameterError

TWO_PI = 2.0 * math.pi


def my_u(phi, a):
    """Independent U(phi, a) for 0 < |phi| < 1, a in [0, 1)."""
    sign = math.copysign(1.0, phi)
    phi = abs(phi)
    if phi <= 1.0 - a:
        return 0.0
    theta_a = math.asin((1.0 - phi) / a)

    def w(psi):
        return (phi - 1.0) * psi + a * (math.cos(theta_a) - math.cos(theta_a + psi))

    psi_c = brentq(w, math.pi - 2.0 * theta_a, TWO_PI, xtol=1e-16, rtol=1e-15)
    travel, _ = quad(w, 0.0, psi_c, epsabs=0.0, epsrel=1e-13, limit=200)
    return sign * travel / (4.0 * math.pi**2)


def my_psi_c(phi, a):
    theta_a = math.asin((1.0 - phi) / a)
    return brentq(
        lambda psi: (phi - 1.0) * psi + a * (math.cos(theta_a) - math.cos(theta_a + psi)),
        math.pi - 2.0 * theta_a, TWO_PI, xtol=1e-16, rtol=1e-15,
    )


# --------------------------------------------------------------------------
# types and shapes
# --------------------------------------------------------------------------


def test_scalars_give_python_floats():
    for fn in (u_map, slip_start_phase, stop_phase_advance):
        assert type(fn(0.7, 0.5)) is float
        assert type(fn(np.float64(0.7), np.float32(0.5))) is float
        assert type(fn(np.array(0.7), 0.5)) is float
    assert type(motion_boundary(0.3)) is float
    assert type(moves(0.7, 0.5)) is bool
    assert type(amplitude_ratio_for(0.005, 0.7)) is float


def test_arrays_broadcast():
    phi = np.linspace(-1.2, 1.2, 7)[:, None]
    a = np.linspace(0.0, 0.9, 4)[None, :]
    for fn in (u_map, slip_start_phase, stop_phase_advance, moves):
        out = fn(phi, a)
        assert isinstance(out, np.ndarray) and out.shape == (7, 4)
    assert u_map([0.7, 0.8], 0.5).shape == (2,)
    assert u_map(0.7, [0.5, 0.6, 0.7]).shape == (3,)
    assert u_map(np.array([[0.7]]), 0.5).shape == (1, 1)
    out = u_map(phi, a)
    for i in range(7):
        for j in range(4):
            one = u_map(float(phi[i, 0]), float(a[0, j]))
            assert out[i, j] == pytest.approx(one, rel=1e-13, abs=0.0)
    inv = amplitude_ratio_for(np.array([[0.001], [0.002]]), np.array([0.7, 0.8, 0.9]))
    assert inv.shape == (2, 3)


# --------------------------------------------------------------------------
# regions
# --------------------------------------------------------------------------


def last_still_phi(a: float) -> float:
    """The largest float phi with phi <= 1 - a exactly (on the given floats,
    as the slider decides it): 1 - a rounded may lie a hair above 1 - a."""
    edge = 1.0 - a
    while Fraction(edge) + Fraction(a) > 1:
        edge = math.nextafter(edge, 0.0)
    return edge


@pytest.mark.parametrize("a", [0.0, 0.1, 0.5, 0.9, 0.99])
def test_zero_where_nothing_moves(a):
    edge = last_still_phi(a)
    phi = np.linspace(0.0, edge, 101)
    phi[-1] = edge
    assert np.all(u_map(phi, a) == 0.0)
    assert np.all(u_map(-phi, a) == 0.0)
    assert u_map(edge, a) == 0.0  # the boundary itself does not move
    assert not moves(edge, a)
    assert motion_boundary(edge) == pytest.approx(a, abs=1e-15)
    assert np.all(np.isnan(stop_phase_advance(phi[:-1], a)))
    beyond = math.nextafter(edge, 2.0)  # one float further moves, however little
    if a > 0.0:
        assert moves(beyond, a) and u_map(beyond, a) > 0.0


def test_sign_symmetry():
    phi = np.linspace(0.0, 1.3, 131)[:, None]
    a = np.linspace(0.0, 0.98, 50)[None, :]
    assert np.array_equal(u_map(-phi, a), -u_map(phi, a))
    assert u_map(-0.7, 0.5) == -u_map(0.7, 0.5) < 0.0


def test_infinite_beyond_phi_one():
    assert u_map(1.2, 0.3) == math.inf
    assert u_map(-1.2, 0.3) == -math.inf
    assert u_map(1.0 + 1e-12, 0.0) == math.inf
    assert np.all(np.isinf(u_map(np.linspace(1.0001, 3.0, 20), 0.5)))


def test_phi_one_and_continuity():
    for a in (0.05, 0.3, 0.5, 0.9):
        assert u_map(1.0, a) == pytest.approx(a / TWO_PI, rel=1e-15)
        assert u_map(-1.0, a) == pytest.approx(-a / TWO_PI, rel=1e-15)
        for eps in (1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12):
            u = u_map(1.0 - eps, a)
            assert u < a / TWO_PI
            # dU/dphi stays bounded (~1/2) near phi = 1: |U - a/(2 pi)| <= eps
            assert abs(u - a / TWO_PI) <= eps
    assert u_map(1.0, 0.0) == 0.0  # Fd == mu*m*g without excitation: stands


def test_nan_phi_gives_nan():
    assert math.isnan(u_map(float("nan"), 0.5))


def test_matches_independent_formula_on_a_grid():
    rng = np.random.default_rng(3)
    for _ in range(60):
        a = rng.uniform(0.01, 0.99)
        phi = rng.uniform(1.0 - a, 1.0) * rng.choice([-1.0, 1.0])
        expected = my_u(phi, a)
        if abs(expected) < 1e-9:
            continue
        assert u_map(phi, a) == pytest.approx(expected, rel=1e-10)
        assert stop_phase_advance(phi, a) == pytest.approx(my_psi_c(abs(phi), a), rel=1e-13)
        assert slip_start_phase(phi, a) == pytest.approx(math.asin((1 - abs(phi)) / a), rel=1e-14)


def test_paper_case_value():
    # phi = 0.7, a = 0.5: slip from asin(0.6) until psi_C, U = D/(4 pi^2)
    # (1 - 0.7)/0.5 rounds once, asin is good to 1 ulp: 1e-15 is 9 ulp of asin(0.6)
    assert slip_start_phase(0.7, 0.5) == pytest.approx(math.asin(0.6), abs=1e-15)
    assert u_map(0.7, 0.5) == pytest.approx(my_u(0.7, 0.5), rel=1e-12)
    psi_c = stop_phase_advance(0.7, 0.5)
    assert math.pi - 2 * math.asin(0.6) < psi_c <= TWO_PI


def test_strictly_increasing_in_a_and_phi_inside_motion_region():
    phi = np.linspace(0.01, 0.999, 150)
    a = np.linspace(0.005, 0.995, 150)
    u = u_map(phi[:, None], a[None, :])
    inside = phi[:, None] > 1.0 - a[None, :]
    checked = 0
    for i in range(phi.size):
        row = u[i, inside[i]]
        assert np.all(np.diff(row) > 0.0), f"not increasing in a at phi={phi[i]}"
        col = u[inside[:, i], i]
        assert np.all(np.diff(col) > 0.0), f"not increasing in phi at a={a[i]}"
        checked += row.size + col.size
    assert checked > 10000
    assert np.all(u[inside] > 0.0)
    # and negative phi: U decreases as phi grows more negative (mirror)
    assert np.all(np.diff(u_map(-np.linspace(0.2, 0.99, 50), 0.9)) < 0.0)


# --------------------------------------------------------------------------
# U is what the core simulates
# --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "m, mu, g, f, phi, a",
    [
        (1.0, 0.1, 10.0, 50.0, 0.7, 0.5),
        (1.0, 0.1, 10.0, 50.0, 0.9, 0.3),
        (1.0, 0.156, 10.0, 100.0, 0.3, 0.8),
        (2.0, 0.2, 9.81, 30.0, -0.6, 0.6),
        (0.3, 0.5, 3.7, 7.0, 0.99, 0.05),
        (5.0, 0.05, 12.0, 400.0, 0.999, 0.9),
    ],
)
def test_u_equals_simulated_mean_speed(m, mu, g, f, phi, a):
    params = SliderParams(mass=m, mu=mu, gravity=g)
    inputs = Inputs(drive_force=phi * mu * m * g, excitation_amplitude=a * m * g, excitation_frequency=f)
    # 12.5 periods: the 10 whole periods after settling end clear of `duration`
    # (see test_simulate_accepts_a_duration_of_whole_periods for the exact fit)
    result = simulate(params, inputs, duration=12.5 / f, settle=2.0 / f)
    assert result.periods == 10
    expected = my_u(phi, a)
    assert u_map(phi, a) == pytest.approx(expected, rel=1e-10)
    assert result.u_measured == pytest.approx(u_map(phi, a), rel=1e-9)
    assert result.u_exact == pytest.approx(u_map(phi, a), rel=1e-12)
    # V = U*g*mu/f by definition
    assert result.mean_velocity == pytest.approx(expected * g * mu / f, rel=1e-9)


@pytest.mark.parametrize("duration, settle", [(0.7, 0.0), (0.82, 0.0), (0.24, 0.04), (0.2, 0.0), (0.36, 0.0)])
def test_simulate_accepts_a_duration_of_whole_periods(duration, settle):
    # 50 Hz: a duration of 35 periods (0.7 s).  simulate() counts the whole
    # periods with a 1e-12 slack, so settle + periods*period can round one ulp
    # past `duration`; the final advance_to(duration) then goes backwards.
    result = simulate(SliderParams(), Inputs(), duration, settle=settle)
    assert result.periods == round((duration - settle) * 50.0)
    assert result.u_measured == pytest.approx(my_u(0.7, 0.5), rel=1e-9)


# --------------------------------------------------------------------------
# the inverse
# --------------------------------------------------------------------------


def test_amplitude_ratio_for_inverts_u_map_on_a_grid():
    phi = np.linspace(0.02, 0.995, 80)
    a = np.linspace(0.01, 0.99, 80)
    P, A = np.meshgrid(phi, a, indexing="ij")
    inside = P > 1.0 - A
    u = u_map(P[inside], A[inside])
    back = amplitude_ratio_for(u, P[inside])
    assert np.max(np.abs(back - A[inside])) <= 1e-12
    # mirrored
    back_neg = amplitude_ratio_for(-u, -P[inside])
    assert np.max(np.abs(back_neg - A[inside])) <= 1e-12
    # scalar calls agree with the vectorised one
    for k in range(0, u.size, 397):
        assert amplitude_ratio_for(float(u[k]), float(P[inside][k])) == pytest.approx(back[k], abs=1e-15)


def test_amplitude_ratio_for_zero_speed_is_zero():
    for phi in (0.0, 0.3, 0.7, -0.7, 0.999, 1.0, 1.5):
        assert amplitude_ratio_for(0.0, phi) == 0.0
    assert np.all(amplitude_ratio_for(np.zeros(5), np.linspace(-1, 1, 5)) == 0.0)


def test_amplitude_ratio_for_unreachable_is_nan():
    u_top = u_map(0.7, np.nextafter(1.0, 0.0))
    cases = [
        (u_top * 1.01, 0.7),  # faster than any a < 1 gives
        (0.01, 0.05),  # a weak drive cannot reach this speed
        (0.01, -0.7),  # wrong sign
        (-0.01, 0.7),  # wrong sign
        (0.01, 0.0),  # no drive, no steering
        (0.01, 1.5),  # |phi| > 1: it runs away, excitation no longer steers
        (-0.01, -1.5),
        (0.2, 1.0),  # at |phi| = 1, U = a/(2 pi) < 1/(2 pi)
        (float("nan"), 0.7),
    ]
    for u, phi in cases:
        assert math.isnan(amplitude_ratio_for(u, phi)), (u, phi)
    reachable = amplitude_ratio_for(u_top * 0.99, 0.7)
    assert 0.3 < reachable < 1.0
    # |phi| = 1 is the runaway boundary, not beyond it: the slider slides on at U = a/(2 pi)
    assert amplitude_ratio_for(0.01, 1.0) == amplitude_ratio_for(-0.01, -1.0) == 2.0 * math.pi * 0.01
    assert u_map(1.0, 2.0 * math.pi * 0.01) == pytest.approx(0.01, rel=1e-15)


def test_amplitude_ratio_for_with_max_ratio():
    u = u_map(0.7, 0.45)
    assert amplitude_ratio_for(u, 0.7, max_ratio=0.5) == pytest.approx(0.45, abs=1e-12)
    assert math.isnan(amplitude_ratio_for(u_map(0.7, 0.6), 0.7, max_ratio=0.5))
    assert math.isnan(amplitude_ratio_for(u, 0.7, max_ratio=0.3))  # 1 - phi >= max_ratio
    for bad in (0.0, -0.5, 1.5, float("nan")):
        with pytest.raises(ParameterError) as excinfo:
            amplitude_ratio_for(u, 0.7, max_ratio=bad)
        assert excinfo.value.field == "max_ratio"
        assert "max_ratio" in str(excinfo.value)


# --------------------------------------------------------------------------
# speed, refusals
# --------------------------------------------------------------------------


def test_a_101_by_101_grid_is_its_points_one_by_one():
    """The grid is one vectorised call (its time is bench/physics.py's figure (b));
    each of its values is the scalar map's at that point, bit for bit."""
    phi, a = np.meshgrid(np.linspace(-1.2, 1.2, 101), np.linspace(0.0, 0.99, 101))
    u = u_map(phi, a)
    assert u.shape == (101, 101)
    for i, j in np.random.default_rng(3).integers(0, 101, size=(200, 2)):
        assert u[i, j] == u_map(float(phi[i, j]), float(a[i, j]))


@pytest.mark.parametrize("bad, text", [(1.0, "1.0"), (1.2, "1.2"), (float("nan"), "nan"),
                                       (-0.1, "-0.1"), (float("inf"), "inf")])
def test_amplitude_ratio_out_of_range_is_refused(bad, text):
    for args in [(0.5, bad), (np.array([0.5, 0.6]), np.array([0.3, bad]))]:
        with pytest.raises(ParameterError) as excinfo:
            u_map(*args)
        err = excinfo.value
        assert isinstance(err, ValueError) and isinstance(err, FrictionSimError)
        assert err.field == "amplitude_ratio"
        assert "amplitude_ratio" in str(err) and text in str(err)


def test_simulate_predicts_with_the_external_force() -> None:
    """With an external force the exact U uses the effective groups, and the
    simulated mean speed agrees with it.  (Fz points away from the track since
    issue 11: -2 N presses the slider on, +2 N takes load off.)"""
    from friction_sim.core.model.params import Inputs, SliderParams
    from friction_sim.core.runtime.simulation import simulate

    result = simulate(SliderParams(), Inputs(external_force_x=0.1, external_force_z=-2.0), 1.0, settle=0.1)
    assert result.u_exact == pytest.approx(my_u(0.8 / 1.2, 5.0 / 12.0), rel=1e-12)
    # measured and exact U are made with the same (effective) groups: they agree
    assert result.u_measured == pytest.approx(result.u_exact, rel=1e-9)
    assert result.phi == pytest.approx(0.8 / 1.2, rel=1e-15)
    assert result.amplitude_ratio == pytest.approx(5.0 / 12.0, rel=1e-15)
    # the case: a load taken off (Fz = +2 N), measured 0.0454 against exact 0.0568 before
    lighter = simulate(SliderParams(), Inputs(external_force_z=2.0), 1.0, settle=0.1)
    assert lighter.u_exact == pytest.approx(my_u(0.7 / 0.8, 5.0 / 8.0), rel=1e-12)
    assert lighter.u_measured == pytest.approx(lighter.u_exact, rel=1e-9)
    # without an external force the effective groups are the paper's, to the bit
    plain = simulate(SliderParams(mass=3.0, gravity=0.1), Inputs(drive_force=0.021, excitation_amplitude=0.15),
                     1.0, settle=0.1)
    assert (plain.phi, plain.amplitude_ratio) == (0.021 / (0.1 * (3.0 * 0.1)), 0.15 / (3.0 * 0.1))
    assert plain.u_measured == pytest.approx(plain.u_exact, rel=1e-9)


def test_a_backward_drive_that_stands_still_gives_plain_zero() -> None:
    """Not -0.0 (``simulate`` printed ``U exact = -0.0``)."""
    assert math.copysign(1.0, u_map(-0.5, 0.1)) == 1.0
    assert not np.signbit(u_map(np.array([-0.5, -0.2]), np.array([0.1, 0.3]))).any()


@pytest.mark.parametrize(("u", "phi"), [(0.015, 0.7), (0.03, 0.7), (0.001, 0.35), (0.1, 0.9)])
def test_the_inverse_converges_in_a_handful_of_newton_steps(u: float, phi: float,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """The controller inverts once per change of its inputs, inside the loop:
    U's rounding noise once kept Newton stepping to and fro for 35 evaluations
    (30-50 ms, a period's delay at 100 Hz in acceptance case 5)."""
    from friction_sim.core.meanspeed import kostek

    calls = []
    real = kostek.u_and_slope

    def counted(phi_: Any, a_: Any) -> Any:
        calls.append(1)
        return real(phi_, a_)

    monkeypatch.setattr(kostek, "u_and_slope", counted)
    a = amplitude_ratio_for(u, phi)
    assert u_map(phi, a) == pytest.approx(u, rel=1e-13)
    assert len(calls) <= 12
