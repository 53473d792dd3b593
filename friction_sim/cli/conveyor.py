"""``friction-sim conveyor``: the classical conveying figure of the general model.

The curves are computed in the core (:mod:`friction_sim.core.meanspeed.conveyor`,
where the figure itself is described), written as CSV by
:func:`friction_sim.io.export.write_conveyor_csv` and drawn by
:func:`friction_sim.cli.figures.conveyor_figure`; this module holds the
command's options and prints the figure's features.

With ``--params calibrated.yaml`` (``friction-sim calibrate``'s) the figure
also draws the calibrated plant in both panels, on an axis of its own (its mean
speed [mm/s], on the right): at the estimates, and the 95 % band the
calibration's uncertainty gives it
(:func:`~friction_sim.experiment.calibration_predict.predict`: parameter
sets drawn from the fit's uncertainty, run on the population engine).  Its
conditions are the figure's (Fd = 0; a level track in the first panel, the
panel's Gamma in the second), its own vibration angle and the rest as
calibrated, each changed by ``--set NAME=VALUE`` (the sweeps' vocabulary: a
plant whose angle is 90 degrees conveys only with a drive force).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

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
from friction_sim.experiment.calibration_fit import CalibrationError
from friction_sim.experiment.calibration_predict import BAND, SAMPLES, Prediction, Uncertain, predict, read_calibrated
from friction_sim.experiment.measurements import read_fixed
from friction_sim.io.export import write_conveyor_csv

POINTS = spec.Setting("points", 101, "points", "throw numbers from 0 to 5 per vibration angle", 11, 2001)
SLOPE_POINTS = spec.Setting("slope_points", 41, "points", "inclinations in the second panel", 5, 2001)
SLOPE_GAMMA_SETTING = spec.Setting("slope_gamma", SLOPE_GAMMA, "-", "throw number Gamma held in the "
                                   "inclination panel", 0.0, 10.0, flag="--slope-gamma")
SLOPE_ANGLE_SETTING = spec.EXCITATION_ANGLE.described("vibration angle beta held in the inclination panel",
                                                      name="slope_angle", flag="--slope-angle")
CONVEYOR_MU = spec.MU.described("kinetic Coulomb friction coefficient mu of the figure")
BAND_POINTS = spec.Setting("band_points", 21, "points", "settings along each panel at which --params' band is "
                           "predicted", 3, 401)
BAND_SAMPLES = spec.Setting("band_samples", SAMPLES, "-", "parameter sets drawn for --params' band", 20, 100_000)
#: Whole periods of each point of the band: settled, then averaged (predict's defaults).
BAND_WINDOW = {"settle_periods": 100, "periods": 100}


@dataclass(frozen=True)
class Band:
    """The calibrated plant along panel ``panel``'s axis ``name`` (throw_number
    or track_inclination): the prediction (mean speed [m/s] and its 95 % band)."""

    panel: int
    name: str
    prediction: Prediction

    @property
    def x(self) -> np.ndarray:
        return np.asarray(self.prediction.settings[self.name], dtype=float)


def calibrated_bands(uncertain: Uncertain, sweep: ConveyorSweep, points: int, given: dict[str, Any] | None = None,
                     samples: int = SAMPLES, seed: int = 0, window: dict[str, int] | None = None) -> tuple[Band, ...]:
    """The calibrated plant's band in each panel of ``sweep``'s figure (see the
    module doc; ``given``: the settings of ``--set``); a panel whose axis is a
    fitted parameter or a given setting is left out."""
    if uncertain.plant.get("actuator", spec.ACTUATOR.default) != "force":
        raise CalibrationError("--params: the conveyor figure sweeps the throw number through Pa, the force "
                               "actuator's input; this plant is resonant")
    given = dict(given or {})
    gammas = sweep.gamma_curves[next(iter(sweep.gamma_curves))].x
    panels = ((0, "throw_number", np.linspace(0.0, float(gammas[-1]), points), {"track_inclination": 0.0}),
              (1, "track_inclination", np.linspace(float(sweep.slope.x[0]), float(sweep.slope.x[-1]), points),
               {"throw_number": sweep.slope_gamma}))
    bands = []
    for panel, name, values, held in panels:
        if name in uncertain.names or name in given:
            continue
        conditions = {key: value for key, value in {"drive_force": 0.0, **held}.items()
                      if key not in uncertain.names}
        settings = {name: values, **conditions, **given}
        bands.append(Band(panel, name, predict(uncertain, settings, samples=samples, seed=seed,
                                               **(window or BAND_WINDOW))))
    return tuple(bands)


def draw_bands(figure: Any, bands: Sequence[Band], source: str) -> Any:
    """``friction-sim conveyor --params``: the calibrated plant's mean speed at the
    estimates and its 95 % band over the conveyor figure's panels (``figure.axes``),
    each on a speed axis of its own on the right."""
    panels = list(figure.axes)
    for band in bands:
        axes = panels[band.panel].twinx()
        p = band.prediction
        axes.fill_between(band.x, p.low * 1e3, p.high * 1e3, color="0.35", alpha=0.35,
                          label=f"calibrated plant: {BAND[1] - BAND[0]:g} % band ({p.samples} parameter sets)")
        axes.plot(band.x, p.speed * 1e3, "-", color="black", linewidth=2.0, label="calibrated plant, at the estimates")
        axes.set_ylabel("calibrated plant: mean speed V [mm/s]")
        axes.legend(loc="lower right", fontsize=7)
    if bands:
        figure.suptitle(f"{suptitle_text(figure)}\nwith the plant calibrated in {source}", fontsize=10)
    return figure


def suptitle_text(figure: Any) -> str:
    """The figure's title ('' if none).  ``Figure.get_suptitle`` is Matplotlib 3.8's; Ubuntu
    24.04 (the Jazzy platform) has 3.6, whose figures keep the title's Text as ``_suptitle``."""
    title = getattr(figure, "_suptitle", None)
    return str(title.get_text()) if title is not None else ""


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
    parser.add_argument("--params", type=Path, help="a calibrated plant (friction-sim calibrate's calibrated.yaml): "
                                                    "draw its curve in each panel with the 95 %% band of the "
                                                    "calibration's uncertainty")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="a setting of --params' plant (repeatable; e.g. drive_force=0.9; default Fd = 0)")
    add_flag(parser, BAND_POINTS, BAND_POINTS.default)
    add_flag(parser, BAND_SAMPLES, BAND_SAMPLES.default)


