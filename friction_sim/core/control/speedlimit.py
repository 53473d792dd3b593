"""The fastest mean velocity a plant in force can show: the control law's refusal of samples (numpy only, no ROS).

Samples no plant in force could produce are refused (:class:`ParameterError`
naming the value and the limit) by :class:`~friction_sim.core.control.law.MeanSpeedController`:

* a sample must be finite and within the speed limit of the plants in force
  (:func:`speed_limit`).  Coulomb friction only ever brakes the slider, so
  from rest it gains at most |Fd|/m of speed per second of slip; a slip of
  the periodic regime (|phi| < 1) starts from rest and ends within the
  period, so the mean speed of a window is at most |Fd|/(2 m f) (the exact
  relation never exceeds |Fd|/(2 pi m f)), backwards for a negative drive
  as well as forwards.  The limit is :data:`SPEED_LIMIT_FACTOR` |Fd|/(m f)
  (beyond Kostek's model: see :func:`speed_limit`),
  four times that: room for a slip that outlasts a period after a change, a
  plant lighter than the model, an external force the controller does not
  see.  With |phi| >= 1 the slider slides away and any speed comes in time:
  no limit.  After a change of drive force, frequency or mass, the limit of
  the plant before holds as well until :data:`LIMIT_SLACK_SAMPLES` samples
  past the window have come and one is within the new limit (windows that
  began before the change are still on their way: :class:`SampleLimit`);
* only samples within the present plant's own limit are integrated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from friction_sim.core.control.relation import branch, runs_away, uses_closed_form
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import amplitude_for, dimensional_speed
from friction_sim.core.model.params import SliderParams

#: A mean-velocity sample is refused beyond this many times |Fd|/(m f).
SPEED_LIMIT_FACTOR = 2.0
#: Beyond Kostek's model, samples up to this many times the model's fastest mean speed are accepted.
GENERAL_SPEED_MARGIN = 4.0 * math.pi
#: Samples past the mean window after a change of the plant before the limit
#: of the plant before the change is dropped (those still queued on their way).
LIMIT_SLACK_SAMPLES = 12


def speed_limit(drive_force: float, model: SliderParams, frequency: float,
                max_ratio: float = float(spec.MAX_AMPLITUDE_RATIO.default)) -> float:
    """The largest |mean velocity| [m/s] a slider of the model's mass, driven
    by ``drive_force`` at excitation ``frequency``, can show (see the module
    doc and :func:`speed_limit_formula`)."""
    return speed_limit_formula(drive_force, model, frequency, max_ratio)[0]


def speed_limit_formula(drive_force: float, model: SliderParams, frequency: float,
                        max_ratio: float = float(spec.MAX_AMPLITUDE_RATIO.default)) -> tuple[float, str]:
    """The speed limit and the formula that gives it, with its numbers (for
    the refusal's message: the words must be the rule that was applied).

    In Kostek's model below lift-off (:func:`~friction_sim.core.control.relation.uses_closed_form`)
    the limit is :data:`SPEED_LIMIT_FACTOR` |Fd|/(m f); inf when |phi| > 1 (it slides
    away, and reaches any speed in time: :func:`~friction_sim.core.control.relation.runs_away`).
    Beyond it the tangential excitation
    Pt <= ``max_ratio``*m*g*|cot(beta)| and the slope's pull add to the drive:
    the limit is :data:`SPEED_LIMIT_FACTOR` (|Fd - m g sin(alpha)| + Pt)/(m f),
    and at least :data:`GENERAL_SPEED_MARGIN` times the fastest mean speed the
    model shows for a <= ``max_ratio``; inf when |Fd - m g sin(alpha)| >
    mu m g cos(alpha) or when the model runs away somewhere in that range (a
    hopping slider without landing friction can).
    """
    m_f = f"m = {model.mass:g} kg, f = {frequency:g} Hz"
    if uses_closed_form(model, max_ratio):
        force = abs(drive_force)
        if runs_away(drive_force, model):
            return math.inf, f"none: |Fd| = {force:g} N > mu m g = {model.mu * model.weight:g} N (|phi| > 1)"
        limit = SPEED_LIMIT_FACTOR * force / (model.mass * frequency)
        return limit, f"{SPEED_LIMIT_FACTOR:g} |Fd|/(m f) = {limit:.6g} m/s for Fd = {drive_force:g} N, {m_f}"
    if runs_away(drive_force, model):
        return math.inf, "none: |Fd - m g sin(alpha)| > mu m g cos(alpha) (the slider runs away)"
    samples = branch(model, drive_force, max_ratio, 1).u
    if not np.all(np.isfinite(samples)):
        return math.inf, f"none: the model runs away somewhere in a <= {max_ratio:g}"
    fastest = dimensional_speed(float(np.max(np.abs(samples))), frequency, model.gravity, model.mu)
    tangential = amplitude_for(max_ratio, model.weight) * abs(model.tangential_ratio)  # Pt at the top
    pull = abs(drive_force - model.downhill_weight) + tangential
    by_pull = SPEED_LIMIT_FACTOR * pull / (model.mass * frequency)
    by_model = GENERAL_SPEED_MARGIN * fastest
    limit = max(by_pull, by_model)
    margin = f"{GENERAL_SPEED_MARGIN / math.pi:g} pi"
    return limit, (f"max({SPEED_LIMIT_FACTOR:g} (|Fd - m g sin(alpha)| + Pt)/(m f), {margin} x the fastest mean speed "
                   f"of the model {fastest:.6g} m/s) = max({by_pull:.6g}, {by_model:.6g}) = {limit:.6g} m/s for "
                   f"|Fd - m g sin(alpha)| + Pt = {pull:g} N, {m_f}")


@dataclass(frozen=True)
class SampleLimit:
    """The speed limits a mean-velocity sample is judged by: the present
    plant's own (``limit``: only samples within it are integrated) and the
    largest of the plants whose windows may still come (``envelope``: beyond
    it a sample is refused), which shrinks to ``limit`` once ``settling``
    more samples have come and one is within it.  Immutable, so that the
    controller's transaction restores it with the rest of its state."""

    limit: float
    envelope: float
    settling: int = 0  # samples to come before the envelope may shrink to the limit

    @classmethod
    def of(cls, limit: float) -> SampleLimit:
        """The limits with one plant in force, whose limit is ``limit`` [m/s]."""
        return cls(limit, limit)

    def changed(self, limit: float, mean_window_periods: int) -> SampleLimit:
        """The plant changed and its limit is now ``limit``; the old one still
        holds for the windows on their way."""
        if limit == self.limit:
            return self
        return SampleLimit(limit, max(self.envelope, limit), mean_window_periods + LIMIT_SLACK_SAMPLES)

    def beyond(self, speed: float) -> bool:
        """Whether a finite ``speed`` [m/s] is faster than any plant in force could creep."""
        return math.isfinite(speed) and abs(speed) > self.envelope

    def within(self, speed: float) -> bool:
        """Whether ``speed`` [m/s] is within the present plant's own limit (then it may be integrated)."""
        return abs(speed) <= self.limit

    def after(self, speed: float) -> SampleLimit:
        """The limits once an accepted sample of ``speed`` [m/s] has come."""
        if self.settling > 0:
            return replace(self, settling=self.settling - 1)
        if self.within(speed) and self.envelope != self.limit:
            return replace(self, envelope=self.limit)
        return self

    def words(self, now: str) -> str:
        """The refusal's rule, given ``now``, the present plant's formula (:func:`speed_limit_formula`)."""
        if self.envelope > self.limit:
            return (f"|mean_velocity| must be <= {self.envelope:.6g} m/s, the limit of the plant before the last "
                    f"change (now {now}); a faster sample is from no plant in force")
        return f"|mean_velocity| must be <= {now}; a faster sample is from no plant in force"
