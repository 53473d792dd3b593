"""A segment of the motion and its next event, written once.

A segment is the motion from one event to the next under constant inputs:
stuck (mode 0), slipping forward or backward (+1, -1) or in flight (2), from
its start phase, velocities and height.  :func:`next_step` detects its next
event (when, where, with what velocities) and works out what follows it (the
outcome: a slip's stop sticks or reverses, a landing's impact law), as one
:class:`Step`.  It depends only on the segment's start and the plant, never on
x or t, so an engine may keep steps in a memo: a periodic motion repeats them
bit for bit.  Kostek's model (``Plant.kostek``) has its own onsets and
outcomes, the paper's case to the last bit; everything else takes the general
ones.  The engines act on steps: the single slider
(:mod:`friction_sim.core.engine.single`, interpreted) and the population
(:mod:`friction_sim.core.engine.compiled`, the same functions compiled), both
through the one stepper of :mod:`friction_sim.core.physics.stepper`.

A :class:`Segment` is the state record the stepper carries from event to
event; :func:`evaluate` gives the state at any time within it, at a float or
at an array of times, as scipy's ``DenseOutput`` does for a solver's step.
"""

from __future__ import annotations

import math
from typing import Final, NamedTuple

from friction_sim.core.physics.numerics import Floats, sine
from friction_sim.core.physics.plant import Form, Plant, form_at, slip_form, slip_gain, stays
from friction_sim.core.physics.roots import (
    NEVER,
    Harmonic,
    from_rest_b0,
    harmonic,
    harmonic_at,
    harmonic_rate,
    landing_delay,
    next_slip_start,
    reduce_phase,
    slip_stop_delay,
)

#: Segment modes: the slip directions -1 and +1, stuck, in flight (the values of events.Mode).
BACKWARD, STUCK, FORWARD, FLIGHT = -1, 0, 1, 2
#: Event kinds, numbered as events.EventKind lists them.
SLIP_START, STICK, REVERSAL, LIFT_OFF, LANDING = 0, 1, 2, 3, 4


class Step(NamedTuple):
    """A segment's next event, worked out.

    ``delay`` after the segment's start (``inf``: none), or for an event
    ``tied`` to a phase: at ``phase`` of period ``whole`` counted from the
    segment's, timed from the phase anchor (:func:`offset`).  ``phase`` and
    ``whole`` are the event's phase in [0, 2*pi) and whole periods in any case.
    ``travel``: the signed x travelled; ``v``, ``vz``: the velocities just
    before.  What follows: the event ``kind`` it turns out to be, the next
    segment's ``mode`` and velocities, and the progress guards of its next
    step (``closing``: the direction of the slip that just stopped;
    ``grounded``: a flight that ended as it began)."""

    delay: float
    tied: bool
    phase: float
    whole: int
    travel: float
    v: float
    vz: float
    kind: int
    mode: int
    v_after: float
    vz_after: float
    closing: int
    grounded: bool


NO_STEP = Step(NEVER, False, 0.0, 0, 0.0, 0.0, 0.0, STICK, STUCK, 0.0, 0.0, 0, False)


class Segment(NamedTuple):
    """The stepper's state: the motion since the last event and what was booked up to its start.

    Its start: ``mode``, the phase ``phase0`` in [0, 2*pi), the velocities
    ``v0``, ``vz0``, the height ``z0`` and the progress guards of its next step
    (``closing``, ``grounded``: see :class:`Step`), the first :data:`START`
    fields; then the offset ``s0`` from the phase anchor and the time ``t0``
    (see :mod:`~friction_sim.core.physics.stepper`), the position ``x0 + xl``
    as a double-double, and the period ``cycles`` that ``phase0`` is in.
    Booked up to its start: the time spent stuck and in flight, and
    ``at_instant``, the events in a row that happened at one instant (the
    no-progress guard)."""

    mode: int
    phase0: float
    v0: float
    vz0: float
    z0: float
    closing: int
    grounded: bool
    s0: float
    t0: float
    x0: float
    xl: float
    cycles: int
    stuck_time: float
    flight_time: float
    at_instant: int


#: A segment's first fields, ``seg[:START]``, are its start but where and when: all
#: its next step depends on under one plant (equal starts, equal steps), so they key
#: an engine's memo of steps (a periodic motion repeats them bit for bit).
START: Final = 7