def run(args: argparse.Namespace) -> int:
    """``conveyor``: compute the sweep, write the CSV and the PNG, print the features."""
    from friction_sim.cli.figures import conveyor_figure, save_outputs

    sweep = conveyor_sweep(args.points, args.slope_points, mu=args.mu, slope_gamma=args.slope_gamma,
                           slope_angle=args.slope_angle)
    if args.params is None:
        return save_outputs(features(sweep), args.png, args.csv, lambda path: write_conveyor_csv(sweep, path),
                            lambda: conveyor_figure(sweep))
    uncertain = read_calibrated(args.params)
    bands = calibrated_bands(uncertain, sweep, args.band_points, read_fixed(None, args.set), args.band_samples)
    lines = [*features(sweep), *(f"calibrated plant ({args.params}; {', '.join(uncertain.names)} with their "
                                 f"uncertainty) along {band.name}: V from {band.prediction.speed.min():.4g} to "
                                 f"{band.prediction.speed.max():.4g} m/s, the 95 % band of "
                                 f"{band.prediction.samples} parameter sets" for band in bands)]
    return save_outputs(lines, args.png, args.csv, lambda path: write_conveyor_csv(sweep, path),
                        lambda: draw_bands(conveyor_figure(sweep), bands, str(args.params)))


VERBS = (Verb("conveyor", "the conveying figure: U against the throw number for vibration angles 15-60 degrees, and "
              "against the track inclination (CSV beside the PNG)", add_arguments, run),)

__all__ = ["BAND_POINTS", "BAND_SAMPLES", "VERBS", "Band", "add_arguments", "calibrated_bands", "draw_bands",
           "features", "run"]
