"""The classical conveying curves of the general model (``friction-sim conveyor``'s figure).

Panel 1: the nondimensional mean speed U = V f/(g mu) against the throw
number Gamma = Pa/(m g cos(alpha)) from 0 to 5, for vibration angles beta of
15, 30, 45 and 60 degrees, on a level track with no drive force (Fd = 0) and
mu = 0.5: the textbook picture of a vibratory conveyor (Gaberson, Winkler,
Sloot & Kruyt).  Gamma = 1 (lift-off begins) and Gamma = 3.30 (just above
sqrt(1 + pi^2) = 3.2969, where a plastic landing's flight lasts one whole
period) are marked.

Panel 2: U against the track inclination alpha at a fixed Gamma and beta
(:data:`SLOPE_GAMMA`, :data:`SLOPE_ANGLE`): uphill the weight's component
along the track works against the conveying, and at some inclination the
part stops climbing and slides back.  That inclination is found by root
bracketing: a sign change of U between two grid points, then bisection on
the mean speed itself (each evaluation an exact simulation), to
:data:`REVERSAL_TOLERANCE` degrees.

Every point is :func:`friction_sim.core.meanspeed.general.mean_speed`: exact to
rounding where the motion repeats (after at most its ``settle_periods``),
else the mean over its ``periods`` after them; those points are drawn hollow.
This module computes them (:func:`conveyor_sweep`), each curve a
:class:`~friction_sim.core.meanspeed.general.MeanSpeedGrid` along its axis;
the CSV is :func:`friction_sim.io.export.write_conveyor_csv`, the picture
:func:`friction_sim.cli.figures.conveyor_figure`, the command
:mod:`friction_sim.cli.conveyor`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from friction_sim.core.meanspeed.general import (
    DEFAULT_PERIODS,
    DEFAULT_SETTLE_PERIODS,
    MeanSpeed,
    MeanSpeedGrid,
    mean_speed,
)
from friction_sim.core.model.dimensionless import amplitude_for_throw
from friction_sim.core.model.params import Inputs, SliderParams

#: The vibration angles of panel 1 [deg].
ANGLES = (15.0, 30.0, 45.0, 60.0)
#: The friction coefficient of the figure (the issue's case).
MU = 0.5
#: Panel 1 runs from Gamma = 0 to this.
GAMMA_MAX = 5.0
#: The marked throw numbers: lift-off begins; one-period flight (sqrt(1 + pi^2) = 3.2969).
MARKED_GAMMAS = ((1.0, r"$\Gamma = 1$ (lift-off)"), (3.30, r"$\Gamma = 3.30$ (one-period flight)"))
#: Panel 2: the fixed throw number and vibration angle, and the inclination range [deg].
SLOPE_GAMMA = 1.5
SLOPE_ANGLE = 30.0
INCLINATION_RANGE = (-20.0, 20.0)
#: The reversal inclination is bracketed to this [deg].
REVERSAL_TOLERANCE = 1e-9
#: Panel 1's peak is refined on a grid this many times finer around the coarse maximum.
PEAK_REFINEMENT = 20

@dataclass(frozen=True)
class Curve:
    """The mean speeds (:class:`MeanSpeedGrid`: U and the kind of motion) along one
    axis ``x``: the throw number, or the track inclination [deg]."""

    x: NDArray[np.float64]
    speeds: MeanSpeedGrid

    @property
    def u(self) -> NDArray[np.float64]:
        """U along the axis."""
        return self.speeds.u

    @property
    def periodic(self) -> NDArray[np.bool_]:
        """Where the motion repeats (the mean exact to rounding)."""
        return self.speeds.periodic


@dataclass(frozen=True)
class Peak:
    """Where U peaks along a Gamma curve: the throw number, U there, and whether the motion there repeats."""

    throw_number: float
    u: float
    periodic: bool


@dataclass(frozen=True)
class ConveyorSweep:
    """Everything the conveyor figure shows.

    ``gamma_curves[angle]``: U against Gamma on a level track (Fd = 0);
    ``peaks[angle]``: where each peaks; ``slope``: U against the inclination at
    ``slope_gamma`` and ``slope_angle``; ``reversal``: the inclination [deg] where
    U changes sign (None if it keeps its sign over the range)."""

    mu: float
    gamma_curves: dict[float, Curve]
    peaks: dict[float, Peak]
    slope: Curve
    slope_gamma: float
    slope_angle: float
    reversal: float | None
    settle_periods: int = DEFAULT_SETTLE_PERIODS
    periods: int = DEFAULT_PERIODS


def plant(angle: float, inclination: float, mu: float) -> SliderParams:
    """The figure's slider: 1 kg, standard g, the given angles and mu (U depends on neither m nor g)."""
    return SliderParams(mass=1.0, gravity=9.81, mu=mu, excitation_angle=angle, track_inclination=inclination)


