"""Fitting the model to a feeder's measured operating points (``friction-sim calibrate``).

A user times a part at a few drive settings; the model predicts each mean
speed exactly for given mu, mu_s/mu, restitution, exciter data...  This module
finds the parameters the data determine, with honest uncertainty:

* **The model** of each point is the exact mean speed over whole periods
  after settling, for all points at once on the population engine
  (:func:`~friction_sim.core.engine.population.run_batch`): the fixed
  settings, the point's own settings (derived keys as in sweeps), and the
  parameters being fitted.
* **The fit** is SciPy's bounded least squares (``least_squares``, trust
  region reflective), bounds from ``spec.py``, residuals (model - measured)
  in units of each point's standard deviation when the file gives one (else of
  the measured speeds' RMS, the scatter then estimated from the fit), with an
  optional robust loss (``soft_l1``, ``huber``) against outliers.  The speed is
  not monotone in restitution or the vibration angle, so it starts from the
  settings given and from ``starts - 1`` more points drawn (seeded) across the
  bounds, and keeps the best.
* **The uncertainty** is the linearized covariance at the optimum,
  (J^T J)^-1 times the residual variance (1 when the deviations were given:
  they are then known), standard errors its diagonal's roots, 95 % intervals
  the estimate +- t(0.975, n - p) (z = 1.96 with known deviations) standard
  errors, and the correlation matrix.
* **Refusal.** A fit the data cannot determine is refused in one line that
  says why (:class:`CalibrationError`): fewer points than parameters (or no
  more, without deviations: the scatter cannot be estimated); a parameter that
  moves no point's speed (every point in the no-motion region, for mu); two
  parameters correlated above :data:`MAX_CORRELATION`.
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from friction_sim.core.engine.population import run_batch
from friction_sim.core.model import spec
from friction_sim.core.model.params import SliderParams, plant_from
from friction_sim.errors import FrictionSimError
from friction_sim.experiment.measurements import Measurements
from friction_sim.experiment.sweep import DERIVED, FIELDS, derive_fields

#: Parameters that may be fitted: the plant's numbers.
FITTABLE = {name: setting for name, setting in spec.PLANT.items() if setting.kind is float}
LOSSES = ("linear", "soft_l1", "huber")
#: Two fitted parameters correlated beyond this cannot be told apart by the data.
MAX_CORRELATION = 0.99
#: Two-sided 95 % quantile of the normal distribution (known deviations).
Z95 = 1.959963984540054


class CalibrationError(FrictionSimError):
    """A calibration the data cannot determine (or cannot be set up), and why."""


@dataclass(frozen=True)
class FitOptions:
    """What to fit and how: ``fit`` the parameter names; ``loss`` and ``f_scale``
    (in standard deviations) as SciPy's; ``starts`` starting points (the first
    the settings given), drawn with ``seed``; the mean speed over ``periods``
    whole periods after ``settle_periods``."""

    fit: tuple[str, ...]
    loss: str = "linear"
    f_scale: float = 1.0
    starts: int = 4
    seed: int = 0
    settle_periods: int = 100
    periods: int = 100

    def __post_init__(self) -> None:
        if not self.fit:
            raise CalibrationError("--fit names no parameter (e.g. --fit mu,static_ratio)")
        unknown = [name for name in self.fit if name not in FITTABLE]
        if unknown:
            raise CalibrationError(f"--fit {unknown[0]!r}: not a plant parameter that can be fitted "
                                   f"(one of {', '.join(FITTABLE)})")
        if len(set(self.fit)) != len(self.fit):
            raise CalibrationError(f"--fit {','.join(self.fit)}: a parameter named twice")
        if self.loss not in LOSSES:
            raise CalibrationError(f"--loss {self.loss!r}: one of {', '.join(LOSSES)}")
        if not (self.f_scale > 0.0 and math.isfinite(self.f_scale)) or self.starts < 1:
            raise CalibrationError("--f-scale must be > 0 and --starts >= 1")


@dataclass(frozen=True)
class Estimate:
    """One fitted parameter: its value, standard error and 95 % interval."""

    name: str
    value: float
    std_error: float
    low: float
    high: float


@dataclass(frozen=True)
class Calibration:
    """The result: the estimates, their correlation, the fitted speeds and
    residuals [m/s] point by point, the calibrated plant (fixed settings and
    estimates), and how the fit went."""

    estimates: tuple[Estimate, ...]
    correlation: np.ndarray
    measurements: Measurements
    fitted_speed: np.ndarray
    params: SliderParams
    known_deviations: bool
    degrees_of_freedom: int
    cost: float
    starts: int
    seconds: float
    evaluations: int = 0
    fixed: dict[str, Any] = field(default_factory=dict)

    @property
    def residuals(self) -> np.ndarray:
        """Measured minus fitted mean speed [m/s], point by point."""
        return np.asarray(self.measurements.speed - self.fitted_speed)

    def parameters_file(self) -> str:
        """The calibrated plant as a ROS 2 parameters file (see :func:`parameters_file`)."""
        return parameters_file(self.params, self.estimates, self.measurements.source)


class _Model:
    """The mean speed of every point for a vector of fitted values."""

    def __init__(self, measurements: Measurements, fixed: dict[str, Any], options: FitOptions) -> None:
        clash = [name for name in options.fit if name in measurements.settings or name in fixed]
        if clash:
            raise CalibrationError(f"{clash[0]} is both fitted and given (in the measurements or the fixed settings)")
        self.measurements, self.fixed, self.options = measurements, fixed, options
        self.evaluations = 0
        n = measurements.count
        self.columns: dict[str, np.ndarray] = {
            name: np.full(n, setting.default) if setting.kind is str else np.full(n, float(setting.default))
            for name, setting in FIELDS.items()}
        for name, value in fixed.items():
            if name in FIELDS:
                self.columns[name] = np.full(n, value) if isinstance(value, str) else np.full(n, float(value))
        self.given = {name: np.full(n, float(value)) for name, value in fixed.items() if name in DERIVED}
        for name, values in measurements.settings.items():
            (self.given if name in DERIVED else self.columns)[name] = values

    def values(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """Every field of every point, with the fitted parameters at ``x`` (derived keys applied after)."""
        columns = dict(self.columns)
        for name, value in zip(self.options.fit, x):
            columns[name] = np.full(self.measurements.count, float(value))
        derive_fields(columns, self.given)
        return columns

    def speed(self, x: np.ndarray) -> np.ndarray:
        self.evaluations += 1
        batch = run_batch(self.values(x), settle_periods=self.options.settle_periods, periods=self.options.periods)
        return np.asarray(batch.mean_velocity, dtype=float)


def calibrate(measurements: Measurements, fixed: dict[str, Any], options: FitOptions) -> Calibration:
    """Fit ``options.fit`` to the measured speeds (see the module doc); a
    :class:`CalibrationError` if the data cannot determine them."""

    started = time.perf_counter()
    n, p = measurements.count, len(options.fit)
    known = measurements.std is not None
    if n < p or (n == p and not known):
        raise CalibrationError(f"{n} points cannot determine {p} parameters ({', '.join(options.fit)})"
                               + ("" if known else "; without a std column the scatter needs more points than "
                                                   "parameters"))
    model = _Model(measurements, fixed, options)
    scale = measurements.std if known else np.full(n, _rms(measurements.speed))

    def residuals(x: np.ndarray) -> np.ndarray:
        return np.asarray((model.speed(x) - measurements.speed) / scale)

    best = fit_least_squares(residuals, options, fixed)
    if not np.all(np.any(np.asarray(best.jac) != 0.0, axis=0)):
        _refuse_unidentifiable(np.asarray(best.jac), measurements, options)
    dof = n - p
    estimates, correlation = estimates_from(best, options.fit, known, dof)
    values = model.values(best.x)
    params = plant_from({name: _scalar(values[name]) for name in spec.PLANT})[0]
    return Calibration(estimates, correlation, measurements, model.speed(best.x), params, known, dof,
                       float(best.cost), options.starts, time.perf_counter() - started, model.evaluations,
                       dict(fixed))


def summary(calibration: Calibration) -> list[str]:
    """What a user reads: the estimates with their errors and intervals, the
    correlation matrix and the residual table, as lines of text."""
    c, m = calibration, calibration.measurements
    scatter = "the std column (known deviations, z intervals)" if c.known_deviations else (
        f"the residuals' scatter ({c.degrees_of_freedom} degrees of freedom, t intervals)")
    lines = [f"calibrated from {m.count} points of {m.source} in {c.seconds:.2f} s ({c.starts} starts, "
             f"{c.evaluations} evaluations); uncertainty from {scatter}",
             *estimate_lines(c.estimates, c.correlation)]
    varied = list(m.settings)
    lines.append("point  " + "  ".join(f"{name:>14}" for name in varied)
                 + f"  {'measured m/s':>14}  {'fitted m/s':>14}  {'residual m/s':>14}")
    for i in range(m.count):
        settings = "  ".join(f"{_cell(m.settings[name][i]):>14}" for name in varied)
        lines.append(f"{i + 1:>5}  {settings}  {m.speed[i]:>14.6g}  {c.fitted_speed[i]:>14.6g}  "
                     f"{c.residuals[i]:>+14.3e}")
    return lines


def write_residuals(calibration: Calibration, path: Path) -> Path:
    """The residual table as CSV: the varied settings, measured, fitted and residual speed [m/s]."""
    m = calibration.measurements
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow([*m.settings, "mean_speed", "fitted_speed", "residual"])
        for i in range(m.count):
            writer.writerow([*(_cell(m.settings[name][i]) for name in m.settings), repr(float(m.speed[i])),
                             repr(float(calibration.fitted_speed[i])), repr(float(calibration.residuals[i]))])
    return path


def _cell(value: Any) -> str:
    return str(value) if isinstance(value, str) else f"{float(value):.10g}"


def fit_least_squares(residuals: Callable[[np.ndarray], np.ndarray], options: FitOptions,
                      given: dict[str, Any], first: np.ndarray | None = None) -> Any:
    """SciPy's bounded least squares of ``residuals`` over ``options.fit`` from
    each starting point (``first``, else the settings ``given``, then the ones
    drawn), the best result kept (scipy.optimize.OptimizeResult)."""
    from scipy.optimize import least_squares

    low, high = _bounds(options.fit)
    best = None
    for start in _starts(options, given, low, high, first):
        result = least_squares(residuals, start, bounds=(low, high), loss=options.loss, f_scale=options.f_scale,
                               x_scale=_scales(start, low, high), diff_step=1e-7, xtol=1e-14, ftol=1e-14,
                               gtol=1e-14, max_nfev=400)
        if best is None or result.cost < best.cost:
            best = result
    assert best is not None
    return best


def estimates_from(best: Any, names: tuple[str, ...], known: bool, dof: int) -> tuple[tuple[Estimate, ...],
                                                                                    np.ndarray]:
    """Estimates with standard errors and 95 % intervals, and their correlation,
    from the linearized covariance at the optimum (residuals in units of their
    deviations: ``known``, or scaled by the residual variance over ``dof``);
    refused if two parameters correlate beyond :data:`MAX_CORRELATION`."""
    jacobian = np.asarray(best.jac, dtype=float)
    variance = 1.0 if known else float(np.sum(best.fun**2)) / dof
    covariance = np.linalg.pinv(jacobian.T @ jacobian) * variance
    errors = np.sqrt(np.diag(covariance))
    correlation = covariance / np.outer(errors, errors)
    _check_correlation(correlation, names)
    quantile = Z95 if known else _t95(dof)
    estimates = tuple(Estimate(name, float(v), float(e), float(v - quantile * e), float(v + quantile * e))
                      for name, v, e in zip(names, best.x, errors))
    return estimates, correlation


def parameters_file(params: SliderParams, estimates: tuple[Estimate, ...], source: str) -> str:
    """A calibrated plant as a ROS 2 parameters file: ``slider --params``, a
    scenario's ``plant_params`` and a sweep's ``plant_params`` read it as it is."""
    lines = ["# Calibrated by friction-sim calibrate from " + source,
             "# " + ", ".join(f"{e.name} = {e.value:.10g} +- {e.std_error:.3g} (95 %: {e.low:.6g} .. "
                              f"{e.high:.6g})" for e in estimates),
             "/**:", "  ros__parameters:"]
    for name in spec.PLANT:
        value = getattr(params, name)
        lines.append(f"    {name}: {value}" if isinstance(value, str) else f"    {name}: {float(value)!r}")
    return "\n".join(lines) + "\n"


def estimate_lines(estimates: tuple[Estimate, ...], correlation: np.ndarray) -> list[str]:
    """The estimates table and the correlation matrix, as lines of text."""
    lines = [f"{'parameter':<24}{'estimate':>16}{'std error':>14}{'95 % interval':>34}"]
    lines += [f"{e.name:<24}{e.value:>16.8g}{e.std_error:>14.3g}   [{e.low:.8g}, {e.high:.8g}]" for e in estimates]
    names = [e.name for e in estimates]
    lines.append("correlation: " + ("  ".join(names) if len(names) > 1 else "(one parameter)"))
    if len(names) > 1:
        lines += [f"  {name:<22}" + " ".join(f"{value:+.4f}" for value in row)
                  for name, row in zip(names, correlation)]
    return lines


def _rms(speed: np.ndarray) -> float:
    """The measured speeds' RMS [m/s] (the residuals' unit without deviations; 1 mm/s if all are 0)."""
    rms = float(np.sqrt(np.mean(speed**2)))
    return rms if rms > 0.0 else 1e-3


def _bounds(names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    low = np.array([-math.inf if (bound := FITTABLE[n].low) is None else float(bound) for n in names])
    high = np.array([math.inf if (bound := FITTABLE[n].high) is None else float(bound) for n in names])
    return low, high


def _scales(start: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """The parameters' characteristic sizes for the trust region: their starting
    values (a tenth of the range for one that starts at 0).  Scaling by the
    Jacobian instead let a weak parameter (mu_s/mu near 1) take a step into the
    no-motion region, where every slope is 0 and the fit stops."""
    span = np.where(np.isfinite(high - low), 0.1 * (high - low), 1.0)
    return np.where(start != 0.0, np.abs(start), span)


def _starts(options: FitOptions, given: dict[str, Any], low: np.ndarray, high: np.ndarray,
            first: np.ndarray | None = None) -> list[np.ndarray]:
    """``first``, else the settings given (else the defaults), then ``starts - 1``
    points drawn (seeded) across the bounds: log-uniform within a decade either
    side for a positive parameter whose range spans decades, uniform otherwise."""
    if first is None:
        first = np.array([float(given.get(n, FITTABLE[n].default)) for n in options.fit])
    first = np.clip(first, low, high)
    rng = np.random.default_rng(options.seed)
    starts = [first]
    for _ in range(options.starts - 1):
        point = np.empty_like(first)
        for i, (a, b, x0) in enumerate(zip(low, high, first)):
            if a > 0.0 and b / a > 100.0:
                lo, hi = max(a, x0 / 10.0), min(b, x0 * 10.0)
                point[i] = math.exp(rng.uniform(math.log(lo), math.log(hi)))
            else:
                lo, hi = (a if math.isfinite(a) else x0 - 1.0), (b if math.isfinite(b) else x0 + 1.0)
                point[i] = rng.uniform(lo, hi)
        starts.append(point)
    return starts


def _refuse_unidentifiable(jacobian: np.ndarray, measurements: Measurements, options: FitOptions) -> None:
    """Refuse a parameter the speeds do not depend on, at any point."""
    dead = [name for name, column in zip(options.fit, jacobian.T) if not np.any(column != 0.0)]
    if not np.any(measurements.speed != 0.0):
        raise CalibrationError(f"every point lies in the no-motion region (mean speed 0 measured and predicted at "
                               f"all {measurements.count} points): {', '.join(dead)} not identifiable there; "
                               "measure where the part moves")
    raise CalibrationError(f"{', '.join(dead)} changes no point's mean speed (at the fit): not identifiable from "
                           "these points")


def _check_correlation(correlation: np.ndarray, names: tuple[str, ...]) -> None:
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if abs(correlation[i, j]) > MAX_CORRELATION:
                raise CalibrationError(
                    f"{names[i]} and {names[j]} correlate {correlation[i, j]:+.4f} over these points (limit "
                    f"{MAX_CORRELATION}): the data cannot tell them apart; fix one, or measure where they act "
                    "differently")


def _t95(dof: int) -> float:
    from scipy.stats import t

    return float(t.ppf(0.975, dof))


def _scalar(column: np.ndarray) -> Any:
    """A setting's value for the calibrated plant: the points' one value (the
    plant's fields do not vary between points; an input may)."""
    value = column[0]
    return value if isinstance(value, str) else float(value)


__all__ = ["FITTABLE", "LOSSES", "MAX_CORRELATION", "Calibration", "CalibrationError", "Estimate", "FitOptions",
           "calibrate", "estimate_lines", "estimates_from", "fit_least_squares", "parameters_file", "summary",
           "write_residuals"]
