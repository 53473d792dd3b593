"""Kostek's mean-speed relation at one point: the formulas of U(phi, a), written once.

The theory, and why the formulas take the forms they do near the motion
boundary, is :mod:`friction_sim.core.meanspeed.urelation`'s docstring; its public
functions apply the ones here, one point at a time.  Each function here takes
and returns plain floats (and tuples of floats) and uses only ``math`` and the
scalar helpers of :mod:`friction_sim.core.physics.roots`, in the subset of
Python that Numba compiles, like the slider's own physics: interpreted they
serve the controller's one inversion per period in tens of microseconds (a
numpy array of one element costs microseconds per operation), and the same
functions could be compiled for whole arrays without a second copy of the
physics.  So a value never depends on the array it came in, and a point asked
for alone gets the very bits it gets in an array.

No exceptions on any float: a division by zero, a ``math.sqrt`` of a
negative or a ``math.sin`` of infinity would raise where numpy gives inf or
NaN, so every such case is decided before the operation ("not found" is NaN,
as in the array functions before).  Unless a function says otherwise, phi is
the drive ratio's magnitude (phi >= 0) and a the amplitude ratio, checked by
the caller to lie in [0, 1) where the public functions check it.
"""

from __future__ import annotations

import math

from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.physics.numerics import two_sum
from friction_sim.core.physics.roots import remainders

FOUR_PI2 = 4.0 * math.pi**2
#: The machine epsilon of a double (numpy's finfo(float).eps, sys.float_info.epsilon).
EPS = 2.220446049250313e-16
#: Iterations that bound every Newton search here (each converges in a handful).
ITERATIONS = 100


def beyond_boundary(phi: float, a: float) -> float:
    """phi - (1 - a), as exactly as its sign: > 0 where the slider moves.

    phi + a is split into its rounded sum and the exact rounding error
    (TwoSum), and the sum minus 1 is exact (Sterbenz) wherever it matters, so
    the distance keeps its full relative precision however small it is
    (inf stays inf, NaN NaN).
    """
    total: float
    error: float
    total, error = two_sum(phi, a)
    if math.isfinite(total):
        return (total - 1.0) + error
    return total - 1.0


def start_sin_cos(phi: float, a: float) -> tuple[float, float]:
    """(sin, cos) of theta_A for phi >= 0: sin = (1 - phi)/a, and
    cos = sqrt(1 - sin^2) = sqrt(e*(2 - e)) with e = 1 - sin = (phi - (1 - a))/a,
    accurate to the last bits even where theta_A is within 1e-6 of pi/2.
    (NaN, NaN) where there is no slip start (e outside (0, 2], or a = 0; a
    tiny a makes e overflow: no start either)."""
    if a == 0.0:
        return math.nan, math.nan
    e = beyond_boundary(phi, a) / a
    if not 0.0 < e <= 2.0:  # (also NaN)
        return math.nan, math.nan
    return (1.0 - phi) / a, math.sqrt(e * (2.0 - e))


def start_phase(phi: float, a: float) -> float:
    """theta_A = asin((1 - |phi|)/a) for any sign of phi: where each period's
    slip starts (NaN where the slider never slips from rest)."""
    sin_a, cos_a = start_sin_cos(abs(phi), a)
    if sin_a < 1.0 and sin_a >= -1.0 and cos_a > 0.0:
        return math.atan2(sin_a, cos_a)
    return math.nan


def moves(phi: float, a: float) -> bool:
    """Whether the slider moves at all: |phi| > 1 - a, decided exactly on the given floats."""
    return beyond_boundary(abs(phi), a) > 0.0


