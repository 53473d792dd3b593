"""``friction-sim calibrate``: fit the model to a feeder's measured operating points.

The fit is :func:`friction_sim.experiment.calibration.calibrate`; the file
formats are :mod:`friction_sim.experiment.measurements`'s; this module holds
the command's options and writes the outputs: the calibrated plant as a ROS 2
parameters file, the residual table as CSV and the check picture as PNG.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

from friction_sim.cli.options import Verb, add_flag
from friction_sim.core.model import spec
from friction_sim.experiment.calibration import (
    LOSSES,
    Calibration,
    CalibrationError,
    FitOptions,
    calibrate,
    quantile,
    summary,
    write_residuals,
)
from friction_sim.experiment.calibration_accel import ReadingsCalibration, fits_exciter
from friction_sim.experiment.calibration_fit import parse_start
from friction_sim.experiment.calibration_run import RunCalibration
from friction_sim.experiment.calibration_sweep import SweepCalibration, calibrate_sweep, is_sweep, read_sweep
from friction_sim.experiment.measurements import read_fixed, read_measurements

F_SCALE = spec.Setting("f_scale", 1.0, "-", "where the robust loss starts, in standard deviations", 1e-6, 1e6)
STARTS = spec.Setting("starts", 4, "-", "starting points in all: the --start ones, the settings given, then the best "
                      "in cost of those drawn where the part moves and does not run away", 1, 1000)
SEED = spec.Setting("seed", 0, "-", "seed of the starting points drawn", 0, 2**31 - 1)
SETTLE = spec.SETTLE_PERIODS.described("whole periods simulated before averaging, per point",
                                       default=FitOptions.settle_periods)
PERIODS = spec.PERIODS.described("whole periods averaged per point", default=FitOptions.periods)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``calibrate`` options."""
    parser.add_argument("measurements", type=Path, help="CSV of operating points (the varied settings, mean_speed "
                                                         "[m/s] and optionally std [m/s]); CSV of a frequency sweep "
                                                         "(excitation_frequency, amplitude [m/s^2], optionally "
                                                         "drive_level, lag_deg, std), which fits the exciter; or a "
                                                         "recording (.mcap) whose trajectory to fit (or, fitting "
                                                         "the exciter's data, whose accelerometer readings)")
    parser.add_argument("--fit", required=True, help="the plant parameters to fit, comma-separated (e.g. "
                                                     "mu,static_ratio)")
    parser.add_argument("--fixed", type=Path, help="the settings that do not vary: a YAML mapping in the sweeps' "
                                                   "vocabulary, or a ROS 2 parameters file")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="a fixed setting (repeatable; overrides --fixed)")
    parser.add_argument("--start", action="append", default=[], metavar="NAME=VALUE[,NAME=VALUE]",
                        help="a starting point of the fit (repeatable; fitted names, the others at their settings), "
                             "tried before the starts drawn where the part moves and does not run away")
    parser.add_argument("--loss", choices=LOSSES, default="linear",
                        help="residual loss: linear (least squares), or soft_l1 / huber against outliers")
    for setting in (F_SCALE, STARTS, SEED, SETTLE, PERIODS):
        add_flag(parser, setting, setting.default)
    parser.add_argument("--output", type=Path, default=Path("out/calibration"),
                        help="folder of calibrated.yaml, residuals.csv, calibration.png and calibration_profile.png "
                             "(default out/calibration)")


