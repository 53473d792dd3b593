"""The advance of one slider from event to event, written once.

Both engines step a slider with these plain functions over its state record,
a :class:`~friction_sim.core.physics.segment.Segment`: the single slider
(:mod:`friction_sim.core.engine.single`) runs them interpreted, the population
engine (:mod:`friction_sim.core.engine.compiled`) compiled, so a slider's
events, positions and booked times are the same numbers in both, bit for bit.
An engine works out the step of each segment start (:func:`step_of`, through
its memo of steps by ``seg[:START]``: see
:data:`~friction_sim.core.physics.segment.START`), then

* :func:`schedule` times the step's event from the phase anchor;
* :func:`advance` carries it out: the position moves by the step's travel
  (as a double-double), the time spent stuck or in flight is booked
  (:func:`spent`), the no-progress guard counts events at one instant, and
  the next segment starts;
* :func:`period_start` gives the position and the booked times at the start of
  an excitation period within a segment (where :func:`to_cycle` says it is).

Under the resonant exciter's transient (:mod:`~friction_sim.core.physics.transient`)
the same engines run the same few functions more, whichever engine runs them:
:func:`exciter_changed` (the slideway and when its transient settles after a
change), :func:`transient_window` (a segment's transient force and how far
its next event is sought), :func:`transient_end` (where the segment is cut
instead), :func:`continued` (the segment that starts there, or at any change,
from the same motion) and :func:`motion` (the closed forms with the transient
added, where it is).

The phase anchor (:class:`Anchor`) ties a time to a total phase under the
present frequency; every event and period start is timed afresh from it
(:func:`offset`), so rounding errors never add up from one event to the next:
after a million periods a slip still starts within a few units in the last
place of its exact time, wherever the run started.
"""

from __future__ import annotations

from typing import NamedTuple

from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.physics.exciter import Slideway, followed, force_transient, settle_delay
from friction_sim.core.physics.numerics import two_sum
from friction_sim.core.physics.plant import Plant
from friction_sim.core.physics.roots import NEVER, reduce_phase
from friction_sim.core.physics.segment import FLIGHT, STUCK, Segment, Step, moved_and_velocities, next_step, travel
from friction_sim.core.physics.transient import LOOK_AHEAD_PERIODS, transient_motion

#: More events than this at one instant means the general model made no
#: progress (a rounding case its guards missed): a stepper (the single slider,
#: the compiled population) stops with a fault instead of looping for ever.  A
#: real instant has at most a handful (a landing, a lift-off at once, a slip onset).
MAX_EVENTS_AT_ONE_INSTANT = 1000


class Anchor(NamedTuple):
    """The phase anchor: time ``t`` is at total phase 2*pi*``cycles`` + ``phase``
    under the excitation ``frequency`` (``omega`` = 2*pi*frequency).  An engine
    sets it at the start and whenever the frequency changes."""

    t: float
    cycles: int
    phase: float
    frequency: float
    omega: float


def offset(anchor: Anchor, cycles: int, phase: float) -> float:
    """When, after the anchor's time, the total phase reaches 2*pi*cycles + phase."""
    return (cycles - anchor.cycles) / anchor.frequency + (phase - anchor.phase) / anchor.omega


def to_cycle(n: int, cycles: int, phase0: float, omega: float) -> float:
    """tau at which a segment that started at phase ``phase0`` of period ``cycles``
    reaches the start of period ``n`` (0 if it already had)."""
    whole = n - cycles
    return 0.0 if whole <= 0 else (TWO_PI * whole - phase0) / omega


def step_of(p: Plant, seg: Segment) -> Step:
    """The next event of ``seg`` under the steady plant ``p``, worked out
    (:func:`~friction_sim.core.physics.segment.next_step`)."""
    return next_step(p, seg.mode, seg.phase0, seg.v0, seg.vz0, seg.z0, seg.closing, seg.grounded)


