"""``friction-sim resonance``: the resonant feeder's tuning curve.

The curve is computed in the core (:mod:`friction_sim.core.meanspeed.tuning`),
written as CSV by :func:`friction_sim.io.export.write_tuning_csv` and drawn by
:func:`friction_sim.cli.figures.tuning_figure`; this module holds the
command's options and prints what a technician reads off the curve.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from friction_sim.cli.options import Verb, add_flag, add_plant_options, plant
from friction_sim.core.meanspeed.tuning import TuningCurve, tuning_curve
from friction_sim.core.model import spec
from friction_sim.errors import ParameterError
from friction_sim.io.export import write_tuning_csv

POINTS = spec.Setting("points", 121, "points", "drive frequencies of the sweep", 3, 10_001)
LOWEST = spec.Setting("lowest", 0.0, "Hz", "lowest drive frequency (0: 0.8 f_n)", 0.0, spec.MAX_PERIODS_PER_SECOND,
                      flag="--from")
HIGHEST = spec.Setting("highest", 0.0, "Hz", "highest drive frequency (0: 1.2 f_n)", 0.0, spec.MAX_PERIODS_PER_SECOND,
                       flag="--to")


def features(curve: TuningCurve) -> list[str]:
    """What the curve shows, as lines of text."""
    f, fast, loud = curve.frequency, curve.fastest, curve.loudest
    return [
        f"f_n = {curve.params.natural_frequency:g} Hz, zeta = {curve.params.damping_ratio:g} "
        f"(Q = {1 / (2 * curve.params.damping_ratio):.4g}), drive level {curve.inputs.drive_level:g}",
        f"largest amplitude {curve.amplitude[loud]:.6g} m/s^2 at {f[loud]:.6g} Hz "
        f"(lag {curve.lag_deg[loud]:.4g} deg)",
        f"fastest conveying {curve.mean_velocity[fast]:.6g} m/s at {f[fast]:.6g} Hz "
        f"(lag {curve.lag_deg[fast]:.4g} deg, flight fraction {curve.flight_fraction[fast]:.3g})",
    ]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``resonance`` options: the plant (made resonant), the frequency range, the outputs."""
    parser.add_argument("--png", type=Path, required=True, help="output picture")
    parser.add_argument("--csv", type=Path, help="the points as CSV (default: beside the PNG, same name)")
    add_flag(parser, LOWEST, LOWEST.default)
    add_flag(parser, HIGHEST, HIGHEST.default)
    add_flag(parser, POINTS, POINTS.default)
    add_plant_options(parser)


def run(args: argparse.Namespace) -> int:
    """``resonance``: sweep the drive frequency, write the CSV and the PNG, print the features."""
    from friction_sim.cli.figures import save_outputs, tuning_figure

    params, inputs = plant(args)
    lowest = args.lowest or 0.8 * params.natural_frequency
    highest = args.highest or 1.2 * params.natural_frequency
    if not lowest < highest:
        raise ParameterError("from", lowest, f"must be below --to {highest:g} Hz")
    curve = tuning_curve(params, inputs, np.linspace(lowest, highest, args.points))
    return save_outputs(features(curve), args.png, args.csv, lambda path: write_tuning_csv(curve, path),
                        lambda: tuning_figure(curve))


VERBS = (Verb("resonance", "the resonant feeder's tuning curve: slideway amplitude, lag and mean speed against the "
              "drive frequency at a fixed drive level (CSV beside the PNG)", add_arguments, run),)

__all__ = ["VERBS", "add_arguments", "features", "run"]
