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
  not monotone in restitution or the vibration angle, and flat where nothing
  moves or everything runs away, so it starts from the user's starts, the
  settings given and points drawn (seeded) where the part moves and does not
  run away (:mod:`~friction_sim.experiment.calibration_fit`,
  :mod:`~friction_sim.experiment.calibration_points`), and keeps the best; a
  start that ends on a flat region is reported, not blamed on the data.
* **The uncertainty**: the linearized covariance at the optimum, (J^T J)^-1
  times the residual variance (1 when the deviations were given: they are
  then known), standard errors its diagonal's roots, 95 % intervals the
  estimate +- t(0.975, n - p) (z = 1.96 with known deviations) standard
  errors; beside them each parameter's profile-likelihood interval
  (:mod:`~friction_sim.experiment.calibration_profile`), honest where the
  parameters correlate nonlinearly, and the correlation over those intervals.
  The fit's uncertainty goes into calibrated.yaml for predictions
  (:mod:`~friction_sim.experiment.calibration_predict`).
* **Refusal.** A fit the data cannot determine is refused in one line that
  says why (:class:`CalibrationError`): fewer points than parameters (or no
  more, without deviations: the scatter cannot be estimated); every point
  measured still; a parameter that changes no point's speed at any start that
  moved; two parameters correlated above :data:`MAX_CORRELATION`; a result
  that is not finite.

The same machinery fits the exciter to a frequency sweep
(:mod:`~friction_sim.experiment.calibration_sweep`) or to a recording's
accelerometer (:mod:`~friction_sim.experiment.calibration_accel`), and the
plant to a recording's trajectory (:mod:`~friction_sim.experiment.calibration_run`),
each with both intervals.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from friction_sim.core.model import spec
from friction_sim.core.model.params import SliderParams, plant_from
from friction_sim.experiment.calibration_fit import (
    FITTABLE,
    LOSSES,
    MAX_CORRELATION,
    Z95,
    CalibrationError,
    Estimate,
    Evaluator,
    FitOptions,
    Floats,
    Outcome,
    Problem,
    check_correlation,
    chosen,
    linearized,
    outcome,
    scales,
    starting_points,
    words,
)
from friction_sim.experiment.calibration_points import PointsModel
from friction_sim.experiment.calibration_predict import uncertain_from, uncertainty_section
from friction_sim.experiment.calibration_profile import Profile, chord_correlation, profiles
from friction_sim.experiment.measurements import SPEED_STD, Measurements

#: Drawn starts screened at once (one population-engine call over that many times the points).
SCREEN = 256


@dataclass(frozen=True)
class Calibration:
    """The result: the estimates, their correlation, the fitted speeds and
    residuals [m/s] point by point, the calibrated plant (fixed settings and
    estimates), how the fit went, and what became of starts that ended where
    nothing changes (``notes``)."""

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
    notes: tuple[str, ...] = ()
    covariance: np.ndarray | None = None
    profiles: tuple[Profile, ...] = ()

    @property
    def residuals(self) -> np.ndarray:
        """Measured minus fitted mean speed [m/s], point by point."""
        return np.asarray(self.measurements.speed - self.fitted_speed)

    def parameters_file(self) -> str:
        """The calibrated plant as a ROS 2 parameters file, with the fit's uncertainty (see :func:`parameters_file`)."""
        return parameters_file(self.params, self.estimates, self.measurements.source, self.correlation,
                               quantile(self.known_deviations, self.degrees_of_freedom))


@dataclass(frozen=True)
class Fitted:
    """A finished multi-start fit: the start kept, every start's outcome, the
    parameter vectors the model was evaluated at, and the notes on flat starts."""

    best: Outcome
    outcomes: tuple[Outcome, ...]
    evaluations: int

    @property
    def result(self) -> Any:
        return self.best.result

    @property
    def notes(self) -> tuple[str, ...]:
        return tuple(note for o in self.outcomes if (note := o.note(len(self.outcomes))))


def fit(problem: Problem, options: FitOptions, reference: Floats, threshold: Callable[[float], float]) -> Fitted:
    """SciPy's bounded least squares (trust region reflective) of ``problem``
    from each of its starting points (:func:`~friction_sim.experiment.calibration_fit.starting_points`),
    the Jacobian by forward differences in one call of the model per point;
    the start kept as :func:`~friction_sim.experiment.calibration_fit.chosen`
    says (``threshold``: the cost difference the data cannot see, given the best cost)."""
    from scipy.optimize import least_squares

    evaluator = Evaluator(problem)
    low, high = problem.bounds
    outcomes = []
    for number, start in enumerate(starting_points(problem, options, reference), start=1):
        try:
            result = least_squares(evaluator.fun, start, jac=evaluator.jac, bounds=(low, high), loss=options.loss,
                                   f_scale=options.f_scale, x_scale=scales(start, low, high), xtol=1e-14,
                                   ftol=1e-14, gtol=1e-14, max_nfev=400)
        except ValueError as error:  # SciPy refuses a residual or a slope that is not finite
            raise CalibrationError(f"start {number}: the fit met a number beyond floating point ({error}) at "
                                   f"{words(problem.names, start)}: are the measurements in their units?") from None
        outcomes.append(outcome(problem, number, start, result))
    moved = [float(o.result.cost) for o in outcomes if not o.flat]
    best = chosen(problem, outcomes, threshold(min(moved)) if moved else 0.0)
    return Fitted(best, tuple(outcomes), evaluator.rows)


