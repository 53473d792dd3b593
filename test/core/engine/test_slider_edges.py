"""The exact core at the edges of the slip window: no creep below or on the motion
boundary phi = 1 - a (to the last bit of the given values), no endless loop of
zero-length events where the window opens or closes, and forward slips that never
step backwards.  Each case once looped for ever or moved by a rounding error."""

import math
from fractions import Fraction

import numpy as np
import pytest

from friction_sim.core.engine.single import EventKind, Mode, Slider
from friction_sim.core.model.params import Inputs, SliderParams

from helpers import EndlessLoop, assert_states_close, paper_slider, time_limit

TWO_PI = 2.0 * math.pi
OMEGA = TWO_PI * 50.0
PERIOD = 1.0 / 50.0


@pytest.mark.parametrize("fd, pa", [(0.4, 5.0), (0.5, 5.0), (-0.5, 5.0), (0.0, 9.0), (0.1, 9.0), (0.05, 9.5)])
def test_zero_creep_below_and_on_the_motion_boundary(fd, pa):
    slider = paper_slider(event_log_size=None)
    slider.set_inputs(drive_force=fd, excitation_amplitude=pa)
    periods = 10_000
    with time_limit(5.0, "advance_to"):
        events = slider.advance_to(periods * PERIOD)
    state = slider.state()
    assert state.x == 0.0 and state.v == 0.0
    assert events == [] and slider.events == []
    assert sum(slider.event_counts.values()) == 0
    assert slider.stuck_time == periods * PERIOD
    slider = paper_slider()
    slider.set_inputs(drive_force=fd, excitation_amplitude=pa)
    tr = slider.sample(np.linspace(0.0, periods * PERIOD, 200_001))
    assert np.all(tr.x == 0.0) and np.all(tr.v == 0.0)
    assert np.all(tr.mode == Mode.STUCK)


def _on_or_below_boundary(mu, m, g, fd, pa):
    """Exactly, on the binary values given: |Fd| <= mu*(m*g - Pa)."""
    F = Fraction
    return abs(F(fd)) <= F(mu) * (F(m) * F(g) - F(pa))


# Decimal inputs on the boundary phi = 1 - a whose binary values are (by exact
# rational arithmetic) at or below it: the slider must never move.  Rounding in
# next_slip_start's edge = (load - |Ft|/mu)/Pa lets it find a slip window of
# width ~1e-8 rad anyway, and slip_stop_delay then returns 0: STICK and
# SLIP_START alternate forever at the same instant (advance_to never returns).
BOUNDARY_CASES = [
    (0.1, 0.93, 0.7),
    (0.1, 0.89, 1.1),
    (0.3, 2.82, 0.6),
    (0.1, 0.5, 5.0),
    (0.1, 0.3, 7.0),
    (0.1, 0.4, 6.0),
]


@pytest.mark.parametrize("mu, fd, pa", BOUNDARY_CASES)
def test_no_motion_exactly_on_the_boundary(mu, fd, pa):
    assert _on_or_below_boundary(mu, 1.0, 10.0, fd, pa)
    slider = Slider(SliderParams(mu=mu), Inputs(drive_force=fd, excitation_amplitude=pa),
                    event_log_size=8)
    with time_limit(0.5, f"advance_to(1.0) with mu={mu}, Fd={fd}, Pa={pa}"):
        slider.advance_to(1.0)
    assert slider.state().x == 0.0
    assert sum(slider.event_counts.values()) == 0


def test_no_motion_on_the_boundary_sweep():
    """Every Pa = 0.1..9.9 N with Fd = mu*(m*g - Pa) rounded to decimals, for
    mu in (0.1, 0.3), that is exactly at or below the boundary."""
    failures = []
    for mu in (0.1, 0.3):
        for k in range(1, 100):
            pa = k / 10
            fd = round(mu * (10.0 - pa), 12)
            if not _on_or_below_boundary(mu, 1.0, 10.0, fd, pa):
                continue
            slider = Slider(SliderParams(mu=mu), Inputs(drive_force=fd, excitation_amplitude=pa),
                            event_log_size=8)
            try:
                with time_limit(0.2, "advance_to"):
                    slider.advance_to(1.0)
            except EndlessLoop:
                failures.append((mu, fd, pa, "hangs"))
                continue
            if slider.state().x != 0.0 or sum(slider.event_counts.values()):
                failures.append((mu, fd, pa, slider.state().x))
    assert failures == []


