"""Independent reference for the resonant exciter (issue 21): solve_ivp on the coupled equations.

The slideway and the part are integrated together, numerically, with SciPy's
DOP853 at rtol 1e-12: state (q, q', x, v, z, vz), where q is the slideway's
normal displacement,

    q'' = 2*zeta*A*u*sin(theta) - 2*zeta*omega_n*q' - omega_n**2*q,   theta = theta0 + omega*t
    P   = -m*q''                                   the part's inertial force, normal to the track
    R   = m*g*cos(alpha) - Fz - P                  contact force needed
    Ft  = Fd + Fx - m*g*sin(alpha) + P*cot(beta)

stuck while s*Ft <= mu_s*R for both s and R >= 0; slipping, m*v' = Ft - s*mu*R;
in flight m*v' = Ft, m*vz' = -R.  Slip stops (v = 0), landings (z = 0),
onsets and lift-offs are solve_ivp's terminal events (sign changes between
steps of at most a fortieth of a period, polished with brentq on the dense
output).  The slideway starts in its steady state, computed here from the
complex amplitude kappa*u/(omega_n**2 - omega**2 + 2i*zeta*omega_n*omega),
not from the core's resonance curve.  A drive level schedule changes u at
given times (q, q' and theta continuous).

Nothing of friction_sim.core is imported: this is the check, not a copy.
"""

from __future__ import annotations

import cmath
import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

RTOL = 1e-12


@dataclass(frozen=True)
class ExciterCase:
    """One coupled case (SI units, angles in degrees); ``changes``: (t, u) drive level steps."""

    mass: float = 1.0
    mu: float = 0.1
    gravity: float = 10.0
    static_ratio: float = 1.0
    excitation_angle: float = 90.0
    track_inclination: float = 0.0
    restitution: float = 0.0
    impulsive: bool = True
    drive_force: float = 0.7
    frequency: float = 50.0
    natural_frequency: float = 50.0
    damping_ratio: float = 0.02
    full_drive_acceleration: float = 10.0
    drive_level: float = 0.5
    changes: tuple[tuple[float, float], ...] = field(default_factory=tuple)

    @property
    def omega(self) -> float:
        return 2 * math.pi * self.frequency

    @property
    def omega_n(self) -> float:
        return 2 * math.pi * self.natural_frequency

    @property
    def cot_beta(self) -> float:
        return 0.0 if self.excitation_angle == 90.0 else 1 / math.tan(math.radians(self.excitation_angle))

    def level(self, t: float) -> float:
        u = self.drive_level
        for when, value in self.changes:
            if t >= when:
                u = value
        return u

    def steady_q(self, t: float, u: float) -> tuple[float, float]:
        """The steady (q, q') at time t under drive level u."""
        kappa = 2 * self.damping_ratio * self.full_drive_acceleration * u
        amplitude = kappa / complex(self.omega_n**2 - self.omega**2, 2 * self.damping_ratio * self.omega_n * self.omega)
        # q = Im(amplitude * exp(i*theta))
        e = cmath.exp(1j * self.omega * t)
        return (amplitude * e).imag, (1j * self.omega * amplitude * e).imag


def random_case(rng: np.random.Generator) -> ExciterCase:
    """A random coupled case that moves (the tests' and the bench's): a drive level
    step at 0.1 s, some with restitution, flight included."""
    return ExciterCase(
        mu=float(rng.uniform(0.1, 0.6)), excitation_angle=float(rng.uniform(20.0, 90.0)),
        track_inclination=float(rng.uniform(-5.0, 5.0)), static_ratio=float(rng.uniform(1.0, 1.5)),
        restitution=float(rng.choice([0.0, 0.3])), drive_force=float(rng.uniform(-0.5, 1.0)),
        natural_frequency=float(rng.uniform(45.0, 55.0)), damping_ratio=float(rng.uniform(0.01, 0.1)),
        full_drive_acceleration=float(rng.uniform(10.0, 25.0)), drive_level=float(rng.uniform(0.4, 0.8)),
        changes=((0.1 + float(rng.uniform(0.0, 0.02)), float(rng.uniform(0.2, 1.0))),))


