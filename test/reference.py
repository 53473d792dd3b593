"""High-accuracy *reference* simulator for Kostek's stick-slip friction model.

What it is
----------
A deliberately independent, numerical solution of the model of R. Kostek
("Influence of an external normal harmonic force on reduction of friction
force"): a rigid slider of mass ``m`` on a slideway with Coulomb friction
(one coefficient ``mu``), driven by a tangential force and loaded by a normal
harmonic force::

    theta(t)   excitation phase, d theta/dt = 2*pi*f(t), theta(0) = phase0
    R(t)     = m*g + Fz - Pa*sin(theta(t))          normal reaction (> 0)
    Ft       = Fd + Fx                               tangential force
    stuck    (v == 0): stays stuck while |Ft| <= mu*R, x constant
    slipping (v != 0): m*dv/dt = Ft - mu*R*sign(v)

From rest, slip starts in the direction ``sign(Ft)`` as soon as
``|Ft| > mu*R``.  When the velocity returns to zero the slider sticks if
``|Ft| <= mu*R`` and otherwise slips on in the direction ``sign(Ft)`` (a
*reversal* when that is opposite to the previous direction).  The inputs
``Fd, Pa, f, Fx, Fz`` are piecewise constant (a schedule of changes); the
phase stays continuous when ``f`` changes.

Why it exists
-------------
``friction_sim`` has an exact, event-driven core.  Tests and benchmarks need
something to compare that core against which does *not* share its code or
its closed-form reasoning.  This module therefore solves the same physics in
the most pedestrian way that is still highly accurate:

* slip phases are integrated with SciPy's ``DOP853`` (as
  :func:`scipy.integrate.solve_ivp` does it, step loop in test/stepping.py:
  dense output, ``max_step`` = excitation period / 20) with a
  terminal event on ``v = 0``.  An event is seen only as a sign change
  between step ends, so a slip is integrated in sections that end at the
  minima of ``s*v`` (``s`` the slip direction): there the state-independent
  acceleration ``s*a(t)`` turns positive, found like the slip start (scan
  including the extrema of ``R``, then brentq), except those that a lower
  bound of ``s*v`` shows to be harmless.  After its last minimum in a section
  ``s*v`` only rises, then falls, so a velocity that touches zero and would
  turn back within one step cannot be stepped over;
* the stick -> slip instant is found numerically: ``|Ft| - mu*R(t)`` is
  scanned on a grid of step at most ``1/(20 f)`` (plus the instants of
  maximal unloading, so a short positive excursion is never stepped over)
  and the first sign change is refined with :func:`scipy.optimize.brentq`;
* only the excitation phase ``theta(t)`` is evaluated in closed form (it is
  linear in time on every schedule piece).

It must not import ``friction_sim.core.engine.single`` or ``friction_sim.core.meanspeed.urelation``.

scipy is a development/test dependency only, so it is imported lazily inside
the functions that need it; importing this module needs numpy alone.

A second, even simpler cross-check, :func:`brute_force_mean_velocity`, is a
fixed-step semi-implicit Euler integrator with explicit stick handling.

Its parts: the schedule of inputs as pieces and the instants found on a
piece are test/reference_schedule.py's; the closed form evaluated at many
digits, and the distance in ulps from it, for exactness checks at the last
bits, test/reference_exact.py's.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from stepping import integrate

from reference_schedule import (
    TWO_PI,
    Piece,
    ReferenceInputs,
    build_pieces,
    check_finite,
    check_positive,
    find_slip_start,
    next_velocity_minimum,
    sign,
)

__all__ = [
    'ReferenceInputs',
    'ReferenceResult',
    'reference_solution',
    'brute_force_mean_velocity',
]

#: ``max_step`` of the slip integration, as a fraction of the excitation period.
_SOLVER_STEPS_PER_PERIOD: int = 20
#: Consecutive slip pieces shorter than this many periods count as "no progress".
_TINY_PIECE_PERIODS: float = 1e-12
_MAX_TINY_PIECES: int = 1000


# --------------------------------------------------------------------------- API types


@dataclass(frozen=True)
class ReferenceResult:
    """Result of :func:`reference_solution`.

    ``t`` are the requested sample times (in the order given), ``x`` and
    ``v`` the position and velocity there.  ``event_times`` (ascending) and
    ``event_kinds`` list every transition: ``'slip_start'`` (stick -> slip),
    ``'stick'`` (slip -> stick) and ``'reversal'`` (the velocity passes through
    zero and the slider slips on in the opposite direction).
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    event_times: np.ndarray
    event_kinds: tuple[str, ...]


# --------------------------------------------------------------------------- internals


