"""The resonant exciter: the slideway on its springs, written once.

A vibratory feeder's track is a slideway that springs carry and an
electromagnet or a piezo stack drives at the drive frequency f with a drive
level u in [0, 1].  Along the vibration line (angle beta to the track) it is
a damped linear oscillator; in terms of its displacement q normal to the track

    q'' + 2*zeta*omega_n*q' + omega_n**2*q = 2*zeta*A*u*sin(theta),   d(theta)/dt = omega = 2*pi*f,

where f_n = omega_n/(2*pi) is its natural frequency, zeta its damping ratio
and A the normal acceleration amplitude it reaches in steady state at full
drive at resonance (the three numbers on a feeder's data sheet, or measured
with an accelerometer).  The part of mass m on it feels the inertial force
P(t) = -m*q''(t) normal to the track and P(t)*cot(beta) along it: the
exciter's P replaces the prescribed Pa*sin(theta) of the force actuator.

Between changes of the drive (u, f) or of the slideway (f_n, zeta) the motion
is the exact solution of that linear equation from its state (q, q') at the
change: the steady response

    P_s(theta) = m*u*A*G(r)*sin(theta - lag),   r = f/f_n,
    G(r) = 2*zeta*r**2/sqrt((1 - r**2)**2 + (2*zeta*r)**2),   lag = atan2(2*zeta*r, 1 - r**2),

plus a transient that decays at the damped frequency, Re(c*exp(lambda*tau)),
lambda = -zeta*omega_n + i*omega_n*sqrt(1 - zeta**2).  q and q' are
continuous at every change, and so is the drive phase theta (the slider
keeps it).  At resonance (r = 1) G is 1 and the lag pi/2, exactly.

Plain functions over floats and complex numbers, in the subset that Numba
compiles (see :mod:`friction_sim.core.physics.roots`).
"""

from __future__ import annotations

import math
from typing import NamedTuple, overload

import numpy as np

from friction_sim.core.model.dimensionless import TWO_PI, Real
from friction_sim.core.physics.numerics import hypot

#: A transient whose force is below this fraction of the plant's force scale
#: (2**-60: a 256th of the last bit of a double of that size) changes no event time and
#: no state by more than rounding: from then on it is dropped, exactly zero,
#: and the motion is periodic again.
SETTLED = 2.0**-60


class Response(NamedTuple):
    """The steady response at a drive frequency: ``gain`` G(r) (the normal
    acceleration amplitude per unit drive, over its value at resonance) and
    ``lag`` of the part's force P behind the drive, in [0, pi]."""

    gain: float
    lag: float


def response(frequency: float, natural_frequency: float, damping_ratio: float) -> Response:
    """The analytic resonance curve at ``frequency`` (see the module's docstring).
    1 - r**2 is formed as (1 - r)*(1 + r), exactly 0 at resonance."""
    r = frequency / natural_frequency
    detune = (1.0 - r) * (1.0 + r)
    quadrature = 2.0 * damping_ratio * r
    return Response(quadrature * r / hypot(detune, quadrature), math.atan2(quadrature, detune))


def peak_gain(damping_ratio: float) -> float:
    """The largest gain G over all drive frequencies: the acceleration's resonance
    curve, normalized to 1 at r = 1, peaks at 1/sqrt(1 - zeta^2) for zeta < 1/sqrt(2)
    (at r = 1/sqrt(1 - 2 zeta^2)) and tends to 2 zeta for r -> inf (above 1/sqrt(2))."""
    if damping_ratio < math.sqrt(0.5):
        return 1.0 / math.sqrt(1.0 - damping_ratio * damping_ratio)
    return 2.0 * damping_ratio


@overload
def steady_acceleration(drive_level: float, full_drive_acceleration: float, gain: float) -> float: ...
@overload
def steady_acceleration(drive_level: Real, full_drive_acceleration: Real, gain: Real) -> Real: ...
def steady_acceleration(drive_level: Real, full_drive_acceleration: Real, gain: Real) -> Real:
    """The steady normal acceleration amplitude of the slideway [m/s^2], u*A*G: the
    one rule (floats, or numpy arrays elementwise: a tuning curve's gains)."""
    return drive_level * full_drive_acceleration * gain


def steady_response(drive_level: float, full_drive_acceleration: float, frequency: float, natural_frequency: float,
                    damping_ratio: float) -> tuple[float, float]:
    """(u*A*G(f/f_n), lag): the slideway's steady normal acceleration amplitude
    [m/s^2] and its lag behind the drive, the one rule the plant and the single
    slider's exciter both take."""
    gain, lag = response(frequency, natural_frequency, damping_ratio)
    return steady_acceleration(drive_level, full_drive_acceleration, gain), lag


def eigenvalue(natural_frequency: float, damping_ratio: float) -> complex:
    """lambda = -zeta*omega_n + i*omega_d: the slideway's free motion is Re(D*exp(lambda*t))."""
    omega_n = TWO_PI * natural_frequency
    return complex(-damping_ratio * omega_n, omega_n * math.sqrt((1.0 - damping_ratio) * (1.0 + damping_ratio)))


class Slideway(NamedTuple):
    """The slideway's motion from a change of drive on: at ``tau`` after it, with the
    drive at phase theta, q = (a_s/omega**2)*sin(theta - lag) + Re(d*exp(lambda*tau)).
    ``amplitude`` a_s [m/s^2] and ``lag`` of the steady response; ``omega`` the
    drive's angular frequency; ``lam`` lambda; ``d`` the transient's complex
    amplitude in metres (0: steady)."""

    amplitude: float
    lag: float
    omega: float
    lam: complex
    d: complex


