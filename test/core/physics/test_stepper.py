"""The one stepper (friction_sim.core.physics.stepper) and the one evaluation of a
segment's state (segment.evaluate), which both engines run: the single slider
interpreted, the population engine compiled (test_batch.py holds the two to the
same bits).  Here their rules, each on its own: an event's time from the phase
anchor, the position as a double-double, the booked times, the no-progress guard;
and the evaluation's hook for a force added to the steady forms, which reproduces
the exciter's transient evaluation bit for bit."""

from __future__ import annotations

import math
from fractions import Fraction

import pytest

from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.physics.roots import NEVER
from friction_sim.core.physics.segment import (
    FLIGHT,
    FORWARD,
    LANDING,
    SLIP_START,
    START,
    STICK,
    STUCK,
    Segment,
    Step,
)
from friction_sim.core.physics.stepper import Anchor, advance, offset, period_start, schedule, spent, to_cycle

#: An anchor at t = 2 s, total phase 2*pi*3 + 1 rad, 50 Hz.
ANCHOR = Anchor(2.0, 3, 1.0, 50.0, TWO_PI * 50.0)


def segment(mode: int = STUCK, *, s0: float = 0.5, t0: float = 2.5, x0: float = 0.25, xl: float = 0.0,
            phase0: float = 2.0, cycles: int = 28, stuck: float = 0.125, flight: float = 0.0625,
            at_instant: int = 0) -> Segment:
    return Segment(mode, phase0, 0.0, 0.0, 0.0, 0, False, s0, t0, x0, xl, cycles, stuck, flight, at_instant)


def step(*, delay: float = 0.0, tied: bool = False, phase: float = 3.0, whole: int = 0, travel: float = 0.0,
         kind: int = SLIP_START, mode: int = FORWARD) -> Step:
    return Step(delay, tied, phase, whole, travel, 0.0, 0.0, kind, mode, 0.0, 0.0, 0, False)


def test_an_event_tied_to_a_phase_is_timed_from_the_anchor_never_before_the_start() -> None:
    seg = segment()
    tied = step(tied=True, phase=3.0, whole=1)
    next_s, next_t = schedule(ANCHOR, seg, tied)
    assert next_s == offset(ANCHOR, 29, 3.0) == (29 - 3) / 50.0 + (3.0 - 1.0) / ANCHOR.omega
    assert next_t == ANCHOR.t + next_s
    early = step(tied=True, phase=0.0, whole=-26)  # (a phase that rounding put before the start)
    assert schedule(ANCHOR, seg, early) == (seg.s0, seg.t0)


def test_any_other_event_is_its_delay_after_the_start_and_never_is_inf() -> None:
    seg = segment()
    assert schedule(ANCHOR, seg, step(delay=0.25)) == (0.75, 2.75)
    assert schedule(ANCHOR, seg, step(delay=NEVER)) == (NEVER, NEVER)
    moved = ANCHOR._replace(t=1.0 + 2.0**-40)  # the anchor's time rounds the sum below the start
    assert schedule(moved, segment(t0=1.5 + 2.0**-40), step(delay=0.0))[1] == 1.5 + 2.0**-40


def test_the_position_moves_as_a_double_double() -> None:
    seg = segment(x0=1.0, xl=2.0**-60)
    after = advance(seg, step(delay=0.25, travel=1e-17), 0.75, 2.75)
    assert Fraction(after.x0) + Fraction(after.xl) == Fraction(1.0) + Fraction(2.0**-60) + Fraction(1e-17)
    assert after.x0 + after.xl == after.x0  # (normalized: x0 is the rounded sum)


@pytest.mark.parametrize("mode, stuck, flight", [(STUCK, 0.125 + 0.25, 0.0625), (FLIGHT, 0.125, 0.0625 + 0.25),
                                                 (FORWARD, 0.125, 0.0625)])
def test_an_event_books_the_time_of_its_segment(mode: int, stuck: float, flight: float) -> None:
    seg = segment(mode)
    assert spent(seg, 0.25) == (stuck, flight)
    after = advance(seg, step(delay=0.25, phase=3.0, whole=2, kind=STICK if mode == FORWARD else SLIP_START), 0.75,
                    2.75)
    assert (after.stuck_time, after.flight_time) == (stuck, flight)
    assert (after.s0, after.t0, after.phase0, after.cycles, after.mode) == (0.75, 2.75, 3.0, 30, FORWARD)


def test_a_period_start_within_a_stuck_segment_holds_x_and_books_the_time() -> None:
    seg = segment(STUCK, x0=0.25, xl=2.0**-60, phase0=2.0, cycles=28)
    tau = to_cycle(29, seg.cycles, seg.phase0, ANCHOR.omega)
    assert tau == (TWO_PI - 2.0) / ANCHOR.omega
    assert period_start(seg, tau, math.nan) == (0.25, 0.125 + tau, 0.0625)  # (a stuck slider's travel: unused)
    slipping = segment(FORWARD, x0=0.25, xl=2.0**-60)
    assert period_start(slipping, tau, 1e-3) == (0.25 + (2.0**-60 + 1e-3), 0.125, 0.0625)


def test_events_in_a_row_at_one_instant_are_counted_for_the_no_progress_guard() -> None:
    seg = segment(FLIGHT, at_instant=7)
    landing = step(delay=0.0, kind=LANDING, mode=FLIGHT)
    assert advance(seg, landing, seg.s0, seg.t0).at_instant == 8
    assert advance(seg, step(delay=1e-9, kind=LANDING, mode=FLIGHT), seg.s0 + 1e-9, seg.t0 + 1e-9).at_instant == 0


def test_a_segment_start_is_its_first_fields() -> None:
    seg = segment(FORWARD)
    assert seg[:START] == (seg.mode, seg.phase0, seg.v0, seg.vz0, seg.z0, seg.closing, seg.grounded)