def schedule(anchor: Anchor, seg: Segment, step: Step) -> tuple[float, float]:
    """(offset from the anchor, time) of the event of ``step``: an event tied to a
    phase is timed from the anchor, never before the segment's start, any other
    ``delay`` after the start (``inf``: never)."""
    if step.tied:
        next_s = offset(anchor, seg.cycles + step.whole, step.phase)
        if next_s < seg.s0:
            next_s = seg.s0
    else:
        next_s = seg.s0 + step.delay
    next_t = anchor.t + next_s
    return next_s, next_t if next_t >= seg.t0 else seg.t0


def spent(seg: Segment, tau: float) -> tuple[float, float]:
    """(time stuck, time in flight) booked up to ``tau`` into ``seg``."""
    if seg.mode == STUCK:
        return seg.stuck_time + tau, seg.flight_time
    if seg.mode == FLIGHT:
        return seg.stuck_time, seg.flight_time + tau
    return seg.stuck_time, seg.flight_time


def advance(seg: Segment, step: Step, next_s: float, next_t: float) -> Segment:
    """The segment that the event of ``step``, scheduled at (``next_s``, ``next_t``)
    (:func:`schedule`), starts: at the event's phase and position (x0 + xl moved by
    the step's travel, as a double-double: Knuth's TwoSum), with the step's outcome,
    and the times of ``seg`` booked.  Its ``at_instant`` counts the events in a row
    at one instant: above :data:`MAX_EVENTS_AT_ONE_INSTANT` the engine stops with a
    fault (and keeps ``seg``, the last good state)."""
    x0, part = seg.x0, seg.xl + step.travel
    x = x0 + part  # (numerics.two_sum, written out: this runs at every event)
    bb = x - x0
    xl = (x0 - (x - bb)) + (part - bb)
    stuck, flight = spent(seg, next_s - seg.s0)
    return Segment(step.mode, step.phase, step.v_after, step.vz_after, 0.0, step.closing, step.grounded, next_s,
                   next_t, x, xl, seg.cycles + step.whole, stuck, flight, seg.at_instant + 1 if next_t == seg.t0 else 0)


def period_start(seg: Segment, tau: float, moved: float) -> tuple[float, float, float]:
    """(x, time stuck, time in flight) at the start of a period ``tau`` into ``seg``
    (:func:`to_cycle`), where the slider has moved by ``moved`` from the segment's
    start (a stuck slider's x is held: ``moved`` is not needed)."""
    stuck, flight = spent(seg, tau)
    if seg.mode == STUCK:
        return seg.x0, stuck, flight
    return seg.x0 + (seg.xl + moved), stuck, flight


# -- under the resonant exciter's transient ----------------------------------------------------

#: The force scale of a plant's transient when it has no force at all (the settling
#: rule needs one above zero): 2**-52, one ulp of 1.
_UNIT_SCALE = 2.0**-52


def exciter_changed(way: Slideway, tau: float, theta: float, amplitude: float, lag: float, omega: float,
                    lam: complex, mass: float, p: Plant) -> tuple[Slideway, float]:
    """(the slideway, the delay after which its transient has settled: 0 if it has none)
    after a change ``tau`` into ``way``, the drive at phase ``theta``, to the steady
    response (``amplitude``, ``lag``, ``omega``) and eigenvalue ``lam`` (the new plant
    ``p``, of a part of ``mass``): q and q' continuous (:func:`~friction_sim.core.physics.exciter.followed`),
    the transient settled once its force is below rounding of the plant's forces."""
    new = followed(way, theta, tau, amplitude, lag, omega, lam)
    c = force_transient(new, mass, 0.0)
    scale = abs(p.n0) + abs(p.tangential.b0) + p.pa * (1.0 + abs(p.cot_beta))
    return new, settle_delay(c, new.lam, scale if scale > 0.0 else _UNIT_SCALE)


