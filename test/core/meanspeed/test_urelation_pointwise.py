"""The U relation at one point (friction_sim.core.meanspeed.kostek) and over arrays.

The formulas of U(phi, a) and its inverses are written once, as functions of
plain floats: a call with scalars evaluates them directly (the controller
inverts once per period, where numpy's per-operation cost on one-element
arrays took milliseconds), a call with arrays applies them element by
element.  So an element's value is the one it gets alone, bit for bit, in
whatever array it comes; the functions stay in the subset Numba compiles, and
compiled they give the same bits (Numba calls the same libm).  The inverses
are checked against mpmath here (the forward map in test_urelation_precision.py).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from friction_sim.core.meanspeed import kostek, urelation
from friction_sim.core.meanspeed.urelation import (
    amplitude_ratio_for,
    drive_ratio_for,
    moves,
    slip_start_phase,
    stop_phase_advance,
    u_map,
)

from reference_exact import high_precision_slip, high_precision_u

EPS = float(np.finfo(float).eps)


def points(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(phi, a): half anywhere (both signs, beyond |phi| = 1 too), half near the
    motion boundary (1e-15 to 1 of a beyond it), and the special values."""
    rng = np.random.default_rng(seed)
    a_near = rng.uniform(1e-4, 0.9999, count)
    phi_near = (1.0 - a_near) + 10.0 ** rng.uniform(-15, 0, count) * a_near
    phi_near[::3] *= -1.0
    special_phi = np.array([0.0, -0.0, 1.0, -1.0, math.nextafter(1.0, 0.0), math.nextafter(1.0, 2.0), math.nan,
                            math.inf, -math.inf, 0.7, -0.3])
    special_a = np.array([0.0, 5e-324, 0.5, math.nextafter(1.0, 0.0)])
    grid_phi, grid_a = np.meshgrid(special_phi, special_a)
    phi = np.concatenate([rng.uniform(-1.2, 1.2, count), phi_near, grid_phi.ravel()])
    a = np.concatenate([rng.uniform(0.0, 0.999, count), a_near, grid_a.ravel()])
    return phi, a


def same_bits(array: Any, alone: list[Any]) -> bool:
    """Equal element by element, NaN where NaN, and zeros of the same sign."""
    values = np.asarray(array)
    expected = np.asarray(alone, dtype=values.dtype)
    if values.dtype == bool:
        return bool(np.array_equal(values, expected))
    return bool(np.array_equal(values, expected, equal_nan=True)
                and np.array_equal(np.signbit(values), np.signbit(expected)))


def alone(function: Callable[..., Any], *arrays: np.ndarray) -> list[Any]:
    """``function`` called on each element as Python floats, one call per point."""
    return [function(*(float(value) for value in values)) for values in zip(*arrays)]


def test_every_element_has_the_bits_it_gets_alone() -> None:
    phi, a = points(400, 23)
    for function in (u_map, stop_phase_advance, slip_start_phase, moves):
        together = function(phi, a)
        assert same_bits(together, alone(function, phi, a)), function.__name__
        assert same_bits(function(phi[::-1], a[::-1])[::-1], list(together)), function.__name__
    u = np.asarray(u_map(phi, a))
    moving = np.isfinite(u) & (u != 0.0)
    targets = np.concatenate([u[moving], 1.01 * u[moving], -u[moving], [0.0, -0.0, math.nan, math.inf]])
    drives = np.concatenate([phi[moving], phi[moving], phi[moving], [0.7, 0.7, 0.7, 0.7]])
    for top in (1.0, 0.95, 0.5):
        together = amplitude_ratio_for(targets, drives, top)
        assert same_bits(together, alone(amplitude_ratio_for, targets, drives, np.full(targets.size, top)))
        assert np.any(np.isfinite(together)) and np.any(np.isnan(together))
    ratios = np.concatenate([a[moving], a[moving], [0.5, 0.5, 0.5, 0.5]])
    speeds = np.concatenate([u[moving], -0.5 * u[moving], [0.0, -0.0, math.nan, 1.0]])
    assert same_bits(drive_ratio_for(speeds, ratios), alone(drive_ratio_for, speeds, ratios))


def test_broadcast_arrays_are_their_points_one_by_one() -> None:
    phi = np.linspace(-1.1, 1.1, 23)[:, None]
    a = np.linspace(0.0, 0.98, 9)[None, :]
    together = u_map(phi, a)
    assert together.shape == (23, 9)
    assert same_bits(together.ravel(), [u_map(float(p), float(r)) for p in phi[:, 0] for r in a[0]])
    inverse = amplitude_ratio_for(np.array([[0.001], [0.002]]), np.array([0.7, -0.8, 0.9]))
    assert inverse.shape == (2, 3)
    assert same_bits(inverse.ravel(), [amplitude_ratio_for(u, p) for u in (0.001, 0.002) for p in (0.7, -0.8, 0.9)])
    assert u_map(np.zeros((0, 3)), 0.5).shape == (0, 3)
    assert moves(np.array([0.2, 0.7]), 0.5).dtype == bool