def periodic_slip(phi: float, a: float) -> tuple[float, float, float]:
    """(sin(theta_A), cos(theta_A), psi_C) of the one periodic slip per period
    (1 - a < phi < 1, a > 0); psi_C is NaN where there is none.

    w/a = cos_a*(1 - cos x) - sin_a*(x - sin x) rises on (0, pi - 2*theta_A)
    and falls from there to below zero at 2*pi, so its root psi_C is found by
    Newton's method kept inside the bracket [pi - 2*theta_A, 2*pi], where w is
    monotone (bisection when a step would leave it).  Near the boundary the
    root is close to 3*(pi/2 - theta_A) (the cubic w ~ x^2*(delta/2 - x/6)),
    where the search starts.  A Newton step that no longer moves ends the
    search even where its point has just become an end of the bracket, as in
    the slider's root polish (:mod:`friction_sim.core.physics.roots`): else
    some fifty bisections from the far end followed, to land within an ulp or
    two of the same root.
    """
    sin_a, cos_a = start_sin_cos(phi, a)
    if not (cos_a > 0.0 and phi < 1.0 and a > 0.0):
        return sin_a, cos_a, math.nan
    delta = math.atan2(cos_a, sin_a)  # pi/2 - theta_A, without cancellation
    lo, hi = 2.0 * delta, TWO_PI
    x = min(max(3.0 * delta, lo), hi)
    for _ in range(ITERATIONS):
        c1, s2, _c2 = remainders(x)
        w = cos_a * c1 - sin_a * s2
        if w > 0.0:
            lo = x
        elif w < 0.0:
            hi = x
        slope = cos_a * math.sin(x) - sin_a * c1
        step = x if w == 0.0 else (x - w / slope if slope != 0.0 else math.nan)
        if lo <= step <= hi and abs(step - x) <= 4.0 * EPS * abs(x):
            return sin_a, cos_a, step  # settled on x, which may just have become an end of the bracket
        if not lo < step < hi:  # (also NaN)
            step = 0.5 * (lo + hi)
        done = abs(step - x) <= 4.0 * EPS * abs(x)
        x = step
        if done:
            break
    return sin_a, cos_a, x


def stop_phase(phi: float, a: float) -> float:
    """psi_C for any sign of phi: the phase the slip lasts, from slip start (A)
    to stick (C); 2*pi at |phi| = 1 (it never sticks), NaN where there is no
    periodic slip."""
    magnitude = abs(phi)
    if magnitude == 1.0 and a > 0.0:
        return TWO_PI
    return periodic_slip(magnitude, a)[2]


def travel(a: float, sin_a: float, cos_a: float, s2: float, c2: float) -> float:
    """D = a*(cos_a*(psi - sin psi) - sin_a*(psi^2/2 - 1 + cos psi)) >= 0 from the
    remainders s2 and c2 of psi_C: the travel of one periodic slip in units of
    mu*g/omega^2 (a rounding-sized negative value is 0; NaN stays NaN)."""
    distance = a * (cos_a * s2 - sin_a * c2)
    return 0.0 if distance < 0.0 else distance


def u_of(phi: float, a: float) -> float:
    """U(phi, a) = V*f/(g*mu) for any sign of phi (a checked to lie in [0, 1)):
    0 where nothing moves, a/(2*pi) at |phi| = 1, inf beyond, the sign of phi,
    NaN for a NaN phi; never -0.0."""
    magnitude = abs(phi)
    if magnitude < 1.0:
        sin_a, cos_a, psi = periodic_slip(magnitude, a)
        if psi == psi:  # (not NaN: a periodic slip)
            _, s2, c2 = remainders(psi)
            u = travel(a, sin_a, cos_a, s2, c2) / FOUR_PI2
        else:
            u = 0.0
    elif magnitude == 1.0:
        u = a / TWO_PI
    elif magnitude > 1.0:
        u = math.inf
    else:
        return math.nan
    return (-u if phi < 0.0 else u) + 0.0  # + 0.0: no -0.0 where a backward drive stands still


def u_and_slope(phi: float, a: float) -> tuple[float, float]:
    """U and dU/da where 1 - a < phi < 1 (one periodic slip per period); (0, NaN)
    elsewhere.

    With D(psi) the travel per period, U = D(psi_C)/(4 pi^2); psi_C moves with
    a, but dD/dpsi = w(psi_C) = 0, and so does dD/d(theta_A) (it equals
    w(psi_C) too, since phi - 1 + a*sin(theta_A) = 0), so only the explicit
    factor a remains: dD/da = sin_a*(1 - cos psi_C) + cos_a*(psi_C - sin psi_C).
    """
    sin_a, cos_a, psi = periodic_slip(phi, a)
    if psi != psi:
        return 0.0, math.nan
    c1, s2, c2 = remainders(psi)
    return travel(a, sin_a, cos_a, s2, c2) / FOUR_PI2, (sin_a * c1 + cos_a * s2) / FOUR_PI2


