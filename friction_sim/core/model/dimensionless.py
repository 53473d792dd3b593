"""The model's dimensionless groups and 2*pi, written once.

Kostek's groups and the conveyor's: the drive ratio phi = Fd/(mu*m*g), the
amplitude ratio a = Pa/(m*g), the throw number Gamma = Pa/(m*g*cos(alpha)),
the nondimensional mean speed U = V*f/(g*mu), each with its inverse, and the
runaway rule |pull| > mu*load.  Every other module calls these (a test reads
the source for inline copies: test/test_vocabulary.py), so a group means the
same everywhere, and a change of one is a change of all.

The functions take the forces and coefficients themselves, not a
:class:`~friction_sim.core.model.params.SliderParams`: a weight may be m*g, or
the load m*g - Fz under an external force, or a column of a population.  They
are plain arithmetic, elementwise on floats and numpy arrays alike, and each
keeps the operations and their order of the expression it replaced (a float in,
the same bits out): phi*mu*m*g, not phi*(mu*m*g), which rounds otherwise.
"""

from __future__ import annotations

import math
from typing import Any, overload

#: 2*pi, the one spelling of it: omega = TWO_PI*f, a period is TWO_PI of phase.
TWO_PI = 2.0 * math.pi

#: A float, or a numpy array of floats (elementwise): what every function here takes and
#: gives (typed float for floats, by the first overload of each).
Real = Any


@overload
def drive_ratio(force: float, mu: float, weight: float) -> float: ...
@overload
def drive_ratio(force: Real, mu: Real, weight: Real) -> Real: ...
def drive_ratio(force: Real, mu: Real, weight: Real) -> Real:
    """phi = F/(mu*W): a tangential force over the nominal friction force, mu times
    the weight W = m*g (or a load, m*g - Fz).  Of the drive force: Kostek's phi."""
    return force / (mu * weight)


@overload
def drive_force_for(phi: float, mu: float, weight: float) -> float: ...
@overload
def drive_force_for(phi: Real, mu: Real, weight: Real) -> Real: ...
def drive_force_for(phi: Real, mu: Real, weight: Real) -> Real:
    """F = phi*mu*W [N]: the force of drive ratio ``phi`` (the inverse of :func:`drive_ratio`)."""
    return phi * mu * weight


@overload
def amplitude_ratio(force: float, weight: float) -> float: ...
@overload
def amplitude_ratio(force: Real, weight: Real) -> Real: ...
def amplitude_ratio(force: Real, weight: Real) -> Real:
    """a = Pa/W: a force in units of the weight W = m*g (or of a load, m*g - Fz).
    Of the excitation amplitude: Kostek's amplitude ratio a."""
    return force / weight


@overload
def amplitude_for(ratio: float, weight: float) -> float: ...
@overload
def amplitude_for(ratio: Real, weight: Real) -> Real: ...
def amplitude_for(ratio: Real, weight: Real) -> Real:
    """Pa = a*W [N]: the force of amplitude ratio ``ratio`` (the inverse of :func:`amplitude_ratio`)."""
    return ratio * weight


@overload
def throw_number(amplitude: float, normal_weight: float) -> float: ...
@overload
def throw_number(amplitude: Real, normal_weight: Real) -> Real: ...
def throw_number(amplitude: Real, normal_weight: Real) -> Real:
    """Gamma = Pa/(m*g*cos(alpha)): the excitation amplitude over the weight's normal
    component (``normal_weight``); above 1 the slider leaves the track once a
    period (without an external force), at sin(theta) = 1/Gamma."""
    return amplitude_ratio(amplitude, normal_weight)


@overload
def amplitude_for_throw(gamma: float, normal_weight: float) -> float: ...
@overload
def amplitude_for_throw(gamma: Real, normal_weight: Real) -> Real: ...
def amplitude_for_throw(gamma: Real, normal_weight: Real) -> Real:
    """Pa = Gamma*m*g*cos(alpha) [N]: the amplitude of throw number ``gamma`` (the
    inverse of :func:`throw_number`, ``normal_weight`` m*g*cos(alpha))."""
    return amplitude_for(gamma, normal_weight)


@overload
def nondimensional_speed(v: float, frequency: float, gravity: float, mu: float) -> float: ...
@overload
def nondimensional_speed(v: Real, frequency: Real, gravity: Real, mu: Real) -> Real: ...
def nondimensional_speed(v: Real, frequency: Real, gravity: Real, mu: Real) -> Real:
    """U = V*f/(g*mu) from a mean speed V [m/s] at excitation frequency f [Hz]."""
    return v * frequency / (gravity * mu)


@overload
def dimensional_speed(u: float, frequency: float, gravity: float, mu: float) -> float: ...
@overload
def dimensional_speed(u: Real, frequency: Real, gravity: Real, mu: Real) -> Real: ...
def dimensional_speed(u: Real, frequency: Real, gravity: Real, mu: Real) -> Real:
    """V = U*g*mu/f [m/s] from a nondimensional mean speed U (the inverse of
    :func:`nondimensional_speed`)."""
    return u * gravity * mu / frequency


@overload
def beats_friction(pull: float, load: float, mu: float) -> bool: ...
@overload
def beats_friction(pull: Real, load: Real, mu: Real) -> Real: ...
def beats_friction(pull: Real, load: Real, mu: Real) -> Real:
    """Whether a slider runs away: the tangential pull (the drive with the slope's
    and any external force) beats the most friction the track gives on average,
    mu times the mean normal load, |pull| > mu*load (any units: N, or forces
    over m*g).  The excitation averages to nothing, so the slider accelerates.
    At equality it does not: its speed oscillates about a bounded mean and
    touches zero once a period (Kostek's U = a/(2*pi) at |phi| = 1).  The one
    runaway rule of the package (a bool, or an array of them)."""
    return abs(pull) > mu * load


__all__ = [
    "TWO_PI", "Real", "amplitude_for", "amplitude_for_throw", "amplitude_ratio", "beats_friction",
    "dimensional_speed", "drive_force_for", "drive_ratio", "nondimensional_speed", "throw_number",
]
