"""The small normal equations solved in plain floats
(:func:`~friction_sim.core.physics.numerics.solve_positive_definite`): the
solution of a symmetric positive definite system to its condition number's
rounding, None where the unknowns cannot be told apart."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from friction_sim.core.physics.numerics import solve_positive_definite

_SCALE = st.floats(min_value=1e-6, max_value=1e6)
_ENTRY = st.floats(min_value=-1.0, max_value=1.0)


@given(size=st.integers(1, 4), data=st.data())
def test_a_positive_definite_system_is_solved_to_its_conditioning(size: int, data: st.DataObject) -> None:
    """A = B^T B + s I from random B, s: the residual is rounding's (a backward-stable
    factorization: |A x - b| <= c n eps |A| |x|), and the solution numpy's to cond(A) eps."""
    entries = data.draw(st.lists(_ENTRY, min_size=size * size, max_size=size * size))
    shift, scale = data.draw(_SCALE), data.draw(_SCALE)
    basis = np.array(entries).reshape(size, size)
    matrix = scale * (basis.T @ basis + shift * np.eye(size))
    rhs = np.array(data.draw(st.lists(_ENTRY, min_size=size, max_size=size)))
    solution = solve_positive_definite(matrix.tolist(), rhs.tolist())
    assert solution is not None
    x = np.array(solution)
    eps = np.finfo(float).eps
    norm = float(np.linalg.norm(matrix, 2))
    residual = float(np.linalg.norm(matrix @ x - rhs))
    assert residual <= 8 * size * eps * norm * float(np.linalg.norm(x)) + 8 * size * eps * float(np.linalg.norm(rhs))
    expected = np.linalg.solve(matrix, rhs)
    condition = float(np.linalg.cond(matrix))
    assert np.linalg.norm(x - expected) <= 16 * size * eps * condition * max(float(np.linalg.norm(expected)), 1e-300)


def test_only_the_lower_triangle_is_read() -> None:
    assert solve_positive_definite([[4.0, math.nan], [2.0, 3.0]], [1.0, 2.0]) == solve_positive_definite(
        [[4.0, 2.0], [2.0, 3.0]], [1.0, 2.0])


def test_unknowns_the_data_do_not_tell_apart_give_none() -> None:
    assert solve_positive_definite([[1.0, 1.0], [1.0, 1.0]], [1.0, 1.0]) is None  # singular
    assert solve_positive_definite([[1.0], [1.0, 1.0 + 1e-17]], [1.0, 1.0]) is None  # singular to rounding
    assert solve_positive_definite([[0.0], [0.0, 0.0]], [0.0, 0.0]) is None  # no data at all
    assert solve_positive_definite([[-1.0]], [1.0]) is None  # not positive
    assert solve_positive_definite([[math.nan]], [1.0]) is None
    assert solve_positive_definite([[math.inf]], [1.0]) is None


def test_a_diagonal_system_is_divided_exactly() -> None:
    assert solve_positive_definite([[4.0], [0.0, 0.25]], [2.0, 3.0]) == [0.5, 12.0]
