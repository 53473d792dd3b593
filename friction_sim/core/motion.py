"""The general model: flight, inclined vibration, a sloped track, static friction.

Track frame: x along the track (+ = conveying), z normal to it, away from it.
With theta the excitation phase (d(theta)/dt = omega = 2*pi*f):

    contact force needed   R(theta)  = m*g*cos(alpha) - Fz - Pa*sin(theta)
    tangential force       Ft(theta) = Fd + Fx - m*g*sin(alpha) + Pt*sin(theta + psi),  Pt = Pa*cot(beta)

In contact (z = 0): stuck while |Ft| <= mu_s*R; slipping in direction s,
m*x'' = Ft - s*mu*R.  When R would become negative the slider lifts off; in
flight m*x'' = Ft and m*z'' = -R.  A landing (z back to 0) is an impact:
normal restitution e, and with ``landing_friction = "impulsive"`` a
tangential impulse of at most mu times the normal one (Coulomb impact).

Every acceleration here is a constant plus a sinusoid of theta, which is
written b0 + b1*sin(theta + delta) with b1 >= 0, and every event is where
such a form (or its first or second integral) crosses zero.  So each segment
is the same closed form as Kostek's slip (:class:`roots.Harmonic`), and the event
finders of :mod:`friction_sim.core.roots` (with the phase shifted by delta)
bracket and polish every root.  This module detects the next event of a
segment (:meth:`Motion.plan`) and computes the state after it
(:func:`impact`); the slider (:mod:`friction_sim.core.slider`) acts on them.
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any, NamedTuple

from friction_sim.core.events import EventKind
from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.roots import (
    NEVER,
    TWO_PI,
    Harmonic,
    from_rest_b0,
    landing_delay,
    next_slip_start,
    reduce_phase,
    slip_stop_delay,
    two_sum,
)

#: Mode numbers of a segment: slip directions -1/+1, stuck 0, flight 2.
STUCK, FLIGHT = 0, 2

#: A rebound slower than this many units of g*cos(alpha)/omega (gravity would
#: stop it within a millionth of a radian of excitation phase) is a plastic
#: landing: bouncing with restitution then ends after finitely many bounces
#: instead of a Zeno sequence.
REBOUND_FLOOR = 1e-6


class Form(NamedTuple):
    """b0 + b1*sin(theta + delta), b1 >= 0: a constant plus a sinusoid of the phase."""

    b0: float
    b1: float
    delta: float

    @staticmethod
    def of(constant: float, sin_part: float, cos_part: float) -> Form:
        """constant + sin_part*sin(theta) + cos_part*cos(theta) as a Form (delta exactly 0
        when there is no cosine part and the sine part is >= 0)."""
        if cos_part == 0.0 and sin_part >= 0.0:
            return Form(constant, sin_part, 0.0)
        return Form(constant, math.hypot(sin_part, cos_part), math.atan2(cos_part, sin_part))

    def at(self, theta: float) -> float:
        return self.b0 + self.b1 * math.sin(theta + self.delta)


class GeneralPlant:
    """The constants of the general motion under one set of parameters and inputs."""

    __slots__ = (
        "omega", "mass", "mu", "restitution", "impulsive", "rebound_floor", "n0", "pa", "tangential",
        "slip", "flight_x", "flight_z", "onset", "lift",
    )

    def __init__(self, params: SliderParams, inputs: Inputs) -> None:
        m, mu, mu_s = params.mass, params.mu, params.mu * params.static_ratio
        pa = inputs.excitation_amplitude
        self.omega = TWO_PI * inputs.excitation_frequency
        self.mass, self.mu, self.restitution = m, mu, params.restitution
        self.impulsive = params.landing_friction == "impulsive"
        n0 = params.normal_weight - inputs.external_force_z  # R = n0 - pa*sin(theta)
        f0 = inputs.tangential_force - params.downhill_weight
        pt = pa * params.tangential_ratio
        psi = math.radians(params.excitation_phase)
        ts, tc = (pt, 0.0) if psi == 0.0 else (pt * math.cos(psi), pt * math.sin(psi))
        self.n0, self.pa = n0, pa  # R(theta) = n0 - pa*sin(theta)
        self.tangential = Form.of(f0, ts, tc)  # Ft(theta)
        self.rebound_floor = REBOUND_FLOOR * max(n0, 0.0) / m / self.omega
        #: dw/dt (w = s*v) of a slip in direction s, per unit mass: s*Ft - mu*R
        self.slip = {s: Form.of((s * f0 - mu * n0) / m, (s * ts + mu * pa) / m, s * tc / m) for s in (1, -1)}
        self.flight_x = Form.of(f0 / m, ts / m, tc / m)
        self.flight_z = Form(-n0 / m, pa / m, 0.0)
        #: where a stuck slider starts to slip in direction s: s*Ft - mu_s*R > 0
        self.onset = {s: Form.of(s * f0 - mu_s * n0, s * ts + mu_s * pa, s * tc) for s in (1, -1)}
        #: where it lifts off: -R > 0
        self.lift = Form(-n0, pa, 0.0)

    def stays(self, theta: float) -> int:
        """At phase theta in contact and at rest: 0 if it stays stuck, else the direction it slips in."""
        for s in (1, -1):
            if self.onset[s].at(theta) > 0.0:
                return s
        return 0


def axis(w0: float, form: Form, theta0: float, omega: float, *, from_rest: bool = False,
         start: float = 0.0) -> Harmonic:
    """The closed form of a speed w0 + integral of form(theta) from phase theta0
    (and its integral from ``start``).  ``from_rest``: a motion that starts from
    rest cannot start decelerating (:func:`roots.from_rest_b0`)."""
    phase = theta0 + form.delta
    b0 = from_rest_b0(w0, form.b0, form.b1, math.sin(phase)) if from_rest else form.b0
    return Harmonic(w0, b0, form.b1, phase, omega, start)


class Plan(NamedTuple):
    """The next event of a segment: its kind, the time after the segment's start,
    and for an event tied to a phase (onsets, lift-offs) the phase it happens at
    counted from the segment's period (None for a stop or a landing)."""

    kind: EventKind
    delay: float
    theta: float | None
    direction: int  # the slip direction of an onset or reversal