def u_and_phi_slope(phi: float, a: float) -> tuple[float, float]:
    """U and dU/dphi where 1 - a < phi < 1; (0, NaN) elsewhere.  As for
    :func:`u_and_slope`, psi_C and theta_A move with phi but D is stationary in
    both, so only the explicit term of D = (phi - 1)*psi**2/2 + ... remains:
    dD/dphi = psi_C**2/2."""
    sin_a, cos_a, psi = periodic_slip(phi, a)
    if psi != psi:
        return 0.0, math.nan
    _, s2, c2 = remainders(psi)
    return travel(a, sin_a, cos_a, s2, c2) / FOUR_PI2, 0.5 * psi * psi / FOUR_PI2


def invert(target: float, lo: float, hi: float, f_hi: float, fixed: float, in_phi: bool) -> float:
    """Solve U(x) = target for x in [lo, hi] (U(lo) = 0 < target <= U(hi) = f_hi,
    U rising): x the amplitude ratio at phi = ``fixed``, or (``in_phi``) phi at
    the amplitude ratio ``fixed``.

    Newton's method with the exact slope, every iterate kept inside the
    shrinking bracket (bisection when Newton would leave it): a handful of
    iterations, which matters to a controller that inverts once per period.
    It stops when U meets the target to rounding, or when the step or the
    bracket is a few ulps (near the motion boundary U's rounding noise exceeds
    the first test; the bracket still closes), also where the point the step
    stays at has just become an end of the bracket (see :func:`periodic_slip`).
    The first guess follows U ~ (x - lo)^2 near the boundary.
    """
    x = lo + (hi - lo) * math.sqrt(target / f_hi)
    for _ in range(ITERATIONS):
        u, slope = u_and_phi_slope(x, fixed) if in_phi else u_and_slope(fixed, x)
        f = u - target
        if f > 0.0:
            hi = x
        else:
            lo = x
        step = x if abs(f) <= 4.0 * EPS * target else (x - f / slope if slope != 0.0 else math.nan)
        if lo <= step <= hi and abs(step - x) <= 4.0 * EPS * x:
            return step  # settled on x, which may just have become an end of the bracket
        if not lo < step < hi:  # (also NaN or inf)
            step = 0.5 * (lo + hi)
        done = abs(step - x) <= 4.0 * EPS * x or hi - lo <= 4.0 * EPS * x
        x = step
        if done:
            break
    return x


def amplitude_ratio(u: float, phi: float, top: float) -> float:
    """The amplitude ratio a <= ``top`` (0 < top < 1) with U(phi, a) = u, for any
    signs: 0 for u = 0, NaN where u cannot be reached (too fast, the sign of u
    disagrees with phi's, |phi| > 1 or phi = 0, or a NaN).

    U rises monotonically with a on (1 - |phi|, 1), so the answer is unique; at
    |phi| = 1 the slider slides on with a bounded speed, U = a/(2*pi), which the
    excitation still sets (only beyond does it run away)."""
    if u == 0.0:
        return 0.0
    magnitude = abs(phi)
    if not (0.0 < magnitude <= 1.0 and 1.0 - magnitude < top and (u > 0.0) == (phi > 0.0)):
        return math.nan
    if magnitude == 1.0:
        ratio = TWO_PI * abs(u)
        return ratio if ratio <= top else math.nan
    target, u_top = abs(u), u_of(magnitude, top)
    if not target <= u_top:  # (also NaN)
        return math.nan
    return invert(target, 1.0 - magnitude, top, u_top, magnitude, False)


def drive_ratio(u: float, a: float) -> float:
    """The drive ratio phi with U(phi, a) = u, for any sign of u (a checked to lie
    in [0, 1)): 1 - a for u = 0, 1 at |u| = a/(2*pi), NaN beyond (or for a
    NaN); -phi(-u, a) for negative u.

    U rises monotonically with phi, from 0 at the motion boundary phi = 1 - a
    to a/(2*pi) at phi = 1 (dU/dphi = psi_C**2/(8*pi**2) > 0), so the answer
    is unique."""
    target, u_top = abs(u), a / TWO_PI
    if target == 0.0:
        phi = 1.0 - a
    elif target == u_top:
        phi = 1.0
    elif target < u_top:
        phi = invert(target, 1.0 - a, 1.0, u_top, a, True)
    else:
        phi = math.nan
    return -phi if u < 0.0 else phi