class Added(NamedTuple):
    """A force added to the steady forms of a segment's plant, ``tau`` into the segment:
    normal to the track, with cot(beta) times it along the track, as the resonant
    exciter's transient force acts (:mod:`~friction_sim.core.physics.transient`).
    ``force`` [N] at ``tau``, and its first and second integrals from the segment's
    start [N s, N s^2]."""

    force: float
    integral: float
    double_integral: float


# -- the closed forms of a segment -------------------------------------------------------------


def axis(w0: float, form: Form, theta0: float, omega: float, from_rest: bool, start: float) -> Harmonic:
    """The closed form of a speed w0 + integral of form(theta) from phase theta0
    (and its integral from ``start``).  ``from_rest``: a motion that starts from
    rest cannot start decelerating (:func:`roots.from_rest_b0`)."""
    phase = theta0 + form.delta
    b0 = from_rest_b0(w0, form.b0, form.b1, math.sin(phase)) if from_rest else form.b0
    return harmonic(w0, b0, form.b1, phase, omega, start)


def x_axis(p: Plant, mode: int, v0: float, phase0: float, steady: bool = True) -> Harmonic:
    """The tangential closed form: w = mode*v of a slip, v of a flight (zero when stuck).
    A slip from rest cannot start decelerating (:func:`axis`), on the ``steady`` forms
    alone; under an :class:`Added` force they are taken as they are (the search that
    started the slip saw the sum)."""
    if mode == FLIGHT:
        return axis(v0, p.flight_x, phase0, p.omega, False, 0.0)
    if mode == STUCK:
        return harmonic(0.0, 0.0, 0.0, phase0, p.omega, 0.0)
    return axis(mode * v0, slip_form(p, mode), phase0, p.omega, steady and v0 == 0.0, 0.0)


def z_axis(p: Plant, phase0: float, vz0: float, z0: float, steady: bool = True) -> Harmonic:
    """The normal closed form of a flight (from a lift-off it cannot start falling; on
    the ``steady`` forms alone, as :func:`x_axis`)."""
    return axis(vz0, p.flight_z, phase0, p.omega, steady and vz0 == 0.0 and z0 == 0.0, z0)


def travel(p: Plant, mode: int, v0: float, phase0: float, tau: float) -> float:
    """x(tau) - x(0) of a segment, signed."""
    if mode == STUCK:
        return 0.0
    moved = harmonic_at(x_axis(p, mode, v0, phase0), tau)[1]
    return moved if mode == FLIGHT else mode * moved


def velocities(p: Plant, mode: int, v0: float, vz0: float, z0: float, phase0: float, tau: float) -> tuple[float,
                                                                                                          float]:
    """(v, vz) ``tau`` into a segment."""
    if mode == FLIGHT:
        return harmonic_at(x_axis(p, mode, v0, phase0), tau)[0], harmonic_at(z_axis(p, phase0, vz0, z0), tau)[0]
    if mode == STUCK:
        return 0.0, 0.0
    return mode * harmonic_at(x_axis(p, mode, v0, phase0), tau)[0], 0.0


def moved_and_velocities(p: Plant, mode: int, v0: float, vz0: float, z0: float, phase0: float,
                         tau: float) -> tuple[float, float, float, float]:
    """(x(tau) - x(0), v, vz, z) ``tau`` into a segment: :func:`travel`,
    :func:`velocities` and the height at once (where an input change cuts it)."""
    if mode == STUCK:
        return 0.0, 0.0, 0.0, 0.0
    w, moved = harmonic_at(x_axis(p, mode, v0, phase0), tau)
    if mode == FLIGHT:
        vz, z = harmonic_at(z_axis(p, phase0, vz0, z0), tau)
        return moved, w, vz, z
    return mode * moved, mode * w, 0.0, 0.0


# -- the next event -----------------------------------------------------------------------------


