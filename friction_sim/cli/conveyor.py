"""``friction-sim conveyor``: the classical conveying figure of the general model.

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

Every point is :func:`friction_sim.core.meanspeed.mean_speed`: exact to
rounding where the motion repeats (after at most its ``settle_periods``),
else the mean over its ``periods`` after them; those points are drawn hollow.
This module computes (:func:`conveyor_sweep`), writes the CSV
(:func:`write_conveyor_csv`) and runs the command; the picture is
:func:`friction_sim.cli.figures.conveyor_figure`.
"""

from __future__ import annotations

import argparse
import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from friction_sim.core import spec
from friction_sim.core.meanspeed import DEFAULT_PERIODS, DEFAULT_SETTLE_PERIODS, MeanSpeed, mean_speed
from friction_sim.core.params import Inputs, SliderParams

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

POINTS = spec.Setting("points", 101, "points", "throw numbers from 0 to 5 per vibration angle", 11, 2001)
SLOPE_POINTS = spec.Setting("slope_points", 41, "points", "inclinations in the second panel", 5, 2001)
SLOPE_GAMMA_SETTING = spec.Setting("slope_gamma", SLOPE_GAMMA, "-", "throw number Gamma held in the "
                                   "inclination panel", 0.0, 10.0, flag="--slope-gamma")
SLOPE_ANGLE_SETTING = spec.EXCITATION_ANGLE.described("vibration angle beta held in the inclination panel",
                                                      name="slope_angle", flag="--slope-angle")
CONVEYOR_MU = spec.MU.described("kinetic Coulomb friction coefficient mu of the figure")


@dataclass(frozen=True)
class Curve:
    """U along one axis (throw number or inclination) with the kind of motion at each point."""

    x: NDArray[np.float64]
    u: NDArray[np.float64]
    periodic: NDArray[np.bool_]
    period_multiple: NDArray[np.int64]
    flight_fraction: NDArray[np.float64]
    stick_fraction: NDArray[np.float64]


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
    return mean_speed(params, Inputs(drive_force=0.0, excitation_amplitude=gamma * params.normal_weight))


def curve(xs: NDArray[np.float64], results: Sequence[MeanSpeed]) -> Curve:
    """A :class:`Curve` from mean speeds at ``xs``."""
    return Curve(x=np.asarray(xs, float), u=np.array([r.u for r in results]),
                 periodic=np.array([r.periodic for r in results], dtype=bool),
                 period_multiple=np.array([r.period_multiple for r in results], dtype=np.int64),
                 flight_fraction=np.array([r.flight_fraction for r in results]),
                 stick_fraction=np.array([r.stick_fraction for r in results]))


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


#: The CSV's columns: one row per point of either panel.
CSV_COLUMNS = ("panel", "excitation_angle", "throw_number", "track_inclination", "U", "periodic",
               "period_multiple", "flight_fraction", "stick_fraction")


def write_conveyor_csv(sweep: ConveyorSweep, path: Path) -> Path:
    """One CSV for both panels: ``panel`` is ``gamma`` (U against Gamma, level
    track) or ``inclination`` (U against alpha at the fixed Gamma and beta);
    angles in degrees; ``periodic`` 1/0 (0: the mean over a window)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(CSV_COLUMNS)
        for angle, c in sweep.gamma_curves.items():
            for k in range(c.x.size):
                writer.writerow(_row("gamma", angle, float(c.x[k]), 0.0, c, k))
        for k in range(sweep.slope.x.size):
            writer.writerow(_row("inclination", sweep.slope_angle, sweep.slope_gamma, float(sweep.slope.x[k]),
                                 sweep.slope, k))
    return path


def _row(panel: str, angle: float, gamma: float, inclination: float, c: Curve, k: int) -> list[object]:
    return [panel, repr(angle), repr(gamma), repr(inclination), repr(float(c.u[k])), int(c.periodic[k]),
            int(c.period_multiple[k]), repr(float(c.flight_fraction[k])), repr(float(c.stick_fraction[k]))]


def features(sweep: ConveyorSweep) -> list[str]:
    """The figure's main features as lines of text: each angle's peak, and the reversal."""
    lines = [f"mu = {sweep.mu:g}, Fd = 0, level track; U = V f/(g mu); Gamma = Pa/(m g cos(alpha))"]
    for angle, p in sweep.peaks.items():
        kind = "" if p.periodic else " (not periodic: mean over a window)"
        if p.throw_number >= GAMMA_MAX:
            kind += " (the end of the range: still rising)"
        lines.append(f"beta = {angle:g} deg: U peaks at Gamma = {p.throw_number:.4f} (U = {p.u:.6f}){kind}")
    where = f"Gamma = {sweep.slope_gamma:g}, beta = {sweep.slope_angle:g} deg"
    low, high = float(sweep.slope.x[0]), float(sweep.slope.x[-1])
    if sweep.reversal is None:
        lines.append(f"{where}: the conveying direction does not reverse for alpha in [{low:g}, {high:g}] deg")
    else:
        lines.append(f"{where}: conveying reverses at track inclination alpha = {sweep.reversal:.6f} deg "
                     f"(uphill; U > 0 below it)" if sweep.reversal > 0.0 else
                     f"{where}: conveying reverses at track inclination alpha = {sweep.reversal:.6f} deg")
    return lines


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``conveyor`` options."""
    from friction_sim.cli.commands import add_flag

    parser.add_argument("--png", type=Path, required=True, help="output picture")
    parser.add_argument("--csv", type=Path, help="the points as CSV (default: beside the PNG, same name)")
    add_flag(parser, POINTS, POINTS.default)
    add_flag(parser, SLOPE_POINTS, SLOPE_POINTS.default)
    add_flag(parser, CONVEYOR_MU, MU)
    add_flag(parser, SLOPE_GAMMA_SETTING, SLOPE_GAMMA)
    add_flag(parser, SLOPE_ANGLE_SETTING, SLOPE_ANGLE)


def run(args: argparse.Namespace) -> int:
    """``conveyor``: compute the sweep, write the CSV and the PNG, print the features."""
    from friction_sim.cli.figures import conveyor_figure, save_figure

    sweep = conveyor_sweep(args.points, args.slope_points, mu=args.mu, slope_gamma=args.slope_gamma,
                           slope_angle=args.slope_angle)
    for line in features(sweep):
        print(line)
    table = args.csv if args.csv is not None else args.png.with_suffix(".csv")
    print(f"wrote {write_conveyor_csv(sweep, table)}")
    print(f"wrote {save_figure(conveyor_figure(sweep), args.png)}")
    return 0


__all__ = [
    "ANGLES", "CSV_COLUMNS", "ConveyorSweep", "Curve", "GAMMA_MAX", "INCLINATION_RANGE", "MARKED_GAMMAS", "MU",
    "Peak", "SLOPE_ANGLE", "SLOPE_GAMMA", "add_arguments", "conveyor_sweep", "features", "reversal", "run",
    "write_conveyor_csv",
]
