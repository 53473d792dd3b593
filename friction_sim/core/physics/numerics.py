"""Floating-point primitives written once, to give one result in both engines.

The physics runs interpreted (the single slider) and compiled with Numba (the
population engine); CPython's ``math`` and Numba call the same libm, so the
same operations in the same order give the same bits.  Where they would not,
or where Numba cannot compile the standard function, the operation is written
out here: :func:`hypot` (``math.hypot`` is CPython's own algorithm), :func:`ulp`
(``math.ulp``), and the exact rounding error of a sum (:func:`two_sum`) or a
product.  :func:`sine` takes a float with libm's sin and an array with numpy's,
so the closed forms of a segment's state evaluate at either (:data:`Floats`).
:func:`solve_positive_definite` solves a fit's small normal equations the same
way on every CPU, which ``numpy.linalg`` does not.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

#: A float or an array of floats: what the closed forms of a segment's state take
#: (:func:`~friction_sim.core.physics.roots.harmonic_at`,
#: :func:`~friction_sim.core.physics.segment.evaluate`).  A float is computed with
#: libm's sin (the compiled engine's bits), an array with numpy's, within an ulp or
#: two of libm's: see :func:`sine`.
Floats = TypeVar("Floats", float, NDArray[np.float64])


def two_sum(a: Any, b: Any) -> tuple[Any, Any]:
    """(a + b rounded, its exact rounding error) (Knuth's TwoSum); also works elementwise on arrays."""
    hi = a + b
    bb = hi - a
    return hi, (a - (hi - bb)) + (b - bb)


def sine(x: Floats) -> Floats:
    """sin of a float with libm (``math.sin``, which Numba calls too: one formulation, one
    result in both engines), of an array elementwise with numpy (within an ulp or two of
    libm's, so an array's values may differ from the floats' in their last bits)."""
    return math.sin(x) if isinstance(x, float) else np.sin(x)


def ulp(x: float) -> float:
    """The unit in the last place of x, as math.ulp (which Numba cannot compile; nor
    can Numba before 0.60 compile math.nextafter): 2**(e - 53) for |x| = m*2**e,
    0.5 <= m < 1, and the least subnormal below the least normal number."""
    magnitude = abs(x)
    if magnitude == math.inf:
        return math.inf
    if magnitude < 2.2250738585072014e-308:
        return 5e-324
    return math.ldexp(1.0, math.frexp(magnitude)[1] - 53)


def _split(a: float) -> tuple[float, float]:
    """Veltkamp's split of a (|a| < 2**996) into two halves of 26 bits, exactly."""
    c = 134217729.0 * a  # 2**27 + 1
    high = c - (c - a)
    return high, a - high


def _two_product(a: float, b: float) -> tuple[float, float]:
    """(a*b rounded, its exact rounding error) (Dekker), without an fma."""
    product = a * b
    ah, al = _split(a)
    bh, bl = _split(b)
    return product, ((ah * bh - product) + ah * bl + al * bh) + al * bl


def hypot(a: float, b: float) -> float:
    """sqrt(a*a + b*b), correctly rounded but in rare hard cases, without overflow or
    underflow.  Not math.hypot: CPython computes that its own way (its algorithm
    changes between versions) and Numba calls libm's, which differ in the last bit
    now and then, and one formulation must give one result everywhere.  The sum
    of squares is formed exactly as a double-double (Dekker's products, no fma),
    from operands scaled by a power of two into [0.5, 1), and the square root gets
    one Newton correction from the exact residual."""
    a, b = abs(a), abs(b)
    if a == math.inf or b == math.inf:
        return math.inf
    if a != a or b != b:
        return math.nan
    big, small = (a, b) if a >= b else (b, a)
    if big == 0.0 or small == 0.0:
        return big
    _, exponent = math.frexp(big)
    x, y = math.ldexp(big, -exponent), math.ldexp(small, -exponent)  # exact unless y underflows (then negligible)
    xx, xx_error = _two_product(x, x)
    yy, yy_error = _two_product(y, y)
    total = xx + yy
    bb = total - xx
    low = ((xx - (total - bb)) + (yy - bb)) + (xx_error + yy_error)  # two_sum's error plus the products'
    h = math.sqrt(total + low)
    hh, hh_error = _two_product(h, h)
    h += ((total - hh) + (low - hh_error)) / (2.0 * h)
    return math.ldexp(h, exponent)


#: The spacing of doubles at 1 (2**-52).
_EPSILON = 2.0**-52


def solve_positive_definite(matrix: Sequence[Sequence[float]], rhs: Sequence[float]) -> list[float] | None:
    """x with ``matrix`` x = ``rhs`` for a small symmetric positive definite matrix (the
    normal equations of a fit of a few unknowns), by Cholesky's factorization in plain
    floats, every sum in one fixed order; None if the matrix is not positive definite
    to rounding (a pivot at or below n*eps times its largest diagonal entry: the data
    do not tell the unknowns apart).  Only the lower triangle is read.

    Not ``numpy.linalg``: LAPACK and BLAS run the kernels OpenBLAS picks for the CPU
    when it loads (fused multiply-adds or not, AVX-512 or not), which round differently,
    and a controller's decisions made with them made a different lockstep recording on
    another CPU.  Nor the builtin ``sum``, whose rounding changed in Python 3.12."""
    size = len(rhs)
    diagonal = [float(matrix[i][i]) for i in range(size)]
    largest = max(diagonal)
    if not 0.0 < largest < math.inf:
        return None
    tolerance = size * _EPSILON * largest
    lower: list[list[float]] = []
    for i in range(size):
        row: list[float] = []
        for k in range(i):
            row.append((matrix[i][k] - _dot(row, lower[k])) / lower[k][k])
        pivot = diagonal[i] - _dot(row, row)
        if not pivot > tolerance:
            return None
        row.append(math.sqrt(pivot))
        lower.append(row)
    forward: list[float] = []
    for i in range(size):
        forward.append((rhs[i] - _dot(lower[i], forward)) / lower[i][i])
    solution = forward  # solved in place, from the last unknown up
    for i in reversed(range(size)):
        above = 0.0
        for k in range(i + 1, size):
            above += lower[k][i] * solution[k]
        solution[i] = (forward[i] - above) / lower[i][i]
    return solution


def _dot(a: Sequence[float], b: Sequence[float]) -> float:
    """a . b over the shorter of the two, summed from the first term on."""
    total = 0.0
    for x, y in zip(a, b):
        total += x * y
    return total