def steady_slideway(amplitude: float, lag: float, omega: float, lam: complex) -> Slideway:
    """The slideway in steady state (no transient)."""
    return Slideway(amplitude, lag, omega, lam, 0j)


def slideway_state(way: Slideway, theta: float, tau: float) -> tuple[float, float, float]:
    """(q, q', q'') of the slideway ``tau`` after its start, the drive at phase ``theta``:
    its normal displacement [m], velocity and acceleration (q'' as the accelerometer
    reads it; the part feels -m*q'')."""
    s, c = math.sin(theta - way.lag), math.cos(theta - way.lag)
    a, w = way.amplitude, way.omega
    q, qd, qdd = a / (w * w) * s, a / w * c, -a * s
    if way.d != 0j:
        e = way.d * _exp(way.lam, tau)
        q, qd, qdd = q + e.real, qd + (way.lam * e).real, qdd + (way.lam * way.lam * e).real
    return q, qd, qdd


def normal_accelerations_into(way: Slideway, frequency: float, t_start: float, times: np.ndarray,
                              out: np.ndarray) -> None:
    """q'' at each of ``times`` of the slideway ``way``, started at ``t_start`` and driven
    at ``frequency``: what a sensor on it reads normal to the track, gravity aside
    (:func:`slideway_state`, one time after the other), into ``out``."""
    for i in range(times.size):
        tau = float(times[i]) - t_start
        out[i] = slideway_state(way, TWO_PI * frequency * tau, tau)[2]


def rebased(way: Slideway, theta: float, tau: float, amplitude: float, lag: float, omega: float,
            lam: complex) -> Slideway:
    """The slideway after a change ``tau`` into ``way`` (drive phase ``theta``
    then): the new steady response (``amplitude``, ``lag``, ``omega``) and the
    new eigenvalue ``lam``, with q and q' continuous, the difference carried by
    the new transient."""
    q, qd, _ = slideway_state(way, theta, tau)
    s, c = math.sin(theta - lag), math.cos(theta - lag)
    yt, vt = q - amplitude / (omega * omega) * s, qd - amplitude / omega * c  # the transient's start
    d = complex(yt, -(vt + (-lam.real) * yt) / lam.imag)  # Re(d) = yt, Re(lam*d) = vt
    return Slideway(amplitude, lag, omega, lam, d)


def followed(way: Slideway, theta: float, tau: float, amplitude: float, lag: float, omega: float,
             lam: complex) -> Slideway:
    """The slideway from a change of parameters or inputs ``tau`` into ``way`` on:
    :func:`rebased` if its steady response or eigenvalue changed; else the same
    motion, its transient carried over exactly (a steady slideway stays steady,
    with no rounding-sized transient from re-deriving it)."""
    if (amplitude, lag, omega, lam) == (way.amplitude, way.lag, way.omega, way.lam):
        return Slideway(amplitude, lag, omega, lam, way.d * _exp(lam, tau) if way.d != 0j else 0j)
    return rebased(way, theta, tau, amplitude, lag, omega, lam)


def force_transient(way: Slideway, mass: float, tau: float) -> complex:
    """c at ``tau`` after the start: the part's transient force is Re(c*exp(lambda*s)) s later
    (c = -m*lambda**2*d*exp(lambda*tau))."""
    if way.d == 0j:
        return 0j
    return -mass * way.lam * way.lam * way.d * _exp(way.lam, tau)


def settle_delay(c: complex, lam: complex, scale: float) -> float:
    """The time after which the transient force Re(c*exp(lambda*s)) stays below
    ``SETTLED`` times ``scale`` (0: already), by the envelope |c|*exp(-sigma*s)."""
    size = abs(c)
    limit = SETTLED * scale
    if size <= limit:
        return 0.0
    return math.log(size / limit) / -lam.real


def _exp(lam: complex, tau: float) -> complex:
    """exp(lambda*tau)."""
    return math.exp(lam.real * tau) * complex(math.cos(lam.imag * tau), math.sin(lam.imag * tau))


def exp_terms(lam: complex, tau: float) -> tuple[complex, complex, complex]:
    """(exp(z), (exp(z) - 1)/lambda, (exp(z) - 1 - z)/lambda**2) at z = lambda*tau, without
    cancellation at small tau: the transient's value and its first and second integrals
    from 0 per unit complex amplitude."""
    z = lam * tau
    decay = math.expm1(lam.real * tau)
    half = math.sin(0.5 * lam.imag * tau)
    cos_m1 = -2.0 * half * half
    e_m1 = complex(decay * math.cos(lam.imag * tau) + cos_m1, math.exp(lam.real * tau) * math.sin(lam.imag * tau))
    if abs(z) < 0.25:
        # (exp(z) - 1 - z)/z**2 by its Taylor series (truncation < 1e-17 relative)
        term, total = 0.5 + 0j, 0j
        for n in range(2, 18):
            total += term
            term = term * z / (n + 1)
        e_m2 = total * tau * tau
    else:
        e_m2 = (e_m1 - z) / (lam * lam)
    return e_m1 + 1.0, e_m1 / lam, e_m2


__all__ = ["SETTLED", "Response", "Slideway", "eigenvalue", "exp_terms", "followed", "force_transient",
           "normal_accelerations_into", "rebased", "response", "settle_delay", "slideway_state", "steady_acceleration",
           "steady_response", "steady_slideway"]