NO_EVENT = Plan(EventKind.STICK, NEVER, None, 0)


class Motion:
    """Closed-form motion from one event to the next under constant inputs:
    stuck (mode 0), slipping (+-1) or in flight (2).

    ``s0``/``t0``, ``x0 + xl``, ``phase0``/``cycles`` mean what they mean in
    :class:`friction_sim.core.kostek.KostekSegment`; ``v0`` is the tangential and
    ``vz0`` the normal velocity and ``z0`` the height at the start (z0 > 0
    only for a flight whose inputs changed in the air).
    """

    __slots__ = ("t0", "s0", "x0", "xl", "v0", "vz0", "z0", "phase0", "cycles", "direction", "plant", "omega",
                 "_x_axis", "_z_axis")

    def __init__(self, s0: float, t0: float, x0: float, xl: float, v0: float, phase0: float, cycles: int,
                 mode: int, plant: GeneralPlant, vz0: float = 0.0, z0: float = 0.0) -> None:
        self.s0, self.t0, self.x0, self.xl, self.v0, self.vz0, self.z0 = s0, t0, x0, xl, v0, vz0, z0
        self.phase0, self.cycles, self.direction, self.plant = phase0, cycles, mode, plant
        self.omega = plant.omega
        self._x_axis: Harmonic | None = None
        self._z_axis: Harmonic | None = None

    # (The closed forms are built on first use: in a periodic motion most
    # segments are never sampled, and their events come from a memo.)

    @property
    def x_axis(self) -> Harmonic | None:
        """The tangential closed form (w = v in flight, w = direction*v in a slip; None stuck)."""
        if self._x_axis is None and self.direction:
            mode, plant = self.direction, self.plant
            if mode == FLIGHT:
                self._x_axis = axis(self.v0, plant.flight_x, self.phase0, self.omega)
            else:
                self._x_axis = axis(mode * self.v0, plant.slip[mode], self.phase0, self.omega, from_rest=self.v0 == 0.0)
        return self._x_axis

    @property
    def z_axis(self) -> Harmonic | None:
        """The normal closed form of a flight (None in contact)."""
        if self._z_axis is None and self.direction == FLIGHT:
            self._z_axis = axis(self.vz0, self.plant.flight_z, self.phase0, self.omega,
                                from_rest=self.vz0 == 0.0 and self.z0 == 0.0, start=self.z0)
        return self._z_axis

    # -- the closed form ---------------------------------------------------------

    def evaluate(self, t: Any, xp: ModuleType = math) -> tuple[Any, ...]:
        """(x, v, acceleration, friction, normal force, phase, z, vz) at time(s) t."""
        return self.after(t - self.t0, xp)

    def after(self, tau: Any, xp: ModuleType = math) -> tuple[Any, ...]:
        """:meth:`evaluate` at ``tau`` after the start (phase unreduced)."""
        plant, mode = self.plant, self.direction
        theta = self.phase0 + self.omega * tau
        zero = tau * 0.0
        if mode == FLIGHT:
            assert self.x_axis is not None and self.z_axis is not None
            v, travel = self.x_axis.at(tau, xp)
            vz, z = self.z_axis.at(tau, xp)
            return (self.x0 + (self.xl + travel), v, self.x_axis.rate(tau, xp), zero, zero, theta, z, vz)
        normal = plant.n0 - plant.pa * xp.sin(theta) if plant.pa else plant.n0 + zero
        if mode == STUCK:
            force = plant.tangential.b0 + plant.tangential.b1 * xp.sin(theta + plant.tangential.delta)
            return self.x0 + zero, zero, zero, -force, normal, theta, zero, zero
        assert self.x_axis is not None
        w, travel = self.x_axis.at(tau, xp)
        return (self.x0 + (self.xl + mode * travel), mode * w, mode * self.x_axis.rate(tau, xp),
                -mode * plant.mu * normal, normal, theta, zero, zero)

    def position(self, tau: float) -> tuple[float, float]:
        """x ``tau`` into the segment as a double-double (hi, lo)."""
        return two_sum(self.x0, self.xl + self.travel(tau))

    def travel(self, tau: float) -> float:
        """x(tau) - x(0), signed."""
        closed = self.x_axis
        if closed is None:
            return 0.0
        travel: float = closed.at(tau)[1]
        return travel if self.direction == FLIGHT else self.direction * travel

    def velocities(self, tau: float) -> tuple[float, float]:
        """(v, vz) ``tau`` into the segment."""
        if self.direction == FLIGHT:
            assert self.x_axis is not None and self.z_axis is not None
            return self.x_axis.at(tau)[0], self.z_axis.at(tau)[0]
        if self.direction == STUCK:
            return 0.0, 0.0
        assert self.x_axis is not None
        return self.direction * self.x_axis.at(tau)[0], 0.0

    def to_cycle(self, n: int) -> float:
        """tau at which the total phase reaches 2*pi*n (0 if it already had)."""
        whole = n - self.cycles
        return 0.0 if whole <= 0 else (TWO_PI * whole - self.phase0) / self.omega

    # -- detecting the next event --------------------------------------------------

    def plan(self, closing: int = 0, grounded: bool = False) -> Plan:
        """The next event under the present inputs.  ``closing`` is the direction
        of the slip that just stopped, ``grounded`` is set after a flight that
        ended as it began: an at-once restart of either would only come from
        rounding (see :func:`roots.next_slip_start`), so it waits for the
        window to open again, which guarantees progress."""
        plant, mode, theta0 = self.plant, self.direction, self.phase0
        if mode == FLIGHT:
            z = self.z_axis  # (from a lift-off it cannot start falling: see from_rest_b0)
            assert z is not None
            return Plan(EventKind.LANDING, landing_delay(z.w0, z.b0, z.b1, z.phase0, z.omega, z.start), None, 0)
        best = _onset(plant.lift, theta0, EventKind.LIFT_OFF, 0, grounded)
        if mode == STUCK:
            for s in (1, -1):
                onset = _onset(plant.onset[s], theta0, EventKind.SLIP_START, s, closing == s)
                if onset.theta is not None and (best.theta is None or onset.theta < best.theta):
                    best = onset
            return best._replace(delay=(best.theta - theta0) / self.omega) if best.theta is not None else NO_EVENT
        slip = self.x_axis
        assert slip is not None
        stop = slip_stop_delay(slip.w0, slip.b0, slip.b1, slip.phase0, self.omega)
        if best.theta is not None:
            lift = (best.theta - theta0) / self.omega
            if lift <= stop:
                return best._replace(delay=lift)
        return Plan(EventKind.STICK, stop, None, 0)


