"""The part's motion while the resonant exciter's transient decays, written once.

After a change of drive the part feels, on top of the steady forms of its
:class:`~friction_sim.core.physics.plant.Plant`, the exciter's transient
force Re(c*exp(lambda*tau)) normal to the track and cot(beta) times it along
it (:mod:`friction_sim.core.physics.exciter`).  Every acceleration is then a
constant, a sinusoid of the drive phase and a decaying sinusoid at the
damped frequency, and every quantity still has a closed form: a speed and a
position are its first and second integrals.

The events are the first times such a closed form reaches zero.  No formula
gives them, so :func:`first_time` finds them by branch and bound: an
interval is ruled out only where the value at its middle is farther from
zero than the largest slope times half its width (plus the rounding of the
evaluation), so no root can be missed; an interval on which the slope keeps
one sign holds at most one crossing, which is bisected to the last bit.
Near grazing (a slip speed, an onset form or a height that stays within
rounding of zero for a while) those two tests alone split ever finer, so an
interval they leave undecided is also bounded by its second-order Taylor
expansion at the middle (the remainder bounded by the largest third
derivative): ruled out where that keeps it clear of zero by more than
rounding; and where it shows the signal varies by at most :data:`FLAT`
rounding allowances over the whole interval (within rounding of zero
throughout), decided by the signs at its middle and end and bisected, not
split.  Exactness: such an interval's exact values are all within a few
rounding allowances of zero, where the sign of any evaluation is rounding's
call (the same call every event's bisection makes at its last bits); an
event reported there holds where it is reported, and one not reported is a
dip of the exact signal by less than those allowances, a graze that changes
the state by no more than that (a speed of that size, over that interval).
The two new tests come only after the old ones, and the first rules out
only intervals where no computed value can meet the condition, so away
from grazing the search returns what it returned before, bit for bit.

Segments work as in :mod:`friction_sim.core.physics.segment` (the same modes,
event kinds, guards and impact law, and the same :class:`Step`), only the
event times come from :func:`first_time`.  The single slider uses these
functions until the transient has settled (below rounding), then the
steady ones again.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.physics.exciter import exp_terms
from friction_sim.core.physics.numerics import ulp
from friction_sim.core.physics.plant import Form, Plant, onset_form, onset_gain, slip_form, slip_gain
from friction_sim.core.physics.roots import NEVER, harmonic, harmonic_at, illinois_update
from friction_sim.core.physics.segment import (
    BACKWARD,
    FLIGHT,
    FORWARD,
    LANDING,
    NO_STEP,
    STICK,
    STUCK,
    Added,
    Segment,
    Step,
    contact_event,
    evaluate,
    event_step,
)

#: Under the exciter's transient a segment's next event is sought this many
#: periods ahead at a time (a slow transient may last millions of periods):
#: without one by then, the single slider starts a new segment there from the
#: same motion, so no search scans more than this.
LOOK_AHEAD_PERIODS = 64
#: Relative rounding allowance of one evaluation of a closed form (a few dozen
#: operations on terms up to the sum of their magnitudes).
ROUNDING = 1e-14
#: An interval on which the exact signal provably varies by at most this many
#: rounding allowances is not split further (see :func:`_search`).
FLAT = 4.0
#: A count of the intervals and bisection steps a root search examines (an int64
#: array of one element, added to in place, so compiled code counts too): a bound
#: on the work of a search whatever the values, for tests.
Work = np.ndarray


class Signal(NamedTuple):
    """A closed form of ``level`` 0 (an acceleration b0 + b1*sin(phase + omega*tau)
    + Re(kc*exp(lam*tau))), 1 (its integral from ``w0``) or 2 (the integral of
    that from ``z0``)."""

    level: int
    z0: float
    w0: float
    b0: float
    b1: float
    phase: float
    omega: float
    kc: complex
    lam: complex


def signal(level: int, form: Form, gain: float, c: complex, lam: complex, phase0: float, omega: float,
           w0: float, z0: float) -> Signal:
    """The closed form of ``level`` of an acceleration ``form`` plus ``gain`` times the
    exciter's transient force Re(c*exp(lam*tau))."""
    return Signal(level, z0, w0, form.b0, form.b1, phase0 + form.delta, omega, gain * c, lam)


