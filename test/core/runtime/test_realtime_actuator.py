"""What the real-time loop says and takes per actuator (issue 28): its
diagnostics show the inputs that act, with the one the actuator in force does
not use marked so (item 4), and a command or parameter set of that input is
refused whatever its value, counted, and changes nothing (finding 8)."""

from __future__ import annotations

import math

import pytest

from friction_sim.core.model.commands import Command
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.exciter import response
from friction_sim.core.runtime.realtime import NS_PER_S, RealtimeSlider

TICK = NS_PER_S // 1000
#: A slideway tuned a little above the drive (f_n = 52 Hz at f = 50 Hz), stiffer than the default.
RESONANT = SliderParams(actuator="resonant", natural_frequency=52.0, full_drive_acceleration=20.0)
#: The resonant actuator's refusal of a Pa, whatever the Pa (held or not).
WHY_RESONANT = "is not used by actuator resonant: set drive_level (0 … 1) instead"
WHY_FORCE = "is not used by actuator force: set excitation_amplitude (0 … 1e+06 N) instead"


def _run(rt: RealtimeSlider, start: int, end: int) -> None:
    for wall in range(start, end + 1, TICK):
        rt.tick(wall)


def test_resonant_diagnostics_show_the_drive_level_its_steady_pa_and_the_envelope_now() -> None:
    """Item 4: with the resonant actuator Pa is what the slideway makes of the
    drive: diagnostics show u, the steady Pa = m u A G(f/f_n) and the envelope of
    the exciter's state now (steady plus transient); excitation_amplitude, which
    this plant ignores, is marked unused, not shown as if it acted."""
    rt = RealtimeSlider(RESONANT, Inputs(drive_level=0.5), wall_ns=0)
    _run(rt, 0, NS_PER_S // 10)
    assert rt.command(Command(0.0, "drive_level", {"drive_level": 0.9}), NS_PER_S // 10).accepted
    _run(rt, NS_PER_S // 10 + TICK, NS_PER_S // 5)  # 0.1 s into the transient (time constant 0.15 s)
    report = rt.diagnostics(NS_PER_S // 5)
    gain = response(50.0, 52.0, RESONANT.damping_ratio).gain
    steady = RESONANT.mass * 0.9 * RESONANT.full_drive_acceleration * gain
    state = rt.slider.exciter
    assert state is not None
    assert report["actuator"] == "resonant" and report["drive_level"] == 0.9
    assert report["steady_excitation_amplitude"] == pytest.approx(steady, rel=1e-12)
    assert report["excitation_envelope"] == state.amplitude, "the exciter's state at the slider's time"
    assert abs(report["excitation_envelope"] - steady) > 1e-3 * steady, "still in the transient: not the steady Pa"
    assert report["excitation_amplitude"] == "5.0 (unused: actuator resonant)"
    assert report["throw_number"] == pytest.approx(steady / RESONANT.normal_weight, rel=1e-12)


def test_force_diagnostics_show_pa_as_set_and_mark_the_drive_level_unused() -> None:
    rt = RealtimeSlider(SliderParams(), Inputs(excitation_amplitude=6.5), wall_ns=0)
    _run(rt, 0, NS_PER_S // 20)
    report = rt.diagnostics(NS_PER_S // 20)
    assert report["actuator"] == "force" and report["excitation_amplitude"] == 6.5
    assert report["steady_excitation_amplitude"] == 6.5 and report["excitation_envelope"] == 6.5
    assert math.isnan(report["exciter_lag_deg"])
    assert report["drive_level"] == "0.5 (unused: actuator force)"


@pytest.mark.parametrize(("params", "inputs", "field", "value", "why"), [
    (RESONANT, Inputs(), "excitation_amplitude", 5.0, WHY_RESONANT),  # the Pa held: still no input of this plant
    (RESONANT, Inputs(), "excitation_amplitude", 3.0, WHY_RESONANT),
    (SliderParams(), Inputs(), "drive_level", 0.5, WHY_FORCE),
    (SliderParams(), Inputs(), "drive_level", 0.8, WHY_FORCE),
], ids=["resonant-held-pa", "resonant-new-pa", "force-held-level", "force-new-level"])
@pytest.mark.parametrize("path", ["topic", "parameter"])
def test_the_input_the_actuator_does_not_use_is_refused(
        params: SliderParams, inputs: Inputs, field: str, value: float, why: str, path: str) -> None:
    """Finding 8: on its topic whatever the value, as a parameter set to any
    value but the one held, the same one-line refusal naming the field, the
    value and the input to use; counted as refused, never as accepted, and the
    last valid state stays.  A parameter set that keeps the value held is
    configuration (``ros2 param load`` of a dump sets every parameter): taken,
    and nothing changes."""
    rt = RealtimeSlider(params, inputs, wall_ns=0)
    _run(rt, 0, NS_PER_S // 20)
    before = rt.slider.params, rt.slider.inputs
    wall = NS_PER_S // 20 + TICK
    outcome = rt.command(Command(0.0, field, {field: value}), wall) if path == "topic" else \
        rt.configure({field: value}, wall)
    held = value == getattr(inputs, field)
    if path == "parameter" and held:
        assert outcome.accepted and (rt.accepted, rt.rejected) == (1, 0)
    else:
        assert not outcome.accepted
        assert outcome.reason == f"{field} = {value!r} rejected: {why}", "one line: the field, the value, why"
        assert (rt.accepted, rt.rejected, rt.last_rejection) == (0, 1, outcome.reason)
    assert (rt.slider.params, rt.slider.inputs) == before


def test_a_parameter_set_that_switches_the_actuator_may_set_the_input_of_the_new_one() -> None:
    """The rule is the actuator's in force after the change: switching to the
    force actuator together with its Pa is one valid set; switching to the
    resonant one while setting a Pa is refused as a lone Pa would be."""
    rt = RealtimeSlider(RESONANT, Inputs(), wall_ns=0)
    assert rt.configure({"actuator": "force", "excitation_amplitude": 7.0}, NS_PER_S // 100).accepted
    assert rt.slider.params.actuator == "force" and rt.slider.inputs.excitation_amplitude == 7.0
    refused = rt.configure({"actuator": "resonant", "excitation_amplitude": 6.0}, NS_PER_S // 50)
    assert refused.reason == f"excitation_amplitude = 6.0 rejected: {WHY_RESONANT}"
    assert rt.slider.params.actuator == "force" and rt.slider.inputs.excitation_amplitude == 7.0
    assert rt.configure({"actuator": "resonant", "drive_level": 0.7}, NS_PER_S // 20).accepted
    assert (rt.accepted, rt.rejected) == (2, 1)
