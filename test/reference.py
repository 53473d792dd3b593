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

For exactness checks at the last bits, :func:`high_precision_u` and
:func:`high_precision_slip` evaluate the periodic slip's textbook closed form
(asin start, bracketed root of the speed, integral of the speed) in mpmath at
many digits, from the exact values of the given floats.  mpmath is a test
dependency only and is imported lazily, like scipy.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from stepping import integrate

__all__ = [
    'ReferenceInputs',
    'ReferenceResult',
    'reference_solution',
    'brute_force_mean_velocity',
    'high_precision_u',
    'high_precision_slip',
    'paper_case_slip',
    'ulps_from_exact',
]

_TWO_PI: float = 2.0 * math.pi
_EPS: float = float(np.finfo(float).eps)
#: Grid step of the stick -> slip scan, as a fraction of the excitation period.
_SCAN_STEPS_PER_PERIOD: int = 20
#: ``max_step`` of the slip integration, as a fraction of the excitation period.
_SOLVER_STEPS_PER_PERIOD: int = 20
#: Number of scan steps evaluated at once (vectorised) while looking for slip.
_SCAN_CHUNK: int = 400
#: Consecutive slip pieces shorter than this many periods count as "no progress".
_TINY_PIECE_PERIODS: float = 1e-12
_MAX_TINY_PIECES: int = 1000


# --------------------------------------------------------------------------- API types


@dataclass(frozen=True)
class ReferenceInputs:
    """Piecewise-constant inputs, valid from their schedule time to the next change.

    Units: forces in N, frequency in Hz.
    """

    drive_force: float = 0.7
    excitation_amplitude: float = 5.0
    excitation_frequency: float = 50.0
    external_force_x: float = 0.0
    external_force_z: float = 0.0


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
class _Piece:
    """One schedule piece ``[t_start, t_end)`` (closed at ``t_end`` if last)."""

    t_start: float
    t_end: float
    theta_start: float  # excitation phase at t_start
    tangential: float  # Ft = Fd + Fx
    base_load: float  # m*g + Fz
    amplitude: float  # Pa
    omega: float  # 2*pi*f
    period: float  # 1/f
    is_last: bool

    def theta(self, t: Any) -> Any:
        return self.theta_start + self.omega * (t - self.t_start)

    def reaction(self, t: Any) -> Any:
        return self.base_load - self.amplitude * np.sin(self.theta(t))

    def slip_margin(self, t: Any, mu: float) -> Any:
        """``|Ft| - mu*R(t)``; slip is possible (from rest) where this is > 0."""
        return abs(self.tangential) - mu * self.reaction(t)

    def phase_times(
        self, theta_target: float, t_lo: float, t_hi: float, spacing: float = _TWO_PI
    ) -> NDArray[np.float64]:
        """Instants in ``(t_lo, t_hi)`` where ``theta(t) = theta_target (mod spacing)``."""
        th_lo = float(self.theta(t_lo))
        th_hi = float(self.theta(t_hi))
        k_lo = math.floor((th_lo - theta_target) / spacing)
        k_hi = math.ceil((th_hi - theta_target) / spacing)
        ks = np.arange(k_lo, k_hi + 1, dtype=float)
        times = self.t_start + (theta_target + spacing * ks - self.theta_start) / self.omega
        return times[(times > t_lo) & (times < t_hi)]

    def peak_times(self, t_lo: float, t_hi: float) -> NDArray[np.float64]:
        """Instants in ``(t_lo, t_hi)`` where ``Pa*sin(theta)`` is maximal (R minimal)."""
        if self.amplitude == 0.0:
            return np.empty(0)
        theta_peak = 0.5 * math.pi if self.amplitude > 0.0 else -0.5 * math.pi
        return self.phase_times(theta_peak, t_lo, t_hi)

    def extremum_times(self, t_lo: float, t_hi: float) -> NDArray[np.float64]:
        """Instants in ``(t_lo, t_hi)`` where ``R`` is extremal (``R`` is monotone in between)."""
        if self.amplitude == 0.0:
            return np.empty(0)
        return self.phase_times(0.5 * math.pi, t_lo, t_hi, math.pi)


def _sign(value: float) -> int:
    return 1 if value > 0.0 else (-1 if value < 0.0 else 0)


def _check_finite(name: str, value: float) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{name} must be a real number, got {value!r}') from exc
    if not math.isfinite(out):
        raise ValueError(f'{name} must be finite, got {value!r}')
    return out


def _check_positive(name: str, value: float) -> float:
    out = _check_finite(name, value)
    if out <= 0.0:
        raise ValueError(f'{name} must be > 0, got {value!r}')
    return out