def value(s: Signal, tau: float) -> float:
    """The signal at ``tau``."""
    if s.level == 0:  # (the root finders' hot path: the transient's value alone)
        decay, angle = math.exp(s.lam.real * tau), s.lam.imag * tau
        transient = decay * (s.kc.real * math.cos(angle) - s.kc.imag * math.sin(angle))
        return s.b0 + s.b1 * math.sin(s.phase + s.omega * tau) + transient
    _, e1, e2 = exp_terms(s.lam, tau)
    w, z = harmonic_at(harmonic(s.w0, s.b0, s.b1, s.phase, s.omega, s.z0), tau)
    return w + (s.kc * e1).real if s.level == 1 else z + (s.kc * e2).real


def slope(s: Signal, tau: float) -> float:
    """d/dtau of the signal at ``tau``."""
    if s.level == 0:
        e0 = exp_terms(s.lam, tau)[0]
        return s.b1 * s.omega * math.cos(s.phase + s.omega * tau) + (s.kc * s.lam * e0).real
    return value(Signal(s.level - 1, 0.0, s.w0, s.b0, s.b1, s.phase, s.omega, s.kc, s.lam), tau)


def envelope(s: Signal, tau: float) -> float:
    """|kc|*exp(-sigma*tau): the transient's size from ``tau`` on."""
    return abs(s.kc) * math.exp(s.lam.real * tau)


def slope_bound(s: Signal, a: float, b: float) -> float:
    """An upper bound of |d/dtau signal| on [a, b]."""
    env = envelope(s, a)
    acceleration = abs(s.b0) + s.b1 + env
    if s.level == 0:
        return s.b1 * s.omega + env * abs(s.lam)
    if s.level == 1:
        return acceleration
    speed = value(Signal(1, 0.0, s.w0, s.b0, s.b1, s.phase, s.omega, s.kc, s.lam), 0.5 * (a + b))
    return abs(speed) + 0.5 * (b - a) * acceleration


def curvature_bound(s: Signal, a: float, b: float) -> float:
    """An upper bound of |d2/dtau2 signal| on [a, b]."""
    env = envelope(s, a)
    if s.level == 0:
        return s.b1 * s.omega * s.omega + env * abs(s.lam) ** 2
    if s.level == 1:
        return s.b1 * s.omega + env * abs(s.lam)
    return abs(s.b0) + s.b1 + env


def slack(s: Signal, tau: float) -> float:
    """The rounding allowance of an evaluation at ``tau``: ROUNDING times the sum of
    the magnitudes of the terms."""
    terms = abs(s.b0) + s.b1 + abs(s.kc)
    if s.level >= 1:
        terms = abs(s.w0) + terms * (tau + 2.0 / s.omega + 2.0 / abs(s.lam))
    if s.level == 2:
        terms = abs(s.z0) + terms * (tau + 2.0 / s.omega + 2.0 / abs(s.lam))
    return ROUNDING * terms


def _holds(x: float, positive: bool) -> bool:
    """The condition sought: above zero (``positive``), else at or below it."""
    return x > 0.0 if positive else x <= 0.0


def _bisect(s: Signal, a: float, b: float, positive: bool, work: Work) -> float:
    """The first time on (a, b] where the condition holds, the condition failing at
    a and holding at b (one crossing: the signal is monotone there), to the last bit.

    A few steps of regula falsi (the Illinois variant) first bring the bracket
    from the interval's width to a few ulps of the crossing in about as many
    evaluations as bisection spends on a handful of bits; each keeps the
    bracket's invariant (failing at a, holding at b), and bisection then ends
    it as before, at two adjacent floats."""
    a, b = _narrowed(s, a, b, positive, work)
    while True:
        work[0] += 1
        m = a + 0.5 * (b - a)
        if m <= a or m >= b:
            return b
        if _holds(value(s, m), positive):
            b = m
        else:
            a = m