@dataclass
class Trace:
    """The reference's dense solution: pieces of (t0, t1, mode, sol) and the events."""

    pieces: list[tuple[float, float, int, Any]] = field(default_factory=list)
    events: list[tuple[float, str]] = field(default_factory=list)

    def at(self, t: float) -> np.ndarray:
        for t0, t1, mode, sol in self.pieces:
            if t0 <= t <= t1:
                return np.asarray(sol(t) if sol is not None else mode, dtype=float)
        raise ValueError(f"t = {t} outside the solution")


def _forces(case: ExciterCase, t: float, y: Any, u: float) -> tuple[float, float, float]:
    """(q'', R, Ft) at time t in state y."""
    q, qd = y[0], y[1]
    qdd = (2 * case.damping_ratio * case.full_drive_acceleration * u * math.sin(case.omega * t)
           - 2 * case.damping_ratio * case.omega_n * qd - case.omega_n**2 * q)
    p = -case.mass * qdd
    alpha = math.radians(case.track_inclination)
    weight = case.mass * case.gravity
    return qdd, weight * math.cos(alpha) - p, case.drive_force - weight * math.sin(alpha) + p * case.cot_beta


def _force_rate(case: ExciterCase, t: float, y: Any, u: float) -> float:
    """The third derivative of q at time t in state y (P turns where it is zero)."""
    qdd = _forces(case, t, y, u)[0]
    return (2 * case.damping_ratio * case.full_drive_acceleration * u * case.omega * math.cos(case.omega * t)
            - 2 * case.damping_ratio * case.omega_n * qdd - case.omega_n**2 * y[1])


def _opened(case: ExciterCase, mode: int, mu_s: float, sol: Any, marks: list[float],
            u: float) -> tuple[float, str] | None:
    """At the turns of P (``marks`` after the piece's start): the first condition
    that holds at one (lift-off, or a slip onset when stuck), and where it
    started to hold since the mark before (P is monotone between turns, so each
    condition crosses once at most there)."""
    from scipy.optimize import brentq

    tests: list[tuple[str, Any]] = [("lift_off", lambda tt: -_forces(case, tt, sol(tt), u)[1])]
    if mode == 0:
        for s in (1, -1):
            tests.append((f"slip_start{s:+d}", lambda tt, s=s: s * _forces(case, tt, sol(tt), u)[2]
                          - mu_s * _forces(case, tt, sol(tt), u)[1]))
    for t0, t1 in itertools.pairwise(marks):
        hits = [(brentq(g, t0, t1, xtol=4e-16 * t1, rtol=1e-15), name) for name, g in tests
                if g(t1) > 0 and g(t0) <= 0]
        if hits:
            return min(hits)
    return None


