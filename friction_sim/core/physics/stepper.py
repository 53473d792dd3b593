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

The phase anchor (:class:`Anchor`) ties a time to a total phase under the
present frequency; every event and period start is timed afresh from it
(:func:`offset`), so rounding errors never add up from one event to the next:
after a million periods a slip still starts within a few units in the last
place of its exact time, wherever the run started.
"""

from __future__ import annotations

from typing import NamedTuple

from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.physics.plant import Plant
from friction_sim.core.physics.segment import FLIGHT, STUCK, Segment, Step, next_step

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


__all__ = ["MAX_EVENTS_AT_ONE_INSTANT", "Anchor", "advance", "offset", "period_start", "schedule", "spent", "step_of",
           "to_cycle"]
