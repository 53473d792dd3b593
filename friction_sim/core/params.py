"""Validated parameters and inputs of the slider model, checked once at the edge.

:class:`SliderParams` holds what describes the plant (mass, friction
coefficient, gravity); :class:`Inputs` holds what an operator or a controller
changes while it runs (drive force, excitation amplitude and frequency, an
optional external force).  Both are frozen dataclasses that refuse a bad value
in ``__post_init__`` with a :class:`~friction_sim.errors.ParameterError` naming
the field, the value and the limit.  The one cross-field rule, that the normal
reaction must stay positive, lives in :func:`check_contact`.

Paper's Fig. 2 case (Kostek): Pa = 5 N, Fd = 0.7 N, f = 50 Hz, mu = 0.1,
g = 10 m/s^2, m = 1 kg.  These are the defaults everywhere.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass
from typing import Any, Iterable

from friction_sim.errors import ParameterError


def require_finite(field: str, value: float) -> float:
    """Return ``value`` as a float, or raise if it is not a finite real number."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(field, value, "must be a finite real number")
    number = float(value)
    if not math.isfinite(number):
        raise ParameterError(field, number, "must be finite")
    return number


def require_positive(field: str, value: float) -> float:
    """Return ``value`` as a float, or raise if it is not finite and > 0."""
    number = require_finite(field, value)
    if number <= 0.0:
        raise ParameterError(field, number, "must be > 0")
    return number


@dataclass(frozen=True)
class SliderParams:
    """The plant: mass [kg], Coulomb friction coefficient [-], gravity [m/s^2]."""

    mass: float = 1.0
    mu: float = 0.1
    gravity: float = 10.0

    def __post_init__(self) -> None:
        for name in ("mass", "mu", "gravity"):
            object.__setattr__(self, name, require_positive(name, getattr(self, name)))

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

    drive_force: float = 0.7
    excitation_amplitude: float = 5.0
    excitation_frequency: float = 50.0
    external_force_x: float = 0.0
    external_force_z: float = 0.0

    def __post_init__(self) -> None:
        for name in ("drive_force", "external_force_x", "external_force_z"):
            object.__setattr__(self, name, require_finite(name, getattr(self, name)))
        amplitude = require_finite("excitation_amplitude", self.excitation_amplitude)
        if amplitude < 0.0:
            raise ParameterError("excitation_amplitude", amplitude, "must be >= 0 N")
        object.__setattr__(self, "excitation_amplitude", amplitude)
        object.__setattr__(
            self,
            "excitation_frequency",
            require_positive("excitation_frequency", self.excitation_frequency),
        )

    @property
    def tangential_force(self) -> float:
        """Ft = Fd + Fx [N]."""
        return self.drive_force + self.external_force_x

    def replace(self, **changes: Any) -> Inputs:
        """A copy with ``changes`` applied, validated like a new instance."""
        return _replace(self, changes)


def _replace(instance: Any, changes: dict[str, Any]) -> Any:
    """dataclasses.replace that names an unknown field instead of a TypeError."""
    known = [f.name for f in dataclasses.fields(instance)]
    for name, value in changes.items():
        if name not in known:
            raise ParameterError(name, value, f"unknown field; known: {', '.join(known)}")
    return dataclasses.replace(instance, **changes)


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
    lift_off = "(the normal reaction would reach zero: the slider would lift off)"
    if weight + fz <= 0.0:
        raise ParameterError("external_force_z", fz, f"must be > -mass*gravity = {-weight!r} N {lift_off}")
    if "external_force_z" in changed and "excitation_amplitude" not in changed:
        raise ParameterError(
            "external_force_z", fz, f"must be > excitation_amplitude - mass*gravity = {pa - weight!r} N {lift_off}"
        )
    for name in ("mass", "gravity"):
        if name in changed and "excitation_amplitude" not in changed:
            other = params.gravity if name == "mass" else params.mass
            unit = "kg" if name == "mass" else "m/s^2"
            raise ParameterError(
                name, getattr(params, name),
                f"must be > (excitation_amplitude - external_force_z)/{'gravity' if name == 'mass' else 'mass'}"
                f" = {(pa - fz) / other!r} {unit} {lift_off}",
            )
    raise ParameterError(
        "excitation_amplitude", pa, f"must be < mass*gravity + external_force_z = {weight + fz!r} N {lift_off}"
    )


def drive_ratio(params: SliderParams, inputs: Inputs) -> float:
    """phi = Fd / (mu*m*g): the drive force over the nominal friction force."""
    return inputs.drive_force / (params.mu * params.weight)


def amplitude_ratio(params: SliderParams, inputs: Inputs) -> float:
    """a = Pa / (m*g): the excitation amplitude over the weight."""
    return inputs.excitation_amplitude / params.weight