def solve(case: ExciterCase, t_final: float) -> Trace:
    """Integrate the case from the part at rest on the track at t = 0 to ``t_final``."""
    from scipy.integrate import solve_ivp

    trace = Trace()
    q0, qd0 = case.steady_q(0.0, case.drive_level)
    y = np.array([q0, qd0, 0.0, 0.0, 0.0, 0.0])
    mode, t = 0, 0.0  # -1/+1 slipping, 0 stuck, 2 flight
    mu_s = case.mu * case.static_ratio
    floor = 1e-6 * max(case.mass * case.gravity * math.cos(math.radians(case.track_inclination)), 0.0) \
        / case.mass / case.omega
    stops = sorted({when for when, _ in case.changes if 0.0 < when < t_final} | {t_final})
    guard = 0
    while t < t_final:
        guard += 1
        assert guard < 100_000, "the reference made no progress"
        u = case.level(t)
        end = next(s for s in stops if s > t)
        if mode == 0:  # a window already open (events see only crossings): it acts at once
            _, r, ft = _forces(case, t, y, u)
            at_once = "lift_off" if r < 0 else next((f"slip_start{s:+d}" for s in (1, -1) if s * ft - mu_s * r > 0),
                                                    None)
            if at_once is not None:
                mode = 2 if at_once == "lift_off" else int(at_once[-2:])
                trace.events.append((t, at_once))
                continue

        def rhs(tt: float, yy: Any, mode: int = mode, u: float = u) -> list[float]:
            qdd, r, ft = _forces(case, tt, yy, u)
            if mode == 0:
                return [yy[1], qdd, 0.0, 0.0, 0.0, 0.0]
            if mode == 2:
                return [yy[1], qdd, yy[3], ft / case.mass, yy[5], -r / case.mass]
            return [yy[1], qdd, yy[3], (ft - mode * case.mu * r) / case.mass, 0.0, 0.0]

        events: list[Any] = []
        names: list[str] = []
        if mode in (0, -1, 1):
            events.append(lambda tt, yy, u=u: -_forces(case, tt, yy, u)[1])
            names.append("lift_off")
            events.append(lambda tt, yy, u=u: _force_rate(case, tt, yy, u))
            names.append("turn")
        if mode == 0:
            for s in (1, -1):
                events.append(lambda tt, yy, s=s, u=u: s * _forces(case, tt, yy, u)[2] - mu_s * _forces(case, tt, yy,
                                                                                                          u)[1])
                names.append(f"slip_start{s:+d}")
        elif mode in (-1, 1):
            events.append(lambda tt, yy, mode=mode: mode * yy[3])
            names.append("stop")
        elif y[4] <= 0.0 and y[5] > 0.0:  # a rebound runs to its apex first: its own start is a zero of z
            events.append(lambda tt, yy: yy[5])
            names.append("apex")
        else:
            events.append(lambda tt, yy: yy[4])
            names.append("landing")
        for e, name in zip(events, names):
            e.terminal = name != "turn"
            e.direction = -1 if name in ("stop", "landing", "apex") else (0 if name == "turn" else 1)
        period = 1 / case.frequency
        sol = solve_ivp(rhs, (t, end), y, method="DOP853", rtol=RTOL, atol=1e-16, max_step=period / 40,
                        dense_output=True, events=events)
        hit = [(te[0], i) for i, te in enumerate(sol.t_events) if len(te) and te[0] > t and names[i] != "turn"]
        assert hit or sol.status == 0, f"an event at the start of a piece at t = {t}"
        if "turn" in names:  # P turns: a window that opened and closed between two steps is found there
            stop = min(hit)[0] if hit else end
            turns = [tt for tt in sol.t_events[names.index("turn")] if t < tt < stop]
            found = _opened(case, mode, mu_s, sol.sol, [t, *turns], u)
            if found is not None:
                trace.pieces.append((t, found[0], mode, sol.sol))
                y = sol.sol(found[0]).copy()
                t = found[0]
                hit, name = [], found[1]
                mode = _after(case, mode, name, mu_s, t, y, floor, trace)
                continue
        if not hit:
            trace.pieces.append((t, end, mode, sol.sol))
            t, y = end, sol.y[:, -1].copy()
            continue
        t_event, which = min(hit)
        trace.pieces.append((t, t_event, mode, sol.sol))
        y = sol.sol(t_event).copy()
        t = t_event
        name = names[which]
        if name == "apex":
            y[4] = max(y[4], 1e-300)  # (in the air: the landing is z's next zero)
            continue
        mode = _after(case, mode, name, mu_s, t, y, floor, trace)
    return trace


def _after(case: ExciterCase, mode: int, name: str, mu_s: float, t: float, y: Any, floor: float,
           trace: Trace) -> int:
    """Carry out event ``name`` at t on state y (in place): the mode after it."""
    _, r, ft = _forces(case, t, y, case.level(t))
    if name == "lift_off":
        mode, y[4], y[5] = 2, 0.0, 0.0
    elif name.startswith("slip_start"):
        mode = int(name[-2:])
    elif name == "stop":
        y[3] = 0.0
        name = "stick"
        mode_before = mode
        mode = 0
        for s in (1, -1):
            if s * ft - mu_s * r > 0 and s == -mode_before:
                mode, name = s, "reversal"
    else:  # landing
        vz = y[5]
        rebound = -case.restitution * vz
        bounces = rebound > floor
        impulse = -vz + (rebound if bounces else 0.0)
        if case.impulsive:
            limit = case.mu * impulse
            y[3] = 0.0 if abs(y[3]) <= limit else y[3] - math.copysign(limit, y[3])
        y[4], y[5] = 0.0, rebound if bounces else 0.0
        mode = 2 if bounces else (0 if y[3] == 0.0 else (1 if y[3] > 0 else -1))
    trace.events.append((t, name))
    return mode


__all__ = ["ExciterCase", "Trace", "random_case", "solve"]
