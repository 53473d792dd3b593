"""Validated parameters and inputs of the slider model: the single gate.

:class:`SliderParams` holds what describes the plant (mass, friction
coefficient, gravity); :class:`Inputs` holds what an operator or a controller
changes while it runs (drive force, excitation amplitude and frequency, an
optional external force).  Both are frozen dataclasses that refuse a bad value
in ``__post_init__`` with a :class:`~friction_sim.errors.ParameterError` naming
the field, the value and the limit; the ranges come from
:mod:`friction_sim.core.spec`.  The cross-field rules live here too:
:func:`check_contact` (the normal reaction must stay positive) and
:func:`check_load` (what the real-time loop can follow).  Every path into the
simulation (topics, parameters, scenarios, the CLI, replay) goes through them.

Paper's Fig. 2 case (Kostek): Pa = 5 N, Fd = 0.7 N, f = 50 Hz, mu = 0.1,
g = 10 m/s^2, m = 1 kg.  These are the defaults everywhere.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any, TypeVar

from friction_sim.core import spec
from friction_sim.errors import ParameterError

_T = TypeVar("_T")


def require_finite(field: str, value: Any) -> float:
    """Return ``value`` as a float, or raise if it is not a finite real number.
    (For values that are arguments of a call, not settings: durations, times.)"""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(field, value, "must be a finite real number")
    number = float(value)
    if not math.isfinite(number):
        raise ParameterError(field, number, "must be finite")
    return number


def require_positive(field: str, value: Any) -> float:
    """Return ``value`` as a float, or raise if it is not finite and > 0."""
    number = require_finite(field, value)
    if number <= 0.0:
        raise ParameterError(field, number, "must be > 0")
    return number


def _check_fields(instance: Any, settings: dict[str, spec.Setting]) -> None:
    """Validate every field of a frozen dataclass against its setting."""
    for name, setting in settings.items():
        object.__setattr__(instance, name, setting.check(getattr(instance, name)))


@dataclass(frozen=True)
class SliderParams:
    """The plant: mass [kg], Coulomb friction coefficient [-], gravity [m/s^2]."""

    mass: float = float(spec.MASS.default)
    mu: float = float(spec.MU.default)
    gravity: float = float(spec.GRAVITY.default)

    def __post_init__(self) -> None:
        _check_fields(self, spec.PLANT)

    @property
    def weight(self) -> float:
        """Q = m*g [N], the normal reaction without excitation."""
        return self.mass * self.gravity

    def replace(self, **changes: Any) -> SliderParams:
        """A copy with ``changes`` applied, validated like a new instance."""
        return _replace(self, changes)


@dataclass(frozen=True)
class Inputs:
    """What may change while the slider runs; held constant between changes.

    drive_force: Fd [N] along +x (negative drives backwards).
    excitation_amplitude: Pa [N] of the normal force -Pa*sin(theta), >= 0.
    excitation_frequency: f [Hz] > 0; the phase stays continuous when it changes.
    external_force_x: extra tangential force [N], added to Fd.
    external_force_z: extra normal force [N]; > 0 loads the contact.
    """

    drive_force: float = float(spec.DRIVE_FORCE.default)
    excitation_amplitude: float = float(spec.EXCITATION_AMPLITUDE.default)
    excitation_frequency: float = float(spec.EXCITATION_FREQUENCY.default)
    external_force_x: float = float(spec.EXTERNAL_FORCE_X.default)
    external_force_z: float = float(spec.EXTERNAL_FORCE_Z.default)

    def __post_init__(self) -> None:
        _check_fields(self, spec.INPUTS)

    @property
    def tangential_force(self) -> float:
        """Ft = Fd + Fx [N]."""
        return self.drive_force + self.external_force_x

    def replace(self, **changes: Any) -> Inputs:
        """A copy with ``changes`` applied, validated like a new instance."""
        return _replace(self, changes)


def _replace(instance: _T, changes: dict[str, Any]) -> _T:
    """dataclasses.replace that names an unknown field instead of a TypeError."""
    known = [f.name for f in dataclasses.fields(instance)]  # type: ignore[arg-type]
    for name, value in changes.items():
        if name not in known:
            raise ParameterError(name, value, f"unknown field; known: {', '.join(known)}")
    return dataclasses.replace(instance, **changes)  # type: ignore[type-var]


_LIFT_OFF = "(the normal reaction would reach zero: the slider would lift off)"


def check_contact(params: SliderParams, inputs: Inputs, changed: Iterable[str] = ()) -> None:
    """Refuse a combination whose normal reaction could reach zero.

    R(t) = m*g + Fz - Pa*sin(theta) must stay > 0 for every phase, i.e.
    Pa < m*g + Fz; otherwise the slider would lift off, which this model does
    not cover.  ``changed`` names the fields just changed, so that the error
    blames the one the user touched (an external force or the mass, say)
    rather than the excitation amplitude that was already in force.
    """
    weight, fz, pa = params.weight, inputs.external_force_z, inputs.excitation_amplitude
    if pa < weight + fz:
        return
    changed = set(changed)
    if weight + fz <= 0.0:
        raise ParameterError("external_force_z", fz, f"must be > -mass*gravity = {-weight!r} N {_LIFT_OFF}")
    if "external_force_z" in changed and "excitation_amplitude" not in changed:
        raise ParameterError(
            "external_force_z", fz, f"must be > excitation_amplitude - mass*gravity = {pa - weight!r} N {_LIFT_OFF}"
        )
    for name in ("mass", "gravity"):
        if name in changed and "excitation_amplitude" not in changed:
            other_name, unit = ("gravity", "kg") if name == "mass" else ("mass", "m/s^2")
            other = getattr(params, other_name)
            raise ParameterError(
                name, getattr(params, name),
                f"must be > (excitation_amplitude - external_force_z)/{other_name} = {(pa - fz) / other!r} {unit} "
                f"{_LIFT_OFF}",
            )
    raise ParameterError(
        "excitation_amplitude", pa, f"must be < mass*gravity + external_force_z = {weight + fz!r} N {_LIFT_OFF}"
    )


def check_load(frequency: float, rate: float, field: str = "excitation_frequency") -> None:
    """Refuse an excitation frequency and real-time factor the real-time loop
    cannot keep up with; ``field`` is the one to blame (the one just set)."""
    limit = spec.MAX_PERIODS_PER_SECOND
    if frequency * rate <= limit:
        return
    why = f"(at most {limit:g} excitation periods per wall-clock second in real time)"
    if field == "real_time_factor":
        raise ParameterError(field, rate, f"must be <= {limit / frequency:g} at excitation_frequency "
                                          f"{frequency:g} Hz {why}")
    raise ParameterError(field, frequency, f"must be <= {limit / rate:g} Hz at real_time_factor {rate:g} {why}")


def drive_ratio(params: SliderParams, inputs: Inputs) -> float:
    """phi = Fd / (mu*m*g): the drive force over the nominal friction force."""
    return inputs.drive_force / (params.mu * params.weight)


def amplitude_ratio(params: SliderParams, inputs: Inputs) -> float:
    """a = Pa / (m*g): the excitation amplitude over the weight."""
    return inputs.excitation_amplitude / params.weight


__all__ = [
    "Inputs", "SliderParams", "amplitude_ratio", "check_contact", "check_load", "drive_ratio",
    "require_finite", "require_positive",
]
