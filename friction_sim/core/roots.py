"""Event detection: when the next event happens, as pure functions of one
segment's data (the slider acts on them; see :mod:`friction_sim.core.slider`).

A stuck slider starts to slip where |Ft| rises above mu*R, found in closed
form with asin (:func:`next_slip_start`); a slip stops where its speed w
returns to zero, a root bracketed on the first falling stretch of w that
ends at or below zero and polished to full precision
(:func:`slip_stop_delay`).  On the motion boundary the decision whether the
slider can move at all is exact (:func:`can_ever_slip`).
"""

from __future__ import annotations

import math
from fractions import Fraction
from types import ModuleType
from typing import Any

import numpy as np

from friction_sim.core.params import Inputs, SliderParams

TWO_PI = 2.0 * math.pi
NEVER = math.inf


#: Phase tolerance [rad] below which a rounding-level distance from the slip
#: window's edge counts as being on the edge (a full period is never skipped).
_PHASE_EDGE = 1e-12
#: Slips predicted to last longer than this many excitation periods never stop.
_LONGEST_SLIP = 1e12


def next_slip_start(phase: float, b0: float, b1: float, *, closing: bool = False) -> tuple[float, float]:
    """``(delta, start)``: the phase still to run until a stuck slider starts to
    slip (0: at once, ``inf``: never), seen from excitation phase ``phase``,
    and the phase in [0, 2*pi) at which it starts.

    ``b0`` and ``b1`` >= 0 are the coefficients the slip would have in its
    direction s = sign(Ft): dw/dt = b0 + b1*sin(theta) with
    b0 = (|Ft| - mu*(m*g + Fz))/m and b1 = mu*Pa/m.  The slider is stuck
    exactly while that would be <= 0 (|Ft| <= mu*R), so the slip window is
    (beta, pi - beta) with beta = asin(-b0/b1), the same expression
    :func:`slip_stop_delay` uses: onset and stop can never disagree.

    ``closing`` is set for a slider that has just come to rest from a slip in
    the same direction.  It stopped because it was decelerating, so on the
    closing side of the window (where mu*R rises again, cos(theta) <= 0) an
    at-once restart could only come from rounding; it waits for the window to
    open again instead.  That guarantees progress at the window's closing edge.
    """
    if b1 <= 0.0:
        return (0.0, phase) if b0 > 0.0 and not closing else (NEVER, NEVER)
    if b0 + b1 <= 0.0:
        return NEVER, NEVER
    closing = closing and math.cos(phase) <= 0.0
    if b0 + b1 * math.sin(phase) > 0.0 and not closing:
        return 0.0, phase
    ratio = -b0 / b1
    if ratio < -1.0:  # the window covers every phase; only rounding kept us here
        return (TWO_PI, phase) if closing else (0.0, phase)
    start = math.asin(ratio) % TWO_PI
    if start >= TWO_PI:  # -tiny % 2*pi rounds to 2*pi: the start is at phase 0
        start = 0.0
    delta = (start - phase) % TWO_PI
    if closing:
        return (delta, start) if delta > 0.0 else (TWO_PI, start)
    if delta > TWO_PI - _PHASE_EDGE:  # a hair past the edge: starts now
        return 0.0, phase
    return delta, start


def can_ever_slip(params: SliderParams, inputs: Inputs) -> bool:
    """Whether |Ft| > mu*(m*g - Fz - Pa): the slider can slip at some phase (Kostek's model).

    Decided in exact rational arithmetic on the given binary values, so that a
    slider on the motion boundary phi = 1 - a (up to its last bit) never
    moves, not even by a rounding-sized step.
    """
    excess_f = abs(inputs.tangential_force)
    least_f = params.weight - inputs.external_force_z - inputs.excitation_amplitude
    margin = excess_f - params.mu * least_f
    if abs(margin) > 1e-9 * (excess_f + params.mu * abs(least_f)):  # clear either way
        return margin > 0.0
    excess = abs(Fraction(inputs.drive_force) + Fraction(inputs.external_force_x))
    least_load = (
        Fraction(params.mass) * Fraction(params.gravity)
        - Fraction(inputs.external_force_z) - Fraction(inputs.excitation_amplitude)
    )
    return excess > Fraction(params.mu) * least_load