def _validate_inputs(inputs: ReferenceInputs, mass: float, gravity: float, where: str) -> None:
    if not isinstance(inputs, ReferenceInputs):
        raise ValueError(f'{where}: expected ReferenceInputs, got {type(inputs).__name__}')
    for fld in fields(inputs):
        _check_finite(f'{where}.{fld.name}', getattr(inputs, fld.name))
    _check_positive(f'{where}.excitation_frequency', inputs.excitation_frequency)
    base = mass * gravity - inputs.external_force_z  # Fz > 0 lifts
    if abs(inputs.excitation_amplitude) >= base:
        raise ValueError(
            f'{where}.excitation_amplitude: |{inputs.excitation_amplitude!r}| >= '
            f'mass*gravity - external_force_z = {base!r}, so the normal reaction '
            'R would become <= 0 (lift-off is outside the model)'
        )


def _build_pieces(
    schedule: Sequence[tuple[float, ReferenceInputs]],
    mass: float,
    gravity: float,
    t_final: float,
    phase0: float,
) -> list[_Piece]:
    if len(schedule) == 0:
        raise ValueError('schedule must contain at least one (t_change, inputs) entry')
    times: list[float] = []
    for i, entry in enumerate(schedule):
        try:
            t_change, inputs = entry
        except (TypeError, ValueError) as exc:
            raise ValueError(f'schedule[{i}] must be a (t_change, inputs) pair') from exc
        t_change = _check_finite(f'schedule[{i}].t_change', t_change)
        _validate_inputs(inputs, mass, gravity, f'schedule[{i}]')
        if times and t_change <= times[-1]:
            raise ValueError(f'schedule[{i}].t_change must be strictly increasing')
        times.append(t_change)
    if times[0] > 0.0:
        raise ValueError(
            f'schedule[0].t_change must be <= 0 (got {times[0]!r}); the simulation starts at t=0'
        )

    # The entry in force at t=0 is the last one with t_change <= 0; ignore changes after t_final.
    first = max(i for i, tc in enumerate(times) if tc <= 0.0)
    starts = [0.0] + [tc for tc in times[first + 1 :] if tc < t_final]
    entries = [schedule[i][1] for i in range(first, first + len(starts))]
    ends = starts[1:] + [t_final]

    pieces: list[_Piece] = []
    theta = phase0
    for j, (t0, t1, inp) in enumerate(zip(starts, ends, entries)):
        f = float(inp.excitation_frequency)
        piece = _Piece(
            t_start=t0,
            t_end=t1,
            theta_start=theta,
            tangential=float(inp.drive_force) + float(inp.external_force_x),
            base_load=mass * gravity - float(inp.external_force_z),
            amplitude=float(inp.excitation_amplitude),
            omega=_TWO_PI * f,
            period=1.0 / f,
            is_last=(j == len(starts) - 1),
        )
        pieces.append(piece)
        # Phase continuity across the change (keep it reduced to limit round-off growth).
        theta = math.fmod(float(piece.theta(t1)), _TWO_PI)
    return pieces


def _first_positive_root(g: Callable[[float], float], a: float, b: float) -> float:
    """Root of ``g`` in ``(a, b]``, moved onto the slip side (``g(r) > 0``).

    Requires ``g(a) <= 0 < g(b)``.
    """
    from scipy.optimize import brentq

    r = float(brentq(g, a, b, xtol=1e-15, rtol=4.0 * _EPS))
    if g(r) > 0.0:
        return r
    # brentq's estimate sits on the stuck side; move to the first float on the slip side.
    lo, hi = r, b
    probe = min(b, r + 8.0 * (1e-15 + 4.0 * _EPS * abs(r)))
    if g(probe) > 0.0:
        hi = probe
    while True:
        mid = lo + 0.5 * (hi - lo)
        if mid <= lo or mid >= hi:
            return hi
        if g(mid) > 0.0:
            hi = mid
        else:
            lo = mid


def _find_slip_start(piece: _Piece, t_from: float, mu: float) -> float | None:
    """First instant in ``[t_from, piece.t_end]`` where slip from rest becomes possible.

    Numerical on purpose: scan ``|Ft| - mu*R`` on a grid of step <= 1/(20 f),
    augmented with the instants of minimal R (so that a positive excursion
    narrower than the grid step is not missed), then refine with brentq.
    """

    def g(t: float) -> float:
        return float(piece.slip_margin(t, mu))

    if g(t_from) > 0.0:
        return t_from
    if piece.amplitude == 0.0:
        return None  # R is constant on the piece: the margin never changes sign
    step = piece.period / _SCAN_STEPS_PER_PERIOD
    t_lo = t_from
    while t_lo < piece.t_end:
        t_hi = min(t_lo + _SCAN_CHUNK * step, piece.t_end)
        n = max(1, math.ceil((t_hi - t_lo) / step))
        grid = t_lo + (t_hi - t_lo) * (np.arange(n + 1, dtype=float) / n)
        grid = np.unique(np.concatenate([grid, piece.peak_times(t_lo, t_hi)]))
        grid[0], grid[-1] = t_lo, t_hi
        positive = np.asarray(piece.slip_margin(grid, mu)) > 0.0
        if positive.any():
            i = int(np.argmax(positive))
            # grid[0] == t_lo is known to be on the stuck side, so i >= 1.
            return _first_positive_root(g, float(grid[i - 1]), float(grid[i]))
        t_lo = t_hi
    return None


