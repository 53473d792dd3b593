"""U(phi, a) near the motion boundary phi = 1 - a (issue 10, item 15).

The textbook closed form cancels there: the slip is tiny, its terms are not
(u_map(0.5930024067205387, 0.4069975942794613) was -4.1e-19, the true value
+2.8e-19).  The map is now never negative and within 1e-12 (relative) of a
high-precision value down to phi - (1 - a) = 1e-12*a, and a value does not
depend on whether it was asked for alone or in an array.  The expectations
come from mpmath at 80 digits (test/reference_exact.py), independent of the core.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from friction_sim.core.meanspeed.urelation import amplitude_ratio_for, stop_phase_advance, u_grid, u_map

from reference_exact import high_precision_slip, high_precision_u

#: The accuracy the map promises (issue 10, item 15), not a figure one machine gave: its
#: worst relative error over every check here is 1.0e-13 (`make margins`, any CPU setting;
#: the map is computed with libm's math, no BLAS and no SIMD).
REL = 1e-12


def near_boundary(a: float, excess: float) -> float:
    """phi at phi - (1 - a) ~ excess*a (as a float)."""
    return (1.0 - a) + excess * a


def test_the_reported_point_is_positive_and_exact() -> None:
    phi, a = 0.5930024067205387, 0.4069975942794613
    u = u_map(phi, a)
    assert u > 0.0
    assert u == pytest.approx(high_precision_u(phi, a), rel=REL, abs=0.0)
    assert u == pytest.approx(2.8006636762303e-19, rel=1e-12)


@pytest.mark.parametrize("a", [1e-3, 0.05, 0.2, 0.4069975942794613, 0.5, 0.75, 0.95, 0.999])
@pytest.mark.parametrize("excess", [1e-12, 3e-11, 1e-9, 1e-7, 1e-5, 1e-3, 3e-3, 1e-2, 0.1, 0.5])
def test_u_is_exact_to_1e_12_down_to_1e_12_a_from_the_boundary(a: float, excess: float) -> None:
    phi = near_boundary(a, excess)
    assert phi < 1.0
    expected = high_precision_u(phi, a)
    assert expected > 0.0
    assert u_map(phi, a) == pytest.approx(expected, rel=REL, abs=0.0)
    assert u_map(-phi, a) == -u_map(phi, a)
    _, psi_c, _ = high_precision_slip(phi, a)
    assert stop_phase_advance(phi, a) == pytest.approx(float(psi_c), rel=1e-13, abs=0.0)


@settings(max_examples=150, deadline=None)
@given(a=st.floats(1e-4, 0.9999), log_excess=st.floats(-12.0, 0.0))
def test_u_is_exact_anywhere_in_the_periodic_region(a: float, log_excess: float) -> None:
    phi = near_boundary(a, 10.0**log_excess)
    if phi >= 1.0:  # excess 1: phi = 1 rounded
        phi = math.nextafter(1.0, 0.0)
    expected = high_precision_u(phi, a)
    assert u_map(phi, a) == pytest.approx(expected, rel=REL, abs=0.0)


def test_u_is_never_negative_near_the_boundary_nor_on_the_map() -> None:
    grid = u_grid(101)
    assert np.all(grid.u >= 0.0)
    a = np.linspace(0.001, 0.999, 400)[:, None]
    excess = np.logspace(-16, -6, 60)[None, :]
    u = u_map((1.0 - a) + excess * a, a)
    assert np.all(u >= 0.0)
    # the smallest values of the map are the ones the textbook form got wrong: check them all
    small = np.argwhere((grid.u > 0.0) & (grid.u < 1e-10))
    assert small.size
    for i, j in small:
        phi, ratio = float(grid.phi[j]), float(grid.amplitude_ratio[i])
        assert grid.u[i, j] == pytest.approx(high_precision_u(phi, ratio), rel=REL, abs=0.0)


def test_scalar_and_array_calls_agree() -> None:
    rng = np.random.default_rng(15)
    a = rng.uniform(0.001, 0.999, 300)
    excess = 10.0 ** rng.uniform(-14, 0, 300)
    phi = np.concatenate([(1.0 - a) + excess * a, rng.uniform(-1.2, 1.2, 300)])
    ratio = np.concatenate([a, rng.uniform(0.0, 0.999, 300)])
    together = u_map(phi, ratio)
    alone = np.array([u_map(float(p), float(r)) for p, r in zip(phi, ratio)])
    reversed_ = u_map(phi[::-1], ratio[::-1])[::-1]
    assert np.array_equal(together, alone, equal_nan=True)  # bit for bit: the same formulas, point by point
    assert np.array_equal(together, reversed_, equal_nan=True)


@pytest.mark.parametrize("a", [0.05, 0.4, 0.9])
@pytest.mark.parametrize("excess", [1e-9, 1e-5, 1e-2])
def test_the_inverse_holds_near_the_boundary(a: float, excess: float) -> None:
    phi = near_boundary(a, excess)
    u = u_map(phi, a)
    assert u > 0.0
    found = amplitude_ratio_for(u, phi)
    # U ~ (a - (1 - phi))^2 near the boundary: a is determined to about sqrt(eps) of the excess
    assert found == pytest.approx(a, rel=0.0, abs=max(1e-15, 1e-7 * excess * a))
    assert u_map(phi, found) == pytest.approx(u, rel=1e-9, abs=0.0)
