"""``friction-sim predict``: the mean speed of a calibrated plant at given settings, give or take.

The prediction is :func:`friction_sim.experiment.calibration_predict.predict`
(the calibration's uncertainty carried through the model by sampling on the
population engine); this module holds the command's options, prints the
table and writes the CSV and, over a swept setting, the picture of the band.
``friction-sim simulate --params calibrated.yaml`` is the same prediction
(:func:`from_simulate`), at the settings simulate's flags give.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path
from typing import Any

import numpy as np

from friction_sim.cli.options import Verb, add_flag, print_json
from friction_sim.core.model import spec
from friction_sim.experiment.calibration_predict import BAND, SAMPLES, Prediction, predict, read_calibrated
from friction_sim.experiment.measurements import MeasurementsError, read_fixed
from friction_sim.experiment.sweep import KEYS

COUNT = spec.Setting("samples", SAMPLES, "-", "parameter sets drawn from the calibration's uncertainty", 20, 100_000)
SEED = spec.Setting("seed", 0, "-", "seed of the parameter sets drawn", 0, 2**31 - 1)
SETTLE = spec.Setting("settle_periods", 100, "periods", "whole periods simulated before averaging", 0, 100_000)
PERIODS = spec.Setting("periods", 100, "periods", "whole periods averaged per point", 1, 100_000)
#: The most values a swept setting takes.
MAX_SWEEP = 1001


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``predict`` options."""
    parser.add_argument("calibrated", type=Path, help="friction-sim calibrate's calibrated.yaml (the plant and the "
                                                      "fit's uncertainty)")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="a setting of the prediction, in the sweeps' vocabulary (repeatable)")
    parser.add_argument("--sweep", metavar="NAME=FROM:TO:COUNT",
                        help="predict along one setting, COUNT values from FROM to TO (the band drawn with --png)")
    for setting in (COUNT, SEED, SETTLE, PERIODS):
        add_flag(parser, setting, setting.default)
    parser.add_argument("--csv", type=Path, help="write the table as CSV")
    parser.add_argument("--png", type=Path, help="draw the prediction and its band against the swept setting")


def swept(text: str) -> tuple[str, np.ndarray]:
    """``name=from:to:count`` as the setting's name and its values, each checked."""
    name, sep, spec_text = (part.strip() for part in text.partition("="))
    parts = spec_text.split(":")
    if not sep or len(parts) != 3:
        raise MeasurementsError(f"--sweep {text!r}: expected NAME=FROM:TO:COUNT")
    if name not in KEYS:
        raise MeasurementsError(f"--sweep {name}: no such setting")
    try:
        low, high, count = float(parts[0]), float(parts[1]), int(parts[2])
    except ValueError:
        raise MeasurementsError(f"--sweep {text!r}: FROM and TO numbers, COUNT an integer") from None
    if not 2 <= count <= MAX_SWEEP:
        raise MeasurementsError(f"--sweep {text!r}: COUNT = {count} rejected: must be in [2, {MAX_SWEEP}]")
    for value in (low, high):
        read_fixed(None, [f"{name}={value!r}"])  # the setting's own range check, one line if out of it
    return name, np.linspace(low, high, count)


def lines(prediction: Prediction) -> list[str]:
    """The table: the settings that vary, the speed at the estimates and the 95 % band."""
    names = list(prediction.settings)
    head = "  ".join(f"{name:>20}" for name in names)
    rows = [f"{head}  {'mean speed m/s':>16}  {'95 % band m/s':>30}"]
    for i in range(prediction.count):
        cells = "  ".join(f"{_cell(prediction.settings[name][i]):>20}" for name in names)
        rows.append(f"{cells}  {prediction.speed[i]:>16.6g}  [{prediction.low[i]:.6g}, {prediction.high[i]:.6g}]")
    return rows


def _cell(value: Any) -> str:
    return str(value) if isinstance(value, str) else f"{float(value):.8g}"


