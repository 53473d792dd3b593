"""``friction-sim conveyor``: the classical conveying figure of the general model.

The curves are computed in the core (:mod:`friction_sim.core.meanspeed.conveyor`,
where the figure itself is described), written as CSV by
:func:`friction_sim.io.export.write_conveyor_csv` and drawn by
:func:`friction_sim.cli.figures.conveyor_figure`; this module holds the
command's options and prints the figure's features.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from friction_sim.cli.options import Verb, add_flag
from friction_sim.core.meanspeed.conveyor import (
    GAMMA_MAX,
    MU,
    SLOPE_ANGLE,
    SLOPE_GAMMA,
    ConveyorSweep,
    conveyor_sweep,
)
from friction_sim.core.model import spec
from friction_sim.io.export import write_conveyor_csv

POINTS = spec.Setting("points", 101, "points", "throw numbers from 0 to 5 per vibration angle", 11, 2001)
SLOPE_POINTS = spec.Setting("slope_points", 41, "points", "inclinations in the second panel", 5, 2001)
SLOPE_GAMMA_SETTING = spec.Setting("slope_gamma", SLOPE_GAMMA, "-", "throw number Gamma held in the "
                                   "inclination panel", 0.0, 10.0, flag="--slope-gamma")
SLOPE_ANGLE_SETTING = spec.EXCITATION_ANGLE.described("vibration angle beta held in the inclination panel",
                                                      name="slope_angle", flag="--slope-angle")
CONVEYOR_MU = spec.MU.described("kinetic Coulomb friction coefficient mu of the figure")


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
    parser.add_argument("--png", type=Path, required=True, help="output picture")
    parser.add_argument("--csv", type=Path, help="the points as CSV (default: beside the PNG, same name)")
    add_flag(parser, POINTS, POINTS.default)
    add_flag(parser, SLOPE_POINTS, SLOPE_POINTS.default)
    add_flag(parser, CONVEYOR_MU, MU)
    add_flag(parser, SLOPE_GAMMA_SETTING, SLOPE_GAMMA)
    add_flag(parser, SLOPE_ANGLE_SETTING, SLOPE_ANGLE)


def run(args: argparse.Namespace) -> int:
    """``conveyor``: compute the sweep, write the CSV and the PNG, print the features."""
    from friction_sim.cli.figures import conveyor_figure, save_outputs

    sweep = conveyor_sweep(args.points, args.slope_points, mu=args.mu, slope_gamma=args.slope_gamma,
                           slope_angle=args.slope_angle)
    return save_outputs(features(sweep), args.png, args.csv, lambda path: write_conveyor_csv(sweep, path),
                        lambda: conveyor_figure(sweep))


VERBS = (Verb("conveyor", "the conveying figure: U against the throw number for vibration angles 15-60 degrees, and "
              "against the track inclination (CSV beside the PNG)", add_arguments, run),)

__all__ = ["VERBS", "add_arguments", "features", "run"]
