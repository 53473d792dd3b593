"""Exact numbers for the reference's exactness checks at the last bits.

:func:`high_precision_u` and :func:`high_precision_slip` evaluate the
periodic slip's textbook closed form (asin start, bracketed root of the
speed, integral of the speed) in mpmath at many digits, from the exact values
of the given floats; :func:`paper_case_slip` gives a plant's slip start and
travel per period from them, and :func:`ulps_from_exact` the distance of
float times from such exact instants, in ulps, without rounding that
matters.  mpmath is a test dependency only and is imported lazily; importing
this module needs numpy alone.  Like test/reference.py it shares nothing
with friction_sim's core.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    'high_precision_u',
    'high_precision_slip',
    'paper_case_slip',
    'ulps_from_exact',
]


def high_precision_slip(phi: float, a: float, dps: int = 80) -> tuple[Any, Any, Any]:
    """``(theta_A, psi_C, U)`` of the periodic slip for 1 - a < phi < 1 in mpmath
    at ``dps`` digits: the start phase asin((1 - phi)/a), the phase the slip
    lasts (root of w(psi) = (phi - 1)*psi + a*(cos thA - cos(thA + psi)) on
    (pi - 2*thA, 2*pi]) and U = D/(4*pi^2), D = the integral of w up to psi_C.
    The textbook form, with its cancellations: the many digits pay for them.
    """
    import mpmath

    with mpmath.workdps(dps):
        phi_, a_ = mpmath.mpf(phi), mpmath.mpf(a)
        if not (0 < a_ < 1 and 1 - a_ < phi_ < 1):
            raise ValueError(f'need 1 - a < phi < 1 and 0 < a < 1, got phi={phi!r}, a={a!r}')
        p = phi_ - 1
        theta = mpmath.asin((1 - phi_) / a_)
        cos_a, sin_a = mpmath.cos(theta), mpmath.sin(theta)

        def speed(psi: Any) -> Any:
            return p * psi + a_ * (cos_a - mpmath.cos(theta + psi))

        lo, hi = mpmath.pi - 2 * theta, 2 * mpmath.pi
        # Bisection to a few digits (w falls monotonically on the bracket),
        # then the secant method to full precision.
        for _ in range(60):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if speed(mid) > 0 else (lo, mid)
        psi_c = mpmath.findroot(speed, (lo, hi), solver='secant', tol=mpmath.mpf(10) ** (-dps + 5))
        travel = p * psi_c**2 / 2 + a_ * (psi_c * cos_a - mpmath.sin(theta + psi_c) + sin_a)
        return theta, psi_c, travel / (4 * mpmath.pi**2)


def high_precision_u(phi: float, a: float, dps: int = 80) -> float:
    """U(phi, a) in mpmath (see :func:`high_precision_slip`), rounded to a float;
    0 for |phi| <= 1 - a, a/(2*pi) at |phi| = 1, inf beyond, sign of phi."""
    import mpmath

    sign = -1.0 if phi < 0 else 1.0
    with mpmath.workdps(dps):
        phi_, a_ = abs(mpmath.mpf(phi)), mpmath.mpf(a)
        if phi_ <= 1 - a_:
            return 0.0 * sign
        if phi_ == 1:
            return sign * float(a_ / (2 * mpmath.pi))
        if phi_ > 1:
            return sign * math.inf
        return sign * float(high_precision_slip(abs(phi), a, dps)[2])


def paper_case_slip(mass: float = 1.0, mu: float = 0.1, gravity: float = 10.0, drive_force: float = 0.7,
                    excitation_amplitude: float = 5.0, excitation_frequency: float = 50.0,
                    ) -> tuple[tuple[float, float], float, float]:
    """``(theta_A/(2*pi) as a double-double (hi, lo), theta_A, D [m])`` of the
    periodic slip of a plant (default: the paper's Fig. 2 case), from the exact
    values of its floats: the slip of period n starts at t0 + (n + theta_A/(2*pi))/f
    and every period moves the slider by D."""
    import mpmath

    with mpmath.workdps(80):
        mu_, m, g = mpmath.mpf(mu), mpmath.mpf(mass), mpmath.mpf(gravity)
        fd, pa, f = mpmath.mpf(drive_force), mpmath.mpf(excitation_amplitude), mpmath.mpf(excitation_frequency)
        theta, _, u = high_precision_slip(fd / (mu_ * m * g), pa / (m * g))
        travel = u * g * mu_ / f**2  # U = V*f/(g*mu), V = D*f
        fraction = theta / (2 * mpmath.pi)
        return (float(fraction), float(fraction - float(fraction))), float(theta), float(travel)


def _split(a: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    c = 134217729.0 * a  # 2**27 + 1 (Veltkamp)
    hi = c - (c - a)
    return hi, a - hi


def _two_product(a: float, b: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(a*b rounded, its exact error) elementwise (Dekker)."""
    p = a * b
    ah, al = _split(np.full_like(b, a))
    bh, bl = _split(b)
    return p, ((ah * bh - p) + ah * bl + al * bh) + al * bl


def ulps_from_exact(times: ArrayLike, t0: float, frequency: float, cycles: ArrayLike,
                    fraction: tuple[float, float]) -> NDArray[np.float64]:
    """|t - exact| / ulp(t) for float times t whose exact values are
    t0 + (cycles + fraction)/frequency, ``fraction`` a double-double (hi, lo).

    Computed without rounding that matters: t - t0 is exact (t0 == 0, or t in
    [t0, 2*t0]: Sterbenz's lemma; checked), frequency*(t - t0) is split exactly
    (Dekker's product), and its difference from the integer ``cycles`` is exact
    again, so an error of a fraction of an ulp reads as such.
    """
    t = np.asarray(times, dtype=float)
    n = np.asarray(cycles, dtype=float)
    d = t - t0
    if not (np.all(d + t0 == t) and np.all(d >= 0.0)):
        raise ValueError('times must lie in [t0, 2*t0] (or t0 == 0) for t - t0 to be exact')
    p, p_err = _two_product(frequency, d)
    off = ((p - n) - fraction[0]) + (p_err - fraction[1])
    result: NDArray[np.float64] = np.abs(off / frequency) / np.spacing(t)
    return result
