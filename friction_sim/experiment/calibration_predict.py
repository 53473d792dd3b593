"""Predictions with their uncertainty (``friction-sim predict calibrated.yaml``).

A calibration leaves the plant's estimates and how uncertain they are; a
designer asks "at these settings, how fast, give or take?".  The answer is
the mean speed of the calibrated plant at the settings asked, with a 95 %
band carried through the model by sampling:

* **What the file keeps.**  ``calibrated.yaml`` holds, beside the plant (the
  ``/**`` section the slider reads), a ``calibration`` section (parameters of
  no node, which ROS 2 and the slider leave alone): the fitted names, their
  estimates, each one's spread below and above (its profile interval's
  half-widths over the quantile q: one standard error each side where the
  profile is the linearized parabola), their correlation (chords across the
  profile intervals) and q.
* **The samples.**  Parameter vectors drawn from a Gaussian copula with that
  correlation, each parameter's normal score scaled by its spread on its
  side of the estimate (so an interval that the data leave lopsided, or open
  at a bound, is sampled so), clipped to the bounds; seeded.
* **The band.**  Every sample at every setting asked is one slider of one
  population-engine run; the band is the 2.5 and 97.5 percentiles of the
  sampled speeds at each setting, beside the speed at the estimates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from friction_sim.core.engine.population import run_batch
from friction_sim.core.model import spec
from friction_sim.experiment.calibration_fit import CalibrationError, Estimate, Floats, bounds_of
from friction_sim.experiment.sweep import DERIVED, FIELDS, derive_fields
from friction_sim.io.paramfile import node_parameters, read_yaml_mapping

#: The section of calibrated.yaml that keeps the uncertainty (no node of that name reads it).
SECTION = "calibration"
#: Samples drawn for a band, and the band's percentiles.
SAMPLES = 400
BAND = (2.5, 97.5)


@dataclass(frozen=True)
class Uncertain:
    """A calibrated plant with the uncertainty of its fitted parameters: the
    plant's settings, the fitted ``names``, their ``estimate``, their spread
    below and above (``below``, ``above``: standard deviations of the normal
    score each side) and their ``correlation``."""

    plant: dict[str, Any]
    names: tuple[str, ...]
    estimate: Floats
    below: Floats
    above: Floats
    correlation: Floats

    def samples(self, count: int, seed: int) -> Floats:
        """``count`` parameter vectors drawn as the module doc says (rows)."""
        rng = np.random.default_rng(seed)
        p = len(self.names)
        correlation = np.nan_to_num(self.correlation, nan=0.0) + 1e-12 * np.eye(p)
        values, vectors = np.linalg.eigh(0.5 * (correlation + correlation.T))
        root = vectors * np.sqrt(np.clip(values, 0.0, None))
        scores = rng.standard_normal((count, p)) @ root.T
        draws = self.estimate + np.where(scores < 0.0, scores * self.below, scores * self.above)
        low, high = bounds_of(self.names)
        return np.asarray(np.clip(draws, low, high))


def uncertain_from(plant: dict[str, Any], estimates: tuple[Estimate, ...], correlation: Floats,
                   q: float) -> Uncertain:
    """What a fit knows, as :class:`Uncertain`: the spreads from the profile
    intervals where computed, else the standard errors."""
    below, above = [], []
    for e in estimates:
        profiled = math.isfinite(e.profile_low) and math.isfinite(e.profile_high)
        below.append((e.value - e.profile_low) / q if profiled else e.std_error)
        above.append((e.profile_high - e.value) / q if profiled else e.std_error)
    return Uncertain(dict(plant), tuple(e.name for e in estimates), np.array([e.value for e in estimates]),
                     np.array(below), np.array(above), np.asarray(correlation, dtype=float))


def uncertainty_section(uncertain: Uncertain) -> list[str]:
    """The ``calibration`` section of calibrated.yaml (ROS 2 parameters: arrays of one type)."""
    def floats(values: Floats) -> str:
        return "[" + ", ".join(repr(float(v)) for v in np.ravel(values)) + "]"

    return [f"{SECTION}:  # the fit's uncertainty, for friction-sim predict (no node reads it)",
            "  ros__parameters:",
            "    fitted: [" + ", ".join(f'"{name}"' for name in uncertain.names) + "]",
            f"    estimates: {floats(uncertain.estimate)}",
            f"    spread_below: {floats(uncertain.below)}",
            f"    spread_above: {floats(uncertain.above)}",
            f"    correlation: {floats(np.nan_to_num(uncertain.correlation, nan=0.0))}"]


def read_calibrated(path: Path) -> Uncertain:
    """A calibrated.yaml: the plant and, from its ``calibration`` section, the uncertainty."""
    document = read_yaml_mapping(path, "a calibrated plant (friction-sim calibrate's calibrated.yaml)")
    plant = {name: value for name, value in node_parameters(document, "slider").items() if name in spec.PLANT}
    section = node_parameters(document, SECTION)
    try:
        names = tuple(str(name) for name in section["fitted"])
        p = len(names)
        arrays = {key: np.asarray(section[key], dtype=float) for key in ("estimates", "spread_below", "spread_above")}
        correlation = np.asarray(section["correlation"], dtype=float).reshape(p, p)
    except (KeyError, TypeError, ValueError) as error:
        raise CalibrationError(f"{path}: no usable '{SECTION}' section ({error}): calibrate again with this "
                               "version of friction-sim calibrate, which keeps the fit's uncertainty") from None
    unknown = next((name for name in names if name not in spec.PLANT), None)
    if unknown or any(a.shape != (p,) or not np.all(np.isfinite(a)) for a in arrays.values()):
        raise CalibrationError(f"{path}: the '{SECTION}' section is damaged (fitted {', '.join(names)})")
    return Uncertain(plant, names, arrays["estimates"], arrays["spread_below"], arrays["spread_above"], correlation)


@dataclass(frozen=True)
class Prediction:
    """The mean speed [m/s] at each setting asked (``settings``: name -> one
    value per point): at the estimates, and the 95 % band of the samples."""

    settings: dict[str, Floats]
    speed: Floats
    low: Floats
    high: Floats
    samples: int

    @property
    def count(self) -> int:
        return int(self.speed.size)


def predict(uncertain: Uncertain, settings: dict[str, Any], *, samples: int = SAMPLES, seed: int = 0,
            settle_periods: int = 100, periods: int = 100) -> Prediction:
    """The mean speed with its 95 % band at ``settings`` (each a scalar or one
    value per point, in the sweeps' vocabulary; the plant's others as calibrated)."""
    clash = next((name for name in settings if name in uncertain.names), None)
    if clash:
        raise CalibrationError(f"{clash} is calibrated (with its uncertainty): it is not set when predicting")
    points = np.broadcast_arrays(*(np.asarray(v) for v in settings.values())) if settings else [np.zeros(1)]
    m = int(points[0].size)
    asked = {name: np.ravel(values) for name, values in zip(settings, points)}
    rows = np.vstack([uncertain.estimate[None, :], uncertain.samples(samples, seed)])
    k = rows.shape[0]
    columns: dict[str, np.ndarray] = {}
    for name, setting in FIELDS.items():
        value = uncertain.plant.get(name, setting.default)
        columns[name] = np.full(k * m, value) if isinstance(value, str) else np.full(k * m, float(value))
    for name, values in asked.items():
        if name in FIELDS:
            columns[name] = np.tile(values if FIELDS[name].kind is str else values.astype(float), k)
    for i, name in enumerate(uncertain.names):
        columns[name] = np.repeat(rows[:, i], m)
    derive_fields(columns, {name: np.tile(values.astype(float), k) for name, values in asked.items()
                            if name in DERIVED})
    speed = np.asarray(run_batch(columns, settle_periods=settle_periods, periods=periods).mean_velocity,
                       dtype=float).reshape(k, m)
    low, high = np.percentile(speed[1:], BAND, axis=0)
    return Prediction({name: values for name, values in asked.items()}, speed[0], low, high, samples)


__all__ = ["BAND", "SAMPLES", "SECTION", "Prediction", "Uncertain", "predict", "read_calibrated",
           "uncertain_from", "uncertainty_section"]
