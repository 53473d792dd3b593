"""How well a regulated mean speed answered a step: settling time, overshoot,
steady error.  Pure functions of (t, v) samples, shared by the acceptance
check and the report (no ROS, no numpy needed).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class StepMetrics:
    """How a regulated mean speed answered one step of the target.

    settling_periods: whole excitation periods from the step until the first
        sample after which every sample stays within the tolerance (inf: never).
    overshoot: largest excursion beyond the target, as a fraction of the step;
        for a disturbance at a constant target, the peak deviation as a
        fraction of the target.
    steady_error: relative error of the last sample before the next step.
    """

    t: float
    target: float
    settling_periods: float
    overshoot: float
    steady_error: float


def settling_periods(samples: Sequence[tuple[float, float]], start: float, target: float, frequency: float,
                     tolerance: float) -> float:
    """Whole excitation periods from ``start`` until the first sample after
    which every sample stays within ``tolerance`` (relative) of ``target``
    (for a target of 0: exactly 0); inf when that never happens."""
    settled_at = None
    for t, v in samples:
        inside = abs(v - target) <= tolerance * abs(target) if target else v == 0.0
        if inside and settled_at is None:
            settled_at = t
        elif not inside:
            settled_at = None
    return math.inf if settled_at is None else float(math.ceil((settled_at - start) * frequency - 1e-6))


def step_metrics(samples: Sequence[tuple[float, float]], t_step: float, t_end: float, before: float,
                 target: float, frequency: float, tolerance: float) -> StepMetrics:
    """Metrics of the mean-speed samples in (t_step, t_end] for a step from
    ``before`` to ``target`` (samples stamped with their period's end)."""
    window = [(t, v) for t, v in samples if t_step < t <= t_end]
    if not window:
        return StepMetrics(t_step, target, math.inf, math.nan, math.nan)
    settling = settling_periods(window, t_step, target, frequency, tolerance)
    steady = abs(window[-1][1] - target) / abs(target) if target != 0 else abs(window[-1][1])
    return StepMetrics(t_step, target, settling, _overshoot(window, before, target), steady)


def _overshoot(window: Sequence[tuple[float, float]], before: float, target: float) -> float:
    """Overshoot beyond a step of the target, per step size; for a disturbance
    at a (nearly) constant target, the peak deviation per target."""
    step = target - before
    if abs(step) > 0.05 * abs(target):
        direction = 1.0 if step > 0 else -1.0
        return max(0.0, max(direction * (v - target) for _, v in window)) / abs(step)
    return max(abs(v - target) for _, v in window) / abs(target) if target else math.nan


__all__ = ["StepMetrics", "settling_periods", "step_metrics"]