def write_csv(prediction: Prediction, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow([*prediction.settings, "mean_speed", "band_low", "band_high"])
        for i in range(prediction.count):
            writer.writerow([*(_cell(values[i]) for values in prediction.settings.values()),
                             repr(float(prediction.speed[i])), repr(float(prediction.low[i])),
                             repr(float(prediction.high[i]))])
    return path


def run(args: argparse.Namespace) -> int:
    """``predict``: read the calibrated plant, predict at the settings asked, print and write."""
    uncertain = read_calibrated(args.calibrated)
    settings: dict[str, Any] = dict(read_fixed(None, args.set))
    sweep_name = None
    if args.sweep:
        sweep_name, values = swept(args.sweep)
        if sweep_name in settings:
            raise MeasurementsError(f"--sweep {sweep_name}: also given by --set")
        settings = {sweep_name: values, **settings}
    prediction = predict(uncertain, settings, samples=args.samples, seed=args.seed,
                         settle_periods=args.settle_periods, periods=args.periods)
    print(f"predicted from {args.calibrated}: {', '.join(uncertain.names)} with their uncertainty, "
          f"{prediction.samples} parameter sets on the population engine")
    for line in lines(prediction):
        print(line)
    if args.csv:
        print(f"wrote {write_csv(prediction, args.csv)}")
    if args.png:
        if sweep_name is None:
            raise MeasurementsError("--png draws the band along a swept setting: give --sweep NAME=FROM:TO:COUNT")
        from friction_sim.cli.calibration_figures import band_figure
        from friction_sim.cli.figures import save_figure

        print(f"wrote {save_figure(band_figure(prediction, sweep_name), args.png)}")
    return 0


def from_simulate(args: argparse.Namespace) -> int:
    """``simulate --params calibrated.yaml``: :func:`run`'s prediction at the
    settings simulate's flags give.  The plant is the file's; a flag at a value
    other than its default sets that setting (a fitted parameter is refused: it
    is calibrated, with its uncertainty), a flag at its default leaves the
    file's value (the inputs default to the paper's, as simulate's do).  The
    mean is over the prediction's whole periods (100 after 100), not simulate's
    --duration and --settle (which the caller refuses, with --csv)."""
    from friction_sim.cli.options import PLANT_OPTIONS, flag_of

    uncertain = read_calibrated(args.params)
    settings = {s.name: getattr(args, s.name) for s in PLANT_OPTIONS if getattr(args, s.name) != s.default}
    clash = next((name for name in settings if name in uncertain.names), None)
    if clash:
        raise MeasurementsError(f"{flag_of(args, clash) or clash}: {clash} is calibrated in {args.params} (with its "
                                "uncertainty): it is not set when predicting")
    prediction = predict(uncertain, settings, samples=int(COUNT.default), seed=int(SEED.default),
                         settle_periods=int(SETTLE.default), periods=int(PERIODS.default))
    if args.json:
        print_json({"calibrated": str(args.params), "fitted": list(uncertain.names),
                    "settings": {name: _plain(values[0]) for name, values in prediction.settings.items()},
                    "mean_velocity": float(prediction.speed[0]), "band_low": float(prediction.low[0]),
                    "band_high": float(prediction.high[0]), "band_percent": BAND[1] - BAND[0],
                    "samples": prediction.samples})
        return 0
    print(f"predicted from {args.params}: {', '.join(uncertain.names)} with their uncertainty, "
          f"{prediction.samples} parameter sets on the population engine (friction-sim predict)")
    for line in lines(prediction) if settings else _one(prediction):
        print(line)
    return 0


def _one(prediction: Prediction) -> list[str]:
    """The table of a prediction at the file's settings (no column varies)."""
    return [f"{'mean speed m/s':>16}  {'95 % band m/s':>30}",
            f"{prediction.speed[0]:>16.6g}  [{prediction.low[0]:.6g}, {prediction.high[0]:.6g}]"]


def _plain(value: Any) -> Any:
    return value if isinstance(value, str) else float(value)


VERBS = (Verb("predict", "the mean speed of a calibrated plant at given settings with its 95 % band, the "
              "calibration's uncertainty carried through the model", add_arguments, run),)

__all__ = ["VERBS", "add_arguments", "from_simulate", "lines", "run", "swept", "write_csv"]
