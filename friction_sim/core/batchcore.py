"""The vectorized engine of :mod:`friction_sim.core.batch`: N sliders advanced
together, event by event, in the scalar core's closed forms.

Every slider carries the state of the scalar core's current segment (mode,
phase and whole periods at its start, velocities, the double-double position,
the progress guards ``closing``/``grounded``) and its worked-out next event
(:class:`friction_sim.core.motion.Step`: when, the travel, what follows).
One round of :meth:`_Engine.run` does for all still-active sliders at once
what :meth:`Slider.advance_to` does for one: first the period starts
(:class:`CycleMark`) that come before the next event, then the samples,
then the event itself and the detection of the one after it
(:mod:`friction_sim.core.batchroots`).  The loops run over events, period
starts and root-finder iterations, never over sliders.

The formulas, and their order of operations, are those of
:mod:`friction_sim.core.motion` (general segments) and, for Kostek's model,
of :mod:`friction_sim.core.kostek` and :class:`Slider`'s own onset timing,
so the results agree with the scalar core to rounding.

Periodic shortcut: the state at a period start (the current segment's mode,
start phase, velocities, guards, and how many periods ago it started) decides
the whole future, up to a shift in x, time and counts (the scalar core's
memo of steps rests on the same fact, and repeats them bit for bit).  When
that state equals, bit for bit, the one p periods earlier (p <= RING), every
later period start follows by adding multiples of the last p periods'
increments, and the slider's window is filled in without stepping through it.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import numpy as np
from numpy.typing import NDArray

from friction_sim.core import batchroots as br
from friction_sim.core.batch import EVENT_KINDS, BatchResult, BatchSamples, Population, finish, scalar_windows
from friction_sim.core.motion import REBOUND_FLOOR
from friction_sim.core.roots import NEVER, TWO_PI, two_sum
from friction_sim.errors import SimulationFault

Floats = NDArray[np.float64]
Ints = NDArray[np.int64]
Index = NDArray[np.intp]
Bools = NDArray[np.bool_]

#: Period starts remembered per slider for the periodic shortcut (longest repeat looked for).
RING = 8
#: As the scalar core: more events than this at one instant means no progress.
MAX_EVENTS_AT_ONE_INSTANT = 1000
_STUCK, _FLIGHT = 0, 2
_SLIP_START, _STICK, _REVERSAL, _LIFT_OFF, _LANDING = (EVENT_KINDS.index(k) for k in (
    "slip_start", "stick", "reversal", "lift_off", "landing"))
_DEG = math.pi / 180.0  # math.radians multiplies by this


def _sin_degrees(angle: Floats) -> Floats:
    """params.sin_degrees for arrays (exact at multiples of 90 degrees)."""
    exact = np.mod(angle, 90.0) == 0.0
    quarter = np.floor_divide(np.where(exact, angle, 0.0), 90.0).astype(np.int64) % 4
    result: Floats = np.where(exact, np.array([0.0, 1.0, 0.0, -1.0])[quarter], np.sin(angle * _DEG))
    return result


def _cos_degrees(angle: Floats) -> Floats:
    exact = np.mod(angle, 90.0) == 0.0
    result: Floats = np.where(exact, _sin_degrees(np.where(exact, angle + 90.0, 0.0)), np.cos(angle * _DEG))
    return result


def _form(constant: Floats, sin_part: Floats, cos_part: Floats) -> tuple[Floats, Floats, Floats]:
    """motion.Form.of for arrays: (b0, b1, delta)."""
    simple = (cos_part == 0.0) & (sin_part >= 0.0)
    return (constant, np.where(simple, sin_part, np.hypot(sin_part, cos_part)),
            np.where(simple, 0.0, np.arctan2(cos_part, sin_part)))


class _Plant:
    """motion.GeneralPlant and kostek.KostekPlant for arrays (one entry per slider)."""

    def __init__(self, pop: Population) -> None:
        c = pop.columns
        m, mu, pa, f = c["mass"], c["mu"], c["excitation_amplitude"], c["excitation_frequency"]
        mu_s = mu * c["static_ratio"]
        self.frequency, self.omega = f, TWO_PI * f
        self.mass, self.mu, self.restitution = m, mu, c["restitution"]
        self.impulsive = c["landing_friction"] == "impulsive"
        weight = m * c["gravity"]
        n0 = weight * _cos_degrees(c["track_inclination"]) - c["external_force_z"]
        ft = c["drive_force"] + c["external_force_x"]
        f0 = ft - weight * _sin_degrees(c["track_inclination"])
        pt = pa * (_cos_degrees(c["excitation_angle"]) / _sin_degrees(c["excitation_angle"]))
        psi = c["excitation_phase"] * _DEG
        ts = np.where(psi == 0.0, pt, pt * np.cos(psi))
        tc = np.where(psi == 0.0, 0.0, pt * np.sin(psi))
        self.n0, self.pa = n0, pa
        self.floor = REBOUND_FLOOR * np.maximum(n0, 0.0) / m / self.omega
        self.slip = {s: _form((s * f0 - mu * n0) / m, (s * ts + mu * pa) / m, s * tc / m) for s in (1, -1)}
        self.flight_x = _form(f0 / m, ts / m, tc / m)
        self.flight_z = (-n0 / m, pa / m)
        self.onset = {s: _form(s * f0 - mu_s * n0, s * ts + mu_s * pa, s * tc) for s in (1, -1)}
        # Kostek's model on its own segments (Slider._set_plant): stuck onsets timed as KostekPlant does.
        load = weight - c["external_force_z"]
        self.kostek = ((c["excitation_angle"] == 90.0) & (c["track_inclination"] == 0.0)
                       & (c["static_ratio"] == 1.0) & (pa < load))
        self.k_direction = np.where(ft > 0.0, 1, -1).astype(np.int64)
        self.k_b1 = mu * pa / m
        self.k_b0 = (self.k_direction * ft - mu * load) / m
        self.can_slip = self._can_ever_slip(c, ft, load, mu, pa)

    @staticmethod
    def _can_ever_slip(c: dict[str, NDArray[Any]], ft: Floats, load: Floats, mu: Floats, pa: Floats) -> Bools:
        """roots.can_ever_slip for arrays (exact rationals on the boundary, a handful of entries)."""
        excess = np.abs(ft)
        least = load - pa
        margin = excess - mu * least
        result = margin > 0.0
        for j in np.flatnonzero(~(np.abs(margin) > 1e-9 * (excess + mu * np.abs(least)))):
            exact_excess = abs(Fraction(float(c["drive_force"][j])) + Fraction(float(c["external_force_x"][j])))
            exact_load = (Fraction(float(c["mass"][j])) * Fraction(float(c["gravity"][j]))
                          - Fraction(float(c["external_force_z"][j])) - Fraction(float(pa[j])))
            result[j] = exact_excess > Fraction(float(mu[j])) * exact_load
        return result


def _reduce_phase(theta: Floats) -> tuple[Floats, Ints]:
    """roots.reduce_phase(theta, 0) for arrays."""
    whole = np.floor(theta / TWO_PI)
    phase = theta - whole * TWO_PI
    neg = phase < 0.0
    phase, whole = np.where(neg, phase + TWO_PI, phase), np.where(neg, whole - 1.0, whole)
    top = phase >= TWO_PI
    phase, whole = np.where(top, 0.0, phase), np.where(top, whole + 1.0, whole)
    return phase, whole.astype(np.int64)


def _axis_at(axis: list[Floats], omega: Floats, tau: Floats) -> tuple[Floats, Floats]:
    """roots.Harmonic.at for arrays: (w, travel); ``axis`` is (w0, g0, k, kk, cos0, sin0)."""
    w0, g0, k, kk, cos0, sin0 = axis
    c1, s2, c2 = br.remainders(omega * tau)
    w = w0 + g0 * tau + k * (cos0 * c1 - sin0 * s2)
    return w, w0 * tau + 0.5 * g0 * tau * tau + kk * (cos0 * s2 - sin0 * c2)


class _Engine:
    """The state of N sliders and the loop that advances them (see the module doc)."""

    def __init__(self, pop: Population, settle: int, count: int, times: Floats | None, shortcut: bool,
                 scalar_tail: int = 0) -> None:
        n = self.n = pop.n
        self.scalar_tail = scalar_tail
        self.pop, self.settle, self.end, self.shortcut = pop, settle, settle + count, shortcut
        self.plant = _Plant(pop)
        self.times = times
        k = 0 if times is None else times.size
        self.k_samples = k
        z = np.zeros
        # the current segment
        self.mode, self.phase, self.cycles = z(n, np.int64), z(n), z(n, np.int64)
        self.v0, self.vz0, self.closing, self.grounded = z(n), z(n), z(n, np.int64), z(n, bool)
        self.s0, self.x0, self.xl, self.stuck, self.flight = z(n), z(n), z(n), z(n), z(n)
        self.counts = z((n, len(EVENT_KINDS)), np.int64)
        self.at_instant = z(n, np.int64)
        # its closed forms (x axis; z axis in flight): w0, g0, k, kk, cos0, sin0
        self.ax = [z(n) for _ in range(6)]
        self.az = [z(n) for _ in range(6)]
        # its next event
        self.next_s, self.travel, self.next_phase, self.next_whole = z(n), z(n), z(n), z(n, np.int64)
        self.kind, self.then_mode, self.then_v, self.then_vz = z(n, np.int64), z(n, np.int64), z(n), z(n)
        self.then_closing, self.then_grounded = z(n, np.int64), z(n, bool)
        # period starts
        self.mark_n = z(n, np.int64)
        self.mark_s = z(n)
        self.got = z((n, 2), bool)
        self.win_x, self.win_stuck, self.win_flight = z((n, 2)), z((n, 2)), z((n, 2))
        self.win_counts = z((n, 2, len(EVENT_KINDS)), np.int64)
        if shortcut:
            self.ring_key = [z((n, RING)) for _ in range(7)]
            self.ring_val = [z((n, RING)) for _ in range(3)]
            self.ring_counts = z((n, RING, len(EVENT_KINDS)), np.int64)
        # samples
        self.sample_k = z(n, np.int64)
        if times is not None:
            self.sx, self.sv, self.sz, self.svz = (z((n, k)) for _ in range(4))
            self.smode = z((n, k), np.int8)

    # -- the loop ------------------------------------------------------------------

    def run(self) -> BatchResult:
        act = np.arange(self.n)
        self._plan(act)
        while act.size:
            while True:
                m = act[(self.mark_n[act] <= self.end) & (self.mark_s[act] <= self.next_s[act])]
                if not m.size:
                    break
                self._mark(m)
            if self.times is not None:
                times, last = self.times, self.k_samples - 1
                while True:
                    k = self.sample_k[act]
                    due = (k <= last) & (times[np.minimum(k, last)] < self.next_s[act])
                    if not due.any():
                        break
                    self._sample(act[due])
            done = (self.mark_n[act] > self.end) & (self.sample_k[act] >= self.k_samples)
            act = act[~done]
            if 0 < act.size <= self.scalar_tail:
                self._finish_with_scalar_core(act)
                break
            if act.size:
                if not np.all(np.isfinite(self.next_s[act])):  # pragma: no cover (an endless segment finishes above)
                    raise SimulationFault("batch core: an endless segment was left unfinished")
                self._apply(act)
        samples = None
        if self.times is not None:
            samples = BatchSamples(self.times, self.sx, self.sv, self.sz, self.svz, self.smode)
        return finish(self.pop, self.settle, self.end - self.settle, (self.win_x[:, 0], self.win_x[:, 1]),
                      (self.win_stuck[:, 0], self.win_stuck[:, 1]), (self.win_flight[:, 0], self.win_flight[:, 1]),
                      self.win_counts[:, 1] - self.win_counts[:, 0], samples)

    def _finish_with_scalar_core(self, rest: Index) -> None:
        """Run the sliders ``rest`` again from the start with the scalar core (see run_batch's scalar_tail)."""
        part = Population(rest.size, {name: column[rest] for name, column in self.pop.columns.items()})
        x, stuck, flight, counts, samples = scalar_windows(part, self.settle, self.end - self.settle, self.times)
        for side in (0, 1):
            self.win_x[rest, side], self.win_stuck[rest, side] = x[side], stuck[side]
            self.win_flight[rest, side] = flight[side]
        self.win_counts[rest, 0], self.win_counts[rest, 1] = 0, counts
        if samples is not None:
            self.sx[rest], self.sv[rest], self.sz[rest], self.svz[rest] = samples.x, samples.v, samples.z, samples.vz
            self.smode[rest] = samples.mode

    # -- acting on events ----------------------------------------------------------

    def _apply(self, e: Index) -> None:
        """Slider._apply_general (and Kostek's _apply) for the sliders ``e``."""
        s = self.next_s[e]
        before = self.s0[e]
        mode = self.mode[e]
        same = s == before
        self.at_instant[e] = np.where(same, self.at_instant[e] + 1, 0)
        if np.any(self.at_instant[e] > MAX_EVENTS_AT_ONE_INSTANT):
            j = int(e[np.argmax(self.at_instant[e])])
            raise SimulationFault(f"the general model made no progress: more than {MAX_EVENTS_AT_ONE_INSTANT} "
                                  f"events at t = {float(self.next_s[j])!r} s (slider {j})")
        spent = s - before
        self.stuck[e] += np.where(mode == _STUCK, spent, 0.0)
        self.flight[e] += np.where(mode == _FLIGHT, spent, 0.0)
        self.x0[e], self.xl[e] = two_sum(self.x0[e], self.xl[e] + self.travel[e])
        self.phase[e] = self.next_phase[e]
        self.cycles[e] += self.next_whole[e]
        self.counts[e, self.kind[e]] += 1
        self.mode[e], self.v0[e], self.vz0[e] = self.then_mode[e], self.then_v[e], self.then_vz[e]
        self.closing[e], self.grounded[e] = self.then_closing[e], self.then_grounded[e]
        self.s0[e] = s
        self._plan(e)

    def _plan(self, idx: Index) -> None:
        """motion.next_step (and Slider's timing of it) for the segments of ``idx``."""
        pl = self.plant
        size = idx.size
        mode, th0, om = self.mode[idx], self.phase[idx], pl.omega[idx]
        delay, theta = np.full(size, NEVER), np.full(size, np.nan)
        tied = np.zeros(size, bool)
        kind, tmode = np.zeros(size, np.int64), np.zeros(size, np.int64)
        tv, tvz, trav = np.zeros(size), np.zeros(size), np.zeros(size)
        tclose, tground = np.zeros(size, np.int64), np.zeros(size, bool)
        phase, whole = np.zeros(size), np.zeros(size, np.int64)
        direct = np.zeros(size, bool)  # phase/whole given directly (Kostek's onsets), not from theta
        for axis in (*self.ax, *self.az):
            axis[idx] = 0.0
        fl = np.flatnonzero(mode == _FLIGHT)
        if fl.size:
            self._plan_flight(idx, fl, th0, om, delay, theta, kind, tmode, tv, tvz, trav, tground)
        st = np.flatnonzero(mode == _STUCK)
        if st.size:
            self._plan_stuck(idx, st, th0, om, delay, theta, tied, kind, tmode, phase, whole, direct)
        sl = np.flatnonzero((mode == 1) | (mode == -1))
        if sl.size:
            self._plan_slip(idx, sl, th0, om, delay, theta, tied, kind, tmode, tv, trav, tclose)
        finite = np.isfinite(delay)
        red = finite & ~direct
        phase[red], whole[red] = _reduce_phase(theta[red])
        s0, cycles, freq = self.s0[idx], self.cycles[idx], pl.frequency[idx]
        with np.errstate(invalid="ignore"):
            offset = np.maximum((cycles + whole) / freq + phase / om, s0)
            next_s = np.where(tied, offset, s0 + delay)
        k_now = direct & (delay == 0.0)
        next_s = np.where(k_now, s0, next_s)
        next_s[~finite] = NEVER
        self.next_s[idx], self.travel[idx] = next_s, np.where(finite, trav, 0.0)
        self.next_phase[idx], self.next_whole[idx] = phase, whole
        self.kind[idx], self.then_mode[idx], self.then_v[idx], self.then_vz[idx] = kind, tmode, tv, tvz
        self.then_closing[idx], self.then_grounded[idx] = tclose, tground

    def _plan_flight(self, idx: Index, fl: Index, th0: Floats, om: Floats, delay: Floats, theta: Floats,
                     kind: Ints, tmode: Ints, tv: Floats, tvz: Floats, trav: Floats, tground: Bools) -> None:
        pl = self.plant
        g = idx[fl]
        t0, o = th0[fl], om[fl]
        v0, vz0 = self.v0[g], self.vz0[g]
        b0x, b1x, dx = (a[g] for a in pl.flight_x)
        px = t0 + dx
        cx, sx = np.cos(px), np.sin(px)
        kx = b1x / o
        ax = [v0, b0x + b1x * sx, kx, kx / o, cx, sx]
        b0z, b1z = pl.flight_z[0][g], pl.flight_z[1][g]
        cz, sz = np.cos(t0), np.sin(t0)
        b0z = np.where(vz0 == 0.0, br.from_rest_b0(vz0, b0z, b1z, sz), b0z)
        kz = b1z / o
        az = [vz0, b0z + b1z * sz, kz, kz / o, cz, sz]
        for store, values in ((self.ax, ax), (self.az, az)):
            for array, value in zip(store, values):
                array[g] = value
        d = br.landing_delay(vz0, b0z, b1z, t0, o)
        ok = np.isfinite(d)
        d_ok = np.where(ok, d, 0.0)
        v, travel = _axis_at(ax, o, d_ok)
        vz, _ = _axis_at(az, o, d_ok)
        # motion.impact
        rebound = -pl.restitution[g] * vz
        bounces = rebound > pl.floor[g]
        impulse = -vz + np.where(bounces, rebound, 0.0)
        limit = pl.mu[g] * impulse
        v_after = np.where(pl.impulsive[g], np.where(np.abs(v) <= limit, 0.0, v - np.copysign(limit, v)), v)
        delay[fl], theta[fl], trav[fl] = d, t0 + o * d_ok, travel
        kind[fl] = _LANDING
        tmode[fl] = np.where(bounces, _FLIGHT, np.sign(v_after).astype(np.int64))
        tv[fl], tvz[fl] = v_after, np.where(bounces, rebound, 0.0)
        tground[fl] = ~bounces & (d == 0.0)

    def _lift(self, g: Index, t0: Floats) -> Floats:
        """The phase a contact segment lifts off at (inf: never), motion._onset of plant.lift."""
        pl = self.plant
        d, _ = br.next_slip_start(t0 + 0.0, -pl.n0[g], pl.pa[g], self.grounded[g])
        return t0 + d

    def _plan_stuck(self, idx: Index, st: Index, th0: Floats, om: Floats, delay: Floats, theta: Floats,
                    tied: NDArray[np.bool_], kind: Ints, tmode: Ints, phase: Floats, whole: Ints,
                    direct: NDArray[np.bool_]) -> None:
        pl = self.plant
        g = idx[st]
        kos = pl.kostek[g]
        gen, kst = st[~kos], st[kos]
        if gen.size:
            gg, t0 = idx[gen], th0[gen]
            best = self._lift(gg, t0)
            best_kind = np.full(gen.size, _LIFT_OFF)
            best_dir = np.zeros(gen.size, np.int64)
            for s in (1, -1):
                b0, b1, dl = (a[gg] for a in pl.onset[s])
                d, _ = br.next_slip_start(t0 + dl, b0, b1, self.closing[gg] == s)
                on = t0 + d
                better = on < best
                best = np.where(better, on, best)
                best_kind = np.where(better, _SLIP_START, best_kind)
                best_dir = np.where(better, s, best_dir)
            ok = np.isfinite(best)
            delay[gen] = np.where(ok, (best - t0) / om[gen], NEVER)
            theta[gen], tied[gen], kind[gen] = best, True, best_kind
            tmode[gen] = np.where(best_kind == _LIFT_OFF, _FLIGHT, best_dir)
        if kst.size:
            gk, t0 = idx[kst], th0[kst]
            direction = pl.k_direction[gk]
            d, start = br.next_slip_start(t0, pl.k_b0[gk], pl.k_b1[gk], self.closing[gk] == direction)
            d = np.where(pl.can_slip[gk], d, NEVER)
            wraps = (start < t0) | ((start == t0) & (d > 0.0))
            delay[kst], tied[kst], direct[kst], kind[kst], tmode[kst] = d, True, True, _SLIP_START, direction
            phase[kst], whole[kst] = np.where(np.isfinite(d), start, 0.0), wraps.astype(np.int64)

    def _plan_slip(self, idx: Index, sl: Index, th0: Floats, om: Floats, delay: Floats, theta: Floats,
                   tied: NDArray[np.bool_], kind: Ints, tmode: Ints, tv: Floats, trav: Floats, tclose: Ints) -> None:
        pl = self.plant
        g = idx[sl]
        t0, o, mode = th0[sl], om[sl], self.mode[g]
        v0 = self.v0[g]
        fwd = mode == 1
        b0, b1, dl = (np.where(fwd, p[g], q[g]) for p, q in zip(pl.slip[1], pl.slip[-1]))
        w0 = mode * v0
        px = t0 + dl
        cx, sx = np.cos(px), np.sin(px)
        b0 = np.where(v0 == 0.0, br.from_rest_b0(w0, b0, b1, sx), b0)
        k = b1 / o
        ax = [w0, b0 + b1 * sx, k, k / o, cx, sx]
        for array, value in zip(self.ax, ax):
            array[g] = value
        stop = br.slip_stop_delay(w0, b0, b1, px, o)
        lift = np.where(pl.kostek[g], NEVER, self._lift(g, t0))
        lift_delay = (lift - t0) / o
        lifts = np.isfinite(lift) & (lift_delay <= stop)
        d = np.where(lifts, lift_delay, stop)
        ok = np.isfinite(d)
        d_ok = np.where(ok, d, 0.0)
        th = np.where(lifts, lift, t0 + o * d_ok)
        w, travel = _axis_at(ax, o, d_ok)
        v = mode * w
        # motion.after_event for a stop: GeneralPlant.stays(theta)
        stays = np.zeros(sl.size, np.int64)
        for s in (-1, 1):  # (+1 checked last wins: it is checked first in stays)
            b0s, b1s, ds = (a[g] for a in pl.onset[s])
            stays = np.where(b0s + b1s * np.sin(th + ds) > 0.0, s, stays)
        reverses = ~pl.kostek[g] & (stays == -mode)
        delay[sl], theta[sl], tied[sl], trav[sl] = d, th, lifts, mode * travel
        kind[sl] = np.where(lifts, _LIFT_OFF, np.where(reverses, _REVERSAL, _STICK))
        tmode[sl] = np.where(lifts, _FLIGHT, np.where(reverses, stays, _STUCK))
        tv[sl] = np.where(lifts, v, 0.0)
        tclose[sl] = np.where(lifts | reverses, 0, mode)

    # -- period starts and samples ----------------------------------------------------

    def _position(self, g: Index, tau: Floats) -> Floats:
        """x ``tau`` into the current segments of ``g`` (Slider._mark_cycle's x)."""
        mode = self.mode[g]
        w0, g0, k, kk, c0, s0 = (a[g] for a in self.ax)
        _, travel = _axis_at([w0, g0, k, kk, c0, s0], self.plant.omega[g], tau)
        signed = np.where(mode == _FLIGHT, travel, mode * travel)
        hi, lo = two_sum(self.x0[g], self.xl[g] + signed)
        result: Floats = np.where(mode == _STUCK, self.x0[g], hi + lo)
        return result

    def _mark(self, m: Index) -> None:
        """Slider._mark_cycle for the sliders ``m`` (period start mark_n), the window's
        bookkeeping and the periodic shortcut."""
        n = self.mark_n[m]
        mode, cycles = self.mode[m], self.cycles[m]
        om = self.plant.omega[m]
        tau = np.where(n > cycles, (TWO_PI * (n - cycles) - self.phase[m]) / om, 0.0)
        x = self._position(m, tau)
        stuck = self.stuck[m] + np.where(mode == _STUCK, tau, 0.0)
        flight = self.flight[m] + np.where(mode == _FLIGHT, tau, 0.0)
        counts = self.counts[m]
        for side, target in enumerate((self.settle, self.end)):
            hit = n == target
            if hit.any():
                h = m[hit]
                self.got[h, side] = True
                self.win_x[h, side], self.win_stuck[h, side] = x[hit], stuck[hit]
                self.win_flight[h, side], self.win_counts[h, side] = flight[hit], counts[hit]
        endless = ~np.isfinite(self.next_s[m])
        periodic = np.zeros(m.size, bool)
        if self.shortcut:
            periodic = self._repeat(m, n, x, stuck, flight, counts, endless)
        # the next period start to look at: every one while a repeat is looked for, else the targets
        step_all = self.shortcut & ~endless & ~periodic
        next_target = np.where(n < self.settle, self.settle, np.where(n < self.end, self.end, self.end + 1))
        nxt = np.where(step_all, n + 1, next_target)
        nxt = np.where(periodic, self.end + 1, nxt)
        self.mark_n[m] = nxt
        self.mark_s[m] = np.where(nxt > self.end, NEVER, nxt / self.plant.frequency[m])

    def _repeat(self, m: Index, n: Ints, x: Floats, stuck: Floats, flight: Floats, counts: Ints,
                endless: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Record the state at period start n in the ring; where it equals the one p
        periods before (bit for bit), fill in the window's missing ends and return True."""
        key = [self.mode[m].astype(float), self.phase[m], self.v0[m], self.vz0[m], self.closing[m].astype(float),
               self.grounded[m].astype(float), (n - self.cycles[m]).astype(float)]
        slot = n % RING
        eligible = ~endless & (self.sample_k[m] >= self.k_samples)
        period = np.zeros(m.size, np.int64)
        for p in range(RING, 0, -1):  # the smallest p wins
            old = (n - p) % RING
            same = eligible & (n - p >= 0)
            for ring, value in zip(self.ring_key, key):
                same &= ring[m, old] == value
            period = np.where(same, p, period)
        found = period > 0
        if found.any():
            f = np.flatnonzero(found)
            mf, nf, pf = m[f], n[f], period[f]
            base = nf - pf
            vals = (x[f], stuck[f], flight[f])
            for side, target in enumerate((self.settle, self.end)):
                need = ~self.got[mf, side]
                if not need.any():
                    continue
                q, r = np.divmod(target - base, pf)
                at = (base + r) % RING
                first = base % RING
                outs = []
                for ring, now in zip(self.ring_val, vals):
                    start = ring[mf, at]
                    outs.append(start + q * (now - ring[mf, first]))
                cnt = self.ring_counts[mf, at] + q[:, None] * (counts[f] - self.ring_counts[mf, first])
                h = mf[need]
                self.win_x[h, side], self.win_stuck[h, side], self.win_flight[h, side] = (o[need] for o in outs)
                self.win_counts[h, side] = cnt[need]
                self.got[h, side] = True
        for ring, value in zip(self.ring_key, key):
            ring[m, slot] = value
        for ring, value in zip(self.ring_val, (x, stuck, flight)):
            ring[m, slot] = value
        self.ring_counts[m, slot] = counts
        return found

    def _sample(self, g: Index) -> None:
        """Slider.sample's evaluation of the current segments of ``g`` at their next sample time."""
        assert self.times is not None
        k = self.sample_k[g]
        t = self.times[k]
        tau = t - self.s0[g]
        mode = self.mode[g]
        om = self.plant.omega[g]
        w, travel = _axis_at([a[g] for a in self.ax], om, tau)
        vz, z = _axis_at([a[g] for a in self.az], om, tau)
        flight = mode == _FLIGHT
        stuck = mode == _STUCK
        signed = np.where(flight, travel, mode * travel)
        self.sx[g, k] = np.where(stuck, self.x0[g] + 0.0, self.x0[g] + (self.xl[g] + signed))
        self.sv[g, k] = np.where(stuck, 0.0, np.where(flight, w, mode * w))
        self.sz[g, k] = np.where(flight, 0.0 + z, 0.0)
        self.svz[g, k] = np.where(flight, vz, 0.0)
        self.smode[g, k] = mode
        self.sample_k[g] = k + 1


def run_numpy(pop: Population, settle: int, count: int, times: Floats | None, *,
              shortcut: bool = True, scalar_tail: int = 0) -> BatchResult:
    """The numpy engine of :func:`friction_sim.core.batch.run_batch`."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return _Engine(pop, settle, count, times, shortcut, scalar_tail).run()


__all__ = ["RING", "run_numpy"]