def next_step(p: Plant, mode: int, phase0: float, v0: float, vz0: float, z0: float, closing: int,
              grounded: bool) -> Step:
    """Detect the next event of the segment that starts with (mode, phase0, v0,
    vz0, z0) and the guards (closing, grounded), and work out its outcome."""
    if p.kostek and mode != FLIGHT:
        return kostek_onset(p, phase0, closing) if mode == STUCK else kostek_stop(p, mode, v0, phase0)
    return general_step(p, mode, phase0, v0, vz0, z0, closing, grounded)


def kostek_onset(p: Plant, phase0: float, closing: int) -> Step:
    """Kostek's model, stuck: the slip starts where |Ft| rises above mu*R (asin),
    in the direction of Ft, tied to its phase (at once: no wait at all)."""
    if not p.can_slip:
        return NO_STEP
    direction = p.direction
    form = slip_form(p, direction)
    delta, start = next_slip_start(phase0, form.b0, form.b1, closing == direction)
    if delta == NEVER:
        return NO_STEP
    if delta == 0.0:
        return Step(0.0, False, start, 0, 0.0, 0.0, 0.0, SLIP_START, direction, 0.0, 0.0, 0, False)
    wraps = start < phase0 or (start == phase0 and delta > 0.0)  # the start passes 2*pi on the way
    return Step(delta / p.omega, True, start, 1 if wraps else 0, 0.0, 0.0, 0.0, SLIP_START, direction, 0.0, 0.0, 0,
                False)


def kostek_stop(p: Plant, mode: int, v0: float, phase0: float) -> Step:
    """Kostek's model, slipping: the slip stops where its speed returns to zero;
    it then sticks, or reverses if the window of the other direction is open."""
    h = x_axis(p, mode, v0, phase0)
    delay = slip_stop_delay(h.w0, h.b0, h.b1, h.phase0, h.omega)
    if delay == NEVER:
        return NO_STEP
    moved = harmonic_at(h, delay)[1]
    phase, whole = reduce_phase(phase0 + p.omega * delay, 0)
    direction = p.direction
    if direction == -mode and p.can_slip:
        form = slip_form(p, direction)
        if next_slip_start(phase, form.b0, form.b1, False)[0] == 0.0:
            return Step(delay, False, phase, whole, mode * moved, 0.0, 0.0, REVERSAL, direction, 0.0, 0.0, 0, False)
    return Step(delay, False, phase, whole, mode * moved, 0.0, 0.0, STICK, STUCK, 0.0, 0.0, mode, False)


def _onset_phase(form: Form, theta0: float, closing: bool) -> float:
    """The phase at which form(theta) first rises above 0 from theta0 (``inf``: never)."""
    delta, _ = next_slip_start(theta0 + form.delta, form.b0, form.b1, closing)
    return NEVER if delta == NEVER else theta0 + delta


def general_step(p: Plant, mode: int, phase0: float, v0: float, vz0: float, z0: float, closing: int,
                 grounded: bool) -> Step:
    """:func:`next_step` of the general model.  ``closing`` and ``grounded``
    guard progress: an at-once restart of the slip that just stopped, or of a
    flight that ended as it began, could only come from rounding, so it waits
    for the window to open again (see :func:`roots.next_slip_start`).  Which
    candidate wins is :func:`contact_event`'s call, and :func:`event_step` works
    out what follows, as for the exciter's transient
    (:func:`~friction_sim.core.physics.transient.transient_step`)."""
    omega = p.omega
    direction, theta = 0, NEVER  # theta: the phase of an event tied to one
    if mode == FLIGHT:
        z = z_axis(p, phase0, vz0, z0)
        kind, delay = LANDING, landing_delay(z.w0, z.b0, z.b1, z.phase0, z.omega, z.start)
    elif mode == STUCK:  # by phase: each onset is tied to one
        lift = _onset_phase(p.lift, phase0, grounded)
        forward = _onset_phase(p.onset_forward, phase0, closing == FORWARD)
        backward = _onset_phase(p.onset_backward, phase0, closing == BACKWARD)
        kind, direction, theta = contact_event(mode, lift, forward, backward, NEVER)
        delay = NEVER if theta == NEVER else (theta - phase0) / omega
    else:  # by delay, a lift-off tied to its phase
        lift = _onset_phase(p.lift, phase0, grounded)
        h = x_axis(p, mode, v0, phase0)
        kind, direction, delay = contact_event(mode, NEVER if lift == NEVER else (lift - phase0) / omega, NEVER,
                                               NEVER, slip_stop_delay(h.w0, h.b0, h.b1, h.phase0, omega))
        if kind == LIFT_OFF:
            theta = lift
    if delay == NEVER:
        return NO_STEP
    v, vz = velocities(p, mode, v0, vz0, z0, phase0, delay)
    return event_step(p, mode, kind, direction, delay, theta, phase0, travel(p, mode, v0, phase0, delay), v, vz,
                      0.0)