def transient_window(way: Slideway, way_t0: float, mass: float, until: float, t0: float,
                     frequency: float) -> tuple[complex, float]:
    """(c, horizon) of a segment starting at ``t0`` under the transient of ``way``
    (started at ``way_t0``, settled by ``until``): its force Re(c*exp(lambda*tau)) on a
    part of ``mass``, and how far its next event is sought, up to the settling or
    :data:`~friction_sim.core.physics.transient.LOOK_AHEAD_PERIODS` periods of
    ``frequency``, whichever is sooner."""
    return force_transient(way, mass, t0 - way_t0), min(until - t0, LOOK_AHEAD_PERIODS / frequency)


def transient_end(seg: Segment, c: complex, look_until: float, next_t: float) -> tuple[float, bool]:
    """(time, cut): where ``seg``'s closed form stops holding, and whether it is cut
    there rather than ended by its next event (at ``next_t``).  Under a transient
    (``c`` other than 0) it holds only up to ``look_until`` (never before its start),
    where its next event was sought no further: there an engine starts a new segment
    from the same motion (:func:`continued`), unless the event comes first."""
    if c != 0j:
        boundary = max(look_until, seg.t0)
        if boundary <= next_t:
            return boundary, True
    return next_t, False


def motion(p: Plant, seg: Segment, c: complex, lam: complex, tau: float) -> tuple[float, float, float, float]:
    """(x(tau) - x(0), v, vz, z) ``tau`` into ``seg``, with the transient force
    Re(c*exp(lam*tau)) added if ``c`` is not 0."""
    if c != 0j:
        return transient_motion(p, seg.mode, c, lam, seg.v0, seg.vz0, seg.z0, seg.phase0, tau)
    return moved_and_velocities(p, seg.mode, seg.v0, seg.vz0, seg.z0, seg.phase0, tau)


def moved(p: Plant, seg: Segment, c: complex, lam: complex, tau: float) -> float:
    """x(tau) - x(0) of ``seg`` (:func:`motion`, without the rest where it is steady)."""
    return motion(p, seg, c, lam, tau)[0] if c != 0j else travel(p, seg.mode, seg.v0, seg.phase0, tau)


def continued(p: Plant, seg: Segment, c: complex, lam: complex, t: float, anchor_t: float) -> Segment:
    """The segment that starts at ``t`` from ``seg``'s motion (under ``p`` and the
    transient ``c``, ``lam``): at a change of parameters or inputs, or where a
    transient's segment is cut (:func:`transient_end`).  The progress guards are
    reset; a slip that has come to rest is stuck; ``anchor_t``: the phase anchor's
    time the new segment is timed from."""
    tau = t - seg.t0
    phase, cycles = reduce_phase(seg.phase0 + p.omega * tau, seg.cycles)
    stuck, flight = spent(seg, tau)
    mode = seg.mode
    if mode == STUCK:  # (the common case: a controller's change between slips)
        x, xl, v, vz, z = seg.x0, seg.xl, 0.0, 0.0, 0.0
    else:
        travelled, v, vz, z = motion(p, seg, c, lam, tau)
        x, xl = two_sum(seg.x0, seg.xl + travelled)
        if mode != FLIGHT:
            mode, vz, z = (STUCK if v == 0.0 else (1 if v > 0.0 else -1)), 0.0, 0.0
    return Segment(mode, phase, v, vz, max(z, 0.0), 0, False, t - anchor_t, t, x, xl, cycles, stuck, flight,
                   seg.at_instant)


def settled_at(way: Slideway, way_t0: float, until: float, t: float) -> tuple[Slideway, float, float]:
    """(slideway, its start, when it settles) from a cut at ``t`` on: the transient
    dropped (exactly zero, -inf) once ``t`` has reached ``until``, else unchanged."""
    if t >= until:
        return Slideway(way.amplitude, way.lag, way.omega, way.lam, 0j), t, -NEVER
    return way, way_t0, until


__all__ = ["MAX_EVENTS_AT_ONE_INSTANT", "Anchor", "advance", "continued", "exciter_changed", "motion", "moved",
           "offset", "period_start", "schedule", "settled_at", "spent", "step_of", "to_cycle", "transient_end",
           "transient_window"]