def test_scalar_calls_evaluate_the_formulas_directly(monkeypatch: pytest.MonkeyPatch) -> None:
    """No numpy arrays on the controller's path: that is what made it slow."""

    def refuse(*_: Any) -> Any:
        raise AssertionError("a scalar call went through the array path")

    monkeypatch.setattr(urelation, "_elementwise", refuse)
    u = u_map(0.7, 0.5)
    assert type(u) is float and type(u_map(np.float64(0.7), np.float32(0.5))) is float
    assert type(amplitude_ratio_for(u, 0.7, 0.95)) is float and type(drive_ratio_for(u, 0.5)) is float
    assert type(stop_phase_advance(0.7, 0.5)) is float and type(slip_start_phase(np.array(0.7), 0.5)) is float
    assert moves(0.7, 0.5) is True and moves(0.3, 0.5) is False


@pytest.mark.parametrize(("phi", "a"), [(0.7, a) for a in (0.35, 0.5, 0.65, 0.8, 0.9)] + [
    (0.999, 0.3), (0.9999999, 0.9), (0.999999, 0.01),                  # near phi = 1
    (0.5 + 1e-9 * 0.5, 0.5), (0.1 + 1e-5 * 0.9, 0.9), (0.95 + 1e-3 * 0.05, 0.05),  # near the boundary
])
def test_the_inverses_meet_the_exact_relation(phi: float, a: float) -> None:
    """The a (and the phi) found for an exact U (mpmath, rounded once) give that
    U exactly (mpmath again) to the map's 1e-12 plus what 9 ulps of the answer
    move U by (its stopping and rounding; test_drive_ratio.py explains the 9),
    with the exact slopes dU/da = (sin thA*(1 - cos psi_C) + cos thA*(psi_C - sin
    psi_C))/(4 pi^2) and dU/dphi = psi_C**2/(8 pi^2)."""
    import mpmath

    u = high_precision_u(phi, a)
    assert u > 0.0
    found = amplitude_ratio_for(u, phi, 0.99)
    theta, psi, _ = high_precision_slip(phi, found)
    slope_a = float((mpmath.sin(theta) * (1 - mpmath.cos(psi)) + mpmath.cos(theta) * (psi - mpmath.sin(psi)))
                    / (4 * mpmath.pi**2))
    assert abs(high_precision_u(phi, found) - u) <= 1e-12 * u + 9.0 * slope_a * math.ulp(found)
    assert amplitude_ratio_for(-u, -phi, 0.99) == found
    found_phi = drive_ratio_for(u, a)
    _, psi, _ = high_precision_slip(found_phi, a)
    slope_phi = float(psi * psi / (8 * mpmath.pi**2))
    assert abs(high_precision_u(found_phi, a) - u) <= 1e-12 * u + 9.0 * slope_phi * math.ulp(found_phi)
    assert drive_ratio_for(-u, a) == -found_phi


def test_the_formulas_compile_with_numba_to_the_same_bits() -> None:
    """Written in the subset Numba compiles, like the slider's physics: compiled
    over whole arrays they give what the interpreted functions give, bit for bit
    (the nodes never import Numba; this only keeps the promise checked)."""
    import numba  # (a dependency of the package: requirements.txt; imported here, not by the module)
    from numba.extending import register_jitable

    import friction_sim.core.engine.compiled  # noqa: F401 - registers the physics (roots) with Numba

    for function in vars(kostek).values():
        if inspect.isfunction(function) and function.__module__ == kostek.__name__:
            register_jitable(function)

    @numba.njit
    def compiled_u(phi: np.ndarray, a: np.ndarray, out: np.ndarray) -> None:
        for i in range(phi.size):
            out[i] = kostek.u_of(phi[i], a[i])

    @numba.njit
    def compiled_inverses(u: np.ndarray, phi: np.ndarray, a: np.ndarray, top: float, ratio: np.ndarray,
                          drive: np.ndarray) -> None:
        for i in range(u.size):
            ratio[i] = kostek.amplitude_ratio(u[i], phi[i], top)
            drive[i] = kostek.drive_ratio(u[i], a[i])

    phi, a = points(300, 5)
    u = np.empty(phi.size)
    compiled_u(phi, a, u)
    assert same_bits(u, list(u_map(phi, a)))
    ratio, drive = np.empty(phi.size), np.empty(phi.size)
    compiled_inverses(u, phi, a, 0.95, ratio, drive)
    assert same_bits(ratio, list(amplitude_ratio_for(u, phi, 0.95)))
    assert same_bits(drive, list(drive_ratio_for(u, a)))
