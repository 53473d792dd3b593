"""Which mean-speed relation the control law inverts, and its cached answers (numpy only, no ROS).

Kostek's model below lift-off has the exact closed form U(phi, a)
(:mod:`friction_sim.core.meanspeed.urelation`); everywhere else the law
inverts the general mean speed on its rising branch
(:mod:`friction_sim.core.meanspeed.inverse`).  Both the sample's speed limit
(:mod:`friction_sim.core.control.speedlimit`) and the law's output
(:mod:`friction_sim.core.control.reach`) ask the same questions of the same
relation once per sample, mostly on unchanged inputs: the answers are
cached here, once for both.
"""

from __future__ import annotations

from functools import lru_cache

from friction_sim.core.meanspeed.inverse import Branch, rising_branch
from friction_sim.core.meanspeed.urelation import amplitude_ratio_for, u_map
from friction_sim.core.model.dimensionless import amplitude_for, beats_friction
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import kostek_applies


def uses_closed_form(model: SliderParams, max_ratio: float) -> bool:
    """True where the law inverts Kostek's exact map (his model, a < 1: the
    controller of issue 10, unchanged); elsewhere it inverts the general mean
    speed on its rising branch (:mod:`friction_sim.core.meanspeed.inverse`)."""
    return bool(kostek_applies(model.excitation_angle, model.track_inclination, model.static_ratio,
                               amplitude_for(max_ratio, model.weight), model.weight, 0.0))  # the rule at the top


def runs_away(drive_force: float, model: SliderParams) -> bool:
    """True when the drive beats the friction whatever the excitation: |Fd -
    m g sin(alpha)| > mu m g cos(alpha) (Kostek: |phi| > 1).  Coulomb friction
    averages at most mu m g cos(alpha) over time (less when the slider hops),
    and the excitation averages to nothing, so the slider then accelerates.
    The boundary itself does not run away (:func:`~friction_sim.core.model.dimensionless.beats_friction`,
    the one rule, which the general mean speed's branch applies too); the closed
    form's U is inf only beyond |phi| = 1."""
    return beats_friction(drive_force - model.downhill_weight, model.normal_weight, model.mu)


# Once per sample, mostly on unchanged inputs: the last answers of the (exact, iterative) relation.
@lru_cache(maxsize=64)
def u_top(phi: float, top: float) -> float:
    """Kostek's U(phi, top): the fastest the closed form conveys at a = ``top``."""
    return float(u_map(phi, top))


@lru_cache(maxsize=64)
def inverse(u: float, phi: float, top: float) -> float:
    """Kostek's a(U, phi), the exact inverse of U, within a <= ``top``."""
    return float(amplitude_ratio_for(u, phi, top))


@lru_cache(maxsize=16)
def branch(model: SliderParams, drive_force: float, top: float, direction: int) -> Branch:
    """The general mean speed's first rising stretch toward ``direction`` within a <= ``top``."""
    return rising_branch(model, Inputs(drive_force=drive_force), top, direction)


def branch_end(model: SliderParams, drive_force: float, top: float, direction: int,
               ceiling: float) -> tuple[float, float]:
    """(a, U) where the rising branch ends under a ceiling of a: its own end, or
    the ceiling (U there exactly) where the actuator gives less; the ceiling
    with the branch's start U where it lies below the start (nothing on the
    branch is reachable: the most the actuator gives is applied)."""
    rising = branch(model, drive_force, top, direction)
    if rising.empty or ceiling >= rising.a_end:
        return rising.a_end, rising.u_end
    if ceiling <= rising.a_start:
        return ceiling, rising.u_start
    return ceiling, _u_on_branch(model, drive_force, top, direction, ceiling)


@lru_cache(maxsize=64)
def _u_on_branch(model: SliderParams, drive_force: float, top: float, direction: int, ratio: float) -> float:
    return branch(model, drive_force, top, direction).u_at(ratio)


@lru_cache(maxsize=64)
def general_inverse(model: SliderParams, drive_force: float, top: float, direction: int, u: float) -> float:
    """The a on the rising branch where the general mean speed is ``u``."""
    return branch(model, drive_force, top, direction).amplitude_ratio_for(u)