@dataclass(frozen=True)
class _Slip:
    """Outcome of one slip phase (see :func:`_integrate_slip`)."""

    stopped: bool  # True: v reached 0 at t_stop; False: reached piece.t_end still slipping
    t_stop: float
    x_stop: float
    v_stop: float  # 0.0 if stopped
    dense: Callable[[Any], NDArray[np.float64]]  # (x, v) on [t_s, t_stop]


def _integrate_slip(
    piece: Piece,
    t_s: float,
    x_s: float,
    v_s: float,
    s: int,
    mass: float,
    mu: float,
    rtol: float,
    atol: float,
) -> _Slip:
    """Integrate one slip phase in direction ``s`` from ``t_s`` until v = 0 or ``piece.t_end``.

    The integrator only sees a zero of the terminal event ``v`` as a sign change between
    the ends of a step, so a velocity that touches zero and turns back within one
    step would be integrated straight through (through a stick).  The slip is
    therefore integrated in sections that end at minima of ``s*v`` (zeros of the
    state-independent ``s*a``, see :func:`_next_velocity_minimum`).  A section
    from ``t0`` ends at the first minimum after ``t_safe``, before which
    ``s*v(t0) + min(s*a)*(t - t0) > 0`` rules out a zero.  Between ``t_safe`` and
    the section end ``s*v`` has no interior minimum, so once it has reached zero
    it stays <= 0 up to the end of the section and the sign change between step
    ends cannot be missed.
    """
    from scipy.integrate import OdeSolution

    ft = piece.tangential
    mu_s = mu * s

    def rhs(t: float, y: NDArray[np.float64]) -> list[float]:
        theta = piece.theta_start + piece.omega * (t - piece.t_start)
        reaction = piece.base_load - piece.amplitude * math.sin(theta)
        return [y[1], (ft - mu_s * reaction) / mass]

    starts_from_rest = v_s == 0.0

    def velocity_zero(t: float, y: NDArray[np.float64]) -> float:
        # A slip piece that starts from rest begins *on* the event surface; report the
        # slip side at the very first instant so the event can only fire on a genuine
        # later crossing (no zero-length slip pieces / endless loops).
        if starts_from_rest and t <= t_s:
            return float(s)
        return float(y[1])

    velocity_zero.terminal = True  # type: ignore[attr-defined]
    velocity_zero.direction = -s  # type: ignore[attr-defined]  # from the slip side towards 0

    max_step = piece.period / _SOLVER_STEPS_PER_PERIOD
    # Lower bound of s*a over the piece: s*v >= s*v(t0) + a_low*(t - t0) in a section.
    a_low = (s * ft - mu * (piece.base_load + abs(piece.amplitude))) / mass
    t0, y0 = t_s, [x_s, v_s]
    sections: list[Any] = []
    while True:
        # v cannot vanish before t_safe (half the bound's margin), so minima before it
        # need not end a section: fast, long slips are integrated in one go.
        speed = s * float(y0[1])
        t_safe = t0 + 0.5 * speed / -a_low if (a_low < 0.0 and speed > 0.0) else t0
        t_min = next_velocity_minimum(piece, s, t_safe, mu)
        t_bound = piece.t_end if t_min is None else t_min
        sol = integrate(rhs, t0, t_bound, y0, velocity_zero, rtol=rtol, atol=atol, max_step=max_step)
        if sol.status == -1:
            raise RuntimeError(
                f'DOP853 failed in slip phase starting at t={t_s!r}: {sol.message}'
            )
        sections.append(sol.dense)
        if sol.status == 1 or t_min is None:
            break
        t0, y0 = sol.t_end, sol.y_end

    if len(sections) == 1:
        dense = sections[0]
    else:
        ts = np.concatenate([sections[0].ts] + [sec.ts[1:] for sec in sections[1:]])
        dense = OdeSolution(ts, [ip for sec in sections for ip in sec.interpolants])
    if sol.status == 1:  # velocity reached zero
        return _Slip(True, sol.t_end, float(sol.y_end[0]), 0.0, dense)
    return _Slip(False, sol.t_end, float(sol.y_end[0]), float(sol.y_end[1]), dense)


