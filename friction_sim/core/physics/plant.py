"""The constants of the motion under one set of parameters and inputs, written once.

Track frame: x along the track (+ = conveying), z normal to it, away from it.
With theta the excitation phase (d(theta)/dt = omega = 2*pi*f):

    contact force needed   R(theta)  = m*g*cos(alpha) - Fz - Pa*sin(theta)
    tangential force       Ft(theta) = Fd + Fx - m*g*sin(alpha) + Pt*sin(theta + psi),  Pt = Pa*cot(beta)

In contact (z = 0): stuck while |Ft| <= mu_s*R; slipping in direction s,
m*x'' = Ft - s*mu*R.  When R would become negative the slider lifts off; in
flight m*x'' = Ft and m*z'' = -R.  Every acceleration is a constant plus a
sinusoid of theta, a :class:`Form` b0 + b1*sin(theta + delta) with b1 >= 0,
and :func:`plant` computes them all once per change of parameters or inputs.
Plain functions over floats (see :mod:`friction_sim.core.physics.roots`):
the single slider and the compiled population engine share them.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any, NamedTuple

from friction_sim.core.model.dimensionless import TWO_PI, throw_number
from friction_sim.core.model.params import Inputs, SliderParams, cos_degrees, sin_degrees
from friction_sim.core.physics.exciter import steady_response
from friction_sim.core.physics.numerics import Floats, hypot, sine

#: A rebound slower than this many units of g*cos(alpha)/omega (gravity would
#: stop it within a millionth of a radian of excitation phase) is a plastic
#: landing: bouncing with restitution then ends after finitely many bounces
#: instead of a Zeno sequence.
REBOUND_FLOOR = 1e-6


class Form(NamedTuple):
    """b0 + b1*sin(theta + delta), b1 >= 0: a constant plus a sinusoid of the phase."""

    b0: float
    b1: float
    delta: float


def form_of(constant: float, sin_part: float, cos_part: float) -> Form:
    """constant + sin_part*sin(theta) + cos_part*cos(theta) as a Form (delta exactly 0
    when there is no cosine part and the sine part is >= 0)."""
    if cos_part == 0.0 and sin_part >= 0.0:
        return Form(constant, sin_part, 0.0)
    return Form(constant, hypot(sin_part, cos_part), math.atan2(cos_part, sin_part))


def form_at(form: Form, theta: Floats) -> Floats:
    """The value of ``form`` at phase ``theta``, a float or an array
    (:func:`~friction_sim.core.physics.numerics.sine`)."""
    return form.b0 + form.b1 * sine(theta + form.delta)


class Plant(NamedTuple):
    """Everything the motion needs of the parameters and inputs in force.

    ``slip_*``: dw/dt (w = s*v) of a slip in direction s, per unit mass, s*Ft - mu*R;
    ``flight_x``, ``flight_z``: the accelerations in flight; ``onset_*``: where a
    stuck slider starts to slip in direction s, s*Ft - mu_s*R > 0; ``lift``: where
    it lifts off, -R > 0; ``tangential``: Ft.  ``kostek``: Kostek's model applies
    (:func:`kostek_applies`: its own fast onsets and outcomes, the paper's case bit
    for bit); ``can_slip``: the slider can ever slip (:func:`can_ever_slip`);
    ``direction``: the direction a slip from rest takes in Kostek's model, sign(Ft);
    ``lag``: the normal excitation is pa*sin(theta - lag) (the resonant
    actuator's steady response lags its drive); ``cot_beta`` and ``mu_s``: what a
    transient of the exciter's force adds to each form (see
    :mod:`friction_sim.core.physics.transient`).
    """

    omega: float
    frequency: float
    mass: float
    mu: float
    restitution: float
    impulsive: bool
    rebound_floor: float
    n0: float  # R(theta) = n0 - pa*sin(theta)
    pa: float
    tangential: Form
    slip_forward: Form
    slip_backward: Form
    flight_x: Form
    flight_z: Form
    onset_forward: Form
    onset_backward: Form
    lift: Form
    kostek: bool
    can_slip: bool
    direction: int
    lag: float  # the normal excitation is pa*sin(theta - lag) (the resonant actuator's lag; else 0)
    cot_beta: float  # the tangential excitation per unit of the normal one
    mu_s: float


def kostek_plant(excitation_angle: Any, track_inclination: Any, static_ratio: Any) -> Any:
    """Kostek's plant: normal excitation, a level track, one friction coefficient
    (the U relation's map holds on it for every amplitude below the load).
    Floats, or numpy arrays elementwise."""
    return (excitation_angle == 90.0) & (track_inclination == 0.0) & (static_ratio == 1.0)  # (& : arrays too)


def is_kostek(params: SliderParams) -> bool:
    """:func:`kostek_plant` for validated parameters (whatever the actuator)."""
    return bool(kostek_plant(params.excitation_angle, params.track_inclination, params.static_ratio))


def kostek_applies(excitation_angle: Any, track_inclination: Any, static_ratio: Any, excitation_amplitude: Any,
                   weight: Any, external_force_z: Any) -> Any:
    """Kostek's model: his plant (:func:`kostek_plant`) and an excitation below the
    load, so the slider never leaves the track.  The one rule for where the
    paper's closed forms (its fast segments, the U relation) hold.  Floats, or
    numpy arrays elementwise."""
    return kostek_plant(excitation_angle, track_inclination, static_ratio) & (
        excitation_amplitude < weight - external_force_z)


def closed_form_applies(params: SliderParams, inputs: Inputs) -> bool:
    """:func:`kostek_applies` for validated parameters and inputs (never with the resonant actuator)."""
    return not params.resonant and bool(kostek_applies(
        params.excitation_angle, params.track_inclination, params.static_ratio, inputs.excitation_amplitude,
        params.weight, inputs.external_force_z))


def slip_margin(excess_force: float, least_load: float, mu: float) -> int:
    """Whether |Ft| = ``excess_force`` > mu*``least_load`` (the load at its least, m*g - Fz - Pa):
    +1 clearly yes, -1 clearly no, 0 too close to tell in floating point (then
    :func:`can_ever_slip` decides in exact arithmetic)."""
    margin = excess_force - mu * least_load
    if abs(margin) > 1e-9 * (excess_force + mu * abs(least_load)):
        return 1 if margin > 0.0 else -1
    return 0


def can_ever_slip(params: SliderParams, inputs: Inputs) -> bool:
    """Whether |Ft| > mu*(m*g - Fz - Pa): the slider can slip at some phase (Kostek's model).

    Decided in exact rational arithmetic on the given binary values where
    :func:`slip_margin` cannot tell, so that a slider on the motion boundary
    phi = 1 - a (up to its last bit) never moves, not even by a rounding-sized
    step.  (Python: the population engine asks :func:`slip_margin` compiled and
    this function for the few it cannot tell.)
    """
    clear = slip_margin(abs(inputs.tangential_force),
                        params.weight - inputs.external_force_z - inputs.excitation_amplitude, params.mu)
    if clear:
        return clear > 0
    excess = abs(Fraction(inputs.drive_force) + Fraction(inputs.external_force_x))
    least_load = (
        Fraction(params.mass) * Fraction(params.gravity)
        - Fraction(inputs.external_force_z) - Fraction(inputs.excitation_amplitude)
    )
    return excess > Fraction(params.mu) * least_load


#: The forms a Kostek plant never uses (its own onsets and outcomes need none of them).
UNUSED = Form(0.0, 0.0, 0.0)


def plant(mass: float, mu: float, gravity: float, static_ratio: float, excitation_angle: float,
          excitation_phase: float, track_inclination: float, restitution: float, impulsive: bool,
          drive_force: float, excitation_amplitude: float, excitation_frequency: float,
          external_force_x: float, external_force_z: float, lag: float, kostek: bool, can_slip: bool) -> Plant:
    """The :class:`Plant` of one set of parameters and inputs (the fields of
    SliderParams and Inputs, ``impulsive`` for landing_friction "impulsive").
    ``kostek``: the slider takes Kostek's own onsets (:func:`kostek_applies`, and
    no flight under way: one goes on in the general model until the next
    change); ``can_slip``: :func:`can_ever_slip` (Kostek's model only);
    ``lag``: the normal excitation is Pa*sin(theta - lag), the tangential one
    Pt*sin(theta + psi - lag) (0 but for the resonant actuator).  A
    Kostek plant, made every time a controller changes Pa, gets only the forms
    it uses."""
    m, pa = mass, excitation_amplitude
    omega = TWO_PI * excitation_frequency
    weight = mass * gravity
    ft = drive_force + external_force_x
    if kostek:  # the general forms below, where beta = 90 and alpha = 0 make them exact
        n0 = weight * 1.0 - external_force_z
        f0 = ft - weight * 0.0
        slip_b1 = (0.0 + mu * pa) / m
        return Plant(omega, excitation_frequency, m, mu, restitution, impulsive,
                     REBOUND_FLOOR * max(n0, 0.0) / m / omega, n0, pa, Form(f0, 0.0, 0.0),
                     Form((f0 - mu * n0) / m, slip_b1, 0.0), Form((-1 * f0 - mu * n0) / m, slip_b1, 0.0),
                     UNUSED, UNUSED, UNUSED, UNUSED, UNUSED, True, can_slip, 1 if ft > 0.0 else -1, 0.0, 0.0, mu)
    mu_s = mu * static_ratio
    n0 = weight * cos_degrees(track_inclination) - external_force_z
    f0 = ft - weight * sin_degrees(track_inclination)
    cot_beta = cos_degrees(excitation_angle) / sin_degrees(excitation_angle)
    pt = pa * cot_beta
    psi = math.radians(excitation_phase) - lag
    ts, tc = (pt, 0.0) if psi == 0.0 else (pt * math.cos(psi), pt * math.sin(psi))
    # pa*sin(theta - lag) = ns*sin(theta) + nc*cos(theta).  With lag 0 (the force actuator) ns is pa and nc
    # -0.0, and every form below is the one it always was, to the sign of a zero (checked on 200,000 plants).
    ns, nc = pa * math.cos(lag), -pa * math.sin(lag)
    return Plant(
        omega, excitation_frequency, m, mu, restitution, impulsive, REBOUND_FLOOR * max(n0, 0.0) / m / omega, n0, pa,
        form_of(f0, ts, tc),
        form_of((f0 - mu * n0) / m, (ts + mu * ns) / m, (tc + mu * nc) / m),
        form_of((-1 * f0 - mu * n0) / m, (-1 * ts + mu * ns) / m, (-1 * tc + mu * nc) / m),
        form_of(f0 / m, ts / m, tc / m),
        form_of(-n0 / m, ns / m, nc / m),
        form_of(f0 - mu_s * n0, ts + mu_s * ns, tc + mu_s * nc),
        form_of(-1 * f0 - mu_s * n0, -1 * ts + mu_s * ns, -1 * tc + mu_s * nc),
        form_of(-n0, ns, nc),
        False, True, 1 if ft > 0.0 else -1, lag, cot_beta, mu_s)


def excitation(mass: float, resonant: bool, amplitude: float, frequency: float, natural_frequency: float,
               damping_ratio: float, full_drive_acceleration: float, drive_level: float) -> tuple[float, float]:
    """(Pa, lag) of the steady normal excitation Pa*sin(theta - lag): the force
    actuator's ``amplitude`` as set, or the resonant actuator's steady response
    m*u*A*G(f/f_n) (:mod:`~friction_sim.core.physics.exciter`)."""
    if not resonant:
        return amplitude, 0.0
    acceleration, lag = steady_response(drive_level, full_drive_acceleration, frequency, natural_frequency,
                                        damping_ratio)
    return mass * acceleration, lag


def steady_excitation(params: SliderParams, inputs: Inputs) -> tuple[float, float]:
    """(Pa, lag) of validated parameters and inputs: the normal excitation in steady
    state, Pa*sin(theta - lag) (:func:`excitation`)."""
    return excitation(params.mass, params.resonant, inputs.excitation_amplitude, inputs.excitation_frequency,
                      params.natural_frequency, params.damping_ratio, params.full_drive_acceleration,
                      inputs.drive_level)


def slideway_amplitude(params: SliderParams, inputs: Inputs) -> tuple[float, float]:
    """(u*A*G(f/f_n) [m/s^2], lag) of the resonant actuator's inputs in force: the
    slideway's steady normal acceleration amplitude and its lag behind the drive
    (:func:`~friction_sim.core.physics.exciter.steady_response`)."""
    return steady_response(inputs.drive_level, params.full_drive_acceleration, inputs.excitation_frequency,
                           params.natural_frequency, params.damping_ratio)


def steady_throw_number(params: SliderParams, inputs: Inputs) -> float:
    """Gamma = Pa/(m*g*cos(alpha)) of the steady excitation (the resonant actuator's
    steady Pa, the force actuator's as set)."""
    return throw_number(steady_excitation(params, inputs)[0], params.normal_weight)


def plant_of(params: SliderParams, inputs: Inputs, in_flight: bool = False) -> Plant:
    """The :class:`Plant` of validated parameters and inputs (``in_flight``: a
    flight is under way, see :func:`plant`), in steady state (the single
    slider adds the exciter's transient)."""
    mass, gravity, angle, inclination, ratio = (params.mass, params.gravity, params.excitation_angle,
                                                params.track_inclination, params.static_ratio)
    amplitude, lag = steady_excitation(params, inputs)
    external_force_z = inputs.external_force_z
    kostek = not in_flight and not params.resonant and kostek_applies(angle, inclination, ratio, amplitude,
                                                                      mass * gravity, external_force_z)
    return plant(mass, params.mu, gravity, ratio, angle, params.excitation_phase, inclination, params.restitution,
                 params.landing_friction == "impulsive", inputs.drive_force, amplitude, inputs.excitation_frequency,
                 inputs.external_force_x, external_force_z, lag, kostek, kostek and can_ever_slip(params, inputs))


def slip_form(p: Plant, direction: int) -> Form:
    """dw/dt of a slip in ``direction`` (+1 forward, -1 backward)."""
    return p.slip_forward if direction > 0 else p.slip_backward


def slip_gain(p: Plant, direction: int) -> float:
    """What a force normal to the track adds to dw/dt (w = s*v) of a slip in ``direction``,
    per unit of that force (its tangential part cot(beta) times it, as the exciter's
    transient force: :mod:`~friction_sim.core.physics.transient`)."""
    return (direction * p.cot_beta + p.mu) / p.mass


def onset_form(p: Plant, direction: int) -> Form:
    """Where a stuck slider starts to slip in ``direction``."""
    return p.onset_forward if direction > 0 else p.onset_backward


def onset_gain(p: Plant, direction: int) -> float:
    """What a force normal to the track adds to the onset form s*Ft - mu_s*R of ``direction``,
    per unit of that force (as the exciter's transient force acts)."""
    return direction * p.cot_beta + p.mu_s


def stays(p: Plant, theta: float, force: float) -> int:
    """At phase theta in contact and at rest, with ``force`` added normal to the track
    (the exciter's transient force; 0.0: none, and adding it changes no sign): 0 if it
    stays stuck, else the direction it slips in."""
    if form_at(p.onset_forward, theta) + onset_gain(p, 1) * force > 0.0:
        return 1
    if form_at(p.onset_backward, theta) + onset_gain(p, -1) * force > 0.0:
        return -1
    return 0
