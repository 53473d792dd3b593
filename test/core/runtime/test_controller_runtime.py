"""The controller's ROS-free runtime (core/runtime/controller.py): what the node only adapts."""

from __future__ import annotations

import math
from typing import Any

import pytest

from friction_sim.core.model.spec import CONTROLLER_NODE, defaults
from friction_sim.core.runtime.controller import ERROR, OK, WARN, RealtimeController, beyond_model_after
from friction_sim.errors import ParameterError


def values(**changes: Any) -> dict[str, Any]:
    return {**defaults(CONTROLLER_NODE), **changes}


def test_a_batch_is_judged_in_order_and_refusals_are_counted_with_their_reason() -> None:
    runtime = RealtimeController(values(active=False))
    refusals = runtime.take_batch([("target_speed", 3e-4), ("drive_force", math.nan), ("drive_force", 0.8)])
    assert len(refusals) == 1 and "drive_force = nan" in refusals[0]
    assert (runtime.accepted, runtime.rejected, runtime.command_batches) == (2, 1, 1)
    assert runtime.last_rejection == refusals[0] and runtime.active, "a target makes the controller active"
    assert runtime.control.drive_force == 0.8 and runtime.control.output.target_speed == 3e-4


def test_a_target_only_the_plant_s_model_allows_waits_for_it() -> None:
    """No drive force: the own (Kostek) model cannot convey, a tilted plant could."""
    with pytest.raises(ParameterError):
        RealtimeController(values(drive_force=0.0, target_speed=1e-4, plant_node=""))
    runtime = RealtimeController(values(drive_force=0.0, target_speed=1e-4))
    assert runtime.pending_target == 1e-4 and runtime.control.output.target_speed == 0.0
    current = values(drive_force=0.0, target_speed=0.0)
    runtime.adopt(runtime.with_parameters({"excitation_angle": 30.0, "mu": 0.5}, current), {}, current)
    assert runtime.settle() == "" and runtime.pending_target is None
    assert runtime.control.output.target_speed == 1e-4


def test_a_refused_parameter_set_changes_nothing_and_is_counted() -> None:
    runtime = RealtimeController(values())
    before = runtime.control
    with pytest.raises(ParameterError, match="max_amplitude_ratio"):
        runtime.with_parameters({"mu": 0.2, "max_amplitude_ratio": -1.0}, values())
    assert runtime.control is before and runtime.rejected == 1


def test_samples_are_counted_and_learnt_while_standing_by() -> None:
    runtime = RealtimeController(values(target_speed=2e-4))
    assert runtime.take_sample(1e-4, 0.02, 20_000_000, regulating=False) is None
    assert runtime.samples_accepted == 0
    output = runtime.take_sample(1e-4, 0.04, 40_000_000, regulating=True)
    assert output is not None and runtime.samples_accepted == 1
    with pytest.raises(ParameterError):
        runtime.take_sample(1e3, 0.06, 60_000_000, regulating=True)  # faster than any plant in force creeps
    assert runtime.samples_rejected == 1 and runtime.rejected == 1 and runtime.last_sample_rejection


def test_the_status_says_what_is_wrong_and_counts_refusals_per_interval() -> None:
    runtime = RealtimeController(values(target_speed=2e-4))
    assert runtime.status(namesake="", ready=True).level == OK
    assert runtime.status(namesake="", ready=False).message == "waiting for the plant's parameters"
    runtime.take_batch([("drive_force", math.inf)])
    warned = runtime.status(namesake="", ready=True)
    assert warned.level == WARN and "1 inputs refused" in warned.message
    assert "inputs refused" not in runtime.status(namesake="", ready=True).message, "counted once per interval"
    runtime.internal_error("mean_velocity callback: ZeroDivisionError")
    failed = runtime.status(namesake="another /controller", ready=True)
    assert failed.level == ERROR and "another /controller" in failed.message
    assert failed.values["internal_errors"] == 1 and failed.values["commands_rejected"] == 1


def test_an_unreachable_target_is_news_once_and_again_when_it_is_reachable() -> None:
    runtime = RealtimeController(values())
    runtime.take_batch([("target_speed", 1.0)])  # far beyond what Pa <= 0.95 m g gives
    output = runtime.control.output
    assert output.unreachable
    warnings, publish = runtime.news(output)
    assert len(warnings) == 1 and "unreachable" in warnings[0] and publish
    assert runtime.news(output) == ([], False)
    runtime.take_batch([("target_speed", 1e-4)])
    assert runtime.news(runtime.control.output) == ([], True)


def test_a_plant_beyond_its_model_is_said_once_driven_to_pa_0_and_never_refused_for_ever() -> None:
    """Issue 23, item 8: a slider that runs away (here: faster than any plant
    of the model creeps) used to have every sample refused from then on.
    Samples beyond the limit are refused for as many as may still be on their
    way after a change; then the plant is taken to be beyond its model: one
    warning with the reason and the plant, Pa 0, its samples taken (counted,
    not refused); the first sample back within the limit resumes regulation
    from the state kept."""
    runtime = RealtimeController(values(target_speed=2e-4))
    ns = 20_000_000
    regulating = runtime.take_sample(1.5e-4, 0.02, ns, regulating=True)
    assert regulating is not None and regulating.amplitude > 0.0
    kept = runtime.control.output
    after = beyond_model_after(runtime.control.config)
    fast = 50.0 * runtime.control.sample_limit
    for n in range(1, after):
        with pytest.raises(ParameterError, match="mean_velocity"):
            runtime.take_sample(fast, 0.02 * (n + 1), (n + 1) * ns, regulating=True)
    assert runtime.samples_rejected == after - 1 and not runtime.beyond_model
    outputs = [runtime.take_sample(fast * (1 + k), 0.02 * (after + k + 1), (after + k + 1) * ns, regulating=True)
               for k in range(5)]
    assert all(out is not None and out.amplitude == 0.0 for out in outputs), "Pa 0 while beyond the model"
    assert runtime.samples_rejected == after - 1 and runtime.samples_beyond_model == 5, "taken, not refused"
    assert runtime.control.measured_speed == fast * 5
    warnings = [text for out in outputs for text in runtime.news(out)[0] if out is not None]
    assert len(warnings) == 1 and "beyond the limit" in warnings[0] and "Pa set to 0" in warnings[0]
    assert "m = 1 kg" in warnings[0] and "f = 50 Hz" in warnings[0], warnings[0]
    status = runtime.status(namesake="", ready=True)
    assert status.level == WARN and "beyond its model" in status.message
    assert status.values["plant_beyond_model"] and status.values["samples_beyond_model"] == 5
    assert runtime.control.output == kept, "the law's state is kept"
    back = runtime.take_sample(1.5e-4, 1.0, 50 * ns, regulating=True)
    assert back is not None and back.amplitude > 0.0 and not runtime.beyond_model
    assert runtime.news(back) == ([], True), "back within the limit: diagnostics at once, no new warning"


def test_the_status_names_the_plant_the_law_inverts() -> None:
    runtime = RealtimeController(values(excitation_frequency=100.0, drive_force=0.8))
    runtime.plant_node = "/feeder2/slider"
    status = runtime.status(namesake="", ready=True).values
    assert status["plant_node"] == "/feeder2/slider"
    assert status["plant"] == "m = 1 kg, mu = 0.1, g = 10 m/s^2, Fd = 0.8 N, f = 100 Hz (Kostek's closed form)"