def sooner(kind: int, direction: int, when: float, other: int, other_direction: int, other_when: float,
           wins_ties: bool) -> tuple[int, int, float]:
    """(kind, direction, when) of the earlier of an event found so far and another
    candidate (``when``: a phase or a delay, ``inf``: never); the candidate wins a tie
    only if it ``wins_ties``."""
    if other_when < when or (wins_ties and other_when == when):
        return other, other_direction, other_when
    return kind, direction, when


def contact_event(mode: int, lift: float, forward: float, backward: float, stop: float) -> tuple[int, int, float]:
    """(kind, direction, when) of the event a segment on the track meets first, from
    when each candidate comes (``inf``: never): stuck, a slip's onset forward or
    backward (forward wins a tie) or a lift-off (which wins any tie); slipping, the
    slip's stop or a lift-off (which wins a tie).  The one rule of both models, the
    steady one (:func:`general_step`) and the exciter's transient
    (:func:`~friction_sim.core.physics.transient.transient_step`)."""
    if mode == STUCK:
        kind, direction, when = sooner(SLIP_START, FORWARD, forward, SLIP_START, BACKWARD, backward, False)
        return sooner(kind, direction, when, LIFT_OFF, 0, lift, True)
    return sooner(STICK, 0, stop, LIFT_OFF, 0, lift, True)


def event_step(p: Plant, mode: int, kind: int, direction: int, delay: float, theta: float, phase0: float,
               moved: float, v: float, vz: float, force: float) -> Step:
    """The :class:`Step` of the event ``contact_event`` (or a landing) chose, ``delay``
    into a segment that started at ``phase0``, tied to the phase ``theta`` (``inf``:
    not tied, at phase0 + omega*delay), after ``moved`` with velocities v and vz just
    before; ``force``: the normal force added then (the exciter's transient; 0.0: none),
    which decides with the forms whether a stopped slip slips on (:func:`stays`)."""
    tied = theta != NEVER
    if not tied:
        theta = phase0 + p.omega * delay
    phase, whole = reduce_phase(theta, 0)
    return outcome(p, mode, kind, direction, stays(p, theta, force) if kind == STICK else 0, delay, tied, phase,
                   whole, moved, v, vz)


def outcome(p: Plant, mode: int, kind: int, direction: int, slips: int, delay: float, tied: bool, phase: float,
            whole: int, moved: float, v: float, vz: float) -> Step:
    """The :class:`Step` of an event of ``kind`` found ``delay`` into a segment in
    ``mode`` (at ``phase`` of period ``whole``, after ``moved``, with velocities
    v and vz just before): what follows it.  ``direction``: a slip start's;
    ``slips``: at a slip's stop, the direction it would slip in at once (0: it
    stays stuck; see :func:`~friction_sim.core.physics.plant.stays`)."""
    if kind == SLIP_START:
        return Step(delay, tied, phase, whole, moved, v, vz, kind, direction, 0.0, 0.0, 0, False)
    if kind == LIFT_OFF:
        return Step(delay, tied, phase, whole, moved, v, vz, kind, FLIGHT, v, 0.0, 0, False)
    if kind == STICK:
        if slips == -mode:
            return Step(delay, tied, phase, whole, moved, v, vz, REVERSAL, slips, 0.0, 0.0, 0, False)
        return Step(delay, tied, phase, whole, moved, v, vz, STICK, STUCK, 0.0, 0.0, mode, False)
    v_after, vz_after, bounces = impact(p, v, vz)
    if bounces:
        return Step(delay, tied, phase, whole, moved, v, vz, LANDING, FLIGHT, v_after, vz_after, 0, False)
    after = STUCK if v_after == 0.0 else (FORWARD if v_after > 0.0 else BACKWARD)
    return Step(delay, tied, phase, whole, moved, v, vz, LANDING, after, v_after, 0.0, 0, delay == 0.0)


