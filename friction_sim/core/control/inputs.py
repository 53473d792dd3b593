"""What the control law is told, checked before it is taken (plain floats, no ROS).

Two kinds of input reach :class:`~friction_sim.core.control.law.MeanSpeedController`:

* the operator's: the target mean speed, the drive force and the excitation
  frequency (:class:`LawInputs`), each within its range
  (:mod:`friction_sim.core.model.spec`) and, on Kostek's model, tied by one
  rule: the slider creeps only along the drive force, so a target must have
  its sign, and a target left pointing the wrong way becomes 0;
* the plant's: a measured mean velocity (:func:`admit_sample`), which must be
  a finite number that some plant in force could produce
  (:mod:`friction_sim.core.control.speedlimit`).

Kept apart from the law's state so that the law (:mod:`friction_sim.core.control.law`)
holds only what it decides with; every value here is immutable, so the law's
transaction restores it with the rest of its state.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, replace
from typing import Any

from friction_sim.core.control.speedlimit import SampleLimit, speed_limit_formula
from friction_sim.core.model import spec
from friction_sim.core.model.params import SliderParams
from friction_sim.core.physics.plant import is_kostek
from friction_sim.errors import ParameterError

#: The inputs the law follows, by name.
INPUTS = {setting.name: setting for setting in (spec.TARGET_SPEED, spec.DRIVE_FORCE, spec.EXCITATION_FREQUENCY)}


def opposes(target: float, force: float) -> bool:
    """Whether a nonzero ``target`` [m/s] cannot be crept to under ``force`` [N]
    on Kostek's model: no drive force, or one of the other sign."""
    return target != 0.0 and (force == 0.0 or math.copysign(1.0, target) != math.copysign(1.0, force))


@dataclass(frozen=True)
class LawInputs:
    """The operator's inputs in force: the target mean speed [m/s], the drive
    force [N] and the excitation frequency [Hz], each checked."""

    target_speed: float
    drive_force: float
    frequency: float

    @classmethod
    def of(cls, drive_force: float, frequency: float) -> LawInputs:
        """The inputs with ``drive_force`` and ``frequency`` (checked) and no target yet."""
        return cls(0.0, float(spec.DRIVE_FORCE.check(drive_force)),
                   float(spec.EXCITATION_FREQUENCY.check(frequency)))

    def changed(self, name: str, value: Any, model: SliderParams) -> LawInputs:
        """The inputs after one change (``target_speed``, ``drive_force`` or
        ``excitation_frequency``), judged against these under ``model``; a
        :class:`ParameterError` (naming field, value and limit) refuses it."""
        if name not in INPUTS:
            raise ParameterError(name, value, f"unknown input; known: {', '.join(INPUTS)}")
        number = float(INPUTS[name].check(value))
        kostek = is_kostek(model)  # elsewhere the vibration conveys too: any direction may be reachable
        if name == "target_speed":
            force = self.drive_force
            if kostek and opposes(number, force):
                raise ParameterError(
                    "target_speed", number,
                    f"must have the sign of drive_force = {force!r} N (the slider only creeps that way)")
            return replace(self, target_speed=number)
        if name == "drive_force":
            target = self.target_speed
            if kostek and target != 0.0 and math.copysign(1.0, target) != math.copysign(1.0, number):
                target = 0.0  # the old target now points the wrong way
            return replace(self, drive_force=number, target_speed=target)
        return replace(self, frequency=number)

    def for_model(self, model: SliderParams) -> LawInputs:
        """The inputs under a new ``model``: on Kostek's model a target the
        drive force does not creep to (taken under a model whose vibration
        conveys by itself) becomes 0."""
        if is_kostek(model) and opposes(self.target_speed, self.drive_force):
            return replace(self, target_speed=0.0)
        return self


def admit_sample(speed: Any, limits: SampleLimit, inputs: LawInputs, model: SliderParams,
                 max_amplitude_ratio: float) -> tuple[float, SampleLimit]:
    """A measured mean velocity ``speed`` as a float, and the limits once it
    has come (the envelope shrinks once the samples show the plant before the
    last change is gone); or a :class:`ParameterError`: not a finite number,
    or beyond the limit of the plants in force (``limits``; the refusal names
    the present plant's formula)."""
    if isinstance(speed, bool) or not isinstance(speed, numbers.Real):
        raise ParameterError("mean_velocity", speed, "must be a finite number [m/s]")
    speed = float(speed)
    if not math.isfinite(speed):
        raise ParameterError("mean_velocity", speed, "must be finite [m/s]")
    if limits.beyond(speed):
        now = speed_limit_formula(inputs.drive_force, model, inputs.frequency, max_amplitude_ratio)[1]
        raise ParameterError("mean_velocity", speed, limits.words(now))
    return speed, limits.after(speed)