def point(angle: float, inclination: float, gamma: float, mu: float) -> MeanSpeed:
    """The mean speed at throw number ``gamma`` with Fd = 0 (Pa = Gamma m g cos(alpha))."""
    params = plant(angle, inclination, mu)
    amplitude = amplitude_for_throw(gamma, params.normal_weight)
    return mean_speed(params, Inputs(drive_force=0.0, excitation_amplitude=amplitude))


def curve(xs: NDArray[np.float64], results: Sequence[MeanSpeed]) -> Curve:
    """A :class:`Curve` from mean speeds at ``xs``."""
    return Curve(x=np.asarray(xs, float), speeds=MeanSpeedGrid.of(results))


def gamma_curve(angle: float, points: int, mu: float) -> Curve:
    """U against Gamma in [0, :data:`GAMMA_MAX`] on a level track."""
    gammas = np.linspace(0.0, GAMMA_MAX, points)
    return curve(gammas, [point(angle, 0.0, float(g), mu) for g in gammas])


def peak(angle: float, coarse: Curve, mu: float) -> Peak:
    """The Gamma where U peaks: the coarse maximum, refined on a grid
    :data:`PEAK_REFINEMENT` times finer across its two neighbouring cells."""
    finite = np.where(np.isfinite(coarse.u), coarse.u, -np.inf)
    best = int(np.argmax(finite))
    low, high = coarse.x[max(best - 1, 0)], coarse.x[min(best + 1, coarse.x.size - 1)]
    fine = np.linspace(low, high, 2 * PEAK_REFINEMENT + 1)
    results = [point(angle, 0.0, float(g), mu) for g in fine]
    k = int(np.argmax([r.u if math.isfinite(r.u) else -math.inf for r in results]))
    if results[k].u < coarse.u[best]:
        return Peak(float(coarse.x[best]), float(coarse.u[best]), bool(coarse.periodic[best]))
    return Peak(float(fine[k]), results[k].u, results[k].periodic)


def reversal(slope: Curve, gamma: float, angle: float, mu: float) -> float | None:
    """The inclination where U changes sign, bracketed between the first two grid
    points of opposite sign (or at a grid point where U is exactly 0) and
    bisected on the mean speed to :data:`REVERSAL_TOLERANCE` degrees."""
    u = slope.u
    for k in range(u.size - 1):
        if u[k] == 0.0:
            return float(slope.x[k])
        if u[k] * u[k + 1] < 0.0:
            low, high, u_low = float(slope.x[k]), float(slope.x[k + 1]), float(u[k])
            while high - low > REVERSAL_TOLERANCE:
                middle = 0.5 * (low + high)
                u_middle = point(angle, middle, gamma, mu).u
                if u_middle == 0.0:
                    return middle
                if (u_middle > 0.0) == (u_low > 0.0):
                    low, u_low = middle, u_middle
                else:
                    high = middle
            return 0.5 * (low + high)
    return float(slope.x[-1]) if u[-1] == 0.0 else None


def conveyor_sweep(points: int = 101, slope_points: int = 41, *, mu: float = MU, angles: Sequence[float] = ANGLES,
                   slope_gamma: float = SLOPE_GAMMA, slope_angle: float = SLOPE_ANGLE,
                   inclinations: tuple[float, float] = INCLINATION_RANGE) -> ConveyorSweep:
    """Compute both panels (see the module docstring)."""
    curves = {float(angle): gamma_curve(angle, points, mu) for angle in angles}
    peaks = {angle: peak(angle, c, mu) for angle, c in curves.items()}
    alphas = np.linspace(inclinations[0], inclinations[1], slope_points)
    slope = curve(alphas, [point(slope_angle, float(a), slope_gamma, mu) for a in alphas])
    return ConveyorSweep(mu=mu, gamma_curves=curves, peaks=peaks, slope=slope, slope_gamma=slope_gamma,
                         slope_angle=slope_angle, reversal=reversal(slope, slope_gamma, slope_angle, mu))


__all__ = [
    "ANGLES", "GAMMA_MAX", "INCLINATION_RANGE", "MARKED_GAMMAS", "MU", "PEAK_REFINEMENT", "REVERSAL_TOLERANCE",
    "SLOPE_ANGLE", "SLOPE_GAMMA", "ConveyorSweep", "Curve", "Peak", "conveyor_sweep", "curve", "gamma_curve", "peak",
    "plant", "point", "reversal",
]
