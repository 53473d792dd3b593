"""The dimensionless groups: each is its formula, bit for bit, on floats and arrays alike.

The expressions written out below are the formulas the package wrote inline
before it called the vocabulary (a replaced expression must give the same
bits, so the paper's case and every recorded digest stay as they were).
"""

import math

import numpy as np
import pytest

from friction_sim.core.meanspeed.urelation import u_map
from friction_sim.core.model.dimensionless import (
    TWO_PI,
    amplitude_for,
    amplitude_for_throw,
    amplitude_ratio,
    beats_friction,
    dimensional_speed,
    drive_force_for,
    drive_ratio,
    nondimensional_speed,
    throw_number,
)
from friction_sim.core.model.params import Inputs, SliderParams

RNG = np.random.default_rng(30)
N = 2000
#: Forces of either sign, coefficients and weights over many decades.
FORCE = RNG.uniform(-1.0, 1.0, N) * 10.0 ** RNG.uniform(-6, 6, N)
MU = 10.0 ** RNG.uniform(-6, 1, N)
WEIGHT = 10.0 ** RNG.uniform(-6, 6, N)
RATIO = RNG.uniform(-2.0, 2.0, N)
FREQUENCY = 10.0 ** RNG.uniform(-1, 3, N)
GRAVITY = RNG.uniform(0.1, 30.0, N)

#: Each function with its formula and the columns it takes.
FORMULAS = [
    (drive_ratio, lambda f, mu, w: f / (mu * w), (FORCE, MU, WEIGHT)),
    (drive_force_for, lambda phi, mu, w: phi * mu * w, (RATIO, MU, WEIGHT)),
    (amplitude_ratio, lambda f, w: f / w, (FORCE, WEIGHT)),
    (amplitude_for, lambda a, w: a * w, (RATIO, WEIGHT)),
    (throw_number, lambda pa, nw: pa / nw, (FORCE, WEIGHT)),
    (amplitude_for_throw, lambda gamma, nw: gamma * nw, (RATIO, WEIGHT)),
    (nondimensional_speed, lambda v, f, g, mu: v * f / (g * mu), (FORCE, FREQUENCY, GRAVITY, MU)),
    (dimensional_speed, lambda u, f, g, mu: u * g * mu / f, (RATIO, FREQUENCY, GRAVITY, MU)),
]


def test_two_pi_is_the_double_nearest_two_pi() -> None:
    assert TWO_PI == 2.0 * math.pi == math.tau
    assert math.pi == TWO_PI / 2.0  # (halving is exact)


@pytest.mark.parametrize("function, formula, columns", FORMULAS, ids=[f[0].__name__ for f in FORMULAS])
def test_a_float_gives_the_formulas_float_bit_for_bit(function, formula, columns) -> None:
    for row in zip(*(column.tolist() for column in columns)):
        got = function(*row)
        assert type(got) is float
        assert got == formula(*row), row


@pytest.mark.parametrize("function, formula, columns", FORMULAS, ids=[f[0].__name__ for f in FORMULAS])
def test_arrays_are_their_elements_one_by_one(function, formula, columns) -> None:
    got = function(*columns)
    assert got.shape == (N,)
    assert np.array_equal(got, formula(*columns))
    alone = [function(*row) for row in zip(*(column.tolist() for column in columns))]
    assert np.array_equal(got, alone)
    # a scalar beside an array broadcasts (a column of ratios, one plant)
    first = [column[0] for column in columns[:-1]]
    assert np.array_equal(function(*first, columns[-1]), formula(*first, columns[-1]))


def test_the_inverses_undo_their_groups() -> None:
    # phi*mu*w and f/(mu*w): four roundings of at most 2**-53 each, within 4.5e-16 relative of the start
    assert np.allclose(drive_ratio(drive_force_for(RATIO, MU, WEIGHT), MU, WEIGHT), RATIO, rtol=5e-16, atol=0)
    # a*w and p/w: two roundings, within 2.3e-16
    assert np.allclose(amplitude_ratio(amplitude_for(RATIO, WEIGHT), WEIGHT), RATIO, rtol=2.3e-16, atol=0)
    assert np.allclose(throw_number(amplitude_for_throw(RATIO, WEIGHT), WEIGHT), RATIO, rtol=2.3e-16, atol=0)


def test_dimensional_round_trip() -> None:
    """(Moved from test_urelation, where U <-> V lived.)"""
    f, g, mu = 50.0, 10.0, 0.1
    u = u_map(0.7, 0.5)
    v = dimensional_speed(u, f, g, mu)
    assert v == pytest.approx(u * g * mu / f, rel=1e-15)
    assert nondimensional_speed(v, f, g, mu) == pytest.approx(u, rel=1e-15)
    assert nondimensional_speed(v, f, g, mu) == pytest.approx(v * f / (g * mu), rel=1e-15)
    # rtol 1e-15 below: two multiplications and a division each way, <= 1.5 ulp (3.3e-16) apart
    us = np.array([[0.0, 1e-3], [-2e-2, 0.5]])
    vs = dimensional_speed(us, 33.0, 9.81, 0.25)
    assert vs.shape == (2, 2)
    assert np.allclose(nondimensional_speed(vs, 33.0, 9.81, 0.25), us, rtol=1e-15, atol=0)
    assert np.allclose(vs, us * 9.81 * 0.25 / 33.0, rtol=1e-15, atol=0)
    assert type(nondimensional_speed(1e-3, 50.0, 10.0, 0.1)) is float
    assert type(dimensional_speed(0.01, 50.0, 10.0, 0.1)) is float


def test_the_papers_case_in_its_groups() -> None:
    """Kostek's Fig. 2: Fd = 0.7 N, Pa = 5 N on 1 kg at g = 10, mu = 0.1: phi = 0.7, a = Gamma = 0.5."""
    params, inputs = SliderParams(), Inputs()
    assert drive_ratio(inputs.drive_force, params.mu, params.weight) == 0.7 / (0.1 * 10.0)
    assert amplitude_ratio(inputs.excitation_amplitude, params.weight) == 0.5
    assert throw_number(inputs.excitation_amplitude, params.normal_weight) == 0.5


def test_the_runaway_rule_is_strict_on_arrays_too() -> None:
    """|pull| > mu*load, not >=: at the boundary the slider does not run away (elementwise)."""
    edge = math.nextafter(1.0, 2.0)
    pulls = np.array([1.0, -1.0, edge, -edge, 0.0])
    assert beats_friction(pulls, 10.0, 0.1).tolist() == [False, False, True, True, False]
    assert beats_friction(1.0, 10.0, 0.1) is False and beats_friction(edge, 10.0, 0.1) is True
