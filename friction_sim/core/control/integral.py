"""The law's integral action: one step of the state r = U_cmd/U* on a clean sample (plain floats, no ROS).

The first clean sample after a change moves U_cmd by integral_gain times the
shortfall e (in units of U); later ones take the secant step e / s, where s
is the measured slope of e against U_cmd from the last two clean samples, so
the loop gain adapts to how far the model's slope is off.  A step never more
than quadruples U_cmd or cuts it below a quarter, and r stays within
:data:`RATIO_LIMITS`; never a step further in the direction of a saturated
output (anti-windup).  See :mod:`friction_sim.core.control.law`.
"""

from __future__ import annotations

import math

#: The state r = U_cmd/U* stays within these bounds: a model may be off by a
#: factor of a million in scale, and r can neither overflow nor reach 0 (from
#: which a multiplicative step would never bring it back).
RATIO_LIMITS = (1e-6, 1e6)

#: The last clean sample the secant learns from: (U_cmd, shortfall), or None.
LastClean = tuple[float, float] | None


def clamp(value: float, low: float, high: float) -> float:
    """``value`` within [low, high]."""
    return min(max(value, low), high)


def integral_step(ratio: float, last_clean: LastClean, u_target: float, error: float, *, saturated: bool,
                  gain: float, secant: bool) -> tuple[float, LastClean]:
    """The state r and the secant's last clean sample after a clean sample
    whose shortfall toward the target is ``error`` (in units of U) while the
    target is ``u_target``; unchanged when nothing may move."""
    if saturated and error > 0.0:
        return ratio, last_clean  # anti-windup: never further in the direction of a saturated output
    command = abs(u_target) * ratio
    if not (0.0 < command < math.inf):
        return ratio, last_clean  # U_cmd underflows: nothing to scale
    step = gain * error
    if secant and last_clean is not None:
        previous_command, previous_error = last_clean
        moved = command - previous_command
        slope = (previous_error - error) / moved if moved != 0.0 else 0.0
        if slope > 0.0:
            step = error / slope
    new_command = min(max(command + step, 0.25 * command), 4.0 * command)
    new_ratio = clamp(ratio * (new_command / command), *RATIO_LIMITS)
    if math.isfinite(new_ratio):
        return new_ratio, (command, error)
    return ratio, last_clean