def run(args: argparse.Namespace) -> int:
    """``calibrate``: read, fit, print the estimates and write the outputs."""
    fitted = tuple(name.strip() for name in args.fit.split(",") if name.strip())
    options = FitOptions(fit=fitted, loss=args.loss, f_scale=args.f_scale, starts=args.starts, seed=args.seed,
                         settle_periods=args.settle_periods, periods=args.periods)
    options = dataclasses.replace(options, start_points=tuple(parse_start(text, fitted) for text in args.start))
    if args.measurements.suffix == ".mcap":
        return _recording(args, options)
    if is_sweep(args.measurements):
        return _sweep(args, options)
    from friction_sim.cli.figures import calibration_figure, save_figure

    measurements = read_measurements(args.measurements)
    fixed = read_fixed(args.fixed, args.set)
    result = calibrate(measurements, fixed, options)
    for line in summary(result):
        print(line)
    _write_plant(args.output, result.parameters_file())
    print(f"wrote {write_residuals(result, args.output / 'residuals.csv')}")
    print(f"wrote {save_figure(calibration_figure(result), args.output / 'calibration.png')}")
    _write_profiles(args.output, result)
    return 0


def _sweep(args: argparse.Namespace, options: FitOptions) -> int:
    """A frequency sweep: fit the exciter's data to its amplitudes (and lags)."""
    from friction_sim.cli.calibration_figures import sweep_figure

    result = calibrate_sweep(read_sweep(args.measurements), read_fixed(args.fixed, args.set), options)
    return _report(args.output, result, sweep_figure)


def _report(folder: Path, result: Any, draw: Callable[[Any], Any]) -> int:
    """What every fit route prints and writes: the summary, calibrated.yaml, the fit's
    figure (``draw``) as calibration.png and the profiles; the exit code 0."""
    from friction_sim.cli.figures import save_figure

    for line in result.summary():
        print(line)
    _write_plant(folder, result.parameters_file())
    print(f"wrote {save_figure(draw(result), folder / 'calibration.png')}")
    _write_profiles(folder, result)
    return 0


def _write_profiles(folder: Path,
                    result: Calibration | SweepCalibration | ReadingsCalibration | RunCalibration) -> None:
    """calibration_profile.png: each fitted parameter's profile (when computed)."""
    if result.profiles:
        from friction_sim.cli.calibration_figures import profile_figure
        from friction_sim.cli.figures import save_figure

        figure = profile_figure(result.estimates, result.profiles,
                                quantile(result.known_deviations, result.degrees_of_freedom))
        print(f"wrote {save_figure(figure, folder / 'calibration_profile.png')}")


def _recording(args: argparse.Namespace, options: FitOptions) -> int:
    """A recording: fit its trajectory (the commands in force are the file's own)."""
    from friction_sim.cli.figures import run_calibration_figure
    from friction_sim.experiment.calibration_run import calibrate_run
    from friction_sim.experiment.verify import recorded_run
    from friction_sim.io.reader import read_recording

    if args.fixed is not None or args.set:
        raise CalibrationError("--fixed and --set do not apply to a recording: its settings are the file's")
    if fits_exciter(options.fit):
        return _readings(args, options)
    result = calibrate_run(recorded_run(read_recording(args.measurements)), options)
    return _report(args.output, result, run_calibration_figure)


def _readings(args: argparse.Namespace, options: FitOptions) -> int:
    """A recording with the accelerometer on: fit the exciter's data to its readings."""
    from friction_sim.cli.calibration_figures import readings_figure
    from friction_sim.experiment.calibration_accel import accelerometer_readings, calibrate_readings
    from friction_sim.experiment.verify import recorded_run
    from friction_sim.io.reader import read_recording

    recording = read_recording(args.measurements)
    run = recorded_run(recording)
    result = calibrate_readings(run, accelerometer_readings(recording, run.initial), options)
    return _report(args.output, result, readings_figure)


def _write_plant(folder: Path, text: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    plant = folder / "calibrated.yaml"
    plant.write_text(text)
    print(f"wrote {plant} (slider --params, a scenario's or a sweep's plant_params)")


VERBS = (Verb("calibrate", "fit mu, static_ratio, restitution, exciter data... to measured mean speeds (or the "
              "exciter to a frequency sweep), with standard errors, 95 % linearized and profile-likelihood "
              "intervals and a calibrated parameters file", add_arguments, run),)

__all__ = ["VERBS", "add_arguments", "run"]