def impact(p: Plant, v: float, vz: float) -> tuple[float, float, bool]:
    """The landing law: the velocities (v, vz) just after a landing and whether the
    slider bounces.  Normal restitution e; a rebound below the plant's floor is
    plastic; then (impulsive) a tangential impulse of at most mu times the normal
    one, which stops the slider if it is enough (Coulomb impact)."""
    rebound = -p.restitution * vz
    bounces = rebound > p.rebound_floor
    normal_impulse = -vz + (rebound if bounces else 0.0)  # per unit mass, >= 0
    if p.impulsive:
        limit = p.mu * normal_impulse
        v = 0.0 if abs(v) <= limit else v - math.copysign(limit, v)
    return v, rebound if bounces else 0.0, bounces


def normal_force(p: Plant, theta: Floats) -> Floats:
    """The contact force R at phase ``theta`` (in contact; a float or an array)."""
    return p.n0 - p.pa * sine(theta - p.lag)


def evaluate(p: Plant, seg: Segment, tau: Floats,
             added: Added | None = None) -> tuple[Floats, Floats, Floats, Floats, Floats, Floats, Floats, Floats]:
    """(x, v, acceleration, friction force, normal force, phase, z, vz) ``tau`` into
    ``seg`` (the phase unreduced), at a float or at an array of times, as scipy's
    ``DenseOutput``: a float with libm's sin (so the compiled engine's samples are
    the single slider's states bit for bit), an array with numpy's (within an ulp or
    two of libm's: the values may differ from the floats' in their last bits).

    ``added``: a force added to the steady forms (the resonant exciter's transient:
    :mod:`~friction_sim.core.physics.transient`).  Its value and its first and second
    integrals, times each form's gain (:func:`~friction_sim.core.physics.plant.slip_gain`,
    cot(beta)/m and 1/m in flight), are added to the acceleration, the speed and the
    position, and it is taken off the contact force.  Under it a start from rest is
    taken as it is (the search that found the event saw the sum: see :func:`x_axis`),
    and the acceleration is the steady form at the phase (:func:`form_at`, the
    transient's own formulation, which may differ from the closed form's rate in
    its last bit) plus the force's part."""
    theta = seg.phase0 + p.omega * tau
    zero = tau * 0.0
    mode = seg.mode
    if mode == FLIGHT:
        hx = x_axis(p, mode, seg.v0, seg.phase0)
        hz = z_axis(p, seg.phase0, seg.vz0, seg.z0, added is None)
        v, moved = harmonic_at(hx, tau)
        vz, z = harmonic_at(hz, tau)
        if added is None:
            return seg.x0 + (seg.xl + moved), v, harmonic_rate(hx, tau), zero, zero, theta, z, vz
        along, across = p.cot_beta / p.mass, 1.0 / p.mass
        return (seg.x0 + (seg.xl + (moved + along * added.double_integral)), v + along * added.integral,
                form_at(p.flight_x, theta) + along * added.force, zero, zero, theta,
                z + across * added.double_integral, vz + across * added.integral)
    normal = normal_force(p, theta) if p.pa else p.n0 + zero
    if added is not None:
        normal = normal - added.force
    if mode == STUCK:
        if p.kostek:  # Kostek's segments: the paper's case as it always was, to the sign of a zero
            friction = -p.tangential.b0 + zero
        elif added is None:
            friction = -form_at(p.tangential, theta)
        else:
            friction = -(form_at(p.tangential, theta) + p.cot_beta * added.force)
        return seg.x0 + zero, zero, zero, friction, normal, theta, zero, zero
    h = x_axis(p, mode, seg.v0, seg.phase0, added is None)
    w, moved = harmonic_at(h, tau)
    if added is None:
        rate = harmonic_rate(h, tau)
    else:
        gain = slip_gain(p, mode)
        moved, w = moved + gain * added.double_integral, w + gain * added.integral
        rate = form_at(slip_form(p, mode), theta) + gain * added.force
    return (seg.x0 + (seg.xl + mode * moved), mode * w, mode * rate, -mode * p.mu * normal, normal, theta, zero,
            zero)
