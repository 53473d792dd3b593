"""Commands handled at one instant are as many changes of the core, in order
(issue 28, finding 7): with the resonant exciter the order matters, a switch of
actuator followed by a new frequency leaves a transient that one merged change
does not, and a recording holds one command after another, so the node takes
them one at a time, through the function verify replays them with
(:func:`friction_sim.core.model.commands.take`)."""

from __future__ import annotations

from collections.abc import Sequence

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.commands import PARAMETERS, Command, apply
from friction_sim.core.model.events import SliderState
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.realtime import RealtimeSlider

NS = 1_000_000_000
PLANT = SliderParams(natural_frequency=52.0, excitation_angle=45.0, restitution=0.3)
INPUTS = Inputs(excitation_amplitude=3.0, drive_level=0.5)
SWITCH_THEN_FREQUENCY = (Command(0.0, PARAMETERS, {"actuator": "resonant"}),
                         Command(0.0, "excitation_frequency", {"excitation_frequency": 55.0}))


def reference(commands: Sequence[Command], at: float, until: float, *, merged: bool) -> SliderState:
    """The plain core, the commands applied at ``at`` one set_plant each (or merged into one)."""
    slider = Slider(PLANT, INPUTS)
    slider.advance_to(at)
    params, inputs = slider.params, slider.inputs
    for command in commands:
        params, inputs = apply(command, params, inputs)
        if not merged:
            slider.set_plant(params, inputs)
    if merged:
        slider.set_plant(params, inputs)
    slider.advance_to(until)
    return slider.state()


def test_a_batch_at_one_instant_is_taken_one_command_at_a_time() -> None:
    rt = RealtimeSlider(PLANT, INPUTS, wall_ns=0)
    outcomes = rt.commands(list(SWITCH_THEN_FREQUENCY), round(0.2537 * NS))
    assert all(o.accepted for o in outcomes) and rt.accepted == 2
    state = rt.tick(round(0.6 * NS)).state
    assert state == reference(SWITCH_THEN_FREQUENCY, 0.2537, 0.6, merged=False)
    assert state.x != reference(SWITCH_THEN_FREQUENCY, 0.2537, 0.6, merged=True).x, \
        "the case where merging differs (else this test proves nothing)"


def test_a_batch_a_parameter_set_and_two_calls_at_a_paused_instant_are_the_same_changes() -> None:
    """The same two changes, however they reach the node at a paused instant
    (one tick's batch, two ticks, two parameter sets), give the same motion."""
    runs = []
    for way in ("batch", "ticks", "sets"):
        rt = RealtimeSlider(PLANT, INPUTS, wall_ns=0)
        rt.tick(round(0.2537 * NS))
        assert rt.pause(round(0.2537 * NS)).accepted
        wall = round(0.3 * NS)  # wall time passes while paused; simulation time does not
        if way == "batch":
            rt.commands(list(SWITCH_THEN_FREQUENCY), wall)
        elif way == "ticks":
            for command in SWITCH_THEN_FREQUENCY:
                rt.tick(wall)
                rt.commands([command], wall)
        else:
            rt.configure({"actuator": "resonant"}, wall)
            rt.configure({"excitation_frequency": 55.0}, wall)
        assert rt.accepted == 2 and rt.slider.t == 0.2537
        assert rt.resume(wall).accepted
        runs.append(rt.tick(wall + round(0.3463 * NS)).state)
    assert runs[0] == runs[1] == runs[2] == reference(SWITCH_THEN_FREQUENCY, 0.2537, 0.6, merged=False)