#: Regula falsi steps before the bisection (each gains several bits near a simple crossing).
POLISH_STEPS = 8


def _narrowed(s: Signal, a: float, b: float, positive: bool, work: Work) -> tuple[float, float]:
    """The bracket (a, b) of :func:`_bisect` narrowed by at most :data:`POLISH_STEPS` steps of
    the Illinois method; stops when a step would not land strictly inside, or the bracket is
    down to a few ulps."""
    fa, fb = value(s, a), value(s, b)
    side = 0  # which end moved last (+1: b, -1: a), to halve the other end's weight
    for _ in range(POLISH_STEPS):
        if not (math.isfinite(fa) and math.isfinite(fb)) or fa == fb:
            break
        m = b - fb * (b - a) / (fb - fa)
        if not a < m < b:
            break
        work[0] += 1
        fm = value(s, m)
        a, fa, b, fb, side = illinois_update(a, fa, b, fb, side, m, fm, _holds(fm, positive))
        if b - a <= 64.0 * ulp(b):  # (bisection ends it in a few steps)
            break
    return a, b


def first_time(s: Signal, lo: float, hi: float, positive: bool, work: Work) -> float:
    """The first time in [lo, hi] at which the signal is above zero (``positive``)
    or at or below it (else); ``inf`` if there is none.  Scanned a drive
    period at a time, each by branch and bound (see the module's docstring)."""
    if lo > hi:
        return NEVER
    if _holds(value(s, lo), positive):
        return lo
    period = TWO_PI / s.omega
    start = lo
    while start < hi:
        stop = min(hi, start + period)
        found = _search(s, start, stop, positive, work)
        if found != NEVER:
            return found
        start = stop
    return NEVER


def _search(s: Signal, lo: float, hi: float, positive: bool, work: Work) -> float:
    """:func:`first_time` on [lo, hi], the condition failing at lo."""
    stack = [(lo, hi)]
    while stack:
        work[0] += 1
        a, b = stack.pop()
        half = 0.5 * (b - a)
        m = a + half
        f = value(s, m)
        reach = slope_bound(s, a, b) * half + slack(s, m)
        if (f - reach > 0.0) if not positive else (f + reach <= 0.0):
            continue  # the condition cannot hold anywhere on [a, b]
        if _holds(value(s, a), positive):
            return a
        fb_holds = _holds(value(s, b), positive)
        if abs(slope(s, m)) > curvature_bound(s, a, b) * half:
            if fb_holds:  # monotone: one crossing at most
                return _bisect(s, a, b, positive, work)
            continue
        if m <= a or m >= b:
            if fb_holds:
                return b
            continue
        low, high = _enclosure(s, a, b, f, reach)
        rounding = slack(s, b)
        if (low > rounding) if not positive else (high + rounding <= 0.0):
            continue  # no value on [a, b], exact or computed, meets the condition
        if high - low <= FLAT * slack(s, m):  # within rounding of zero throughout: decided by signs
            if _holds(f, positive):
                return _bisect(s, a, m, positive, work)
            if fb_holds:
                return _bisect(s, m, b, positive, work)
            continue
        stack.append((m, b))
        stack.append((a, m))
    return NEVER


def _enclosure(s: Signal, a: float, b: float, f: float, reach: float) -> tuple[float, float]:
    """(low, high): bounds of the exact signal on [a, b], f its value at the middle
    m: the tighter of f +- ``reach`` (the largest slope times half the width, plus
    rounding) and the second-order Taylor expansion at m with the remainder
    bounded by the largest third derivative (plus the roundings of the value
    and the two derivatives at m)."""
    h = 0.5 * (b - a)
    m = a + h
    f1, f2, e1, e2 = _derivatives(s, m)
    k = 3 - s.level  # the signal's third derivative is the acceleration's k-th
    third = s.b1 * s.omega ** k + envelope(s, a) * abs(s.lam) ** k
    error = (slack(s, m) + e1 * h + 0.5 * e2 * h * h + third * h * h * h / 6.0
             + ROUNDING * (abs(f) + abs(f1) * h + abs(f2) * h * h))
    left, right = f - f1 * h + 0.5 * f2 * h * h, f + f1 * h + 0.5 * f2 * h * h
    q_low, q_high = min(left, right), max(left, right)
    if f2 != 0.0 and abs(f1) < abs(f2) * h:  # the parabola's vertex lies within
        vertex = f - 0.5 * f1 * f1 / f2
        q_low, q_high = min(q_low, vertex), max(q_high, vertex)
    return max(f - reach, q_low - error), min(f + reach, q_high + error)