def _onset(form: Form, theta0: float, kind: EventKind, direction: int, closing: bool = False) -> Plan:
    """When form(theta) first rises above 0 from theta0 (theta None: never)."""
    delta, _ = next_slip_start(theta0 + form.delta, form.b0, form.b1, closing=closing)
    if delta == NEVER:
        return Plan(kind, NEVER, None, direction)
    return Plan(kind, 0.0, theta0 + delta, direction)


class Step(NamedTuple):
    """A segment's next event, worked out: when (``delay`` after the start, or
    for an event ``tied`` to a phase, at ``phase`` in period ``whole`` counted
    from the segment's), the signed ``travel`` and the velocities (v, vz) just
    before it, and what follows (``then``).  It depends only on the segment's
    start (mode, phase, velocities, height, guards) and the plant, never on
    x or t, so the slider keeps it in a memo: a periodic motion repeats its
    steps bit for bit."""

    delay: float
    tied: bool
    phase: float
    whole: int
    travel: float
    v: float
    vz: float
    then: After | None


NEVER_STEP = Step(NEVER, False, 0.0, 0, 0.0, 0.0, 0.0, None)


def next_step(seg: Motion, closing: int = 0, grounded: bool = False) -> Step:
    """Detect the next event of ``seg`` (:meth:`Motion.plan`) and work out its outcome."""
    plan = seg.plan(closing, grounded)
    if plan.delay == NEVER:
        return NEVER_STEP
    theta = plan.theta if plan.theta is not None else seg.phase0 + seg.omega * plan.delay
    phase, whole = reduce_phase(theta, 0)
    v, vz = seg.velocities(plan.delay)
    then = after_event(seg, plan, theta, v, vz)
    return Step(plan.delay, plan.theta is not None, phase, whole, seg.travel(plan.delay), v, vz, then)


