"""What the mean-speed law applies: the inverse, the ceiling of a, saturation and the reachable speed (numpy only).

:class:`~friction_sim.core.control.law.MeanSpeedController` keeps the state
(the target, the inputs, the ratio r = U_cmd/U*); :func:`decide` turns it
into the output:

* Kostek's model below lift-off: a = a(r U*, phi), the exact inverse of U,
  clamped to the ceiling; a target beyond U(phi, ceiling) is unreachable
  and saturates there;
* elsewhere: the inverse of the general mean speed on its rising branch
  toward U*'s sign, saturated at the branch's end (or the ceiling, if lower);
  a target beyond it, or where there is no branch, is unreachable;
* the ceiling of a is max_amplitude_ratio, or less where the actuator gives
  less (the resonant exciter at full drive: :func:`ceiling`); every output
  names the fastest mean speed within it (``reachable_speed``);
* anti-windup: a ratio r that asks for more than the ceiling gives is cut back
  to what it gives (the ratio :func:`decide` returns).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from friction_sim.core.control.integral import RATIO_LIMITS, clamp
from friction_sim.core.control.relation import (
    branch,
    branch_end,
    general_inverse,
    inverse,
    runs_away,
    u_top,
    uses_closed_form,
)
from friction_sim.core.model.dimensionless import (
    amplitude_for,
    amplitude_ratio,
    dimensional_speed,
    drive_ratio,
    nondimensional_speed,
)
from friction_sim.core.model.params import SliderParams


@dataclass(frozen=True)
class ControlOutput:
    """What the controller decided and why (all of it goes to diagnostics)."""

    amplitude: float  # Pa [N] to apply
    target_speed: float  # V* [m/s]
    u_target: float  # U* in the model's units
    phi: float  # model phi = Fd/(mu m g)
    feedforward_ratio: float  # a_ff = a(U*, phi) (NaN when unreachable)
    applied_ratio: float  # a actually applied
    integral: float  # I [U]
    saturated: bool  # a clamped at max_amplitude_ratio (general model: at the rising branch's end)
    unreachable: bool  # U* > U(phi, max_amplitude_ratio) (beyond the branch's end), or no drive that way
    runaway: bool  # |phi| > 1 (|Fd - m g sin(alpha)| > mu m g cos(alpha)): it accelerates whatever Pa is
    #: The fastest mean speed [m/s] toward the target within the ceiling of a (NaN: no target, or no branch).
    reachable_speed: float = math.nan


def ceiling(max_ratio: float, actuator_limit: float | None, weight: float) -> float:
    """The largest amplitude ratio a the law applies: ``max_ratio``, or less
    where the actuator gives less than that (``actuator_limit`` [N]; None: no limit)."""
    return max_ratio if actuator_limit is None else min(max_ratio, amplitude_ratio(actuator_limit, weight))


def decide(model: SliderParams, max_ratio: float, actuator_limit: float | None, drive_force: float,
           frequency: float, target: float, ratio: float) -> tuple[ControlOutput, float]:
    """The output for ``target`` [m/s] under the state ``ratio`` (r = U_cmd/U*),
    and the ratio after anti-windup (see the module doc)."""
    decision = _Decision(model, max_ratio, actuator_limit, drive_force, frequency, target, ratio)
    phi = drive_ratio(drive_force, model.mu, model.weight)
    u_target = nondimensional_speed(target, frequency, model.gravity, model.mu)
    law = decision.closed_form if uses_closed_form(model, max_ratio) else decision.general
    return law(phi, u_target), decision.ratio


@dataclass
class _Decision:
    """One decision of the law: its inputs, and the ratio, which anti-windup may cut."""

    model: SliderParams
    top: float
    actuator_limit: float | None
    drive_force: float
    frequency: float
    target: float
    ratio: float

    def _ceiling(self) -> float:
        return ceiling(self.top, self.actuator_limit, self.model.weight)

    def _speed(self, u: float) -> float:
        """The mean speed [m/s] of ``u`` in the model's units (U = V f/(g mu))."""
        return dimensional_speed(u, self.frequency, self.model.gravity, self.model.mu)

    def closed_form(self, phi: float, u_target: float) -> ControlOutput:
        """The law on Kostek's exact U(phi, a)."""
        top = self.top
        runaway = abs(phi) > 1.0  # (runs_away in phi, the ratio the relation inverts: U(1, a) = a/(2*pi))
        if self.target == 0.0 or runaway:
            return self._output(0.0, u_target, phi, 0.0 if self.target == 0.0 else math.nan, False, False, runaway)
        if u_target == 0.0:
            # So slow that U* is zero in floating point (1e-321 m/s at 1 mHz): standing still is closest.
            return self._output(0.0, u_target, phi, 0.0, False, False, False)
        roof = self._ceiling()  # (top itself, unless the actuator gives less: then the same calls as ever)
        u_roof = u_top(phi, roof)
        reach = self._speed(u_roof)
        if abs(u_target) > abs(u_roof):
            return self._output(roof, u_target, phi, math.nan, True, True, False, reach)
        feedforward = inverse(u_target, phi, top)
        u_command = u_target * self.ratio
        if abs(u_command) >= abs(u_roof):
            # Anti-windup: no ratio beyond the ceiling (u_roof / u_target <= r here, so no overflow).
            self.ratio = clamp(abs(u_roof) / abs(u_target), *RATIO_LIMITS)
            return self._output(roof, u_target, phi, feedforward, True, False, False, reach)
        ratio = inverse(u_command, phi, top)
        if not 0.0 <= ratio <= top:  # not expected: the relation is exact and u_command < u_roof
            raise ArithmeticError(f"the inverse U relation gave a = {ratio!r} for U = {u_command!r}, "
                                  f"phi = {phi!r} (expected 0 <= a <= {top!r})")
        # (u_command < U(ceiling): a is below the ceiling but for the inverse's rounding, which may not pass it)
        return self._output(min(ratio, roof), u_target, phi, feedforward, False, False, False, reach)

    def general(self, phi: float, u_target: float) -> ControlOutput:
        """The law on the general mean speed's rising branch toward U*'s sign:
        saturated at its end (the fastest it conveys), unreachable beyond it
        or where the branch does not exist, and kept from below its start."""
        model, top, force = self.model, self.top, self.drive_force
        runaway = runs_away(force, model)
        if self.target == 0.0 or runaway:
            return self._output(0.0, u_target, phi, 0.0 if self.target == 0.0 else math.nan, False, False, runaway)
        if u_target == 0.0:
            return self._output(0.0, u_target, phi, 0.0, False, False, False)
        direction = 1 if u_target > 0.0 else -1
        rising = branch(model, force, top, direction)
        a_end, u_end = branch_end(model, force, top, direction, self._ceiling())
        reach = self._speed(u_end) if not rising.empty else math.nan

        def on_branch(u: float) -> bool:
            return rising.reachable(u) and direction * u <= direction * u_end

        if not on_branch(u_target):
            beyond = not rising.empty and direction * u_target > direction * u_end
            ratio = min(a_end if beyond else rising.a_start, self._ceiling())
            return self._output(ratio, u_target, phi, math.nan, beyond, True, False, reach)
        feedforward = general_inverse(model, force, top, direction, u_target)
        u_command = u_target * self.ratio
        if direction * u_command >= direction * u_end:
            self.ratio = clamp(u_end / u_target, *RATIO_LIMITS)
            return self._output(a_end, u_target, phi, feedforward, True, False, False, reach)
        if not rising.reachable(u_command):  # below the start: the plant already moves that fast at a_start
            if direction * rising.u_start > 0.0:
                self.ratio = clamp(rising.u_start / u_target, *RATIO_LIMITS)
            return self._output(rising.a_start, u_target, phi, feedforward, False, False, False, reach)
        ratio = general_inverse(model, force, top, direction, u_command)
        if not 0.0 <= ratio <= top:  # not expected: u_command is on the branch
            raise ArithmeticError(f"the general inverse gave a = {ratio!r} for U = {u_command!r} "
                                  f"(expected 0 <= a <= {top!r})")
        # (u_command < U(a_end): a is below a_end but for the inverse's rounding, which may not pass it)
        return self._output(min(ratio, a_end), u_target, phi, feedforward, False, False, False, reach)

    def _output(self, ratio: float, u_target: float, phi: float, feedforward: float,
                saturated: bool, unreachable: bool, runaway: bool, reachable_speed: float = math.nan) -> ControlOutput:
        amplitude = amplitude_for(ratio, self.model.weight)
        if self.actuator_limit is not None:  # (ratio <= limit/weight may round to a Pa an ulp above the limit)
            amplitude = min(amplitude, self.actuator_limit)
        return ControlOutput(
            amplitude=amplitude, target_speed=self.target, u_target=u_target,
            phi=phi, feedforward_ratio=feedforward, applied_ratio=ratio,
            integral=u_target * (self.ratio - 1.0),
            saturated=saturated, unreachable=unreachable, runaway=runaway, reachable_speed=reachable_speed,
        )