def _derivatives(s: Signal, tau: float) -> tuple[float, float, float, float]:
    """(first, second derivative of the signal at ``tau``, and their rounding allowances)."""
    acc = Signal(0, 0.0, 0.0, s.b0, s.b1, s.phase, s.omega, s.kc, s.lam)
    if s.level == 0:
        return (slope(s, tau), _acceleration_derivative(s, 2, tau), _derivative_slack(s, 1),
                _derivative_slack(s, 2))
    if s.level == 1:
        return value(acc, tau), slope(acc, tau), slack(acc, tau), _derivative_slack(s, 1)
    speed = Signal(1, 0.0, s.w0, s.b0, s.b1, s.phase, s.omega, s.kc, s.lam)
    return value(speed, tau), value(acc, tau), slack(speed, tau), slack(acc, tau)


def _acceleration_derivative(s: Signal, k: int, tau: float) -> float:
    """The k-th derivative (k >= 1) of the acceleration b0 + b1*sin(phase + omega*tau)
    + Re(kc*exp(lam*tau)) at ``tau``."""
    theta = s.phase + s.omega * tau
    quarter = k % 4
    turned = (math.sin(theta), math.cos(theta), -math.sin(theta), -math.cos(theta))[quarter]
    return s.b1 * s.omega ** k * turned + (s.kc * s.lam ** k * exp_terms(s.lam, tau)[0]).real


def _derivative_slack(s: Signal, k: int) -> float:
    """The rounding allowance of :func:`_acceleration_derivative` of order k."""
    return ROUNDING * (s.b1 * s.omega ** k + abs(s.kc) * abs(s.lam) ** k)




# -- a segment's next event --------------------------------------------------------------------


def _after_window(s: Signal, lo: float, hi: float, guard: bool, work: Work) -> float:
    """The first time the signal rises above zero; with ``guard`` (the window just
    closed: a restart at once could only come from rounding) only after it has
    been at or below zero."""
    if guard:
        lo = first_time(s, lo, hi, False, work)
    return first_time(s, lo, hi, True, work) if lo != NEVER else NEVER


def _returns_to_zero(rate: Signal, speed: Signal, hi: float, work: Work) -> float:
    """When a speed that starts at ``speed.w0`` >= 0 first returns to zero; from
    rest it must first rise (its rate above zero) and fall (at or below): 0 if
    it never rises."""
    lo = 0.0
    if speed.w0 <= 0.0:
        rising = first_time(rate, 0.0, hi, True, work)
        if rising == NEVER:
            return 0.0
        lo = first_time(rate, rising, hi, False, work)
        if lo == NEVER:
            return NEVER
    return first_time(speed, lo, hi, False, work)