# A stuck slider whose phase is (to rounding) at the END of the slip window,
# theta = pi - asin(edge), edge = (m*g + Fz - |Ft|/mu)/Pa: there dw/dt = 0 and
# then < 0, so nothing may move.  next_slip_start's direct test
# |Ft| > mu*R(phase) can say "slip now" while slip_stop_delay, which recomputes
# the edge as asin(-b0/b1), finds the slip already decelerating and returns 0:
# STICK and SLIP_START then alternate forever at one instant.
EDGE_FD, EDGE_PA = 0.92, 2.0  # edge = (10 - 9.2)/2 = 0.4
WINDOW_END = math.pi - math.asin(0.4)


def _check_no_motion_until_next_window(slider, t_start):
    next_window = t_start + (TWO_PI + math.asin(0.4) - WINDOW_END) / OMEGA
    with time_limit(0.5, "advance_to from the end of the slip window"):
        events = slider.advance_to(next_window - 1e-6)
    assert abs(slider.state().x) <= 1e-18
    assert len(events) <= 2  # at most one zero-length slip
    with time_limit(0.5, "advance_to"):
        events = slider.advance_to(next_window + 1e-6)
    assert [e.kind for e in events] == [EventKind.SLIP_START]
    assert abs(events[0].phase - math.asin(0.4)) < 1e-9


def test_start_at_the_end_of_the_slip_window_via_phase0():
    slider = Slider(SliderParams(), Inputs(drive_force=EDGE_FD, excitation_amplitude=EDGE_PA),
                    phase0=WINDOW_END, event_log_size=8)
    _check_no_motion_until_next_window(slider, 0.0)


def test_set_inputs_at_the_end_of_the_slip_window():
    # A stuck slider (Fd = 0) whose drive force is switched on at the instant
    # the excitation phase reaches the end of the slip window.
    t = 0.008690101195655437  # = (pi - asin(0.4))/(2*pi*50) to rounding
    assert abs(OMEGA * t - WINDOW_END) < 1e-14
    slider = Slider(SliderParams(), Inputs(drive_force=0.0, excitation_amplitude=EDGE_PA),
                    event_log_size=8)
    slider.advance_to(t)
    slider.set_inputs(drive_force=EDGE_FD)
    _check_no_motion_until_next_window(slider, t)


@pytest.mark.parametrize("phase0", [-1e-300, -1e-17])
@pytest.mark.parametrize("fd", [0.9999999999999999, 0.7, 1.0])
def test_tiny_negative_phase0_is_phase_zero(phase0, fd):
    # phase0 = -1e-300 is phase 0 to every digit (though -1e-300 % (2*pi)
    # rounds to exactly 2*pi, outside [0, 2*pi)).  With phi a rounding error
    # below 1 the slip's speed minima fall by only ~1e-15*T per period.
    inputs = Inputs(drive_force=fd, excitation_amplitude=5.0)
    t_end = 0.105  # mid-period: away from the v = 0 tangency of phi = 1
    reference = Slider(SliderParams(), inputs, phase0=0.0, event_log_size=None)
    reference.advance_to(t_end)
    slider = Slider(SliderParams(), inputs, phase0=phase0, event_log_size=None)
    with time_limit(0.5, f"advance_to with phase0={phase0!r}, Fd={fd!r}"):
        slider.advance_to(t_end)
    assert_states_close(slider.state(), reference.state(), rel=1e-9)


@pytest.mark.parametrize("fd, pa", [(0.7, 5.0), (0.95, 1.0), (0.28, 7.2)])
def test_forward_slips_never_move_backwards(fd, pa):
    # Fd > 0 and no reversal: x(t) is non-decreasing and never below x0 = 0.
    # (0.28, 7.2) sits a rounding error above the motion boundary: its slips
    # are ~1e-8 rad long and travel ~1e-29 m, which must still be >= 0.
    slider = paper_slider(event_log_size=None)
    slider.set_inputs(drive_force=fd, excitation_amplitude=pa)
    with time_limit(2.0, "sample"):
        tr = slider.sample(np.linspace(0.0, 0.2, 20001))
    assert slider.event_counts[EventKind.REVERSAL] == 0
    assert np.all(tr.v >= 0.0)
    assert np.all(np.diff(tr.x) >= 0.0)
    assert np.all(tr.x >= 0.0)
    assert all(e.x >= 0.0 for e in slider.events)