def quantile(known: bool, dof: int) -> float:
    """The two-sided 95 % quantile of the intervals: z with known deviations, else t over ``dof``."""
    return Z95 if known else t95(dof)


def visible(known: bool, dof: int) -> Callable[[float], float]:
    """The rise of the cost (0.5 sum of squared residuals) that 95 % confidence
    allows for one parameter: chi2_1(0.95)/2 with known deviations, else the F
    (t^2) form, t^2 times the residual variance over 2 (cost/dof)."""
    q = quantile(known, dof)
    return (lambda cost: 0.5 * q * q) if known else (lambda cost: q * q * cost / dof)


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
    if not np.any(measurements.speed != 0.0):
        raise CalibrationError(f"every point lies in the no-motion region (mean speed 0 measured at all "
                               f"{n} points): {', '.join(options.fit)} not identifiable there; measure where the "
                               "part moves")
    model = PointsModel(measurements, fixed, options)
    scale = measurements.std if measurements.std is not None else np.full(n, _rms(measurements.speed))
    problem = Problem(options.fit, lambda xs: (model.speeds(xs) - measurements.speed[None, :]) / scale[None, :],
                      model.flat, model.violations, "point's mean speed", SCREEN)
    dof = n - p
    fitted = fit(problem, options, model.reference, visible(known, dof))
    best = fitted.result
    found = uncertainty(problem, best, options, known, dof)
    estimates, correlation, covariance, profiled = found.estimates, found.correlation, found.covariance, found.profiles
    values = model.values(best.x)
    params = plant_from({name: _scalar(values[name]) for name in spec.PLANT})[0]
    fitted_speed = model.speeds(best.x)[0]
    check_finite(estimates, fitted_speed)
    return Calibration(estimates, correlation, measurements, fitted_speed, params, known, dof,
                       float(best.cost), len(fitted.outcomes), time.perf_counter() - started, fitted.evaluations,
                       dict(fixed), fitted.notes, covariance, profiled)


@dataclass(frozen=True)
class Uncertainty:
    """What a fit's uncertainty is: the estimates with their linearized and
    profile intervals, the correlation (chords across the profile intervals
    when profiled, else the tangent one), the linearized covariance and the profiles."""

    estimates: tuple[Estimate, ...]
    correlation: Floats
    covariance: Floats
    profiles: tuple[Profile, ...]


def uncertainty(problem: Problem, best: Any, options: FitOptions, known: bool, dof: int) -> Uncertainty:
    """The uncertainty of the fit ``best`` of ``problem`` (residuals in units of
    their deviations: ``known``, or of an unknown scale then estimated over
    ``dof``); refused if two parameters correlate beyond the limit."""
    estimates, correlation, covariance = linearized(best, problem.names, known, dof, quantile(known, dof),
                                                    check=not options.profile)
    profiled: tuple[Profile, ...] = ()
    if options.profile:
        profiled, estimates = profile_intervals(problem, best, estimates, covariance, options, known, dof)
        correlation = chord_correlation(problem, best.x, profiled, quantile(known, dof))
        check_correlation(correlation, problem.names)
    return Uncertainty(estimates, correlation, covariance, profiled)


def check_finite(estimates: tuple[Estimate, ...], fitted: Floats) -> None:
    """Never a result that is not finite: refused, naming the number."""
    for e in estimates:
        numbers = {"estimate": e.value, "standard error": e.std_error, "interval": e.low + e.high}
        if math.isfinite(e.profile_low) or math.isfinite(e.profile_high):
            numbers["profile interval"] = e.profile_low + e.profile_high
        bad = next((what for what, number in numbers.items() if not math.isfinite(number)), None)
        if bad:
            raise CalibrationError(f"{e.name}: the fit's {bad} is not finite: the data cannot determine it")
    if not np.all(np.isfinite(fitted)):
        raise CalibrationError("a fitted value is not finite: the data cannot determine the parameters")


def profile_intervals(problem: Problem, best: Any, estimates: tuple[Estimate, ...], covariance: Floats,
                      options: FitOptions, known: bool, dof: int) -> tuple[tuple[Profile, ...], tuple[Estimate, ...]]:
    """Each parameter's profile and the estimates with their profile intervals
    (:mod:`~friction_sim.experiment.calibration_profile`)."""
    variance = 1.0 if known else 2.0 * float(best.cost) / dof
    profiled = profiles(problem, np.asarray(best.x, dtype=float), float(best.cost), covariance, variance,
                        quantile(known, dof), options.loss, options.f_scale)
    return profiled, tuple(dataclasses.replace(e, profile_low=pr.low, profile_high=pr.high, open_low=pr.open_low,
                                               open_high=pr.open_high) for e, pr in zip(estimates, profiled))


