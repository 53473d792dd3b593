"""Validated parameters and inputs of the slider model: the single gate.

:class:`SliderParams` holds what describes the plant (mass, friction
coefficient, gravity); :class:`Inputs` holds what an operator or a controller
changes while it runs (drive force, excitation amplitude and frequency, an
optional external force).  Both are frozen dataclasses that refuse a bad value
in ``__post_init__`` with a :class:`~friction_sim.errors.ParameterError` naming
the field, the value and the limit; the ranges come from
:mod:`friction_sim.core.model.spec`.  The cross-field rules live here too:
:func:`check_load` (what the real-time loop can follow).  There is no
physical refusal beyond the ranges: an amplitude above the weight makes the
slider hop, which the core follows exactly.  Every path into the
simulation (topics, parameters, scenarios, the CLI, replay) goes through them.
Their dimensionless groups (phi, a, Gamma, U) and the runaway rule are
:mod:`friction_sim.core.model.dimensionless`'s.

Paper's Fig. 2 case (Kostek): Pa = 5 N, Fd = 0.7 N, f = 50 Hz, mu = 0.1,
g = 10 m/s^2, m = 1 kg.  These are the defaults everywhere.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

from friction_sim.core.model import spec
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
    """The plant: the slider and its track.

    mass [kg], kinetic Coulomb friction coefficient mu [-], gravity [m/s^2];
    static_ratio mu_s/mu >= 1; excitation_angle beta [deg] of the vibration
    line to the track (90: purely normal, Kostek's model); excitation_phase
    psi [deg] of the tangential component; track_inclination alpha [deg]
    (> 0: conveying uphill); restitution e of a landing; landing_friction,
    the tangential impulse at a landing ("impulsive" or "none"); actuator,
    what vibrates the slideway ("force": Pa as set; "resonant": the exciter
    of :mod:`friction_sim.core.physics.exciter`, with natural_frequency f_n
    [Hz], damping_ratio zeta and full_drive_acceleration A [m/s^2]).
    """

    mass: float = float(spec.MASS.default)
    mu: float = float(spec.MU.default)
    gravity: float = float(spec.GRAVITY.default)
    static_ratio: float = float(spec.STATIC_RATIO.default)
    excitation_angle: float = float(spec.EXCITATION_ANGLE.default)
    excitation_phase: float = float(spec.EXCITATION_PHASE.default)
    track_inclination: float = float(spec.TRACK_INCLINATION.default)
    restitution: float = float(spec.RESTITUTION.default)
    landing_friction: str = str(spec.LANDING_FRICTION.default)
    actuator: str = str(spec.ACTUATOR.default)
    natural_frequency: float = float(spec.NATURAL_FREQUENCY.default)
    damping_ratio: float = float(spec.DAMPING_RATIO.default)
    full_drive_acceleration: float = float(spec.FULL_DRIVE_ACCELERATION.default)

    def __post_init__(self) -> None:
        _check_fields(self, spec.PLANT)
        _check_across(self)

    @property
    def resonant(self) -> bool:
        """The resonant actuator drives the slideway (else the force actuator: Pa as set)."""
        return self.actuator == "resonant"

    @property
    def weight(self) -> float:
        """Q = m*g [N], the weight."""
        return self.mass * self.gravity

    @property
    def normal_weight(self) -> float:
        """m*g*cos(alpha) [N]: the weight's component pressing on the track."""
        return self.weight * cos_degrees(self.track_inclination)

    @property
    def downhill_weight(self) -> float:
        """m*g*sin(alpha) [N]: the weight's component along -x (uphill track: > 0)."""
        return self.weight * sin_degrees(self.track_inclination)

    @property
    def tangential_ratio(self) -> float:
        """cot(beta): the tangential excitation amplitude over the normal one (0 at 90 degrees)."""
        return cos_degrees(self.excitation_angle) / sin_degrees(self.excitation_angle)

    def replace(self, **changes: Any) -> SliderParams:
        """A copy with ``changes`` applied, validated like a new instance."""
        return _replace(self, changes)


def sin_degrees(angle: float) -> float:
    """sin of an angle in degrees, exact (0, +-1) at multiples of 90 degrees."""
    if angle % 90.0 == 0.0:
        return float((0, 1, 0, -1)[int(angle // 90.0) % 4])
    return math.sin(math.radians(angle))


def cos_degrees(angle: float) -> float:
    """cos of an angle in degrees, exact (0, +-1) at multiples of 90 degrees."""
    return sin_degrees(angle + 90.0) if angle % 90.0 == 0.0 else math.cos(math.radians(angle))


@dataclass(frozen=True)
class Inputs:
    """What may change while the slider runs; held constant between changes.

    drive_force: Fd [N] along +x (negative drives backwards).
    excitation_amplitude: Pa [N] of the normal force -Pa*sin(theta), >= 0.
    excitation_frequency: f [Hz] > 0; the phase stays continuous when it changes.
    external_force_x: extra tangential force [N], added to Fd.
    external_force_z: extra force [N] along +z, away from the track; > 0 lifts
        (it unloads the contact, and can lift the slider off).
    drive_level: u in [0, 1] of the resonant actuator (the force actuator ignores it).
    """

    drive_force: float = float(spec.DRIVE_FORCE.default)
    excitation_amplitude: float = float(spec.EXCITATION_AMPLITUDE.default)
    excitation_frequency: float = float(spec.EXCITATION_FREQUENCY.default)
    external_force_x: float = float(spec.EXTERNAL_FORCE_X.default)
    external_force_z: float = float(spec.EXTERNAL_FORCE_Z.default)
    drive_level: float = float(spec.DRIVE_LEVEL.default)

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
    """A copy of a validated instance with ``changes`` applied, each checked against
    its setting (an unknown field is named): the fields it keeps were checked when
    it was made, so only the changed ones are, which makes a change of one input
    a third of the cost of a whole new instance (a controller makes one per period)."""
    settings: dict[str, spec.Setting] = _SETTINGS[type(instance)]
    copy = object.__new__(type(instance))
    vars(copy).update(vars(instance))
    for name, value in changes.items():
        setting = settings.get(name)
        if setting is None:
            raise ParameterError(name, value, f"unknown field; known: {', '.join(settings)}")
        object.__setattr__(copy, name, setting.check(value))
    _check_across(copy)
    return copy


def _check_across(instance: Any) -> None:
    """The cross-field rules of a validated type, in one place: a reason names the field to change."""
    if isinstance(instance, SliderParams) and instance.resonant and instance.excitation_phase != 0.0:
        raise ParameterError("excitation_phase", instance.excitation_phase,
                             "must be 0 with actuator resonant (its slideway moves along one line)")


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


def plant_from(values: Mapping[str, Any], params: SliderParams | None = None,
               inputs: Inputs | None = None) -> tuple[SliderParams, Inputs]:
    """The parameters and inputs a mapping of field names gives: the fields of
    SliderParams and of Inputs that ``values`` holds (other keys are the
    caller's), each checked as a new instance checks it (a ParameterError names
    the first bad one), the others as in ``params`` and ``inputs`` (default: the
    paper's case).  The one way a file, a recording, a scenario, a node's
    parameters or a command line becomes a plant."""
    base_params = params if params is not None else SliderParams()
    base_inputs = inputs if inputs is not None else Inputs()
    return (base_params.replace(**{name: value for name, value in values.items() if name in spec.PLANT}),
            base_inputs.replace(**{name: value for name, value in values.items() if name in spec.INPUTS}))


def field_values(params: SliderParams, inputs: Inputs) -> dict[str, Any]:
    """Every field of the plant and the inputs by name: the inverse of :func:`plant_from`
    (what the population engine takes, with any field turned into a column)."""
    return {**{name: getattr(params, name) for name in spec.PLANT},
            **{name: getattr(inputs, name) for name in spec.INPUTS}}


#: The settings behind each validated type, by type.
_SETTINGS: dict[type, dict[str, spec.Setting]] = {SliderParams: spec.PLANT, Inputs: spec.INPUTS}


__all__ = [
    "Inputs", "SliderParams", "check_load", "cos_degrees", "field_values", "plant_from", "require_finite",
    "require_positive", "sin_degrees",
]