class _Sampler:
    """Fills the requested samples segment by segment (later segments win at shared ends)."""

    def __init__(self, sample_times: NDArray[np.float64]) -> None:
        self.order = np.argsort(sample_times, kind='stable')
        self.ts = sample_times[self.order]
        self.x = np.full(self.ts.shape, np.nan)
        self.v = np.full(self.ts.shape, np.nan)

    def _range(self, t_a: float, t_b: float) -> slice:
        lo = int(np.searchsorted(self.ts, t_a, 'left'))
        hi = int(np.searchsorted(self.ts, t_b, 'right'))
        return slice(lo, hi)

    def stuck(self, t_a: float, t_b: float, x: float) -> None:
        sl = self._range(t_a, t_b)
        self.x[sl] = x
        self.v[sl] = 0.0

    def slip(
        self, t_a: float, t_b: float, dense: Callable[[NDArray[np.float64]], NDArray[np.float64]]
    ) -> None:
        sl = self._range(t_a, t_b)
        if sl.stop > sl.start:
            y = dense(self.ts[sl])
            self.x[sl] = y[0]
            self.v[sl] = y[1]

    def point(self, t: float, x: float, v: float) -> None:
        sl = self._range(t, t)
        self.x[sl] = x
        self.v[sl] = v

    def results(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        x = np.empty_like(self.x)
        v = np.empty_like(self.v)
        x[self.order] = self.x
        v[self.order] = self.v
        return x, v


# --------------------------------------------------------------------------- public functions


def reference_solution(
    mass: float,
    mu: float,
    gravity: float,
    schedule: Sequence[tuple[float, ReferenceInputs]],
    sample_times: ArrayLike,
    *,
    rtol: float = 1e-10,
    atol: float = 1e-14,
    x0: float = 0.0,
    v0: float = 0.0,
    phase0: float = 0.0,
) -> ReferenceResult:
    """Solve the stick-slip model from t=0 to ``max(sample_times)`` numerically.

    ``schedule`` is a sequence of ``(t_change, inputs)`` with strictly
    increasing times, the first one ``<= 0``; each ``inputs`` holds from its
    ``t_change`` until the next change.  ``sample_times`` (any order, all
    ``>= 0``) are where ``x`` and ``v`` are reported.  ``rtol``/``atol`` are
    passed to ``solve_ivp``.  Raises :class:`ValueError` (naming the field) for
    invalid input.
    """
    mass = check_positive('mass', mass)
    mu = check_positive('mu', mu)
    gravity = check_positive('gravity', gravity)
    rtol = check_positive('rtol', rtol)
    atol = check_positive('atol', atol)
    x0 = check_finite('x0', x0)
    v0 = check_finite('v0', v0)
    phase0 = check_finite('phase0', phase0)

    ts = np.asarray(sample_times, dtype=float)
    if ts.ndim > 1:
        raise ValueError('sample_times must be a scalar or a 1-D array')
    ts = np.atleast_1d(ts).copy()
    if ts.size == 0:
        raise ValueError('sample_times must not be empty')
    if not np.all(np.isfinite(ts)):
        raise ValueError('sample_times must be finite')
    if np.any(ts < 0.0):
        raise ValueError('sample_times must be >= 0')
    t_final = float(ts.max())

    pieces = build_pieces(schedule, mass, gravity, t_final, phase0)
    sampler = _Sampler(ts)
    event_times: list[float] = []
    event_kinds: list[str] = []

    t, x, v = 0.0, x0, v0
    s = sign(v0)  # current slip direction, 0 while stuck
    k = 0
    tiny_pieces = 0
    sampler.point(0.0, x, v)

    while True:
        piece = pieces[k]
        if t >= piece.t_end and not piece.is_last:
            k += 1
            continue

        if s == 0:  # ------------------------------------------------------- stuck
            t_s = find_slip_start(piece, t, mu)
            if t_s is None or (t_s >= piece.t_end and not piece.is_last):
                # Stays stuck to the end of the piece (a slip possible only exactly at a
                # schedule change is decided with the new inputs in the next piece).
                sampler.stuck(t, piece.t_end, x)
                t = piece.t_end
                if piece.is_last:
                    break
                k += 1
                continue
            sampler.stuck(t, t_s, x)
            t = t_s
            s = sign(piece.tangential)
            event_times.append(t_s)
            event_kinds.append('slip_start')
            if t_s >= t_final:
                break
            continue

        # ------------------------------------------------------------------ slipping
        if t >= t_final:
            break
        t_begin = t
        slip = _integrate_slip(piece, t, x, v, s, mass, mu, rtol, atol)
        if slip.stopped:  # velocity reached zero
            t_e = slip.t_stop
            sampler.slip(t_begin, t_e, slip.dense)
            t, x, v = t_e, slip.x_stop, 0.0
            if t_e - t_begin < _TINY_PIECE_PERIODS * piece.period:
                tiny_pieces += 1
                if tiny_pieces > _MAX_TINY_PIECES:
                    raise RuntimeError(
                        f'no progress: repeated zero-length slip phases near t={t!r}'
                    )
            else:
                tiny_pieces = 0
            # Decide with the inputs in force at t_e.
            here = piece if (t_e < piece.t_end or piece.is_last) else pieces[k + 1]
            if float(here.slip_margin(t_e, mu)) > 0.0:
                new_s = sign(here.tangential)
                if new_s != s:
                    event_times.append(t_e)
                    event_kinds.append('reversal')
                # new_s == s: v only touched zero (degenerate tangency): keep slipping, no event.
                s = new_s
            else:
                event_times.append(t_e)
                event_kinds.append('stick')
                s = 0
            sampler.point(t, x, v)
        else:  # reached the end of the schedule piece while slipping
            sampler.slip(t_begin, slip.t_stop, slip.dense)
            t, x, v = slip.t_stop, slip.x_stop, slip.v_stop
            tiny_pieces = 0
            if piece.is_last:
                break
            k += 1

    x_out, v_out = sampler.results()
    if np.any(np.isnan(x_out)) or np.any(np.isnan(v_out)):  # pragma: no cover - internal check
        raise RuntimeError('internal error: some sample times were not covered')
    return ReferenceResult(
        t=ts,
        x=x_out,
        v=v_out,
        event_times=np.asarray(event_times, dtype=float),
        event_kinds=tuple(event_kinds),
    )


def brute_force_mean_velocity(
    mass: float,
    mu: float,
    gravity: float,
    drive_force: float,
    excitation_amplitude: float,
    excitation_frequency: float,
    *,
    periods: int = 20,
    settle_periods: int = 5,
    steps_per_period: int = 200_000,
) -> float:
    """Mean velocity from a fixed-step semi-implicit Euler integration (crude cross-check).

    Starts from rest at t=0 with phase 0, integrates ``settle_periods`` whole
    periods, then returns ``(x_end - x_start) / (periods * T)`` over the next
    ``periods`` whole periods.  Each step of ``h = T/steps_per_period`` uses the
    normal reaction at the step's midpoint, updates ``v`` first and then
    ``x += h*v`` (symplectic Euler).  Stick handling is explicit: a stuck
    slider (v == 0) starts to slip only if ``|Fd| > mu*R``; a slipping slider
    whose velocity would pass through zero within the step is set to v = 0 if
    ``|Fd| <= mu*R`` there, and otherwise restarts from rest in the direction of
    ``Fd``.

    Plain Python loop; about 0.25-0.4 s for the paper case with the defaults
    (25 periods x 200 000 steps).  Measured relative deviation of the mean
    velocity from the closed-form value in the paper case (m=1, mu=0.1, g=10,
    Fd=0.7, Pa=5, f=50): 1.8e-6 at 2 000, 6.7e-9 at 20 000 and 1e-11 at
    200 000 steps per period (errors at the transitions are O(h) in time but
    occur where v = O(h), so the displacement error is O(h^2)).
    """
    mass = check_positive('mass', mass)
    mu = check_positive('mu', mu)
    gravity = check_positive('gravity', gravity)
    force = check_finite('drive_force', drive_force)
    amplitude = check_finite('excitation_amplitude', excitation_amplitude)
    frequency = check_positive('excitation_frequency', excitation_frequency)
    if abs(amplitude) >= mass * gravity:
        raise ValueError(
            'excitation_amplitude: |Pa| >= mass*gravity makes the normal reaction R <= 0'
        )
    if int(periods) != periods or periods < 1:
        raise ValueError('periods must be a positive integer')
    if int(settle_periods) != settle_periods or settle_periods < 0:
        raise ValueError('settle_periods must be a non-negative integer')
    if int(steps_per_period) != steps_per_period or steps_per_period < 2:
        raise ValueError('steps_per_period must be an integer >= 2')
    periods, settle_periods, n = int(periods), int(settle_periods), int(steps_per_period)

    period = 1.0 / frequency
    h = period / n
    h_over_m = h / mass
    load = mass * gravity
    # mu*R at the midpoint of every step of one period (R is periodic, grid is whole periods).
    mu_r = [mu * (load - amplitude * math.sin(TWO_PI * (i + 0.5) / n)) for i in range(n)]
    abs_f = abs(force)
    dir_f = 1.0 if force > 0.0 else -1.0

    x = 0.0
    v = 0.0
    x_start = 0.0
    for p in range(settle_periods + periods):
        if p == settle_periods:
            x_start = x
        for i in range(n):
            mr = mu_r[i]
            if v == 0.0:
                if abs_f > mr:
                    v = h_over_m * (force - mr * dir_f)
                    x += h * v
            elif v > 0.0:
                v_new = v + h_over_m * (force - mr)
                if v_new <= 0.0:
                    v_new = 0.0 if abs_f <= mr else h_over_m * (force - mr * dir_f)
                v = v_new
                x += h * v
            else:
                v_new = v + h_over_m * (force + mr)
                if v_new >= 0.0:
                    v_new = 0.0 if abs_f <= mr else h_over_m * (force - mr * dir_f)
                v = v_new
                x += h * v
    return (x - x_start) / (periods * period)
