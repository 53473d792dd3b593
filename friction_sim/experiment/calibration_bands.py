"""A calibrated plant's 95 % band over a sweep's maps (``friction-sim sweep-report``).

A sweep whose ``plant_params`` is ``friction-sim calibrate``'s calibrated.yaml
runs the calibrated plant at its estimates; the file also keeps the fit's
uncertainty (:mod:`~friction_sim.experiment.calibration_predict`).  The band
of each map cell is the prediction's at the cell's settings (its x and y,
its slice's values, the sweep's fixed settings): parameter sets drawn from
that uncertainty, run on the population engine over the sweep's own periods,
their 2.5 and 97.5 percentiles.  ``random`` keys (parts that differ) take the
calibrated plant's values there: the band is the calibration's uncertainty,
not the parts' spread, which the maps show beside it.

There is no band (None, and the reason) where it would not mean that: the
maps are not of the mean speed; the plant file keeps no uncertainty (a plain
parameters file); or the sweep sets a fitted parameter itself (on an axis, a
slice, or fixed to a value of its own).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from friction_sim.experiment.calibration_fit import CalibrationError, Floats
from friction_sim.experiment.calibration_predict import SAMPLES, Uncertain, predict, read_calibrated
from friction_sim.experiment.sweep import Sweep, parse_sweep
from friction_sim.experiment.sweep_report import SweepMaps
from friction_sim.experiment.sweep_run import META


@dataclass(frozen=True)
class SweepBands:
    """Each slice's band (``low``, ``high`` [m/s], cells as the maps': NaN where no
    point), the calibrated plant's file, its fitted names and the sets drawn."""

    low: tuple[Floats, ...]
    high: tuple[Floats, ...]
    source: Path
    names: tuple[str, ...]
    samples: int

    @property
    def width(self) -> tuple[Floats, ...]:
        """Each slice's band width high - low [m/s]."""
        return tuple(high - low for low, high in zip(self.low, self.high))


def calibrated_sweep(maps: SweepMaps) -> tuple[Sweep, Path | None]:
    """The sweep the maps' results came from, and its ``plant_params`` file (None: none)."""
    text, where = maps.metadata.get(META + "sweep", ""), maps.metadata.get(META + "sweep_file", "<sweep>")
    base = Path(where).parent
    sweep = parse_sweep(text, where, base=base)
    top = yaml.safe_load(text) or {}
    params = top.get("plant_params") if isinstance(top, dict) else None
    if params is None:
        return sweep, None
    path = Path(str(params))
    return sweep, path if path.is_absolute() else base / path


def sweep_bands(maps: SweepMaps, samples: int = SAMPLES, seed: int = 0) -> tuple[SweepBands | None, str]:
    """The band of every cell of every slice (see the module doc), or None and why not."""
    if maps.value != "mean_velocity":
        return None, f"no band: the maps are of {maps.value}, the band is the mean speed's"
    sweep, path = calibrated_sweep(maps)
    if path is None:
        return None, "no band: the sweep's plant is not a calibrated one (no plant_params)"
    try:
        uncertain = read_calibrated(path)
    except CalibrationError:
        return None, f"no band: {path} keeps no calibration's uncertainty"
    set_here = _settings(sweep, uncertain)
    design = (maps.x, maps.y, *(maps.slices[0].key if maps.slices else {}))
    clash = next((name for name in (*design, *set_here) if name in uncertain.names), None)
    if clash:
        return None, f"no band: the sweep sets {clash}, which {path} calibrates"
    x = np.tile(maps.x_values, maps.y_values.size)
    y = np.repeat(maps.y_values, maps.x_values.size)
    lows, highs = [], []
    for piece in maps.slices:
        settings: dict[str, Any] = {**set_here, **piece.key, maps.x: x, maps.y: y}
        prediction = predict(uncertain, settings, samples=samples, seed=seed, settle_periods=sweep.settle_periods,
                             periods=sweep.periods)
        shape = piece.mean.shape
        absent = np.isnan(piece.mean)
        lows.append(np.where(absent, math.nan, prediction.low.reshape(shape)))
        highs.append(np.where(absent, math.nan, prediction.high.reshape(shape)))
    return SweepBands(tuple(lows), tuple(highs), path, uncertain.names, samples), (
        f"the 95 % band of the plant calibrated in {path} ({', '.join(uncertain.names)}): {samples} parameter "
        "sets per cell")


def _settings(sweep: Sweep, uncertain: Uncertain) -> dict[str, Any]:
    """The sweep's fixed settings but those its plant file gave (the calibrated plant's own)."""
    return {name: value for name, value in sweep.fixed.items()
            if not (name in uncertain.plant and uncertain.plant[name] == value)}


__all__ = ["SweepBands", "calibrated_sweep", "sweep_bands"]
