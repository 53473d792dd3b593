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


# --------------------------------------------------------------------------
# Flight: when the height returns to zero.
# --------------------------------------------------------------------------

#: A flight still in the air after this many turning points of its vertical
#: speed (two per excitation period) is taken as endless: its mean vertical
#: acceleration is then within rounding of zero.
_LONGEST_FLIGHT_PIECES = 2_000_000


class Harmonic:
    """The closed form of a speed under dw/dt = b0 + b1*sin(phase0 + omega*tau)
    with w(0) = w0, and of its integral from ``start``: a slip's speed and
    travel, a flight's tangential velocity and position, its vertical velocity
    and height.  Written with :func:`trig_remainders`, so a short stretch keeps
    its last bits (the same form as Kostek's slip in :mod:`friction_sim.core.kostek`)."""

    __slots__ = ("w0", "b0", "b1", "phase0", "omega", "g0", "k", "kk", "cos0", "sin0", "start")

    def __init__(self, w0: float, b0: float, b1: float, phase0: float, omega: float, start: float = 0.0) -> None:
        self.w0, self.b0, self.b1, self.phase0, self.omega, self.start = w0, b0, b1, phase0, omega, start
        self.cos0, self.sin0 = math.cos(phase0), math.sin(phase0)
        self.g0 = b0 + b1 * self.sin0
        self.k = b1 / omega
        self.kk = self.k / omega

    def rate(self, tau: Any, xp: ModuleType = math) -> Any:
        """dw/dt at ``tau``."""
        return self.b0 + self.b1 * xp.sin(self.phase0 + self.omega * tau)

    def at(self, tau: Any, xp: ModuleType = math) -> tuple[Any, Any]:
        """(w, start + integral of w) at ``tau``; floats or numpy arrays."""
        c1, s2, c2 = trig_remainders(self.omega * tau, xp)
        w = self.w0 + self.g0 * tau + self.k * (self.cos0 * c1 - self.sin0 * s2)
        return w, self.start + (self.w0 * tau + 0.5 * self.g0 * tau * tau + self.kk * (self.cos0 * s2 - self.sin0 * c2))

    def speed(self, tau: float) -> float:
        """w at ``tau`` (the root finders' hot path: no integral)."""
        c1, s2, _ = trig_remainders(self.omega * tau)
        speed: float = self.w0 + self.g0 * tau + self.k * (self.cos0 * c1 - self.sin0 * s2)
        return speed

    def travel(self, tau: float) -> float:
        """start + the integral of w at ``tau``."""
        height: float = self.at(tau)[1]
        return height


def _polish(f: Any, df: Any, lo: float, hi: float, f_lo: float, f_hi: float) -> float:
    """The root of a monotone ``f`` on [lo, hi], f(lo) and f(hi) of opposite
    signs (or zero): Newton kept inside the shrinking bracket, bisection when
    it would leave it, to full double precision."""
    if f_lo == 0.0:
        return lo
    if f_hi == 0.0:
        return hi
    if (f_lo > 0.0) == (f_hi > 0.0):  # no sign change: rounding at an end (values far above their root's scale)
        return lo if abs(f_lo) <= abs(f_hi) else hi
    rising = f_hi > 0.0
    tau = lo + (hi - lo) * (f_lo / (f_lo - f_hi))
    for _ in range(200):
        value = f(tau)
        if value == 0.0:
            return tau
        if (value > 0.0) == rising:
            hi = tau
        else:
            lo = tau
        slope = df(tau)
        step = tau - value / slope if slope != 0.0 else math.nan
        if not lo < step < hi:
            step = 0.5 * (lo + hi)
        if step == tau or abs(step - tau) <= 2.2e-16 * abs(tau):
            return step
        tau = step
    return tau


class _TurningPoints:
    """The times tau > 0 at which dz/dt has a turning point (b0 + b1*sin = 0),
    in order (:meth:`next`), each with True where it is a minimum of dz/dt."""

    def __init__(self, b0: float, b1: float, phase0: float, omega: float) -> None:
        low = math.asin(-b0 / b1)  # sin rises through -b0/b1: minimum of the speed
        self.marks = sorted(((low % TWO_PI, True), ((math.pi - low) % TWO_PI, False)))
        self.phase0, self.omega = phase0, omega
        self.base = phase0 - phase0 % TWO_PI
        self.n, self.i = 0, 0

    def next(self) -> tuple[float, bool]:
        while True:
            mark, is_min = self.marks[self.i]
            tau = (self.base + TWO_PI * self.n + mark - self.phase0) / self.omega
            self.i += 1
            if self.i == 2:
                self.n, self.i = self.n + 1, 0
            if tau > 0.0:
                return tau, is_min

    def skip_to(self, tau: float) -> None:
        """Go on from the period that holds time ``tau``."""
        self.n = max(self.n, math.floor((self.phase0 + self.omega * tau - self.base) / TWO_PI))
        self.i = 0


