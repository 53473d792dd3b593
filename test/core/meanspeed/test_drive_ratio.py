"""The inverse of U in phi (issue 22, item 4): the drive ratio phi = Fd/(mu m g)
a slider needs to move at a given U, hence the apparent friction mu_app/mu = phi
that vibration leaves it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from friction_sim.core.meanspeed.urelation import drive_ratio_for, stop_phase_advance, u_map
from friction_sim.errors import ParameterError

EPS = np.finfo(float).eps


def _slope(phi: np.ndarray, a: np.ndarray) -> np.ndarray:
    """dU/dphi = psi_C**2/(8 pi**2), the exact slope (independent of the inverse's own)."""
    psi = np.asarray(stop_phase_advance(phi, a))
    return psi * psi / (8.0 * math.pi**2)


def test_the_inverse_meets_the_forward_relation_to_its_own_rounding() -> None:
    """|U(phi(u), a) - u| within what the forward relation promises (1e-12
    relative: test_urelation_precision.py, worst seen 1e-13) plus what the
    inverse's own stopping leaves phi off by, times the slope: it stops when its
    step or bracket is within 4 eps phi, at most 8 ulps of phi, and phi is
    rounded once more (9 ulps; 7.6 is the worst seen).  Near the motion
    boundary U rises like (phi - phi_0)**2, so phi's rounding is amplified there:
    a flat 1e-12 relative would ask for more than a double holds, and so it
    would for a small a, whose whole range of phi, [1 - a, 1], is few ulps wide."""
    rng = np.random.default_rng(22)
    a = rng.uniform(0.0, 0.999, 20_000)
    u = rng.uniform(0.0, 1.0, a.size) ** 3 * a / (2.0 * math.pi)
    phi = drive_ratio_for(u, a)
    assert np.all(np.isfinite(phi)) and np.all((phi >= 1.0 - a) & (phi <= 1.0))
    bound = 1e-12 * u + _slope(phi, a) * 9.0 * np.spacing(phi)
    assert np.all(np.abs(u_map(phi, a) - u) <= bound)
    # Where phi's rounding moves U by less than the map's own error, that is the 1e-12 relative.
    resolved = _slope(phi, a) * 9.0 * np.spacing(phi) <= 1e-13 * u
    assert np.count_nonzero(resolved) > a.size // 2
    assert np.all(np.abs(u_map(phi[resolved], a[resolved]) - u[resolved]) <= 1.1e-12 * u[resolved])


@given(st.floats(0.0, 1.0, exclude_min=True, exclude_max=True), st.floats(0.01, 0.99))
def test_the_round_trip_in_phi_is_exact_to_a_few_ulps(fraction: float, a: float) -> None:
    """phi -> U -> phi: the well-conditioned direction (near the boundary dphi =
    dU/(dU/dphi) shrinks with U's own size), so a few ulps of phi."""
    phi = (1.0 - a) + fraction * a
    u = u_map(phi, a)
    if u == 0.0:  # phi rounded onto the boundary: nothing moves, the inverse gives the boundary
        assert drive_ratio_for(u, a) == 1.0 - a
        return
    assert drive_ratio_for(u, a) == pytest.approx(phi, abs=8.0 * EPS)


def test_the_ends_and_the_mirror() -> None:
    a = np.array([0.0, 0.3, 0.5, 0.9])
    assert np.array_equal(drive_ratio_for(0.0, a), 1.0 - a), "standing still: the breakaway friction 1 - a"
    assert drive_ratio_for(0.5 / (2.0 * math.pi), 0.5) == 1.0, "U = a/(2 pi) is phi = 1"
    assert math.isnan(drive_ratio_for(0.1, 0.5)), "faster than phi = 1 allows: only phi > 1, unbounded"
    assert math.isnan(drive_ratio_for(1e-6, 0.0)), "no vibration: nothing moves below phi = 1"
    u = u_map(0.7, 0.5)
    assert drive_ratio_for(u, 0.5) == pytest.approx(0.7, abs=4 * EPS), "the paper's case"
    assert drive_ratio_for(-u, 0.5) == -drive_ratio_for(u, 0.5)
    assert isinstance(drive_ratio_for(u, 0.5), float)


def test_each_element_is_solved_on_its_own() -> None:
    """A value does not depend on the array it came in (each element stops on its own)."""
    rng = np.random.default_rng(3)
    a = rng.uniform(0.05, 0.95, 200)
    u = rng.uniform(0.0, 1.0, a.size) * a / (2.0 * math.pi)
    together = drive_ratio_for(u, a)
    alone = np.array([drive_ratio_for(ui, ai) for ui, ai in zip(u, a)])
    assert np.array_equal(together, alone)


@pytest.mark.parametrize("a", [-0.1, 1.0, math.nan])
def test_an_amplitude_ratio_outside_kostek_s_model_is_refused(a: float) -> None:
    with pytest.raises(ParameterError, match="amplitude_ratio"):
        drive_ratio_for(0.01, a)
