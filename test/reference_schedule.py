"""The reference simulator's schedule (test/reference.py): its inputs, checked,
as pieces on which the phase is linear in time, and the instants found on a piece.

Part of the deliberately independent reference: numpy alone at import (scipy
is imported lazily, inside the root search), nothing of friction_sim's core.

* :class:`ReferenceInputs`, piecewise constant, are checked
  (:func:`validate_inputs`: finite, a positive frequency, no lift-off) and
  cut into :class:`Piece` s (:func:`build_pieces`), the phase continuous
  across a change of frequency;
* the stick -> slip instant (:func:`find_slip_start`) is found by scanning
  ``|Ft| - mu*R(t)`` on a grid of step at most ``1/(20 f)`` plus the instants
  of maximal unloading, the first sign change refined with
  :func:`scipy.optimize.brentq` onto the slip side;
* the next minimum of ``s*v`` during a slip (:func:`next_velocity_minimum`)
  is found the same way, from the state-independent acceleration ``s*a(t)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    'TWO_PI',
    'Piece',
    'ReferenceInputs',
    'build_pieces',
    'check_finite',
    'check_positive',
    'find_slip_start',
    'next_velocity_minimum',
    'sign',
    'validate_inputs',
]

TWO_PI: float = 2.0 * math.pi
_EPS: float = float(np.finfo(float).eps)
#: Grid step of the stick -> slip scan, as a fraction of the excitation period.
_SCAN_STEPS_PER_PERIOD: int = 20
#: Number of scan steps evaluated at once (vectorised) while looking for slip.
_SCAN_CHUNK: int = 400


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
class Piece:
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
        self, theta_target: float, t_lo: float, t_hi: float, spacing: float = TWO_PI
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


def sign(value: float) -> int:
    return 1 if value > 0.0 else (-1 if value < 0.0 else 0)


def check_finite(name: str, value: float) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{name} must be a real number, got {value!r}') from exc
    if not math.isfinite(out):
        raise ValueError(f'{name} must be finite, got {value!r}')
    return out


def check_positive(name: str, value: float) -> float:
    out = check_finite(name, value)
    if out <= 0.0:
        raise ValueError(f'{name} must be > 0, got {value!r}')
    return out


def validate_inputs(inputs: ReferenceInputs, mass: float, gravity: float, where: str) -> None:
    if not isinstance(inputs, ReferenceInputs):
        raise ValueError(f'{where}: expected ReferenceInputs, got {type(inputs).__name__}')
    for fld in fields(inputs):
        check_finite(f'{where}.{fld.name}', getattr(inputs, fld.name))
    check_positive(f'{where}.excitation_frequency', inputs.excitation_frequency)
    base = mass * gravity - inputs.external_force_z  # Fz > 0 lifts
    if abs(inputs.excitation_amplitude) >= base:
        raise ValueError(
            f'{where}.excitation_amplitude: |{inputs.excitation_amplitude!r}| >= '
            f'mass*gravity - external_force_z = {base!r}, so the normal reaction '
            'R would become <= 0 (lift-off is outside the model)'
        )


def build_pieces(
    schedule: Sequence[tuple[float, ReferenceInputs]],
    mass: float,
    gravity: float,
    t_final: float,
    phase0: float,
) -> list[Piece]:
    if len(schedule) == 0:
        raise ValueError('schedule must contain at least one (t_change, inputs) entry')
    times: list[float] = []
    for i, entry in enumerate(schedule):
        try:
            t_change, inputs = entry
        except (TypeError, ValueError) as exc:
            raise ValueError(f'schedule[{i}] must be a (t_change, inputs) pair') from exc
        t_change = check_finite(f'schedule[{i}].t_change', t_change)
        validate_inputs(inputs, mass, gravity, f'schedule[{i}]')
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

    pieces: list[Piece] = []
    theta = phase0
    for j, (t0, t1, inp) in enumerate(zip(starts, ends, entries)):
        f = float(inp.excitation_frequency)
        piece = Piece(
            t_start=t0,
            t_end=t1,
            theta_start=theta,
            tangential=float(inp.drive_force) + float(inp.external_force_x),
            base_load=mass * gravity - float(inp.external_force_z),
            amplitude=float(inp.excitation_amplitude),
            omega=TWO_PI * f,
            period=1.0 / f,
            is_last=(j == len(starts) - 1),
        )
        pieces.append(piece)
        # Phase continuity across the change (keep it reduced to limit round-off growth).
        theta = math.fmod(float(piece.theta(t1)), TWO_PI)
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


def find_slip_start(piece: Piece, t_from: float, mu: float) -> float | None:
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


def next_velocity_minimum(piece: Piece, s: int, t_from: float, mu: float) -> float | None:
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
