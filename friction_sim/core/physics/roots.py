"""Event detection, written once: when the next event of a segment happens.

Every acceleration of the model is a constant plus a sinusoid of the
excitation phase, dw/dt = b0 + b1*sin(phase0 + omega*tau) with b1 >= 0, and
every event is where such a form, or its first or second integral, crosses
zero.  The functions here find those roots: a slip onset in closed form with
asin (:func:`next_slip_start`), a slip stop bracketed on the first falling
stretch of the speed and polished (:func:`slip_stop_delay`), a landing
bracketed between the turning points of the vertical speed and polished
(:func:`landing_delay`).

They are plain functions over floats and tuples of floats, in the subset of
Python that Numba compiles: the single slider (:mod:`friction_sim.core.engine.single`)
calls them as ordinary Python, the population engine
(:mod:`friction_sim.core.engine.compiled`) compiles the very same functions,
so both follow one formulation and agree bit for bit (CPython's ``math`` and
Numba call the same libm; where they would not, :mod:`~friction_sim.core.physics.numerics`
writes the operation out).  No objects, no ``None``: "never" is ``inf``, "not
found" is ``nan``.  The closed form of a speed and its integral
(:class:`Harmonic`) evaluates at a float or at an array of times.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.physics.numerics import Floats, sine, ulp

NEVER = math.inf

#: Phase tolerance [rad] below which a rounding-level distance from the slip
#: window's edge counts as being on the edge (a full period is never skipped).
PHASE_EDGE = 1e-12
#: Slips predicted to last longer than this many excitation periods never stop.
LONGEST_SLIP = 1e12
#: A flight still in the air after this many turning points of its vertical
#: speed (two per excitation period) is taken as endless: its mean vertical
#: acceleration is then within rounding of zero.
LONGEST_FLIGHT_PIECES = 2_000_000
#: Iterations of a safeguarded Newton polish (it converges in a handful; bisection bounds it).
POLISH_ITERATIONS = 200


# -- the closed form of a speed and its integral ------------------------------------------


def series_s2(psi: float, p2: float) -> float:
    """psi - sin(psi) by its Taylor series (|psi| < 0.25: truncation < 1e-18 relative);
    arithmetic only, so it also evaluates numpy arrays."""
    return psi * p2 * (1 / 6 - p2 * (1 / 120 - p2 * (1 / 5040 - p2 * (
        1 / 362880 - p2 * (1 / 39916800 - p2 / 6227020800)))))


def series_c2(p2: float) -> float:
    """psi**2/2 - (1 - cos(psi)) by its Taylor series (see :func:`series_s2`)."""
    return p2 * p2 * (1 / 24 - p2 * (1 / 720 - p2 * (1 / 40320 - p2 * (
        1 / 3628800 - p2 * (1 / 479001600 - p2 / 87178291200)))))


def remainders(psi: float) -> tuple[float, float, float]:
    """(1 - cos psi, psi - sin psi, psi**2/2 - (1 - cos psi)) without cancellation.

    Writing the motion with these remainders keeps tiny slips (at the motion
    boundary, or just after an event) accurate to the last bits, so a forward
    slip never shows a rounding-sized step backwards.  Taylor series below
    |psi| = 0.25.
    """
    half = math.sin(0.5 * psi)
    c1 = 2.0 * half * half
    p2 = psi * psi
    if abs(psi) >= 0.25:
        return c1, psi - math.sin(psi), 0.5 * p2 - c1
    return c1, series_s2(psi, p2), series_c2(p2)


def remainders_many(psi: Any) -> tuple[Any, Any, Any]:
    """:func:`remainders` for an array of phases (numpy's sin: within an ulp or two
    of libm's, so the U map's arrays and a slider's samples may differ from the
    scalar functions in their last bits)."""
    half = np.sin(0.5 * psi)
    c1 = 2.0 * half * half
    p2 = psi * psi
    small = np.abs(psi) < 0.25
    return c1, np.where(small, series_s2(psi, p2), psi - np.sin(psi)), np.where(small, series_c2(p2), 0.5 * p2 - c1)


class Harmonic(NamedTuple):
    """The closed form of a speed w under dw/dt = b0 + b1*sin(phase0 + omega*tau) with
    w(0) = w0, and of its integral from ``start``: a slip's speed and travel, a
    flight's tangential velocity and position, its vertical velocity and height.
    ``g0`` = dw/dt at 0, ``k`` = b1/omega, ``kk`` = k/omega, and the start phase's
    cosine and sine (see :func:`harmonic`)."""

    w0: float
    b0: float
    b1: float
    phase0: float
    omega: float
    start: float
    g0: float
    k: float
    kk: float
    cos0: float
    sin0: float


def harmonic(w0: float, b0: float, b1: float, phase0: float, omega: float, start: float) -> Harmonic:
    """The :class:`Harmonic` with these coefficients."""
    cos0, sin0 = math.cos(phase0), math.sin(phase0)
    k = b1 / omega
    return Harmonic(w0, b0, b1, phase0, omega, start, b0 + b1 * sin0, k, k / omega, cos0, sin0)


def speed_after(h: Harmonic, c1: Floats, s2: Floats, tau: Floats) -> Floats:
    """w at ``tau`` from its remainders (arithmetic only: floats or arrays)."""
    return h.w0 + h.g0 * tau + h.k * (h.cos0 * c1 - h.sin0 * s2)


def travel_after(h: Harmonic, s2: Floats, c2: Floats, tau: Floats) -> Floats:
    """start + the integral of w at ``tau`` from its remainders (floats or arrays)."""
    return h.start + (h.w0 * tau + 0.5 * h.g0 * tau * tau + h.kk * (h.cos0 * s2 - h.sin0 * c2))


def harmonic_at(h: Harmonic, tau: Floats) -> tuple[Floats, Floats]:
    """(w, start + integral of w) at ``tau``, a float or an array (see :data:`Floats`)."""
    psi = h.omega * tau
    c1, s2, c2 = remainders(psi) if isinstance(psi, float) else remainders_many(psi)
    return speed_after(h, c1, s2, tau), travel_after(h, s2, c2, tau)


def harmonic_speed(h: Harmonic, tau: float) -> float:
    """w at ``tau`` (the root finders' hot path: no integral)."""
    c1, s2, _ = remainders(h.omega * tau)
    return speed_after(h, c1, s2, tau)


def harmonic_height(h: Harmonic, tau: float) -> float:
    """start + the integral of w at ``tau``."""
    _, s2, c2 = remainders(h.omega * tau)
    return travel_after(h, s2, c2, tau)


def harmonic_rate(h: Harmonic, tau: Floats) -> Floats:
    """dw/dt at ``tau``, a float or an array."""
    return h.b0 + h.b1 * sine(h.phase0 + h.omega * tau)


# -- slip onset ----------------------------------------------------------------------------


def next_slip_start(phase: float, b0: float, b1: float, closing: bool) -> tuple[float, float]:
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
        if b0 > 0.0 and not closing:
            return 0.0, phase
        return NEVER, NEVER
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
    if delta > TWO_PI - PHASE_EDGE:  # a hair past the edge: starts now
        return 0.0, phase
    return delta, start


# -- slip stop -------------------------------------------------------------------------------


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


def slip_speed(w0: float, g0: float, k: float, cos0: float, sin0: float, omega: float, tau: float) -> float:
    """w(tau) of a slip: w0 + g0*tau + k*(cos0*(1 - cos psi) - sin0*(psi - sin psi))."""
    c1, s2, _ = remainders(omega * tau)
    return w0 + g0 * tau + k * (cos0 * c1 - sin0 * s2)


def slip_stop_delay(w0: float, b0: float, b1: float, phase0: float, omega: float) -> float:
    """Time until the speed w = s*v of a slip returns to zero (``inf``: never).

    ``w0`` >= 0 is the speed at the start, ``b0`` and ``b1`` >= 0 the constant
    and sinusoidal parts of dw/dt = b0 + b1*sin(phase0 + omega*tau).  A slip
    predicted to last more than ``LONGEST_SLIP`` excitation periods is taken
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
        if not hi * omega <= TWO_PI * LONGEST_SLIP:  # (also when hi overflows to inf)
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
        if delta0 > TWO_PI - PHASE_EDGE:
            delta0 = 0.0
        if delta0 >= rise:  # would start from rest while decelerating
            return 0.0
    period = TWO_PI / omega
    lo = max(0.0, (rise - delta0) / omega)
    hi = (TWO_PI - delta0) / omega
    k, cos0, sin0 = b1 / omega, math.cos(phase0), math.sin(phase0)
    g0 = initial_slope(w0, b0, b1, phase0)
    w_min = slip_speed(w0, g0, k, cos0, sin0, omega, hi)
    if w_min > 0.0:
        if b0 >= 0.0:  # the minima only grow: never back to rest
            return NEVER
        drop = -b0 * period  # how much the minima fall per period
        if drop == 0.0:  # a subnormal drift that rounds away over a period: never back to rest
            return NEVER
        estimate = w_min / drop
        if not estimate <= LONGEST_SLIP:  # (also when it overflows to inf)
            return NEVER
        hi += max(1.0, math.ceil(estimate)) * period
        found = False
        for _ in range(8):  # rounding guard: the formula's period may be one short
            if slip_speed(w0, g0, k, cos0, sin0, omega, hi) <= 0.0:
                found = True
                break
            hi += period
        if not found:
            return NEVER
        lo = hi - (TWO_PI - rise) / omega
    return _falling_root(w0, b0, b1, phase0, omega, lo, hi)


def _falling_root(w0: float, b0: float, b1: float, phase0: float, omega: float, lo: float, hi: float) -> float:
    """The root of w on [lo, hi], where w is monotone with w(lo) > 0 >= w(hi).

    Newton's method from the secant point, with every iterate kept inside the
    shrinking bracket (bisection when Newton would leave it), to full double
    precision.
    """
    k, cos0, sin0 = b1 / omega, math.cos(phase0), math.sin(phase0)
    g0 = initial_slope(w0, b0, b1, phase0)
    w_lo = slip_speed(w0, g0, k, cos0, sin0, omega, lo)
    w_hi = slip_speed(w0, g0, k, cos0, sin0, omega, hi)
    if w_hi >= 0.0:
        return hi
    if w_lo <= 0.0:
        return lo
    tau = lo + (hi - lo) * (w_lo / (w_lo - w_hi))
    for _ in range(POLISH_ITERATIONS):
        psi = omega * tau
        if psi >= 0.25:  # slip_speed inlined: this loop is the hot path of the periodic regime
            half = math.sin(0.5 * psi)
            w = w0 + g0 * tau + k * (cos0 * 2.0 * half * half - sin0 * (psi - math.sin(psi)))
        else:
            w = slip_speed(w0, g0, k, cos0, sin0, omega, tau)
        if w > 0.0:
            lo = tau
        elif w < 0.0:
            hi = tau
        else:
            return tau
        slope = b0 + b1 * math.sin(phase0 + psi)
        step = tau - w / slope if slope < 0.0 else math.nan
        if not lo < step < hi:
            step = 0.5 * (lo + hi)
        if step == tau or abs(step - tau) <= 2.2e-16 * abs(tau):
            return step
        tau = step
    return tau


# -- flight: when the height returns to zero ------------------------------------------------


def _value(h: Harmonic, height: bool, tau: float) -> float:
    """The height (``height``) or the vertical speed of a flight at ``tau``."""
    return harmonic_height(h, tau) if height else harmonic_speed(h, tau)


def _slope(h: Harmonic, height: bool, tau: float) -> float:
    """The derivative of :func:`_value`."""
    return harmonic_speed(h, tau) if height else harmonic_rate(h, tau)


def _polish(h: Harmonic, height: bool, lo: float, hi: float, f_lo: float, f_hi: float) -> float:
    """The root of the height (or the vertical speed) of ``h``, monotone on [lo, hi]
    with values of opposite signs (or zero) at the ends: Newton kept inside the
    shrinking bracket, bisection when it would leave it, to full double precision.
    A Newton step that no longer moves ends the search even where its point has
    just become an end of the bracket (otherwise up to fifty bisections from the
    far end follow, to land within an ulp or two of the same root)."""
    if f_lo == 0.0:
        return lo
    if f_hi == 0.0:
        return hi
    if (f_lo > 0.0) == (f_hi > 0.0):  # no sign change: rounding at an end (values far above their root's scale)
        return lo if abs(f_lo) <= abs(f_hi) else hi
    rising = f_hi > 0.0
    tau = lo + (hi - lo) * (f_lo / (f_lo - f_hi))
    for _ in range(POLISH_ITERATIONS):
        value = _value(h, height, tau)
        if value == 0.0:
            return tau
        if (value > 0.0) == rising:
            hi = tau
        else:
            lo = tau
        slope = _slope(h, height, tau)
        step = tau - value / slope if slope != 0.0 else math.nan
        if lo <= step <= hi and (step == tau or abs(step - tau) <= 2.2e-16 * abs(tau)):
            return step  # Newton has settled on tau, which may just have become an end of the bracket
        if not lo < step < hi:
            step = 0.5 * (lo + hi)
        if step == tau or abs(step - tau) <= 2.2e-16 * abs(tau):
            return step
        tau = step
    return tau


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
    r1, r2 = (-b + root) / (2.0 * a), (-b - root) / (2.0 * a)
    return (r1, r2) if r1 <= r2 else (r2, r1)


class _Turns(NamedTuple):
    """The turning points of a flight's vertical speed (where b0 + b1*sin = 0), as
    phases within a period in order, each flagged when it is a minimum of the speed."""

    first: float
    second: float
    first_is_min: bool
    base: float


def _turns(h: Harmonic) -> _Turns:
    low = math.asin(-h.b0 / h.b1)  # sin rises through -b0/b1: minimum of the speed
    low_mark, high_mark = low % TWO_PI, (math.pi - low) % TWO_PI
    base = h.phase0 - h.phase0 % TWO_PI
    if low_mark < high_mark:  # in order of phase; a tie puts the maximum first
        return _Turns(low_mark, high_mark, True, base)
    return _Turns(high_mark, low_mark, False, base)


def _turn_time(h: Harmonic, turns: _Turns, n: int, i: int) -> float:
    """The time of turning point i (0, 1) of period n counted from the flight's period."""
    mark = turns.first if i == 0 else turns.second
    return (turns.base + TWO_PI * n + mark - h.phase0) / h.omega


def landing_delay(vz0: float, b0: float, b1: float, phase0: float, omega: float, z0: float) -> float:
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
    h = harmonic(vz0, b0, b1, phase0, omega, z0)
    if b1 <= 0.0 or abs(b0) >= b1:  # the acceleration never changes sign
        if b0 >= 0.0:
            return NEVER
        return _fall_from(h, _apex(h, 0.0, vz0))
    safe_from, safe_to = _safe_stretch(h)
    period = TWO_PI / omega
    lo, v_lo = 0.0, vz0
    turns = _turns(h)
    n, i = 0, 0
    for _ in range(LONGEST_FLIGHT_PIECES):
        tau, is_min, n, i = _next_turn(h, turns, n, i)
        if safe_from < lo and tau < safe_to - 4.0 * period:  # surely in the air until near safe_to
            n, i = max(n, math.floor((phase0 + omega * (safe_to - 4.0 * period) - turns.base) / TWO_PI)), 0
            lo, _, n, i = _next_turn(h, turns, n, i)  # a turning point inside the stretch: z > 0 there
            v_lo = harmonic_speed(h, lo)
            continue
        v = harmonic_speed(h, tau)
        if v_lo > 0.0 and v <= 0.0:  # the apex is in (lo, tau): z rises to it, then falls
            apex = _polish(h, False, lo, tau, v_lo, v)
            found = _falling(h, apex, tau)
            if found == found:  # (not nan)
                return found
        elif v_lo <= 0.0 and (lo > 0.0 or z0 > 0.0):  # falling from lo (above 0 there)
            end = tau if v <= 0.0 else _polish(h, False, lo, tau, v_lo, v)
            found = _falling(h, lo, end)
            if found == found:
                return found
        elif v_lo <= 0.0 and v <= 0.0:  # at the start and falling: no rise at all
            return 0.0
        if is_min and v > 0.0 and b0 >= 0.0:  # the speed's minima only grow: it never comes down
            return NEVER
        lo, v_lo = tau, v
    return NEVER


def _next_turn(h: Harmonic, turns: _Turns, n: int, i: int) -> tuple[float, bool, int, int]:
    """The next turning point after time 0 from (period n, point i): its time,
    whether it is a minimum, and the position after it."""
    while True:
        tau = _turn_time(h, turns, n, i)
        is_min = turns.first_is_min if i == 0 else not turns.first_is_min
        if i == 0:
            i = 1
        else:
            n, i = n + 1, 0
        if tau > 0.0:
            return tau, is_min, n, i


def _falling(h: Harmonic, lo: float, hi: float) -> float:
    """The landing on [lo, hi], where z falls, if z reaches 0 there (at lo if
    rounding already puts z at or below 0 there: a height far above its
    rounding error, such as 1e16 m under a 1e12 m/s^2 excitation); nan if not."""
    z_hi = harmonic_height(h, hi)
    if z_hi > 0.0:
        return math.nan
    z_lo = harmonic_height(h, lo)
    return lo if z_lo <= 0.0 else _polish(h, True, lo, hi, z_lo, z_hi)


def _apex(h: Harmonic, lo: float, v_lo: float) -> float:
    """Where a speed that only falls reaches zero (lo if it is not above it)."""
    if v_lo <= 0.0:
        return lo
    hi = lo + 1.0 / h.omega
    while harmonic_speed(h, hi) > 0.0:
        hi = lo + 2.0 * max(hi - lo, ulp(lo))  # never 0: 1/omega may be below lo's rounding
    return _polish(h, False, lo, hi, v_lo, harmonic_speed(h, hi))


def _fall_from(h: Harmonic, apex: float) -> float:
    """The landing after ``apex`` when z only falls from there."""
    if apex == 0.0 and h.start == 0.0:
        return 0.0
    hi = apex + 1.0 / h.omega
    while harmonic_height(h, hi) > 0.0:
        hi = apex + 2.0 * max(hi - apex, ulp(apex))  # never 0: 1/omega may be below apex's rounding
    return _polish(h, True, apex, hi, harmonic_height(h, apex), harmonic_height(h, hi))


def reduce_phase(theta: float, cycles: int) -> tuple[float, int]:
    """Split a phase counted from period ``cycles`` into [0, 2*pi) and whole periods."""
    whole = math.floor(theta / TWO_PI)
    phase = theta - whole * TWO_PI
    if phase < 0.0:  # theta/2*pi rounded up (a large theta, where whole*2*pi is coarse)
        phase, whole = phase + TWO_PI, whole - 1
    if phase >= TWO_PI:  # rounding at the very end of a period
        phase, whole = 0.0, whole + 1
    return phase, cycles + whole


def illinois_update(lo: float, f_lo: float, hi: float, f_hi: float, side: int, x: float, f_x: float,
                    upper: bool) -> tuple[float, float, float, float, int]:
    """One step of regula falsi, Illinois variant: ``x`` (value ``f_x``) replaces
    the bracket's upper end (``upper``) or its lower one; an end that stays while
    the other moves twice in a row has its value halved, so the bracket closes
    from both sides.  ``side``: which end moved last (+1 upper, -1 lower, 0 none).
    Returns (lo, f_lo, hi, f_hi, side)."""
    if upper:
        return lo, f_lo * 0.5 if side == 1 else f_lo, x, f_x, 1
    return x, f_x, hi, f_hi * 0.5 if side == -1 else f_hi, -1