def summary(calibration: Calibration) -> list[str]:
    """What a user reads: the estimates with their errors and intervals, the
    correlation matrix and the residual table, as lines of text."""
    c, m = calibration, calibration.measurements
    scatter = "the std column (known deviations, z intervals)" if c.known_deviations else (
        f"the residuals' scatter ({c.degrees_of_freedom} degrees of freedom, t intervals)")
    lines = [f"calibrated from {m.count} points of {m.source} in {c.seconds:.2f} s ({c.starts} starts, "
             f"{c.evaluations} evaluations); uncertainty from {scatter}",
             *c.notes, *estimate_lines(c.estimates, c.correlation)]
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


def parameters_file(params: SliderParams, estimates: tuple[Estimate, ...], source: str,
                    correlation: Floats | None = None, q: float = Z95) -> str:
    """A calibrated plant as a ROS 2 parameters file: ``slider --params``, a
    scenario's ``plant_params`` and a sweep's ``plant_params`` read it as it is;
    with the ``correlation``, the fit's uncertainty too, in a section of its own
    (:func:`~friction_sim.experiment.calibration_predict.uncertainty_section`,
    what ``friction-sim predict`` reads)."""
    lines = ["# Calibrated by friction-sim calibrate from " + source,
             *(f"# {e.name} = {e.value:.10g} +- {e.std_error:.3g} (95 %: linearized {e.low:.6g} .. {e.high:.6g}"
               + (f"; profile likelihood {e.profile_low:.6g} .. {e.profile_high:.6g})"
                  if math.isfinite(e.profile_low) else ")") for e in estimates),
             "/**:", "  ros__parameters:"]
    for name in spec.PLANT:
        value = getattr(params, name)
        lines.append(f"    {name}: {value}" if isinstance(value, str) else f"    {name}: {float(value)!r}")
    if correlation is not None:
        plant = {name: getattr(params, name) for name in spec.PLANT}
        lines += uncertainty_section(uncertain_from(plant, estimates, correlation, q))
    return "\n".join(lines) + "\n"


def estimate_lines(estimates: tuple[Estimate, ...], correlation: np.ndarray) -> list[str]:
    """The estimates table (the profile interval beside the linearized one, when
    computed; an end at the parameter's bound marked open) and the correlation
    matrix, as lines of text."""
    profiled = any(math.isfinite(e.profile_low) for e in estimates)
    lines = [f"{'parameter':<24}{'estimate':>16}{'std error':>12}   {'95 % linearized':<32}"
             + ("  95 % profile likelihood" if profiled else "")]
    for e in estimates:
        line = f"{e.name:<24}{e.value:>16.8g}{e.std_error:>12.3g}   {f'[{e.low:.8g}, {e.high:.8g}]':<32}"
        if profiled:
            line += (f"  {'(' if e.open_low else '['}{e.profile_low:.8g}, {e.profile_high:.8g}"
                     f"{')' if e.open_high else ']'}")
        lines.append(line)
    if any(e.open_low or e.open_high for e in estimates):
        lines.append("(an end in round brackets is the parameter's bound: the data do not close the interval there)")
    names = [e.name for e in estimates]
    lines.append("correlation: " + ("  ".join(names) if len(names) > 1 else "(one parameter)"))
    if len(names) > 1:
        width = max(22, *(len(name) + 1 for name in names))
        lines += [f"  {name:<{width}}" + " ".join(f"{value:+.4f}" for value in row)
                  for name, row in zip(names, correlation)]
    return lines


def _rms(speed: np.ndarray) -> float:
    """The measured speeds' RMS [m/s], the residuals' unit without deviations: at
    least the smallest deviation a std column may give (residuals divided by
    less overflow), 1 mm/s if all are 0."""
    rms = float(np.sqrt(np.mean(speed**2)))
    return max(rms, float(SPEED_STD.low or 0.0)) if rms > 0.0 else 1e-3


def t95(dof: int) -> float:
    """The t distribution's two-sided 95 % quantile over ``dof`` degrees of freedom."""
    from scipy.stats import t

    return float(t.ppf(0.975, dof))


def _scalar(column: np.ndarray) -> Any:
    """A setting's value for the calibrated plant: the points' one value (the
    plant's fields do not vary between points; an input may)."""
    value = column[0]
    return value if isinstance(value, str) else float(value)


__all__ = ["FITTABLE", "LOSSES", "MAX_CORRELATION", "Z95", "Calibration", "CalibrationError", "Estimate", "FitOptions",
           "Fitted", "Problem", "Uncertainty", "calibrate", "check_finite", "estimate_lines", "fit", "parameters_file",
           "quantile", "summary", "t95", "uncertainty", "visible", "write_residuals"]
