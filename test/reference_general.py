"""Independent high-accuracy reference for the general slider model (issue 11).

What it is
----------
A numerical solution, built on SciPy's DOP853 integrator, of the
point-mass model of vibratory conveying that ``friction_sim.core`` solves in
closed form: flight, inclined vibration, a sloped track, static friction and
landings with restitution.  Track frame: x along the track, z normal to it
and away from it.  With theta(t) = phase0 + 2*pi*f*t::

    R(t)  = m*g*cos(alpha) - Pa*sin(theta) - Fz        contact force needed to stay on the track
    Ft(t) = Fd + Fx - m*g*sin(alpha) + Pt*sin(theta + psi),   Pt = Pa*cot(beta)

    stuck     (z = 0, v = 0): while |Ft| <= mu_s*R (mu_s = static_ratio*mu) and R >= 0
    slipping  (z = 0, v != 0): m*x'' = Ft - mu*R*sign(v)
    flight    (z > 0):         m*x'' = Ft,  m*z'' = -R     (no friction)

Transitions (event kinds, the strings of ``friction_sim.core.model.events.EventKind``):

* ``slip_start``: stuck and |Ft| rises above mu_s*R; the slip takes the
  direction of Ft.
* ``stick`` / ``reversal``: slipping and v returns to 0; the slider sticks if
  |Ft| <= mu_s*R there, otherwise it slips on in the direction of Ft.
* ``lift_off``: in contact and R falls below 0; z = vz = 0, v continuous.
* ``landing``: in flight and z returns to 0 moving down (vz_before < 0).
  The normal impact has restitution e: vz_after = e*|vz_before|, except that a
  rebound slower than :attr:`GeneralModel.plastic_speed` counts as plastic
  (vz_after = 0, e taken as 0 for this impact): the documented floor that ends
  the geometric series of ever shorter bounces (no Zeno loop).  The normal
  impulse per mass is J = (1 + e)*|vz_before|.  ``landing_friction``
  "impulsive": the tangential velocity changes by at most mu*J towards 0 and
  becomes exactly 0 if that is enough (Coulomb impact); "none": v is kept.
  After a plastic landing the slider is in contact: if R < 0 there it lifts
  off again at once (a ``lift_off`` event at the same instant); otherwise it
  slips with v_after != 0, or is stuck (and may start to slip at once,
  a ``slip_start`` at the same instant).

How (independent of the core on purpose)
----------------------------------------
The core evaluates closed forms and brackets their roots analytically.  This
module uses none of that reasoning and imports nothing of
``friction_sim.core``:

* Every motion segment is integrated with SciPy's DOP853 (the stepper of
  ``solve_ivp(method="DOP853")``, its loop written out in test/stepping.py) at
  ``rtol`` (default 1e-12) and a tiny ``atol``, ``max_step`` = T/20, dense
  output, from a zero displacement (so the tolerance is relative to the
  segment's own travel).  Slip stops (v crosses 0) and landings (z crosses 0
  downwards) are terminal events, bracketed between step ends and polished
  with brentq on the dense output (xtol 4 eps), as solve_ivp does, so
  an event time is as good as the dense output, ~rtol.
* Transitions that depend on time only (slip start: |Ft| - mu_s*R > 0; lift-off:
  -R > 0) are found by :func:`first_positive`: a scan of 64 points per period,
  each local maximum of the samples refined with a bounded Brent search (so a
  narrow excursion between grid points is not missed), then brentq, moved to
  the side where the condition holds.  The functions are T-periodic, so a
  period without a crossing proves there is none.
* A root that touches zero between two step ends could be stepped over by
  the event detection.  So a slip is integrated in sections that end at the
  minima of s*v (s the slip direction; there s*a(t), a function of time only,
  turns positive) and a flight in sections that end where R changes sign: on a
  section where R > 0, z is concave and can only cross 0 once; where R < 0, z
  is convex and its one minimum is located (vz = 0 on the dense output) and
  checked.  A rebound (z = 0, vz > 0) first runs to its apex (a vz = 0 event):
  z's own zero at the start would otherwise bracket a false landing when a
  first step overshoots a short bounce.  Every slip stop and landing is
  therefore bracketed.

:func:`solve` returns a :class:`GeneralResult`: the event list and
``evaluate(times)`` for x, v, z, vz.  scipy is a test dependency only.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from stepping import Section, integrate

__all__ = ["GeneralModel", "GeneralResult", "RefEvent", "first_positive", "solve"]

TWO_PI = 2.0 * math.pi
STUCK, FORWARD, BACKWARD, FLIGHT = 0, 1, -1, 2  # the values of friction_sim.core.model.events.Mode
#: Grid points per period of the time-only scans.
SCAN_POINTS = 64
#: max_step of the integration, as a fraction of the period.
STEPS_PER_PERIOD = 20
#: Default plastic floor: a rebound slower than this times (g*cos(alpha) - Fz/m)/omega is plastic
#: (gravity would stop it within a millionth of a radian of phase; the core documents the same rule).
PLASTIC_RATIO = 1e-6


def _sin_deg(angle: float) -> float:
    """sin of degrees, exactly 0 or +-1 at multiples of 90 (so beta = 90 gives Pt = 0 exactly)."""
    if angle % 90.0 == 0.0:
        return float((0, 1, 0, -1)[int(angle // 90.0) % 4])
    return math.sin(math.radians(angle))


def _cos_deg(angle: float) -> float:
    return _sin_deg(angle + 90.0)


@dataclass(frozen=True)
class GeneralModel:
    """Parameters and (constant) inputs of the general model, plain floats.

    ``plastic_speed`` [m/s]: a rebound speed e*|vz_before| below it makes the
    landing plastic (None: :data:`PLASTIC_RATIO` times (g*cos(alpha) - Fz/m)/omega,
    the speed scale of the excitation, the floor the core documents; a bounce
    sequence that chatters down to rest depends on it).
    """

    mass: float = 1.0
    mu: float = 0.1
    gravity: float = 10.0
    static_ratio: float = 1.0
    excitation_angle: float = 90.0
    excitation_phase: float = 0.0
    track_inclination: float = 0.0
    restitution: float = 0.0
    landing_friction: str = "impulsive"
    drive_force: float = 0.7
    excitation_amplitude: float = 5.0
    excitation_frequency: float = 50.0
    external_force_x: float = 0.0
    external_force_z: float = 0.0
    plastic_speed: float | None = None

    @classmethod
    def from_core(cls, params: Any, inputs: Any, plastic_speed: float | None = None) -> GeneralModel:
        """The model of a core ``SliderParams`` and ``Inputs`` (read by attribute name only)."""
        names = [f for f in cls.__dataclass_fields__ if f != "plastic_speed"]
        values = {name: getattr(params, name) if hasattr(params, name) else getattr(inputs, name) for name in names}
        return cls(**values, plastic_speed=plastic_speed)

    # -- derived constants --------------------------------------------------------
    @property
    def floor(self) -> float:
        """The rebound speed [m/s] below which a landing is plastic."""
        if self.plastic_speed is not None:
            return self.plastic_speed
        return PLASTIC_RATIO * max(self.normal_load, 0.0) / self.mass / self.omega

    @property
    def omega(self) -> float:
        return TWO_PI * self.excitation_frequency

    @property
    def period(self) -> float:
        return 1.0 / self.excitation_frequency

    @property
    def normal_load(self) -> float:
        """m*g*cos(alpha) - Fz: R without the excitation."""
        return self.mass * self.gravity * _cos_deg(self.track_inclination) - self.external_force_z

    @property
    def tangential_constant(self) -> float:
        """Fd + Fx - m*g*sin(alpha): Ft without the excitation."""
        return (self.drive_force + self.external_force_x
                - self.mass * self.gravity * _sin_deg(self.track_inclination))

    @property
    def tangential_amplitude(self) -> float:
        """Pt = Pa*cot(beta)."""
        beta = self.excitation_angle
        return self.excitation_amplitude * _cos_deg(beta) / _sin_deg(beta)

    @property
    def throw_number(self) -> float:
        """Gamma = Pa/(m*g*cos(alpha))."""
        return self.excitation_amplitude / (self.mass * self.gravity * _cos_deg(self.track_inclination))

    # -- forces (numpy-vectorised in t) ------------------------------------------
    def theta(self, t: Any, phase0: float = 0.0) -> Any:
        return phase0 + self.omega * t

    def normal(self, t: Any, phase0: float = 0.0) -> Any:
        """R(t)."""
        return self.normal_load - self.excitation_amplitude * np.sin(self.theta(t, phase0))

    def tangential(self, t: Any, phase0: float = 0.0) -> Any:
        """Ft(t)."""
        psi = math.radians(self.excitation_phase)
        return self.tangential_constant + self.tangential_amplitude * np.sin(self.theta(t, phase0) + psi)


@dataclass(frozen=True)
class RefEvent:
    """One transition (mode values as in ``friction_sim.core.model.events.Mode``)."""

    t: float
    kind: str
    x: float
    before: int
    after: int
    v_before: float = 0.0
    v_after: float = 0.0
    vz_before: float = 0.0
    vz_after: float = 0.0
    phase: float = 0.0


@dataclass
class _Segment:
    """Motion on [t0, t1]: ``dense`` maps t to (dx, v) or (dx, v, z, vz); None: at rest at x0."""

    t0: float
    t1: float
    mode: int
    x0: float
    dense: Callable[[Any], NDArray[np.float64]] | None


@dataclass
class GeneralResult:
    """Events and piecewise dense motion of one reference run."""

    model: GeneralModel
    phase0: float
    t_final: float
    rtol: float = 1e-12
    atol: tuple[float, float] = (0.0, 0.0)  # (of a position, of a speed)
    events: list[RefEvent] = field(default_factory=list)
    segments: list[_Segment] = field(default_factory=list)
    steps: int = 0

    def speed_error(self, speed: float) -> float:
        """A bound of the reference's error in a speed of size <= ``speed``: DOP853 keeps
        each step's local error within atol + rtol*|y|, and the accelerations are
        functions of time alone within a segment (nothing feeds back), so the errors of
        ``steps`` steps at most add up."""
        return self.steps * (self.atol[1] + self.rtol * speed)

    def position_error(self, length: float, speed: float) -> float:
        """A bound of its error in a position at most ``length`` from its section's start,
        of a motion whose speeds stay within ``speed``: the positions' own local errors
        added up, plus the speed error integrated over the run (x' = v)."""
        return self.steps * (self.atol[0] + self.rtol * length) + self.t_final * self.speed_error(speed)

    def times(self, kind: str) -> NDArray[np.float64]:
        """Times of the events of one kind."""
        return np.array([e.t for e in self.events if e.kind == kind])

    def counts(self) -> dict[str, int]:
        """Number of events of each kind."""
        out: dict[str, int] = {}
        for e in self.events:
            out[e.kind] = out.get(e.kind, 0) + 1
        return out

    def evaluate(self, times: Sequence[float] | NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """x, v, z, vz and mode at the given times (in [0, t_final]); at an
        event time the state after the event."""
        ts = np.asarray(times, dtype=float)
        out = {name: np.full(ts.shape, np.nan) for name in ("x", "v", "z", "vz", "mode")}
        starts = np.array([s.t0 for s in self.segments])
        index = np.clip(np.searchsorted(starts, ts, side="right") - 1, 0, len(self.segments) - 1)
        for k in np.unique(index):
            seg = self.segments[k]
            sel = index == k
            t = ts[sel]
            out["mode"][sel] = seg.mode
            if seg.dense is None:
                out["x"][sel], out["v"][sel], out["z"][sel], out["vz"][sel] = seg.x0, 0.0, 0.0, 0.0
                continue
            y = np.atleast_2d(seg.dense(np.clip(t, seg.t0, seg.t1)))
            out["x"][sel] = seg.x0 + y[0]
            out["v"][sel] = y[1]
            out["z"][sel] = y[2] if y.shape[0] > 2 else 0.0
            out["vz"][sel] = y[3] if y.shape[0] > 2 else 0.0
        return out


# ------------------------------------------------------------------------ time-only roots


def first_positive(func: Callable[[Any], Any], t_lo: float, t_hi: float, period: float) -> float | None:
    """First t in [t_lo, t_hi] with func(t) > 0 (on that side of the root), or None.

    ``func`` is smooth except for kinks that are local minima (|.|), vectorised,
    and periodic with ``period``: one period without a positive value proves
    there is none.  Scan of :data:`SCAN_POINTS` per period; every local maximum
    of the samples is refined with a bounded Brent search so that an excursion
    narrower than the grid is found; the first crossing is polished by brentq.
    """
    from scipy.optimize import brentq, minimize_scalar

    if float(func(t_lo)) > 0.0:
        return t_lo
    step = period / SCAN_POINTS
    lo = t_lo
    end = min(t_hi, t_lo + period * (1.0 + 1e-9))
    while lo < end:
        hi = min(lo + period / 4.0, end)
        n = max(2, math.ceil((hi - lo) / step))
        grid = lo + (hi - lo) * np.arange(-1, n + 2) / n  # one extra point each side, for maxima
        values = np.asarray(func(grid), dtype=float)
        bracket: tuple[float, float] | None = None
        for i in range(1, n + 2):  # grid[1] == lo ... grid[n+1] == hi
            if values[i] > 0.0:
                bracket = (float(grid[i - 1]), float(grid[i]))
                break
            if i <= n and values[i] >= values[i - 1] and values[i] >= values[i + 1]:
                a, b = float(grid[i - 1]), float(grid[i + 1])
                found = minimize_scalar(lambda u: -float(func(u)), bounds=(a, b), method="bounded",
                                        options={"xatol": 1e-15 * max(period, abs(a))})
                peak = float(found.x)
                if float(func(peak)) > 0.0 and peak >= lo:
                    bracket = (max(a, lo), peak)
                    break
        if bracket is not None:
            a, b = bracket
            if a < lo:
                a = lo
            if float(func(a)) > 0.0:
                return a if a <= t_hi else None
            root = float(brentq(lambda u: float(func(u)), a, b, xtol=1e-16, rtol=4 * np.finfo(float).eps))
            while float(func(root)) <= 0.0:  # step onto the positive side
                root = float(np.nextafter(root, b))
            return root if root <= t_hi else None
        lo = hi
    return None


# ------------------------------------------------------------------------ the integrator


@dataclass
class _State:
    t: float
    x: float
    v: float
    z: float
    vz: float
    mode: int


class _Runner:
    """One run: owns the state, appends events and segments."""

    def __init__(self, model: GeneralModel, phase0: float, t_final: float, rtol: float) -> None:
        self.m = model
        self.phase0 = phase0
        self.t_final = t_final
        self.rtol = rtol
        self.mu_s = model.static_ratio * model.mu
        self.result = GeneralResult(model, phase0, t_final, rtol)
        self.max_step = model.period / STEPS_PER_PERIOD
        # R >= normal_load - |Pa| everywhere: a trivial bound that spares the lift-off scan.
        self.never_lifts = model.normal_load - abs(model.excitation_amplitude) > 0.0
        # Absolute tolerances far below the natural scales (acceleration A, speed A/omega, length A/omega^2).
        accel = max(model.gravity, (abs(model.excitation_amplitude) + abs(model.tangential_amplitude)
                                    + abs(model.tangential_constant) + abs(model.normal_load)) / model.mass)
        speed, length = accel / model.omega, accel / model.omega**2
        self.atol = [1e-16 * length, 1e-16 * speed, 1e-16 * length, 1e-16 * speed]
        self.result.atol = (self.atol[0], self.atol[1])

    # forces
    def R(self, t: Any) -> Any:
        return self.m.normal(t, self.phase0)

    def Ft(self, t: Any) -> Any:
        return self.m.tangential(t, self.phase0)

    def slip_margin(self, t: Any) -> Any:
        """|Ft| - mu_s*R: positive where a stuck slider starts to slip."""
        return np.abs(self.Ft(t)) - self.mu_s * self.R(t)

    def next_lift_off(self, t: float) -> float | None:
        if self.never_lifts:
            return None
        return first_positive(lambda u: -self.R(u), t, self.t_final, self.m.period)

    def event(self, st: _State, kind: str, after: int, **velocities: float) -> None:
        phase = math.fmod(self.m.theta(st.t, self.phase0), TWO_PI)
        self.result.events.append(RefEvent(st.t, kind, st.x, st.mode, after, phase=phase, **velocities))
        st.mode = after

    def _ivp(self, rhs: Callable[[float, Any], Any], t0: float, t1: float, y0: list[float],
             event: Callable[[float, Any], float]) -> Section:
        section = integrate(rhs, t0, t1, y0, event, rtol=self.rtol, atol=self.atol[:len(y0)], max_step=self.max_step)
        self.result.steps += section.steps
        return section

    # -- phases ---------------------------------------------------------------------
    def stuck(self, st: _State) -> None:
        t_slip = first_positive(self.slip_margin, st.t, self.t_final, self.m.period)
        t_lift = self.next_lift_off(st.t)
        ends = [t for t in (t_slip, t_lift) if t is not None]
        t_next = min(ends) if ends else self.t_final
        self.result.segments.append(_Segment(st.t, t_next, STUCK, st.x, None))
        if not ends:
            st.t = self.t_final
            return
        st.t = t_next
        if t_lift is not None and (t_slip is None or t_lift <= t_slip or float(self.R(t_next)) <= 0.0):
            self.event(st, "lift_off", FLIGHT)
        else:
            direction = FORWARD if float(self.Ft(t_next)) > 0.0 else BACKWARD
            self.event(st, "slip_start", direction)

    def slip(self, st: _State) -> None:
        from scipy.optimize import brentq

        s = st.mode
        t_lift = self.next_lift_off(st.t)
        limit = t_lift if t_lift is not None else self.t_final
        mass, mu, period = self.m.mass, self.m.mu, self.m.period

        def sa(t: Any) -> Any:  # s * acceleration, a function of time only
            return (s * self.Ft(t) - mu * self.R(t)) / mass

        def rhs(t: float, y: Any) -> list[float]:
            return [y[1], s * float(sa(t))]

        def stop(t: float, y: Any) -> float:
            return float(y[1])

        stop.terminal = True  # type: ignore[attr-defined]
        stop.direction = -s  # type: ignore[attr-defined]
        while True:
            # the next minimum of s*v: s*a turns from negative to positive
            t_neg = st.t if float(sa(st.t)) < 0.0 else first_positive(lambda u: -sa(u), st.t, limit, period)
            t_min = None if t_neg is None else first_positive(sa, t_neg, limit, period)
            t_end = limit if t_min is None else min(t_min, limit)
            if t_end <= st.t:
                sol = None
            else:
                sol = self._ivp(rhs, st.t, t_end, [0.0, st.v], stop)
                if sol.status < 0:
                    raise RuntimeError(f"DOP853 failed in a slip: {sol.message}")
            if sol is not None:
                self.result.segments.append(_Segment(st.t, sol.t_end, s, st.x, sol.dense))
            if sol is not None and sol.event_t is not None:
                t_stop = sol.event_t
                st.x, st.t, st.v = st.x + float(sol.y_end[0]), t_stop, 0.0
                ft, r = float(self.Ft(t_stop)), float(self.R(t_stop))
                if abs(ft) <= self.mu_s * r:
                    self.event(st, "stick", STUCK)
                else:
                    new = FORWARD if ft > 0.0 else BACKWARD
                    if new == s:  # pragma: no cover - impossible with s*a(t_stop) <= 0
                        raise RuntimeError("slip stopped while pushed on")
                    self.event(st, "reversal", new)
                return
            if sol is not None:
                st.x, st.v, st.t = st.x + float(sol.y_end[0]), float(sol.y_end[1]), t_end
            if st.t >= limit:
                if t_lift is not None and t_lift <= self.t_final:
                    self.event(st, "lift_off", FLIGHT, v_before=st.v, v_after=st.v)
                    st.z, st.vz = 0.0, 0.0
                return
            if s * st.v <= 0.0:  # a touch at the section end, missed by the event (exact tangency)
                t_stop = st.t if s * st.v == 0.0 else float(brentq(
                    lambda u: float(self.result.segments[-1].dense(u)[1]),  # type: ignore[misc]
                    self.result.segments[-1].t0, st.t, xtol=4e-16))
                raise RuntimeError(f"slip stop at {t_stop!r} reached only at a section end")

    def flight(self, st: _State) -> None:
        from scipy.optimize import brentq

        mass, period = self.m.mass, self.m.period

        def rhs(t: float, y: Any) -> list[float]:
            return [y[1], float(self.Ft(t)) / mass, y[3], -float(self.R(t)) / mass]

        def land(t: float, y: Any) -> float:
            return float(y[2])

        def apex(t: float, y: Any) -> float:
            return float(y[3])

        land.terminal = apex.terminal = True  # type: ignore[attr-defined]
        land.direction = apex.direction = -1  # type: ignore[attr-defined]
        while st.t < self.t_final:
            # A rebound starts on the track (z = 0) moving up: z's own zero at the start would
            # bracket a false landing when a first step overshoots a short bounce, so such a
            # section only runs to the apex (vz = 0, found the same way); the landing is looked
            # for from there, where z > 0.
            rising_from_track = st.z == 0.0 and st.vz > 0.0
            r0 = float(self.R(st.t))
            convex = r0 < 0.0
            if convex:
                t_change = first_positive(self.R, st.t, self.t_final, period)
            else:
                t_change = first_positive(lambda u: -self.R(u), st.t, self.t_final, period)
            t_end = self.t_final if t_change is None else t_change
            x_start = st.x
            sol = self._ivp(rhs, st.t, t_end, [0.0, st.v, st.z, st.vz], apex if rising_from_track else land)
            if sol.status < 0:
                raise RuntimeError(f"DOP853 failed in a flight: {sol.message}")
            dense = sol.dense
            if rising_from_track:
                t_top = sol.t_end
                self.result.segments.append(_Segment(st.t, t_top, FLIGHT, x_start, dense))
                y = dense(t_top)
                st.t, st.x, st.v, st.z, st.vz = t_top, x_start + float(y[0]), float(y[1]), float(y[2]), float(y[3])
                if not st.z > 0.0:  # pragma: no cover - a rebound is above the track until its apex
                    raise RuntimeError(f"rebound below the track at {t_top!r}")
                continue
            t_land: float | None = sol.event_t
            if t_land is None and convex and st.vz < 0.0 < float(sol.y_end[3]):
                # the one minimum of a convex stretch of z: below the track means a landing before it
                t_low = float(brentq(lambda u, d=dense: float(d(u)[3]), st.t, t_end, xtol=4e-16))
                if float(dense(t_low)[2]) <= 0.0:
                    t_land = float(brentq(lambda u, d=dense: float(d(u)[2]), st.t, t_low, xtol=4e-16))
            if t_land is None and float(sol.y_end[2]) < 0.0:
                raise RuntimeError("flight ended below the track without a landing event")
            seg_end = t_land if t_land is not None else sol.t_end
            self.result.segments.append(_Segment(st.t, seg_end, FLIGHT, x_start, dense))
            if t_land is None:
                st.x, st.v, st.z, st.vz = (x_start + float(sol.y_end[0]), float(sol.y_end[1]),
                                           float(sol.y_end[2]), float(sol.y_end[3]))
                st.t = t_end
                continue
            y = dense(t_land)
            st.t, st.x, st.v, st.vz, st.z = t_land, x_start + float(y[0]), float(y[1]), float(y[3]), 0.0
            self.land(st)
            return

    def land(self, st: _State) -> None:
        """The impact law at a landing (see the module docstring)."""
        vb, vzb = st.v, st.vz
        e = self.m.restitution
        if e * abs(vzb) < self.m.floor:
            e = 0.0
        impulse = (1.0 + e) * abs(vzb)
        va = vb
        if self.m.landing_friction == "impulsive":
            bound = self.m.mu * impulse
            va = 0.0 if abs(vb) <= bound else vb - math.copysign(bound, vb)
        vza = e * abs(vzb)
        st.v, st.vz = va, vza
        if e > 0.0:
            self.event(st, "landing", FLIGHT, v_before=vb, v_after=va, vz_before=vzb, vz_after=vza)
            return
        after = STUCK if va == 0.0 else (FORWARD if va > 0.0 else BACKWARD)
        self.event(st, "landing", after, v_before=vb, v_after=va, vz_before=vzb, vz_after=0.0)
        if float(self.R(st.t)) < 0.0:
            self.event(st, "lift_off", FLIGHT, v_before=va, v_after=va)

    def run(self, x0: float) -> GeneralResult:
        st = _State(0.0, x0, 0.0, 0.0, 0.0, STUCK)
        guard = 0
        while st.t < self.t_final:
            guard += 1
            if guard > 10_000_000:  # pragma: no cover
                raise RuntimeError("too many segments")
            if st.mode == STUCK:
                self.stuck(st)
            elif st.mode == FLIGHT:
                self.flight(st)
            else:
                self.slip(st)
        return self.result


def solve(model: GeneralModel, t_final: float, *, phase0: float = 0.0, x0: float = 0.0,
          rtol: float = 1e-12) -> GeneralResult:
    """Integrate the general model from rest on the track at t = 0 (phase
    ``phase0``, position ``x0``) to ``t_final``."""
    if not (math.isfinite(t_final) and t_final > 0.0):
        raise ValueError(f"t_final must be finite and > 0, got {t_final!r}")
    return _Runner(model, float(phase0), float(t_final), rtol).run(float(x0))