class After(NamedTuple):
    """What an event leaves: the mode and velocities the next segment starts
    with, and the progress guards of its :meth:`Motion.plan`."""

    kind: EventKind
    mode: int
    v: float
    vz: float
    closing: int = 0
    grounded: bool = False


def after_event(seg: Motion, plan: Plan, theta: float, v: float, vz: float) -> After:
    """The event ``plan`` of ``seg`` carried out at phase ``theta`` with
    velocities (v, vz) just before it: what kind it turns out to be and how the
    motion goes on."""
    kind, plant = plan.kind, seg.plant
    if kind is EventKind.SLIP_START:
        return After(kind, plan.direction, 0.0, 0.0)
    if kind is EventKind.LIFT_OFF:
        return After(kind, FLIGHT, v, 0.0)
    if kind is EventKind.STICK:
        direction = plant.stays(theta)
        if direction == -seg.direction:
            return After(EventKind.REVERSAL, direction, 0.0, 0.0)
        return After(kind, STUCK, 0.0, 0.0, closing=seg.direction)
    hit = impact(plant, v, vz)
    if hit.bounces:
        return After(kind, FLIGHT, hit.v, hit.vz)
    mode = STUCK if hit.v == 0.0 else (1 if hit.v > 0.0 else -1)
    return After(kind, mode, hit.v, 0.0, grounded=plan.delay == 0.0)


class Impact(NamedTuple):
    """The velocities just after a landing, and whether the slider bounces."""

    v: float
    vz: float
    bounces: bool


def impact(plant: GeneralPlant, v: float, vz: float) -> Impact:
    """The landing law: normal restitution, then (impulsive) a tangential
    impulse of at most mu times the normal one, which stops the slider if it
    is enough (Coulomb impact)."""
    rebound = -plant.restitution * vz
    bounces = rebound > plant.rebound_floor
    normal_impulse = -vz + (rebound if bounces else 0.0)  # per unit mass, >= 0
    if plant.impulsive:
        limit = plant.mu * normal_impulse
        v = 0.0 if abs(v) <= limit else v - math.copysign(limit, v)
    return Impact(v, rebound if bounces else 0.0, bounces)


__all__ = ["FLIGHT", "NEVER_STEP", "NO_EVENT", "REBOUND_FLOOR", "STUCK", "After", "Form", "GeneralPlant",
           "Impact", "axis", "Motion", "Plan", "Step", "after_event", "impact", "next_step"]