def slip_stop_delay(w0: float, b0: float, b1: float, phase0: float, omega: float) -> float:
    """Time until the speed w = s*v of a slip returns to zero (``inf``: never).

    ``w0`` >= 0 is the speed at the start, ``b0`` and ``b1`` >= 0 the constant
    and sinusoidal parts of dw/dt = b0 + b1*sin(phase0 + omega*tau).  A slip
    predicted to last more than ``_LONGEST_SLIP`` excitation periods is taken
    as endless (its drift b0 is then within rounding of zero).
    """
    b0 = from_rest_b0(w0, b0, b1, math.sin(phase0))
    if b1 <= 0.0:
        if b0 >= 0.0:
            return NEVER
        return w0 / -b0
    if b0 >= b1:  # dw/dt >= 0 everywhere: it never comes back
        return NEVER
    if b0 <= -b1:  # dw/dt <= 0 everywhere: one falling stretch from now on
        if w0 == 0.0:
            return 0.0
        hi = (w0 + (b1 / omega) * (1.0 + math.cos(phase0))) / -b0
        if not hi * omega <= TWO_PI * _LONGEST_SLIP:  # (also when hi overflows to inf)
            return NEVER
        return _falling_root(w0, b0, b1, phase0, omega, 0.0, hi)
    return _stop_with_turning_points(w0, b0, b1, phase0, omega)


def _stop_with_turning_points(w0: float, b0: float, b1: float, phase0: float, omega: float) -> float:
    """slip_stop_delay for |b0| < b1, where w rises and falls once per period.

    In delta = phase - beta (beta = asin(-b0/b1), where w has its minimum)
    w rises on (0, pi - 2*beta) and falls on [pi - 2*beta, 2*pi], and so on
    every period; the minima (at delta = 2*pi*k) differ by exactly b0*T.
    """
    beta = math.asin(-b0 / b1)
    rise = math.pi - 2.0 * beta
    delta0 = (phase0 - beta) % TWO_PI
    if w0 == 0.0:
        if delta0 > TWO_PI - _PHASE_EDGE:
            delta0 = 0.0
        if delta0 >= rise:  # would start from rest while decelerating
            return 0.0
    period = TWO_PI / omega
    lo = max(0.0, (rise - delta0) / omega)
    hi = (TWO_PI - delta0) / omega
    k, cos0, sin0 = b1 / omega, math.cos(phase0), math.sin(phase0)
    g0 = initial_slope(w0, b0, b1, phase0)
    w_min = _speed(w0, g0, k, cos0, sin0, omega, hi)
    if w_min > 0.0:
        if b0 >= 0.0:  # the minima only grow: never back to rest
            return NEVER
        estimate = w_min / (-b0 * period)
        if not estimate <= _LONGEST_SLIP:  # (also when it overflows to inf)
            return NEVER
        hi += max(1, math.ceil(estimate)) * period
        for _ in range(8):  # rounding guard: the formula's period may be one short
            if _speed(w0, g0, k, cos0, sin0, omega, hi) <= 0.0:
                break
            hi += period
        else:
            return NEVER
        lo = hi - (TWO_PI - rise) / omega
    return _falling_root(w0, b0, b1, phase0, omega, lo, hi)


def initial_slope(w0: float, b0: float, b1: float, phase0: float) -> float:
    """dw/dt at the start of a slip (b0 must come from :func:`from_rest_b0`)."""
    return b0 + b1 * math.sin(phase0)


def from_rest_b0(w0: float, b0: float, b1: float, sin0: float) -> float:
    """b0 as a slip from rest sees it.  A slip that starts from rest cannot
    start decelerating, so at the slip window's edge a rounding-sized negative
    slope b0 + b1*sin(phase0) is taken as zero, by moving b0 by that rounding
    residue; using the adjusted b0 everywhere keeps the slip's long-run drift
    b0 consistent with its start."""
    if w0 == 0.0 and b0 + b1 * sin0 < 0.0:
        return -b1 * sin0
    return b0