def _safe_stretch(h: Harmonic) -> tuple[float, float]:
    """(tau1, tau2): while tau1 < tau < tau2 the height is surely above 0, for a
    flight whose mean acceleration b0 < 0 pulls it back (empty: (inf, -inf)).

    z = z0 + (vz0 + b1*cos(phase0)/omega)*tau + b0*tau**2/2 + an oscillation of
    amplitude at most 2*b1/omega**2, so z > 0 wherever that parabola is above
    twice the oscillation (with a margin for rounding).  A long flight (a
    throw number of 1e5 flies for thousands of periods) skips that stretch
    instead of walking it turning point by turning point.
    """
    margin = 4.0 * h.b1 / (h.omega * h.omega) * (1.0 + 1e-6)
    slope = h.w0 + h.k * h.cos0
    a, b, c = 0.5 * h.b0, slope, h.start - margin
    disc = b * b - 4.0 * a * c
    if not (h.b0 < 0.0 and disc > 0.0):
        return NEVER, -NEVER
    root = math.sqrt(disc)
    tau1, tau2 = sorted(((-b + root) / (2.0 * a), (-b - root) / (2.0 * a)))
    return tau1, tau2


def landing_delay(vz0: float, b0: float, b1: float, phase0: float, omega: float, z0: float = 0.0) -> float:
    """Time until a flight's height z returns to 0 (``inf``: never), for a
    flight that starts at height ``z0`` >= 0 with dz/dt = ``vz0`` (>= 0 when
    z0 = 0) under d2z/dt2 = b0 + b1*sin(phase0 + omega*tau), b1 >= 0.

    Every root is bracketed: dz/dt is monotone between the turning points of
    the acceleration (closed form), so its zeros are bracketed; z is monotone
    between those, so the first stretch on which z falls to <= 0 holds the
    landing, which is then polished to full precision.  A near-tangent landing
    (z just grazing 0 at a minimum) is found as long as the minimum is <= 0.
    The stretch of a long flight where z is surely positive is skipped
    (:func:`_safe_stretch`), so the cost does not grow with the flight's length.
    """
    h = Harmonic(vz0, b0, b1, phase0, omega, z0)
    if b1 <= 0.0 or abs(b0) >= b1:  # the acceleration never changes sign
        if b0 >= 0.0:
            return NEVER
        return _fall_from(h, _apex(h, 0.0, vz0))
    safe_from, safe_to = _safe_stretch(h)
    period = TWO_PI / omega
    lo, v_lo = 0.0, vz0
    points = _TurningPoints(b0, b1, phase0, omega)
    for _ in range(_LONGEST_FLIGHT_PIECES):
        tau, is_min = points.next()
        if safe_from < lo and tau < safe_to - 4.0 * period:  # surely in the air until near safe_to
            points.skip_to(safe_to - 4.0 * period)
            lo = points.next()[0]  # a turning point inside the stretch: z > 0 there
            v_lo = h.speed(lo)
            continue
        v = h.speed(tau)
        if v_lo > 0.0 and v <= 0.0:  # the apex is in (lo, tau): z rises to it, then falls
            apex = _polish(h.speed, h.rate, lo, tau, v_lo, v)
            found = _falling(h, apex, tau)
            if found is not None:
                return found
        elif v_lo <= 0.0 and (lo > 0.0 or z0 > 0.0):  # falling from lo (above 0 there)
            found = _falling(h, lo, tau) if v <= 0.0 else _falling(h, lo, _polish(h.speed, h.rate, lo, tau, v_lo, v))
            if found is not None:
                return found
        elif v_lo <= 0.0 and v <= 0.0:  # at the start and falling: no rise at all
            return 0.0
        if is_min and v > 0.0 and b0 >= 0.0:  # the speed's minima only grow: it never comes down
            return NEVER
        lo, v_lo = tau, v
    return NEVER


def _falling(h: Harmonic, lo: float, hi: float) -> float | None:
    """The landing on [lo, hi], where z falls, if z reaches 0 there (at lo if
    rounding already puts z at or below 0 there: a height far above its
    rounding error, such as 1e16 m under a 1e12 m/s^2 excitation)."""
    z_hi = h.travel(hi)
    if z_hi > 0.0:
        return None
    z_lo = h.travel(lo)
    return lo if z_lo <= 0.0 else _polish(h.travel, h.speed, lo, hi, z_lo, z_hi)


def _apex(h: Harmonic, lo: float, v_lo: float) -> float:
    """Where a speed that only falls reaches zero (lo if it is not above it)."""
    if v_lo <= 0.0:
        return lo
    hi = lo + 1.0 / h.omega
    while h.speed(hi) > 0.0:
        hi = lo + 2.0 * max(hi - lo, math.ulp(lo))  # never 0: 1/omega may be below lo's rounding
    return _polish(h.speed, h.rate, lo, hi, v_lo, h.speed(hi))


def _fall_from(h: Harmonic, apex: float) -> float:
    """The landing after ``apex`` when z only falls from there."""
    if apex == 0.0 and h.start == 0.0:
        return 0.0
    hi = apex + 1.0 / h.omega
    while h.travel(hi) > 0.0:
        hi = apex + 2.0 * max(hi - apex, math.ulp(apex))  # never 0: 1/omega may be below apex's rounding
    return _polish(h.travel, h.speed, apex, hi, h.travel(apex), h.travel(hi))


def reduce_phase(theta: float, cycles: int) -> tuple[float, int]:
    """Split a phase counted from period ``cycles`` into [0, 2*pi) and whole periods."""
    whole = math.floor(theta / TWO_PI)
    phase = theta - whole * TWO_PI
    if phase < 0.0:  # theta/2*pi rounded up (a large theta, where whole*2*pi is coarse)
        phase, whole = phase + TWO_PI, whole - 1
    if phase >= TWO_PI:  # rounding at the very end of a period
        phase, whole = 0.0, whole + 1
    return phase, cycles + whole
