"""The transient's root search near grazing: bounded work, and the motion still right.

On the motion boundary (the drive force just what static friction holds at
the normal force's least value) or at lift-off (drive level 1 at resonance,
the normal force's least value 0) a slip speed, an onset form or a flight's
height stays within rounding of zero over a stretch: a search that bounds
the signal by its largest slope alone splits that stretch ever finer (12 s
at 1e-7 off the boundary, more than 10 minutes exactly on it, at a single
event).  The work is counted (:func:`search_steps`), not timed: a bound on
it holds on any machine.  The motion found there is checked against the
independent reference (solve_ivp on the coupled equations), as far as the
reference itself resolves the grazing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_exciter import ExciterCase, solve

from friction_sim.core.engine.single import Slider
from friction_sim.core.engine.transient_kernel import search_steps
from friction_sim.core.model.events import EventKind
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.roots import NEVER
from friction_sim.core.physics.transient import Signal, first_time, value

PLANT = SliderParams(actuator="resonant", natural_frequency=36.0, damping_ratio=math.exp(-1))
#: The step from drive level 1 to 0.5 puts the part on the motion boundary (drive force
#: 0.5 = mu*(m*g - 0.5*A)); the step from 0.5 to 1 at drive force 0.7 at lift-off.
BOUNDARY, LIFT_OFF = (0.5, 1.0, 0.5), (0.7, 0.5, 1.0)
#: Search steps allowed for a run of 0.5 s (18 periods, 15-52 events): the search takes
#: 2,000-6,500; without the grazing tests it took millions (1e-7 off) or never ended (on it).
STEP_BUDGET = 30_000


def _slider(case: tuple[float, float, float], delta: float) -> Slider:
    force, before, after = case
    slider = Slider(PLANT, Inputs(excitation_frequency=36.0, drive_level=before, drive_force=force + delta),
                    event_log_size=None)
    slider.set_inputs(drive_level=after)
    return slider


@pytest.mark.timeout(120)  # (a backstop only: the bound is on the count)
@pytest.mark.parametrize(("case", "delta"), [(BOUNDARY, 0.0), (BOUNDARY, 1e-7), (LIFT_OFF, 0.0), (LIFT_OFF, 1e-7)])
def test_the_search_takes_bounded_work_at_grazing(case: tuple[float, float, float], delta: float) -> None:
    slider = _slider(case, delta)
    before = search_steps()
    slider.advance_to(0.5)
    assert search_steps() - before <= STEP_BUDGET
    assert slider.event_counts[EventKind.STICK] > 0
    if case == LIFT_OFF:  # (the flights are there: the grazing is the lift-off's)
        assert slider.event_counts[EventKind.LIFT_OFF] > 0


@pytest.mark.timeout(120)
@pytest.mark.parametrize(("case", "delta", "until"), [(BOUNDARY, 0.0, 0.2), (BOUNDARY, 1e-7, 0.2),
                                                      (LIFT_OFF, 0.0, 0.12), (LIFT_OFF, 1e-7, 0.12)])
def test_the_motion_at_grazing_agrees_with_the_coupled_reference(case: tuple[float, float, float], delta: float,
                                                                 until: float) -> None:
    # (until: as far as the reference resolves it; its event finder stops at the next graze,
    # an event at the start of a piece: at 0.35 s on the boundary, at the lift-off at 0.125 s)
    force, before, after = case
    reference = solve(ExciterCase(drive_force=force + delta, frequency=36.0, natural_frequency=36.0,
                                  damping_ratio=math.exp(-1), drive_level=before, changes=((0.0, after),)), until)
    slider = _slider(case, delta)
    times = np.linspace(0.0, until, 41)[1:]
    ours = []
    for t in times:
        slider.advance_to(float(t))
        state = slider.state()
        ours.append((state.x, state.v, state.z, state.vz))
    theirs = np.array([reference.at(float(t))[2:6] for t in times])
    scale = np.max(np.abs(theirs), axis=0)
    assert np.all(np.abs(np.array(ours) - theirs) <= 1e-9 * scale + 1e-300)
    kinds = [kind if not kind.startswith("slip_start") else EventKind.SLIP_START.value for _, kind in reference.events]
    assert [event.kind.value for event in slider.events] == kinds
    assert len(kinds) >= 8
    assert np.all(np.abs(np.array([event.t for event in slider.events]) - [t for t, _ in reference.events])
                  <= 1e-9 / 36.0)


OMEGA = 2 * math.pi * 50.0
LAM = complex(-20.0, 300.0)


@pytest.mark.timeout(60)
@pytest.mark.parametrize("kc", [0j, 1e-30 + 0j, 1e-17j])
def test_a_form_that_touches_zero_is_decided_in_bounded_work(kc: complex) -> None:
    # an onset form whose greatest value is 0 (to rounding): whether it rises above zero there
    # is rounding's call; the search decides it within a few allowances, in bounded work
    s = Signal(0, 0.0, 0.0, -1.0, 1.0, 0.3, OMEGA, kc, LAM)
    work = np.zeros(1, np.int64)
    found = first_time(s, 0.0, 0.1, True, work)
    assert work[0] <= 2_000
    touch = (math.pi / 2 - 0.3) / OMEGA  # the first touch, then every period
    assert found == NEVER or min(abs(found - touch - n / 50.0) for n in range(5)) < 1e-6
    if found != NEVER:
        assert value(s, found) > 0.0


@pytest.mark.timeout(60)
@pytest.mark.parametrize("b0", [-1.0, -1.0 + 1e-12, -1.0 - 1e-12])
def test_a_speed_that_barely_rises_returns_to_zero_in_bounded_work(b0: float) -> None:
    # a slip speed from rest under an acceleration whose greatest value is (about) 0: a triple
    # zero at the start; its return to zero is found, or it is never above zero
    s = Signal(1, 0.0, 0.0, b0, 1.0, math.pi / 2, OMEGA, 0j, LAM)
    work = np.zeros(1, np.int64)
    found = first_time(s, 1e-9, 0.1, False, work)
    assert work[0] <= 2_000
    assert found <= 1e-9 + 1e-3  # (it returns within the same bulge: b0 <= -1 + 1e-12)
    assert value(s, found) <= 0.0
