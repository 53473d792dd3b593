"""What a node under fuzzing must do with each input: the test's model of it.

The slider's model validates through the core's one gate
(:func:`friction_sim.core.model.commands.apply` and the real-time load rule), the
rule the node promises to apply to every command and parameter set; the
controller's follows the documented rules of its inputs (ranges from the
spec, a target agrees in sign with the drive force).  Type, read-only and
range checks are the parameter descriptors' (rclpy's) and the spec's.

Each model keeps what ``get_parameters`` must answer, what the simulation (or
control law) must have in force, and bounds on how many refusals the node's
diagnostics must have counted.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from friction_sim.core.model import spec
from friction_sim.core.model.commands import PARAMETERS, Command, apply
from friction_sim.core.model.params import Inputs, SliderParams, check_load, plant_from
from friction_sim.errors import ParameterError

from fuzz_strategies import USE_SIM_TIME


@dataclass
class Count:
    """Bounds on a counter: [low, high]."""

    low: int = 0
    high: int = 0

    def add(self, low: int, high: int | None = None) -> None:
        self.low += low
        self.high += low if high is None else high

    def holds(self, value: int) -> bool:
        return self.low <= value <= self.high


@dataclass(frozen=True)
class Verdict:
    """What the node must answer to one parameter set."""

    successful: bool
    #: The refusal came from a rule between fields (each value alone is fine):
    #: the reason must name a parameter of the set.
    cross_field: bool = False


class ParameterModel:
    """The parameters a node declares and what a set of them must do."""

    def __init__(self, settings: Mapping[str, spec.Setting], overrides: Mapping[str, Any] | None = None) -> None:
        self.settings = settings
        self.values: dict[str, Any] = {name: s.default for name, s in settings.items()}
        self.values[USE_SIM_TIME] = False
        self.values.update(overrides or {})
        self.rejected = Count()

    def declared_check(self, items: Sequence[tuple[str, Any]]) -> tuple[bool, dict[str, Any]]:
        """(declared, writable and in range, the values converted) for rclpy's
        checks and the spec's ranges; the second is {} when refused."""
        converted: dict[str, Any] = {}
        refused = False
        for name, value in items:
            if name not in self.values:
                refused = True  # not declared: rclpy refuses it, the node counts it
                continue
            if name == USE_SIM_TIME:
                refused |= not isinstance(value, bool)
                converted[name] = value
                continue
            setting = self.settings[name]
            if setting.start_only:
                refused = True  # read-only: counted the same way
                continue
            if type(value) is not setting.kind:
                refused = True  # wrong type (None: NOT_SET, would undeclare it)
                continue
            try:
                converted[name] = setting.check(value)
            except ParameterError:
                refused = True
        return not refused, converted if not refused else {}

    def set(self, items: Sequence[tuple[str, Any]]) -> Verdict:
        """One set, as one SetParametersAtomically request: what the node must answer."""
        raise NotImplementedError

    def refuse(self) -> Verdict:
        """A set refused by rclpy's checks: counted once, whatever is wrong in it
        (rclpy stops at its first bad value, and the node counts its refusal once)."""
        self.rejected.add(1)
        return Verdict(False)


class SliderModel(ParameterModel):
    """The slider node: parameters, and the plant and inputs in force."""

    def __init__(self, overrides: Mapping[str, Any] | None = None) -> None:
        super().__init__(spec.SLIDER_NODE, overrides)
        self.params = SliderParams()
        self.inputs = Inputs()
        self.rate = float(spec.REAL_TIME_FACTOR.default)  # type: ignore[arg-type]
        self.publish_rate = float(spec.PUBLISH_RATE.default)  # type: ignore[arg-type]
        self.window = int(spec.MEAN_WINDOW_PERIODS.default)  # type: ignore[call-overload]
        #: At least this many commands the node has taken (diagnostics ``commands_accepted``): a
        #: diagnostics that counts fewer was computed before the last of them (then it is not fresh).
        self.taken = 0

    def topic(self, name: str, values: Mapping[str, float]) -> bool:
        """A command message: taken through the core's gate, or refused and counted."""
        try:
            params, inputs = apply(Command(0.0, name, values), self.params, self.inputs)
            check_load(inputs.excitation_frequency, self.rate)
        except ParameterError:
            self.rejected.add(1)
            return False
        self.params, self.inputs = params, inputs
        self.taken += 1
        return True

    def set(self, items: Sequence[tuple[str, Any]]) -> Verdict:
        """One atomic set: checked as one new state against the state in force."""
        ok, values = self.declared_check(items)
        if not ok:
            return self.refuse()
        physics = {k: v if isinstance(v, str) else float(v) for k, v in values.items()
                   if k in spec.PLANT or k in spec.INPUTS}
        try:
            params, inputs = apply(Command(0.0, PARAMETERS, physics), self.params, self.inputs)
            rate = float(values.get("real_time_factor", self.rate))
            check_load(inputs.excitation_frequency, rate)
        except ParameterError:
            self.rejected.add(1)  # one set, one refusal
            return Verdict(False, cross_field=True)
        self.params, self.inputs, self.rate = params, inputs, rate
        self.taken += 1 if physics else 0  # (a set of the plant or the inputs is a command the core takes)
        self.publish_rate = float(values.get("publish_rate", self.publish_rate))
        self.window = int(values.get("mean_window_periods", self.window))
        self.values.update(values)
        return Verdict(True)

    def in_force(self) -> dict[str, float | str]:
        """What the diagnostics must report, by key."""
        return {
            "drive_force": self.inputs.drive_force,
            "excitation_amplitude": self.inputs.excitation_amplitude,
            "excitation_frequency": self.inputs.excitation_frequency,
            "external_force_x": self.inputs.external_force_x,
            "external_force_z": self.inputs.external_force_z,
            "drive_level": self.inputs.drive_level,
            "actuator": self.params.actuator,
            "natural_frequency": self.params.natural_frequency,
            "damping_ratio": self.params.damping_ratio,
            "real_time_factor": self.rate,
            "publish_rate": self.publish_rate,
            "max_catch_up": float(self.values["max_catch_up"]),
            "mass": self.params.mass,
            "mu": self.params.mu,
            "gravity": self.params.gravity,
            "mean_window_periods": self.window,
        }