def _next_velocity_minimum(piece: _Piece, s: int, t_from: float, mu: float) -> float | None:
    """First instant in ``(t_from, piece.t_end)`` where ``s*v`` has a local minimum.

    In a slip in direction ``s`` the acceleration ``a(t) = (Ft - s*mu*R(t))/m``
    does not depend on the state; ``s*v`` has a minimum where ``s*a`` changes sign
    from negative to non-negative.  Numerical, like :func:`_find_slip_start`: the
    scan grid (step <= 1/(20 f)) contains every extremum of ``R``, so ``s*a`` is
    monotone between grid points and no sign change can be stepped over.  The
    returned instant is on the ``s*a >= 0`` side, so a search started from it
    finds the *next* minimum.  ``None`` if there is none on the rest of the piece.
    """

    def g(t: float) -> float:  # m*s*a(t)
        theta = piece.theta_start + piece.omega * (t - piece.t_start)
        return s * piece.tangential - mu * (piece.base_load - piece.amplitude * math.sin(theta))

    if piece.amplitude == 0.0:
        return None  # a is constant on the piece
    spread = mu * abs(piece.amplitude)
    centre = s * piece.tangential - mu * piece.base_load
    if centre + spread <= 0.0 or centre - spread >= 0.0:
        return None  # s*a never becomes positive (or never negative): s*v is monotone
    step = piece.period / _SCAN_STEPS_PER_PERIOD
    # s*a changes sign in every period, so the first window (one period) almost always decides.
    window = (_SCAN_STEPS_PER_PERIOD + 1) * step
    t_lo = t_from
    while t_lo < piece.t_end:
        t_hi = min(t_lo + window, piece.t_end)
        n = max(1, math.ceil((t_hi - t_lo) / step))
        grid = t_lo + (t_hi - t_lo) * (np.arange(n + 1, dtype=float) / n)
        grid = np.unique(np.concatenate([grid, piece.extremum_times(t_lo, t_hi)]))
        grid[0], grid[-1] = t_lo, t_hi
        # Scalar evaluation, the same as in the root search: the sign at t_from (a previous
        # minimum, on the s*a >= 0 side) must not flip with a differently rounded sin.
        points = grid.tolist()
        values = [g(t) for t in points]
        for i in range(1, len(points)):
            if values[i - 1] < 0.0 <= values[i]:
                t_min = points[i]
                if values[i] > 0.0:
                    t_min = _first_positive_root(g, points[i - 1], t_min)
                return t_min if t_min < piece.t_end else None
        t_lo = t_hi
    return None


@dataclass(frozen=True)
class _Slip:
    """Outcome of one slip phase (see :func:`_integrate_slip`)."""

    stopped: bool  # True: v reached 0 at t_stop; False: reached piece.t_end still slipping
    t_stop: float
    x_stop: float
    v_stop: float  # 0.0 if stopped
    dense: Callable[[Any], NDArray[np.float64]]  # (x, v) on [t_s, t_stop]


def _integrate_slip(
    piece: _Piece,
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
        t_min = _next_velocity_minimum(piece, s, t_safe, mu)
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
    mass = _check_positive('mass', mass)
    mu = _check_positive('mu', mu)
    gravity = _check_positive('gravity', gravity)
    rtol = _check_positive('rtol', rtol)
    atol = _check_positive('atol', atol)
    x0 = _check_finite('x0', x0)
    v0 = _check_finite('v0', v0)
    phase0 = _check_finite('phase0', phase0)

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

    pieces = _build_pieces(schedule, mass, gravity, t_final, phase0)
    sampler = _Sampler(ts)
    event_times: list[float] = []
    event_kinds: list[str] = []

    t, x, v = 0.0, x0, v0
    s = _sign(v0)  # current slip direction, 0 while stuck
    k = 0
    tiny_pieces = 0
    sampler.point(0.0, x, v)

    while True:
        piece = pieces[k]
        if t >= piece.t_end and not piece.is_last:
            k += 1
            continue

        if s == 0:  # ------------------------------------------------------- stuck
            t_s = _find_slip_start(piece, t, mu)
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
            s = _sign(piece.tangential)
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
                new_s = _sign(here.tangential)
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
    mass = _check_positive('mass', mass)
    mu = _check_positive('mu', mu)
    gravity = _check_positive('gravity', gravity)
    force = _check_finite('drive_force', drive_force)
    amplitude = _check_finite('excitation_amplitude', excitation_amplitude)
    frequency = _check_positive('excitation_frequency', excitation_frequency)
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
    mu_r = [mu * (load - amplitude * math.sin(_TWO_PI * (i + 0.5) / n)) for i in range(n)]
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
