"""The controller's five acceptance cases, as experiments with pass criteria.

Each case is an :class:`~friction_sim.experiment.ExperimentSpec` and the
target steps to judge: after each step the regulated mean speed must be within
``tolerance`` of the target in at most ``max_periods`` excitation periods (at
the frequency in force after the step), overshooting by at most
``max_overshoot`` of the step.  ``bench/controller.py`` prints the figures and
draws them; the tests assert them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from friction_sim.experiment import ExperimentResult, ExperimentSpec, ScheduledCommand, StepMetrics, step_metrics

MM_S = 1e-3


@dataclass(frozen=True)
class Step:
    """A change to judge: at ``t`` the target becomes (or stays) ``target``."""

    t: float
    target: float
    max_periods: int
    tolerance: float
    max_overshoot: float = math.inf


@dataclass(frozen=True)
class AcceptanceCase:
    name: str
    title: str
    spec: ExperimentSpec
    initial_target: float
    steps: tuple[Step, ...]


def _target(t: float, speed_mm_s: float) -> ScheduledCommand:
    return ScheduledCommand(t, "target_speed", speed_mm_s * MM_S)


CASES = (
    AcceptanceCase(
        "matched", "1. matched model, target steps 0.10 -> 0.30 -> 0.15 mm/s",
        ExperimentSpec(duration=1.8, controller=True,
                       controller_parameters={"target_speed": 0.10 * MM_S},
                       schedule=(_target(0.6, 0.30), _target(1.2, 0.15))),
        0.10 * MM_S,
        (Step(0.6, 0.30 * MM_S, 3, 0.01), Step(1.2, 0.15 * MM_S, 3, 0.01)),
    ),
    AcceptanceCase(
        "mu_plus_20", "2. controller model mu 20% above the plant's, same steps",
        ExperimentSpec(duration=3.0, controller=True,
                       controller_parameters={"target_speed": 0.10 * MM_S, "mu": 0.12, "plant_node": ""},
                       schedule=(_target(1.0, 0.30), _target(2.0, 0.15))),
        0.10 * MM_S,
        (Step(1.0, 0.30 * MM_S, 20, 0.02, 0.10), Step(2.0, 0.15 * MM_S, 20, 0.02, 0.10)),
    ),
    AcceptanceCase(
        "drive_step", "3. drive force 0.7 -> 0.8 N while regulating 0.3 mm/s",
        ExperimentSpec(duration=1.4, controller=True, controller_parameters={"target_speed": 0.30 * MM_S},
                       schedule=(ScheduledCommand(0.7, "drive_force", 0.8),)),
        0.30 * MM_S,
        (Step(0.7, 0.30 * MM_S, 5, 0.02),),
    ),
    AcceptanceCase(
        "unreachable", "4. unreachable 5 mm/s for 2 s, then 0.3 mm/s",
        ExperimentSpec(duration=3.2, controller=True, controller_parameters={"target_speed": 0.30 * MM_S},
                       schedule=(_target(0.5, 5.0), _target(2.5, 0.30))),
        0.30 * MM_S,
        (Step(2.5, 0.30 * MM_S, 5, 0.02),),
    ),
    AcceptanceCase(
        "frequency_step", "5. excitation frequency 50 -> 100 Hz while regulating 0.3 mm/s",
        ExperimentSpec(duration=1.4, controller=True, controller_parameters={"target_speed": 0.30 * MM_S},
                       schedule=(ScheduledCommand(0.7, "excitation_frequency", 100.0),)),
        0.30 * MM_S,
        (Step(0.7, 0.30 * MM_S, 5, 0.02),),
    ),
)


def frequency_at(case: AcceptanceCase, t: float) -> float:
    """The excitation frequency in force at ``t`` in a case."""
    frequency = case.spec.inputs.excitation_frequency
    for command in case.spec.schedule:
        if command.topic == "excitation_frequency" and command.t <= t:
            frequency = float(command.value)  # type: ignore[arg-type]
    return frequency


def judge(case: AcceptanceCase, result: ExperimentResult) -> list[tuple[Step, StepMetrics, bool]]:
    """Each step with its metrics and whether it meets its criteria."""
    verdicts = []
    ends = [s.t for s in case.steps[1:]] + [case.spec.duration]
    for step, end in zip(case.steps, ends):
        before = result.target_at(step.t - 1e-9, case.initial_target)
        if before == step.target or before > 1.0:  # no target step (or from an unreachable one)
            before = _measured_before(result, step.t)
        metrics = step_metrics(result.mean_velocity, step.t, end, before, step.target,
                               frequency_at(case, step.t + 1e-9), step.tolerance)
        ok = metrics.settling_periods <= step.max_periods and not metrics.overshoot > step.max_overshoot
        verdicts.append((step, metrics, ok))
    return verdicts


def _measured_before(result: ExperimentResult, t: float) -> float:
    """The last mean speed measured before ``t`` (the level a disturbance starts from)."""
    earlier = [v for when, v in result.mean_velocity if when <= t]
    return earlier[-1] if earlier else 0.0
