"""Event detection for many segments at once: the root finders of
:mod:`friction_sim.core.roots`, vectorized over numpy arrays.

Each function here takes 1-D arrays (one entry per segment) and returns what
its scalar namesake returns for each entry, with the same formulas in the
same order of operations (so the same rounding, up to numpy's asin, hypot
and atan2 against libm's: a unit in the last place), the same brackets and
the same Newton-with-bisection polish.  Loops run over iterations (Newton
steps, turning points), never over segments: at every step the entries
still unresolved are advanced together and the finished ones drop out.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from friction_sim.core import roots
from friction_sim.core.roots import NEVER, TWO_PI

Floats = NDArray[np.float64]
Bools = NDArray[np.bool_]
#: roots' constants, read once (the same values, so the same decisions).
PHASE_EDGE = 1e-12
LONGEST_SLIP = 1e12
LONGEST_FLIGHT_PIECES = 2_000_000
_ITERATIONS = 200
#: Accept a Newton step that has converged onto tau even where tau is the
#: bracket's new end.  The scalar polish then bisects from the far end: up to
#: fifty more iterations (a quarter of its landings take over twelve) that end
#: within an ulp or two of the same root, and a batch waits for its slowest
#: entry.  Off by default: on, a bouncing slider's ulp-level landing times can
#: grow to a few 1e-12 over its bounces, beyond the agreement required of the
#: batch core (on, mixed populations with bouncers run ~20% faster).
EARLY_CONVERGENCE = False


def _settled(newton: Floats, tau: Floats) -> Bools:
    """Where a Newton step has converged onto tau (see EARLY_CONVERGENCE)."""
    if not EARLY_CONVERGENCE:
        return np.zeros(tau.shape, dtype=bool)
    result: Bools = (newton == tau) | (np.abs(newton - tau) <= 2.2e-16 * np.abs(tau))
    return result


def _step(newton: Floats, tau: Floats, lo: Floats, hi: Floats) -> Floats:
    """The next iterate of a safeguarded Newton search: the Newton step where
    it stays inside the bracket (or has settled), else the bisection."""
    step: Floats = np.where(_settled(newton, tau) | ((lo < newton) & (newton < hi)), newton, 0.5 * (lo + hi))
    return step


def _retire(out: Floats, act: NDArray[np.intp], tau: Floats, step: Floats, zero: Bools) -> Bools | None:
    """Write the roots of the entries that are done (an exact zero at tau, or a
    step that no longer moves) into ``out`` at their indices ``act``; the mask
    of those that go on, or None when none is done."""
    finished = zero | (~zero & ((step == tau) | (np.abs(step - tau) <= 2.2e-16 * np.abs(tau))))
    if not finished.any():
        return None
    out[act[finished]] = np.where(zero[finished], tau[finished], step[finished])
    keep: Bools = ~finished
    return keep


def from_rest_b0(w0: Floats, b0: Floats, b1: Floats, sin0: Floats) -> Floats:
    """:func:`roots.from_rest_b0` for arrays."""
    result: Floats = np.where((w0 == 0.0) & (b0 + b1 * sin0 < 0.0), -b1 * sin0, b0)
    return result


def next_slip_start(phase: Floats, b0: Floats, b1: Floats, closing: Bools) -> tuple[Floats, Floats]:
    """:func:`roots.next_slip_start` for arrays: (delta, start) per entry."""
    n = phase.size
    delta, start = np.full(n, NEVER), np.full(n, NEVER)
    with np.errstate(all="ignore"):
        flat = b1 <= 0.0
        now = flat & (b0 > 0.0) & ~closing
        delta[now], start[now] = 0.0, phase[now]
        done = flat | (b0 + b1 <= 0.0)
        closing = closing & (np.cos(phase) <= 0.0)
        now = ~done & (b0 + b1 * np.sin(phase) > 0.0) & ~closing
        delta[now], start[now] = 0.0, phase[now]
        done |= now
        ratio = -b0 / b1
        wide = ~done & (ratio < -1.0)
        delta[wide] = np.where(closing[wide], TWO_PI, 0.0)
        start[wide] = phase[wide]
        done |= wide
        rest = np.flatnonzero(~done)
        if rest.size:
            st = np.mod(np.arcsin(ratio[rest]), TWO_PI)
            st[st >= TWO_PI] = 0.0
            d = np.mod(st - phase[rest], TWO_PI)
            shut = closing[rest]
            edge = ~shut & (d > TWO_PI - PHASE_EDGE)
            d = np.where(shut & ~(d > 0.0), TWO_PI, d)
            delta[rest] = np.where(edge, 0.0, d)
            start[rest] = np.where(edge, phase[rest], st)
    return delta, start


def remainders(psi: Floats) -> tuple[Floats, Floats, Floats]:
    """roots.trig_remainders(psi, numpy): the same values, with the Taylor
    series evaluated only on the entries with |psi| < 0.25 that need it."""
    half = np.sin(0.5 * psi)
    c1 = 2.0 * half * half
    p2 = psi * psi
    s2, c2 = psi - np.sin(psi), 0.5 * p2 - c1
    small = np.flatnonzero(np.abs(psi) < 0.25)
    if small.size:
        q, q2 = psi[small], p2[small]
        s2[small] = q * q2 * (1 / 6 - q2 * (1 / 120 - q2 * (1 / 5040 - q2 * (
            1 / 362880 - q2 * (1 / 39916800 - q2 / 6227020800)))))
        c2[small] = q2 * q2 * (1 / 24 - q2 * (1 / 720 - q2 * (1 / 40320 - q2 * (
            1 / 3628800 - q2 * (1 / 479001600 - q2 / 87178291200)))))
    return c1, s2, c2


def _speed(w0: Any, g0: Any, k: Any, cos0: Any, sin0: Any, omega: Any, tau: Any) -> Any:
    """roots._speed for arrays (the trig_remainders form)."""
    c1, s2, _ = remainders(omega * tau)
    return w0 + g0 * tau + k * (cos0 * c1 - sin0 * s2)


def slip_stop_delay(w0: Floats, b0: Floats, b1: Floats, phase0: Floats, omega: Floats) -> Floats:
    """:func:`roots.slip_stop_delay` for arrays."""
    n = w0.size
    out = np.full(n, NEVER)
    sin0, cos0 = np.sin(phase0), np.cos(phase0)
    b0 = from_rest_b0(w0, b0, b1, sin0)
    with np.errstate(all="ignore"):
        flat = b1 <= 0.0
        sel = flat & (b0 < 0.0)
        out[sel] = w0[sel] / -b0[sel]
        done = flat | (b0 >= b1)
        # dw/dt <= 0 everywhere: one falling stretch
        falling = ~done & (b0 <= -b1)
        lo_all, hi_all = np.zeros(n), np.full(n, NEVER)
        at_rest = falling & (w0 == 0.0)
        out[at_rest] = 0.0
        hi = (w0 + (b1 / omega) * (1.0 + cos0)) / -b0
        ok = falling & ~at_rest & (hi * omega <= TWO_PI * LONGEST_SLIP)
        hi_all[ok] = hi[ok]
        root = ok.copy()
        done |= falling
        # |b0| < b1: turning points
        turn = np.flatnonzero(~done)
        if turn.size:
            tw0, tb0, tb1, tp0, tom = w0[turn], b0[turn], b1[turn], phase0[turn], omega[turn]
            beta = np.arcsin(-tb0 / tb1)
            rise = math.pi - 2.0 * beta
            delta0 = np.mod(tp0 - beta, TWO_PI)
            rest0 = tw0 == 0.0
            delta0 = np.where(rest0 & (delta0 > TWO_PI - PHASE_EDGE), 0.0, delta0)
            stops_now = rest0 & (delta0 >= rise)
            period = TWO_PI / tom
            lo = np.maximum(0.0, (rise - delta0) / tom)
            hi = (TWO_PI - delta0) / tom
            k = tb1 / tom
            g0 = tb0 + tb1 * sin0[turn]
            tc, ts = cos0[turn], sin0[turn]
            w_min = _speed(tw0, g0, k, tc, ts, tom, hi)
            live = ~stops_now
            far = live & (w_min > 0.0)
            never = far & (tb0 >= 0.0)
            estimate = w_min / (-tb0 * period)
            never |= far & ~never & ~(estimate <= LONGEST_SLIP)
            walk = far & ~never
            hi = np.where(walk, hi + np.maximum(1.0, np.ceil(np.where(walk, estimate, 0.0))) * period, hi)
            pending = walk.copy()
            for _ in range(8):  # rounding guard: the formula's period may be one short
                if not pending.any():
                    break
                below = pending & (_speed(tw0, g0, k, tc, ts, tom, hi) <= 0.0)
                pending &= ~below
                hi = np.where(pending, hi + period, hi)
            never |= pending
            lo = np.where(walk, hi - (TWO_PI - rise) / tom, lo)
            out[turn[stops_now]] = 0.0
            good = live & ~never
            lo_all[turn], hi_all[turn] = lo, hi
            root[turn[good]] = True
    idx = np.flatnonzero(root)
    if idx.size:
        out[idx] = falling_root(w0[idx], b0[idx], b1[idx], phase0[idx], omega[idx], lo_all[idx], hi_all[idx])
    return out


def falling_root(w0: Floats, b0: Floats, b1: Floats, phase0: Floats, omega: Floats, lo: Floats,
                 hi: Floats) -> Floats:
    """roots._falling_root for arrays: the root of w on [lo, hi], w falling."""
    k, cos0, sin0 = b1 / omega, np.cos(phase0), np.sin(phase0)
    g0 = b0 + b1 * sin0
    w_lo = _speed(w0, g0, k, cos0, sin0, omega, lo)
    w_hi = _speed(w0, g0, k, cos0, sin0, omega, hi)
    out = np.where(w_hi >= 0.0, hi, lo)
    act = np.flatnonzero(~(w_hi >= 0.0) & ~(w_lo <= 0.0))
    if not act.size:
        return out
    lo, hi = lo[act].copy(), hi[act].copy()
    w0, g0, k, cos0, sin0, omega, b0, b1, phase0 = (a[act] for a in (w0, g0, k, cos0, sin0, omega, b0, b1, phase0))
    wl, wh = w_lo[act], w_hi[act]
    tau = lo + (hi - lo) * (wl / (wl - wh))
    with np.errstate(all="ignore"):
        for _ in range(_ITERATIONS):
            psi = omega * tau
            half = np.sin(0.5 * psi)
            w = w0 + g0 * tau + k * (cos0 * 2.0 * half * half - sin0 * (psi - np.sin(psi)))
            small = psi < 0.25
            if small.any():
                w = np.where(small, _speed(w0, g0, k, cos0, sin0, omega, tau), w)
            lo = np.where(w > 0.0, tau, lo)
            hi = np.where(w < 0.0, tau, hi)
            slope = b0 + b1 * np.sin(phase0 + psi)
            newton = np.where(slope < 0.0, tau - w / slope, np.nan)
            step = _step(newton, tau, lo, hi)
            keep = _retire(out, act, tau, step, w == 0.0)
            if keep is not None:
                if not keep.any():
                    return out
                act, tau, step = act[keep], tau[keep], step[keep]
                lo, hi, w0, g0, k, cos0, sin0, omega, b0, b1, phase0 = (
                    a[keep] for a in (lo, hi, w0, g0, k, cos0, sin0, omega, b0, b1, phase0))
            tau = step
    out[act] = tau
    return out


# --------------------------------------------------------------------------
# Flight: landing_delay for arrays (z0 = 0: a batch never changes inputs in the air).
# --------------------------------------------------------------------------


class Harmonic:
    """roots.Harmonic for arrays (start 0): speed, height and rate at tau;
    ``i`` picks the entries (None: all, in order)."""

    def __init__(self, w0: Floats, b0: Floats, b1: Floats, phase0: Floats, omega: Floats) -> None:
        self.w0, self.b0, self.b1, self.phase0, self.omega = w0, b0, b1, phase0, omega
        self.cos0, self.sin0 = np.cos(phase0), np.sin(phase0)
        self.g0 = b0 + b1 * self.sin0
        self.k = b1 / omega
        self.kk = self.k / omega

    def take(self, i: NDArray[np.intp]) -> Harmonic:
        """The entries ``i`` as a Harmonic of their own (no recomputation)."""
        part = object.__new__(Harmonic)
        for name in ("w0", "b0", "b1", "phase0", "omega", "cos0", "sin0", "g0", "k", "kk"):
            setattr(part, name, getattr(self, name)[i])
        return part

    def rate(self, tau: Floats, i: NDArray[np.intp] | None = None) -> Floats:
        h = self if i is None else self.take(i)
        result: Floats = h.b0 + h.b1 * np.sin(h.phase0 + h.omega * tau)
        return result

    def speed(self, tau: Floats, i: NDArray[np.intp] | None = None) -> Floats:
        h = self if i is None else self.take(i)
        c1, s2, _ = remainders(h.omega * tau)
        result: Floats = h.w0 + h.g0 * tau + h.k * (h.cos0 * c1 - h.sin0 * s2)
        return result

    def travel(self, tau: Floats, i: NDArray[np.intp] | None = None) -> Floats:
        h = self if i is None else self.take(i)
        _, s2, c2 = remainders(h.omega * tau)
        result: Floats = 0.0 + (h.w0 * tau + 0.5 * h.g0 * tau * tau + h.kk * (h.cos0 * s2 - h.sin0 * c2))
        return result


def polish(h: Harmonic, name: str, i: NDArray[np.intp], lo: Floats, hi: Floats, f_lo: Floats,
           f_hi: Floats) -> Floats:
    """roots._polish for arrays, of ``h``'s height (name "travel", slope: speed)
    or speed ("speed", slope: rate) at its entries ``i``."""
    out = np.where(f_lo == 0.0, lo, hi)
    act = np.flatnonzero(~(f_lo == 0.0) & ~(f_hi == 0.0))
    if not act.size:
        return out
    lo, hi, f_lo, f_hi = lo[act].copy(), hi[act].copy(), f_lo[act], f_hi[act]
    part = h.take(i[act])
    slope_name = "speed" if name == "travel" else "rate"
    f, df = getattr(part, name), getattr(part, slope_name)
    rising = f_hi > 0.0
    tau = lo + (hi - lo) * (f_lo / (f_lo - f_hi))
    with np.errstate(all="ignore"):
        for _ in range(_ITERATIONS):
            value = f(tau)
            zero = value == 0.0
            up = (value > 0.0) == rising
            hi = np.where(up, tau, hi)
            lo = np.where(up, lo, tau)
            slope = df(tau)
            newton = np.where(slope != 0.0, tau - value / slope, np.nan)
            step = _step(newton, tau, lo, hi)
            keep = _retire(out, act, tau, step, zero)
            if keep is not None:
                if not keep.any():
                    return out
                act, rising = act[keep], rising[keep]
                tau, step, lo, hi = (a[keep] for a in (tau, step, lo, hi))
                part = part.take(np.flatnonzero(keep))
                f, df = getattr(part, name), getattr(part, slope_name)
            tau = step
    out[act] = tau
    return out


def landing_delay(vz0: Floats, b0: Floats, b1: Floats, phase0: Floats, omega: Floats) -> Floats:
    """:func:`roots.landing_delay` (z0 = 0) for arrays."""
    n = vz0.size
    out = np.full(n, NEVER)
    with np.errstate(all="ignore"):
        monotone = (b1 <= 0.0) | (np.abs(b0) >= b1)
    for j in np.flatnonzero(monotone & (b0 < 0.0)):  # (unreachable from a lift-off: kept for completeness)
        out[j] = roots.landing_delay(float(vz0[j]), float(b0[j]), float(b1[j]), float(phase0[j]), float(omega[j]))
    h = Harmonic(vz0, b0, b1, phase0, omega)
    # roots._safe_stretch
    with np.errstate(all="ignore"):
        margin = 4.0 * b1 / (omega * omega) * (1.0 + 1e-6)
        slope = vz0 + h.k * h.cos0
        a, b, c = 0.5 * b0, slope, 0.0 - margin
        disc = b * b - 4.0 * a * c
        has = (b0 < 0.0) & (disc > 0.0)
        root = np.sqrt(np.where(has, disc, 0.0))
        r1, r2 = (-b + root) / (2.0 * a), (-b - root) / (2.0 * a)
        safe_from = np.where(has, np.minimum(r1, r2), NEVER)
        safe_to = np.where(has, np.maximum(r1, r2), -NEVER)
        period = TWO_PI / omega
        # roots._TurningPoints
        low = np.arcsin(-b0 / b1)
    m_min, m_max = np.mod(low, TWO_PI), np.mod(math.pi - low, TWO_PI)
    min_first = m_min < m_max  # sorted((m_min, True), (m_max, False))
    marks = (np.where(min_first, m_min, m_max), np.where(min_first, m_max, m_min))
    is_min = (min_first, ~min_first)
    base = phase0 - np.mod(phase0, TWO_PI)
    tp_n = np.zeros(n, dtype=np.int64)
    tp_i = np.zeros(n, dtype=np.int64)

    def next_point(j: NDArray[np.intp]) -> tuple[Floats, Bools]:
        tau = np.empty(j.size)
        flag = np.empty(j.size, dtype=bool)
        todo = np.arange(j.size)
        while todo.size:
            k = j[todo]
            first = tp_i[k] == 0
            mark = np.where(first, marks[0][k], marks[1][k])
            t = (base[k] + TWO_PI * tp_n[k] + mark - phase0[k]) / omega[k]
            tau[todo], flag[todo] = t, np.where(first, is_min[0][k], is_min[1][k])
            tp_i[k] += 1
            wrap = tp_i[k] == 2
            tp_n[k[wrap]] += 1
            tp_i[k[wrap]] = 0
            todo = todo[~(t > 0.0)]
        return tau, flag

    act = np.flatnonzero(~monotone)
    lo = np.zeros(n)
    v_lo = vz0.copy()
    for _ in range(LONGEST_FLIGHT_PIECES):
        if not act.size:
            break
        tau, minimum = next_point(act)
        skip = (safe_from[act] < lo[act]) & (tau < safe_to[act] - 4.0 * period[act])
        skipped = act[:0]
        if skip.any():
            k = act[skip]
            target = safe_to[k] - 4.0 * period[k]
            tp_n[k] = np.maximum(tp_n[k], np.floor((phase0[k] + omega[k] * target - base[k]) / TWO_PI)
                                 ).astype(np.int64)
            tp_i[k] = 0
            lo[k] = next_point(k)[0]
            v_lo[k] = h.speed(lo[k], k)
        skipped = act[skip]  # (they take their next point on the next round)
        act, tau, minimum = act[~skip], tau[~skip], minimum[~skip]
        v = h.speed(tau, act)
        vl, l0 = v_lo[act], lo[act]
        found = np.full(act.size, np.nan)
        apex_case = (vl > 0.0) & (v <= 0.0)
        fall_case = ~apex_case & (vl <= 0.0) & (l0 > 0.0)
        start_case = ~apex_case & ~fall_case & (vl <= 0.0) & (v <= 0.0)
        # where z falls on [start, end] (the apex or lo, to tau or the speed's zero)
        f_start = np.where(apex_case | fall_case, l0, 0.0)
        f_end = tau.copy()
        need = apex_case | (fall_case & ~(v <= 0.0))
        if need.any():
            sel = np.flatnonzero(need)
            zero_v = polish(h, "speed", act[sel], l0[sel], tau[sel], vl[sel], v[sel])
            f_start[sel] = np.where(apex_case[sel], zero_v, l0[sel])
            f_end[sel] = np.where(apex_case[sel], tau[sel], zero_v)
        check = np.flatnonzero(apex_case | fall_case)
        if check.size:
            k = act[check]
            z_hi = h.travel(f_end[check], k)
            lands = ~(z_hi > 0.0)
            if lands.any():
                sel = check[lands]
                found[sel] = polish(h, "travel", act[sel], f_start[sel], f_end[sel],
                                    h.travel(f_start[sel], act[sel]), z_hi[lands])
        found[start_case] = 0.0
        hit = ~np.isnan(found)
        out[act[hit]] = found[hit]
        never = ~hit & minimum & (v > 0.0) & (b0[act] >= 0.0)
        go_on = ~hit & ~never
        lo[act[go_on]], v_lo[act[go_on]] = tau[go_on], v[go_on]
        act = np.concatenate((skipped, act[go_on]))
    return out


__all__ = ["Harmonic", "falling_root", "from_rest_b0", "landing_delay", "next_slip_start", "polish",
           "slip_stop_delay"]
