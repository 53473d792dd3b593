"""``friction-sim reduction``: the friction-reduction curve, the paper's title claim.

The curves are computed in the core (:mod:`friction_sim.core.meanspeed.reduction`),
written as CSV by :func:`friction_sim.io.export.write_reduction_csv` and drawn by
:func:`friction_sim.cli.figures.reduction_figure`; this module holds the
command's options (Lomakin's conditions by default) and prints what the
curves say.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from friction_sim.cli.options import MODEL_OPTIONS, Verb, add_flag
from friction_sim.core.meanspeed.reduction import LOMAKIN, LOMAKIN_FREQUENCY, ReductionCurves, reduction_curves
from friction_sim.core.model import spec
from friction_sim.core.model.params import plant_from
from friction_sim.errors import ParameterError
from friction_sim.io.export import write_reduction_csv

POINTS = spec.Setting("points", 101, "points", "points along each curve", 2, 10_001)
#: Lomakin's conditions replace the paper's Fig. 2 defaults for this command.
DEFAULTS = {"mu": LOMAKIN.mu, "gravity": LOMAKIN.gravity, "excitation_frequency": LOMAKIN_FREQUENCY}


def _numbers(name: str, text: str) -> list[float]:
    """A comma-separated list of finite numbers > 0 (one line naming the option if not)."""
    try:
        values = [float(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise ParameterError(name, text, "must be comma-separated numbers") from None
    if not values or not all(math.isfinite(v) and v > 0.0 for v in values):
        raise ParameterError(name, text, "must be one or more finite numbers > 0")
    return values


def features(curves: ReductionCurves) -> list[str]:
    """What the curves say, as lines of text."""
    lines = [f"mu = {curves.params.mu:g}, g = {curves.params.gravity:g} m/s^2, f = {curves.frequency:g} Hz "
             f"({'closed form' if curves.closed_form else 'general model, bisection on the exact mean speed'})"]
    for ratio, speeds, row in zip(curves.ratios, curves.speeds, curves.by_speed):
        reached = np.isfinite(row)
        top = speeds[reached][-1] if np.any(reached) else 0.0
        lines.append(f"Pa/Q = {ratio:g}: mu_app/mu = {row[0]:.4g} at V -> 0 (breakaway), "
                     f"{row[reached][-1]:.4g} at {top * 1e3:.4g} mm/s" if np.any(reached) else
                     f"Pa/Q = {ratio:g}: no steady stick-slip in the range")
    return lines


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``reduction`` options: the model (Lomakin's mu), g, f, the curves, the outputs."""
    parser.add_argument("--png", type=Path, required=True, help="output picture")
    parser.add_argument("--csv", type=Path, help="the points as CSV (default: beside the PNG, same name)")
    parser.add_argument("--ratios", default="0.2,0.4,0.6,0.8",
                        help="amplitude ratios Pa/Q of the curves against the mean speed (default 0.2,0.4,0.6,0.8)")
    parser.add_argument("--speeds", default="0.0002,0.0005,0.001",
                        help="mean speeds [m/s] of the curves against Pa/Q (default 0.0002,0.0005,0.001)")
    add_flag(parser, POINTS, POINTS.default)
    group = parser.add_argument_group("model (defaults: Lomakin's conditions, the paper's Fig. 4)")
    for setting in (*MODEL_OPTIONS, spec.GRAVITY, spec.EXCITATION_FREQUENCY):
        add_flag(group, setting, DEFAULTS.get(setting.name, setting.default))


def run(args: argparse.Namespace) -> int:
    """``reduction``: compute both views, write the CSV and the PNG, print what they say."""
    from friction_sim.cli.figures import reduction_figure, save_outputs

    params = plant_from({s.name: getattr(args, s.name) for s in (*MODEL_OPTIONS, spec.GRAVITY)},
                        LOMAKIN)[0]
    curves = reduction_curves(params, args.excitation_frequency, ratios=_numbers("ratios", args.ratios),
                              marked_speeds=_numbers("speeds", args.speeds), points=args.points)
    return save_outputs(features(curves), args.png, args.csv, lambda path: write_reduction_csv(curves, path),
                        lambda: reduction_figure(curves))


VERBS = (Verb("reduction", "the friction-reduction curve: the apparent friction mu_app/mu a slider needs to move "
              "at a mean speed, against the speed and against Pa/Q (Lomakin's conditions by default; CSV beside "
              "the PNG)", add_arguments, run),)

__all__ = ["VERBS", "add_arguments", "features", "run"]