def trig_remainders(psi: Any, xp: ModuleType = math) -> tuple[Any, Any, Any]:
    """(1 - cos psi, psi - sin psi, psi**2/2 - (1 - cos psi)) without cancellation.

    Writing the motion with these remainders keeps tiny slips (at the motion
    boundary, or just after an event) accurate to the last bits, so a forward
    slip never shows a rounding-sized step backwards.  Taylor series below
    |psi| = 0.25 (truncation < 1e-18 relative); ``xp`` is math or numpy.
    """
    half = xp.sin(0.5 * psi)
    c1 = 2.0 * half * half
    p2 = psi * psi
    if xp is math and abs(psi) >= 0.25:
        return c1, psi - math.sin(psi), 0.5 * p2 - c1
    s2_series = psi * p2 * (1 / 6 - p2 * (1 / 120 - p2 * (1 / 5040 - p2 * (
        1 / 362880 - p2 * (1 / 39916800 - p2 / 6227020800)))))
    c2_series = p2 * p2 * (1 / 24 - p2 * (1 / 720 - p2 * (1 / 40320 - p2 * (
        1 / 3628800 - p2 * (1 / 479001600 - p2 / 87178291200)))))
    if xp is math:
        return c1, s2_series, c2_series
    small = np.abs(psi) < 0.25
    return c1, np.where(small, s2_series, psi - np.sin(psi)), np.where(small, c2_series, 0.5 * p2 - c1)


def two_sum(a: Any, b: Any) -> tuple[Any, Any]:
    """(a + b rounded, its exact rounding error) (Knuth's TwoSum), for floats
    or numpy arrays alike."""
    hi = a + b
    bb = hi - a
    return hi, (a - (hi - bb)) + (b - bb)


def _speed(w0: float, g0: float, k: float, cos0: float, sin0: float, omega: float, tau: float) -> float:
    """w(tau) of a slip segment: w0 + g0*tau + k*(cos0*(1 - cos psi) - sin0*(psi - sin psi))."""
    c1, s2, _ = trig_remainders(omega * tau)
    speed: float = w0 + g0 * tau + k * (cos0 * c1 - sin0 * s2)
    return speed


def _falling_root(
    w0: float, b0: float, b1: float, phase0: float, omega: float, lo: float, hi: float
) -> float:
    """The root of w on [lo, hi], where w is monotone with w(lo) > 0 >= w(hi).

    Newton's method from the secant point, with every iterate kept inside the
    shrinking bracket (bisection when Newton would leave it), to full double
    precision.
    """
    k, cos0, sin0 = b1 / omega, math.cos(phase0), math.sin(phase0)
    g0 = initial_slope(w0, b0, b1, phase0)
    w_lo = _speed(w0, g0, k, cos0, sin0, omega, lo)
    w_hi = _speed(w0, g0, k, cos0, sin0, omega, hi)
    if w_hi >= 0.0:
        return hi
    if w_lo <= 0.0:
        return lo
    tau = lo + (hi - lo) * (w_lo / (w_lo - w_hi))
    sin = math.sin
    for _ in range(200):
        psi = omega * tau
        if psi >= 0.25:  # _speed inlined: this loop is the hot path of the periodic regime
            half = sin(0.5 * psi)
            w = w0 + g0 * tau + k * (cos0 * 2.0 * half * half - sin0 * (psi - sin(psi)))
        else:
            w = _speed(w0, g0, k, cos0, sin0, omega, tau)
        if w > 0.0:
            lo = tau
        elif w < 0.0:
            hi = tau
        else:
            return tau
        slope = b0 + b1 * sin(phase0 + psi)
        step = tau - w / slope if slope < 0.0 else math.nan
        if not lo < step < hi:
            step = 0.5 * (lo + hi)
        if step == tau or abs(step - tau) <= 2.2e-16 * abs(tau):
            return step
        tau = step
    return tau