def transient_step(p: Plant, c: complex, lam: complex, horizon: float, mode: int, phase0: float, v0: float,
                   vz0: float, z0: float, closing: int, grounded: bool, work: Work) -> Step:
    """:func:`~friction_sim.core.physics.segment.next_step` under the steady forms of
    ``p`` plus the transient force Re(c*exp(lam*tau)): the next event before
    ``horizon`` (when the transient settles), or none.  The candidates are found by
    :func:`first_time`, each only before the earliest found so far; which one wins,
    and what follows it, is the steady model's rule
    (:func:`~friction_sim.core.physics.segment.contact_event`,
    :func:`~friction_sim.core.physics.segment.event_step`)."""
    omega = p.omega
    kind, direction, delay = LANDING, 0, NEVER
    if mode == FLIGHT:
        rate = signal(0, p.flight_z, 1.0 / p.mass, c, lam, phase0, omega, 0.0, 0.0)
        speed = signal(1, p.flight_z, 1.0 / p.mass, c, lam, phase0, omega, vz0, 0.0)
        height = signal(2, p.flight_z, 1.0 / p.mass, c, lam, phase0, omega, vz0, z0)
        if z0 > 0.0:
            delay = first_time(height, 0.0, horizon, False, work)
        elif vz0 < 0.0:  # on the track and moving into it: lands at once
            delay = 0.0
        else:
            apex = _returns_to_zero(rate, speed, horizon, work)
            delay = first_time(height, apex, horizon, False, work) if apex != NEVER else NEVER
    elif mode == STUCK:  # each candidate is sought only before the earliest found so far
        forward = _after_window(_onset(p, FORWARD, c, lam, phase0), 0.0, horizon, closing == FORWARD, work)
        backward = _after_window(_onset(p, BACKWARD, c, lam, phase0), 0.0, min(forward, horizon),
                                 closing == BACKWARD, work)
        lift = _after_window(signal(0, p.lift, 1.0, c, lam, phase0, omega, 0.0, 0.0), 0.0,
                             min(forward, backward, horizon), grounded, work)
        kind, direction, delay = contact_event(mode, lift, forward, backward, NEVER)
    else:
        form, gain = slip_form(p, mode), slip_gain(p, mode)
        stop = _returns_to_zero(signal(0, form, gain, c, lam, phase0, omega, 0.0, 0.0),
                                signal(1, form, gain, c, lam, phase0, omega, mode * v0, 0.0), horizon, work)
        lift = _after_window(signal(0, p.lift, 1.0, c, lam, phase0, omega, 0.0, 0.0), 0.0, min(stop, horizon),
                             grounded, work)
        kind, direction, delay = contact_event(mode, lift, NEVER, NEVER, stop)
    if delay == NEVER:
        return NO_STEP
    moved, v, vz, _ = transient_motion(p, mode, c, lam, v0, vz0, z0, phase0, delay)
    force = transient_force(c, lam, delay) if kind == STICK else 0.0  # (it decides whether a stop slips on)
    return event_step(p, mode, kind, direction, delay, NEVER, phase0, moved, v, vz, force)


def _onset(p: Plant, direction: int, c: complex, lam: complex, phase0: float) -> Signal:
    """The onset form of ``direction`` with the transient force added."""
    return signal(0, onset_form(p, direction), onset_gain(p, direction), c, lam, phase0, p.omega, 0.0, 0.0)


# -- the state within a segment ----------------------------------------------------------------


def transient_force(c: complex, lam: complex, tau: float) -> float:
    """The transient normal force Re(c*exp(lam*tau)) [N]."""
    return (c * exp_terms(lam, tau)[0]).real


def transient_motion(p: Plant, mode: int, c: complex, lam: complex, v0: float, vz0: float, z0: float,
                     phase0: float, tau: float) -> tuple[float, float, float, float]:
    """(x(tau) - x(0), v, vz, z) ``tau`` into a segment: the steady closed forms plus
    the integrals of the transient force."""
    if mode == STUCK:
        return 0.0, 0.0, 0.0, 0.0
    _, e1, e2 = exp_terms(lam, tau)
    if mode == FLIGHT:
        along, normal = p.cot_beta / p.mass, 1.0 / p.mass
        v, moved = _integrals(p.flight_x, phase0, p.omega, v0, 0.0, tau)
        vz, z = _integrals(p.flight_z, phase0, p.omega, vz0, z0, tau)
        return (moved + along * (c * e2).real, v + along * (c * e1).real, vz + normal * (c * e1).real,
                z + normal * (c * e2).real)
    gain = slip_gain(p, mode)
    w, moved = _integrals(slip_form(p, mode), phase0, p.omega, mode * v0, 0.0, tau)
    return mode * (moved + gain * (c * e2).real), mode * (w + gain * (c * e1).real), 0.0, 0.0


