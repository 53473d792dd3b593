"""The controller's acceptance cases: the shipped scenarios
``config/acceptance_*.yaml`` and the check of their ``expect`` criteria.

After each judged change the regulated mean speed must be within the given
tolerance of the target in at most the given number of excitation periods (at
the frequency in force after the change), overshooting by at most the given
fraction of the step.  ``bench/controller.py`` prints the figures and draws
them; the tests assert them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from friction_sim.core.control.law import ControllerConfig, MeanSpeedController
from friction_sim.core.model.commands import in_force
from friction_sim.core.model.params import Inputs
from friction_sim.experiment.job import ExperimentResult
from friction_sim.experiment.metrics import StepMetrics, step_metrics
from friction_sim.experiment.scenario import Expectation, Scenario, controller_values, load_scenario


def config_dir() -> Path:
    """The package's config/ folder: in the source tree, or installed by colcon."""
    source = Path(__file__).resolve().parents[2] / "config"
    if source.is_dir():
        return source
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory("friction_sim")) / "config"


def acceptance_scenarios() -> list[Scenario]:
    """The controller acceptance cases, in order (1-5: the paper's model; 6: the general one)."""
    return [load_scenario(path) for path in sorted(config_dir().glob("acceptance_*.yaml"))]


@dataclass(frozen=True)
class Verdict:
    """One expectation judged: the target it was about, the metrics measured, and whether it was met."""

    expectation: Expectation
    target: float
    metrics: StepMetrics
    met: bool


def verdict_line(verdict: Verdict) -> str:
    """One line per expectation for the report: what it asked, PASS or FAIL, and what was
    measured (NOT JUDGED where the run's record lacks what it needs)."""
    e, m = verdict.expectation, verdict.metrics
    asked = (f"expect t = {e.t:g} s: {e.quantity.replace('_', ' ')} within {e.within * 100:g} % in <= {e.periods} "
             f"periods" + (f", overshoot <= {e.overshoot * 100:g} %" if math.isfinite(e.overshoot) else ""))
    if not math.isfinite(verdict.target):
        return (f"{asked}: NOT JUDGED (no {e.quantity.replace('_', ' ')} before the change in this record: "
                f"{'the controller reads it, a recording does not hold it' if e.quantity != 'mean_speed' else 'none'})")
    periods = m.settling_periods
    settled = "never settled" if math.isinf(periods) else f"settled in {periods:g} period{'s' * (periods != 1)}"
    return f"{asked}: {'PASS' if verdict.met else 'FAIL'} ({settled}, overshoot {m.overshoot * 100:.2f} %)"


def judged(verdicts: list[Verdict]) -> list[Verdict]:
    """The verdicts that could be judged (a target to judge against)."""
    return [v for v in verdicts if math.isfinite(v.target)]


def judge(scenario: Scenario, result: ExperimentResult) -> list[Verdict]:
    """Each expectation of ``scenario`` checked against a run."""
    verdicts = []
    starts = sorted({e.t for e in scenario.expect} | {c.t for c in scenario.schedule} | {scenario.duration})
    initial = scenario.initial_target or 0.0
    for expectation in scenario.expect:
        end = next(t for t in starts if t > expectation.t)
        if expectation.quantity == "amplitude_per_drive":
            verdicts.append(_judge_per_drive(scenario, result, expectation, end))
            continue
        target = target_at(scenario, expectation.t, initial)
        before = target_at(scenario, expectation.t - 1e-9, initial)
        if before == target or _unreachable(scenario, before, expectation.t - 1e-9):
            before = _measured_before(result, expectation.t)  # a disturbance, or leaving a saturated target
        metrics = step_metrics(result.mean_velocity, expectation.t, end, before, target,
                               inputs_at(scenario, expectation.t + 1e-9).excitation_frequency, expectation.within)
        met = metrics.settling_periods <= expectation.periods and not metrics.overshoot > expectation.overshoot
        verdicts.append(Verdict(expectation, target, metrics, met))
    return verdicts


def _judge_per_drive(scenario: Scenario, result: ExperimentResult, expectation: Expectation,
                     end: float) -> Verdict:
    """The amplitude per unit drive back within tolerance of its value before the change."""
    series = [(t, per_drive) for t, _, _, per_drive in result.drive if math.isfinite(per_drive)]
    before = [value for t, value in series if t <= expectation.t]
    target = before[-1] if before else math.nan
    frequency = next((f for t, _, f, _ in reversed(result.drive) if t <= expectation.t),
                     inputs_at(scenario, expectation.t).excitation_frequency)
    metrics = step_metrics(series, expectation.t, end, target, target, frequency, expectation.within)
    met = metrics.settling_periods <= expectation.periods and not metrics.overshoot > expectation.overshoot
    return Verdict(expectation, target, metrics, met)


def inputs_at(scenario: Scenario, t: float) -> Inputs:
    """The plant's inputs scheduled to be in force at ``t``."""
    return in_force(scenario.schedule, scenario.params, scenario.inputs, t)[1]


def _unreachable(scenario: Scenario, target: float, t: float) -> bool:
    """Whether the plant cannot reach ``target`` (the controller saturates): the plant's
    own model (not the controller's, which may be wrong) under the controller's ceiling."""
    inputs = inputs_at(scenario, t)
    top = controller_values(scenario.controller or {}, scenario.params, inputs)["max_amplitude_ratio"]
    controller = MeanSpeedController(ControllerConfig(model=scenario.params, max_amplitude_ratio=top),
                                     drive_force=inputs.drive_force, frequency=inputs.excitation_frequency,
                                     target_speed=target)
    return controller.output.unreachable


def target_at(scenario: Scenario, t: float, initial: float) -> float:
    """The target speed scheduled to be in force at ``t``."""
    target = initial
    for command in scenario.schedule:
        if command.t <= t:
            target = float(command.values.get("target_speed", target))
    return target


def _measured_before(result: ExperimentResult, t: float) -> float:
    """The last mean speed measured before ``t`` (the level a disturbance starts from)."""
    earlier = [v for when, v in result.mean_velocity if when <= t]
    return earlier[-1] if earlier else 0.0
