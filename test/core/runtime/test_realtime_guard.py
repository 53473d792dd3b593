"""The real-time loop never takes a state the exact core cannot carry on from
(core/realtime.py): a command the core fails on is refused and everything is
put back; a failure while advancing is a SimulationFault, for good."""

from __future__ import annotations

import math
from typing import Any

import pytest

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.commands import PARAMETERS, Command
from friction_sim.core.model.events import SliderState
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.errors import SimulationFault

from helpers import POISON

NS = 1_000_000_000


def realtime(**kwargs: Any) -> RealtimeSlider:
    return RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, **kwargs)



def reference_states(times_ns: list[int]) -> list[SliderState]:
    """The exact motion without any command."""
    slider = Slider(SliderParams(), Inputs())
    states = []
    for t in times_ns:
        slider.advance_to(t / NS)
        states.append(slider.state())
    return states


@pytest.mark.usefixtures("failing_core")
def test_a_command_the_core_fails_on_is_refused_and_undone_completely() -> None:
    rt = realtime(mean_window_periods=1)
    rt.tick(int(0.31 * NS))  # mid-period, the slider slipping or stuck: a state worth restoring
    (outcome,) = rt.commands([Command(0.0, "drive_force", {"drive_force": POISON})], int(0.337 * NS))
    assert not outcome.accepted
    assert "drive_force" in outcome.reason and "OverflowError" in outcome.reason
    assert "last valid state kept" in outcome.reason
    assert rt.slider.inputs == Inputs() and rt.accepted == 0 and rt.rejected == 1
    assert rt.last_rejection == outcome.reason
    # The motion goes on exactly as if the command had never come, period marks included.
    times = [int(t * NS) for t in (0.35, 0.5, 1.0)]
    states = [rt.tick(t).state for t in times]
    assert states == reference_states(times)
    marks = [mark.n for mark in rt.slider.cycle_marks]
    assert marks == sorted(set(marks)), "no period counted twice"


@pytest.mark.usefixtures("failing_core")
def test_in_a_batch_only_the_command_the_core_fails_on_is_refused() -> None:
    rt = realtime()
    batch = [Command(0.0, "excitation_amplitude", {"excitation_amplitude": 4.0}),
             Command(0.0, "drive_force", {"drive_force": POISON}),
             Command(0.0, "excitation_frequency", {"excitation_frequency": 60.0})]
    outcomes = rt.commands(batch, int(0.2 * NS))
    assert [o.accepted for o in outcomes] == [True, False, True]
    assert rt.slider.inputs == Inputs(excitation_amplitude=4.0, excitation_frequency=60.0)
    assert (rt.accepted, rt.rejected) == (2, 1)


@pytest.mark.usefixtures("failing_core")
def test_a_parameter_set_the_core_fails_on_is_refused_whole() -> None:
    rt = realtime()
    outcome = rt.configure({"drive_force": POISON, "real_time_factor": 2.0, "publish_rate": 50.0}, int(0.2 * NS))
    assert not outcome.accepted and "OverflowError" in outcome.reason and "drive_force" in outcome.reason
    assert rt.clock.rate == 1.0 and rt.publish_rate == 1000.0 and rt.slider.inputs == Inputs()


def test_a_state_that_is_not_finite_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    real = Slider.state

    def state(self: Slider) -> SliderState:
        exact = real(self)
        if self.inputs.drive_force == POISON:
            return SliderState(exact.t, math.inf, exact.v, exact.acceleration, exact.friction_force,
                               exact.normal_force, exact.phase, exact.mode)
        return exact

    monkeypatch.setattr(Slider, "state", state)
    rt = realtime()
    (outcome,) = rt.commands([Command(0.0, "drive_force", {"drive_force": POISON})], int(0.2 * NS))
    assert not outcome.accepted and "x = inf" in outcome.reason
    assert rt.slider.inputs == Inputs()
    assert math.isfinite(rt.tick(int(0.3 * NS)).state.x)


def test_a_failure_while_advancing_is_a_fault_for_good(monkeypatch: pytest.MonkeyPatch) -> None:
    rt = realtime()
    rt.tick(int(0.1 * NS))
    real = Slider.advance_to

    def advance_to(self: Slider, t: float) -> Any:
        if t > 0.5:
            raise ValueError("math domain error")
        return real(self, t)

    monkeypatch.setattr(Slider, "advance_to", advance_to)
    with pytest.raises(SimulationFault) as fault:
        rt.tick(int(0.6 * NS))
    text = str(fault.value)
    assert "\n" not in text and "ValueError: math domain error" in text and "t = 0." in text
    assert rt.fault == text
    monkeypatch.setattr(Slider, "advance_to", real)  # even if the core would now go on: the run is over
    with pytest.raises(SimulationFault):
        rt.tick(int(0.7 * NS))
    with pytest.raises(SimulationFault):
        rt.commands([Command(0.0, "drive_force", {"drive_force": 0.8})], int(0.7 * NS))
    with pytest.raises(SimulationFault):
        rt.configure({"mass": 2.0}, int(0.7 * NS))
    assert rt.diagnostics(int(0.8 * NS))["sim_time"] > 0.0, "diagnostics still answer"


def test_a_state_that_becomes_non_finite_while_advancing_is_a_fault(monkeypatch: pytest.MonkeyPatch) -> None:
    rt = realtime()
    real = Slider.state
    monkeypatch.setattr(Slider, "state", lambda self: SliderState(
        self.t, math.nan, 0.0, 0.0, 0.0, 10.0, 0.0, real(self).mode))
    with pytest.raises(SimulationFault, match="x = nan"):
        rt.tick(int(0.1 * NS))


def test_commands_the_core_takes_are_unaffected_by_the_guard() -> None:
    rt = realtime()
    outcomes = rt.commands([Command(0.0, PARAMETERS, {"mass": 2.0}),
                            Command(0.0, "drive_force", {"drive_force": 1.2})], int(0.25 * NS))
    assert all(o.accepted for o in outcomes)
    reference = Slider(SliderParams(), Inputs())
    reference.advance_to(0.25)
    reference.set_plant(SliderParams(mass=2.0), Inputs(drive_force=1.2))
    reference.advance_to(0.75)
    assert rt.tick(int(0.75 * NS)).state == reference.state()