def _integrals(form: Form, phase0: float, omega: float, w0: float, start: float, tau: float) -> tuple[float, float]:
    """(w, start + integral of w) of dw/dt = form from w0: the steady part of a segment's closed forms,
    as the root finders see it (no adjustment of a start from rest: the transient decides it)."""
    return harmonic_at(harmonic(w0, form.b0, form.b1, phase0 + form.delta, omega, start), tau)


def slideway_acceleration(p: Plant, phase0: float, c: complex, lam: complex, tau: float) -> tuple[float, float]:
    """(along, normal) [m/s^2]: the slideway's acceleration in the track frame ``tau``
    into a segment that started at ``phase0``, what moves the part: -1/m times the
    excitation forces it feels (the tangential and normal parts of Pa*sin, plus the
    exciter's transient force Re(c*exp(lam*tau)) and cot(beta) times it)."""
    theta = phase0 + p.omega * tau
    force = transient_force(c, lam, tau) if c else 0.0
    normal = p.pa * math.sin(theta - p.lag) + force
    along = p.tangential.b1 * math.sin(theta + p.tangential.delta) + p.cot_beta * force
    return -along / p.mass, -normal / p.mass


def transient_evaluate(p: Plant, seg: Segment, c: complex, lam: complex,
                       tau: float) -> tuple[float, float, float, float, float, float, float, float]:
    """(x, v, acceleration, friction force, normal force, phase, z, vz) ``tau`` into
    ``seg`` under the transient: the steady evaluation with the transient force and its
    integrals added (:func:`~friction_sim.core.physics.segment.evaluate`)."""
    e0, e1, e2 = exp_terms(lam, tau)
    x, v, acc, friction, normal, theta, z, vz = evaluate(p, seg, tau, Added((c * e0).real, (c * e1).real,
                                                                             (c * e2).real))
    return float(x), float(v), float(acc), float(friction), float(normal), float(theta), float(z), float(vz)


def state_at(p: Plant, seg: Segment, c: complex, lam: complex,
             tau: float) -> tuple[float, float, float, float, float, float, float, float]:
    """The state ``tau`` into ``seg`` at a float (x, v, acceleration, friction force, normal
    force, unreduced phase, z, vz): :func:`transient_evaluate` under the transient (``c``
    other than 0), else the steady :func:`~friction_sim.core.physics.segment.evaluate`."""
    if c != 0j:
        return transient_evaluate(p, seg, c, lam, tau)
    return evaluate(p, seg, tau)


def states_into(p: Plant, seg: Segment, c: complex, lam: complex, taus: np.ndarray, out: np.ndarray) -> None:
    """The state at each of ``taus`` into ``seg`` into the columns of ``out`` (8 rows, as
    :func:`state_at` gives them): one time after the other, so a column is the state a
    scalar evaluation gives, bit for bit, compiled or not."""
    for i in range(taus.size):
        x, v, acc, friction, normal, theta, z, vz = state_at(p, seg, c, lam, float(taus[i]))
        out[0, i], out[1, i], out[2, i], out[3, i] = x, v, acc, friction
        out[4, i], out[5, i], out[6, i], out[7, i] = normal, theta, z, vz


def accelerations_into(p: Plant, phase0: float, c: complex, lam: complex, taus: np.ndarray, out: np.ndarray) -> None:
    """The slideway's (along, normal) acceleration at each of ``taus`` into a segment that
    started at ``phase0`` (:func:`slideway_acceleration`, one time after the other) into
    the columns of ``out`` (2 rows)."""
    for i in range(taus.size):
        out[0, i], out[1, i] = slideway_acceleration(p, phase0, c, lam, float(taus[i]))


__all__ = ["LOOK_AHEAD_PERIODS", "Signal", "accelerations_into", "first_time", "slideway_acceleration", "state_at",
           "states_into", "transient_evaluate", "transient_force", "transient_motion", "transient_step"]