def _sign(value: float) -> float:
    return math.copysign(1.0, value)


class ControllerModel(ParameterModel):
    """The controller node: parameters, and the law's inputs in force."""

    def __init__(self, overrides: Mapping[str, Any] | None = None) -> None:
        super().__init__(spec.CONTROLLER_NODE, overrides={"plant_node": "", **(overrides or {})})
        self.drive_force = float(spec.DRIVE_FORCE.default)  # type: ignore[arg-type]
        self.frequency = float(spec.EXCITATION_FREQUENCY.default)  # type: ignore[arg-type]
        self.target = float(spec.TARGET_SPEED.default)  # type: ignore[arg-type]
        self.active = True
        self.accepted = 0
        #: Bounds on the refused mean_velocity samples (a count of their own, or part of commands_rejected).
        self.samples = Count()
        #: The largest max_amplitude_ratio m g any configuration in force had: a bound for Pa in flight.
        self.largest_limit = self.amplitude_limit()

    @property
    def weight(self) -> float:
        return float(self.values["mass"]) * float(self.values["gravity"])

    @staticmethod
    def _kostek(values: Mapping[str, Any]) -> bool:
        """Whether the model is the paper's (normal vibration, level track, one mu):
        only there does the slider creep along the drive force alone."""
        return (float(values["excitation_angle"]) == 90.0 and float(values["track_inclination"]) == 0.0
                and float(values["static_ratio"]) == 1.0)

    @property
    def kostek(self) -> bool:
        return self._kostek(self.values)

    def _target_allowed(self, target: float, drive_force: float, kostek: bool | None = None) -> bool:
        """On the paper's model a target must agree in sign with the drive force;
        on any other, the vibration conveys by itself: any sign."""
        if not (self.kostek if kostek is None else kostek):
            return True
        return target == 0.0 or (drive_force != 0.0 and _sign(target) == _sign(drive_force))

    def topic(self, name: str, value: float) -> bool:
        """target_speed, drive_force or excitation_frequency on its topic."""
        setting = {"target_speed": spec.TARGET_SPEED, "drive_force": spec.DRIVE_FORCE,
                   "excitation_frequency": spec.EXCITATION_FREQUENCY}[name]
        try:
            value = float(setting.check(value))
        except ParameterError:
            self.rejected.add(1)
            return False
        if name == "target_speed":
            if not self._target_allowed(value, self.drive_force):
                self.rejected.add(1)
                return False
            self.target = value
            self.active = True
        elif name == "drive_force":
            self.drive_force = value
            if self.kostek and self.target != 0.0 and _sign(self.target) != _sign(value):
                self.target = 0.0  # the old target would point the wrong way
        else:
            self.frequency = value
        self.accepted += 1
        return True

    def sample(self, speed: float) -> None:
        """A mean_velocity sample: one that is not finite must be refused and
        counted (when the controller regulates); a finite one may be refused as
        implausible."""
        if not self.active:
            return
        self.samples.add(0 if math.isfinite(speed) else 1, 1)

    def set(self, items: Sequence[tuple[str, Any]]) -> Verdict:
        ok, values = self.declared_check(items)
        if not ok:
            return self.refuse()
        merged = {**self.values, **values}
        try:  # the model's own cross-field rules (resonant actuator: excitation_phase 0)
            plant_from({name: merged[name] for name in spec.PLANT if name in merged})
        except ParameterError:
            self.rejected.add(1)  # one set, one refusal
            return Verdict(False, cross_field=True)
        drive, target = self.drive_force, self.target
        kostek = self._kostek(merged)
        if kostek and target != 0.0 and (drive == 0.0 or _sign(target) != _sign(drive)):
            target = 0.0  # back on the paper's model: a target against the drive is dropped
        if "drive_force" in values:
            drive = float(values["drive_force"])
            if kostek and target != 0.0 and _sign(target) != _sign(drive):
                target = 0.0
        if "target_speed" in values:
            target = float(values["target_speed"])
            if not self._target_allowed(target, drive, kostek):
                self.rejected.add(1)  # one set, one refusal
                return Verdict(False, cross_field=True)
        self.drive_force, self.target = drive, target
        self.frequency = float(values.get("excitation_frequency", self.frequency))
        if "active" in values or "target_speed" in values:
            self.active = bool(values.get("active", True)) or "target_speed" in values
        self.values.update(values)
        self.largest_limit = max(self.largest_limit, self.amplitude_limit())
        return Verdict(True)

    def in_force(self) -> dict[str, float]:
        return {"drive_force": self.drive_force, "excitation_frequency": self.frequency,
                "target_speed": self.target}

    def amplitude_limit(self) -> float:
        """The largest Pa the law may ask for now: max_amplitude_ratio m g."""
        return float(self.values["max_amplitude_ratio"]) * self.weight


__all__ = ["ControllerModel", "Count", "ParameterModel", "SliderModel", "Verdict"]
