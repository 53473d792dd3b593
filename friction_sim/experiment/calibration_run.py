"""Fitting the model to a recorded run (``friction-sim calibrate run.mcap``).

A recording holds the plant's initial values, every command that was in force
and when, and the slider's trajectory: the position x and velocity v sampled
on the log grid.  With the parameters being fitted replaced, the run is
re-simulated exactly from the same commands (the re-simulation of ``replay
--verify``, :func:`friction_sim.experiment.verify.resimulate`), and the fit minimizes
the differences at every recorded sample.

Position and velocity are measured by different means and in different units,
each with its own noise, which the file does not state.  So the fit runs twice
(the method of weighted least squares with estimated variances): first with
each series in units of its own RMS, then with each in units of the scatter of
its residuals from the first fit, starting from the first fit's answer; the
intervals come from the second, the deviations then taken as known: the
linearized ones and, beside them, profile likelihood's (the cost with the
other parameters re-fitted rising by chi2_1(0.95)/2,
:func:`~friction_sim.experiment.calibration.uncertainty`), honest where the
trajectory depends on the parameters nonlinearly (a hop's restitution, a
stick-slip's mu).  A fitted parameter that the recording
itself changes mid-run (a ``ros2 param set`` on it) is refused: the run does
not have one value of it to find.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from friction_sim.core.model.commands import PARAMETERS
from friction_sim.core.model.params import Inputs, SliderParams, plant_from
from friction_sim.errors import ParameterError
from friction_sim.experiment.calibration import (
    FITTABLE,
    Z95,
    CalibrationError,
    Estimate,
    FitOptions,
    Problem,
    Profile,
    check_finite,
    estimate_lines,
    fit,
    parameters_file,
    uncertainty,
    visible,
)
from friction_sim.experiment.calibration_fit import scatter, size
from friction_sim.experiment.verify import RecordedRun, resimulate


@dataclass(frozen=True)
class RunCalibration:
    """The result of a fit to a recording: the estimates (linearized and profile
    intervals) and their correlation, the calibrated plant, the fitted trajectory
    at the recorded samples, the noise of each series the fit estimated [m, m/s],
    and the profiles (the deviations are then known: z quantiles over
    ``degrees_of_freedom``)."""

    run: RecordedRun
    estimates: tuple[Estimate, ...]
    correlation: np.ndarray
    params: SliderParams
    fitted_x: np.ndarray
    fitted_v: np.ndarray
    noise_x: float
    noise_v: float
    evaluations: int
    seconds: float
    profiles: tuple[Profile, ...] = ()
    degrees_of_freedom: int = 0
    known_deviations: bool = True  # (from the second pass on, the noise of each series is taken as known)

    def parameters_file(self) -> str:
        """The calibrated plant as a ROS 2 parameters file, with the fit's uncertainty."""
        return parameters_file(self.params, self.estimates, self.run.path, self.correlation, Z95)

    def summary(self) -> list[str]:
        """The estimates, their correlation and how well the trajectory is met, as lines of text."""
        run = self.run
        return [f"calibrated against {run.path}: {run.x.size} positions and {run.v.size} velocities, "
                f"{len(run.commands)} commands in force, in {self.seconds:.2f} s ({self.evaluations} re-simulations)",
                *estimate_lines(self.estimates, self.correlation),
                f"residual RMS: x {self.noise_x:.3g} m, v {self.noise_v:.3g} m/s (the noise the fit attributes "
                "to each series)"]


class _Replays:
    """The recording re-simulated for a vector of fitted values."""

    def __init__(self, run: RecordedRun, names: tuple[str, ...]) -> None:
        changed = sorted({name for command in run.commands if command.name == PARAMETERS
                          for name in command.values if name in names})
        if changed:
            raise CalibrationError(f"{run.path}: the recording changes {', '.join(changed)} during the run: it has "
                                   "no one value of it to fit")
        if run.x.size + run.v.size <= len(names):
            raise CalibrationError(f"{run.path}: {run.x.size + run.v.size} samples cannot determine "
                                   f"{len(names)} parameters")
        self.run, self.names = run, names
        self.evaluations = 0

    def plant(self, x: np.ndarray) -> tuple[SliderParams, Inputs]:
        try:
            return plant_from({**self.run.initial, **dict(zip(self.names, (float(v) for v in x)))})
        except ParameterError as error:  # a cross-field rule of the plant (the bounds are the ranges)
            raise CalibrationError(f"{self.run.path}: {error}") from None

    def trajectory(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        self.evaluations += 1
        return resimulate(self.run, *self.plant(x))


def calibrate_run(run: RecordedRun, options: FitOptions) -> RunCalibration:
    """Fit ``options.fit`` to the recorded trajectory (see the module doc)."""
    started = time.perf_counter()
    replays = _Replays(run, options.fit)
    scale_x, scale_v = size(run.x), size(run.v)

    def problem_in(sx: float, sv: float) -> Problem:
        def residuals(xs: np.ndarray) -> np.ndarray:
            rows = []
            for x in xs:
                sim_x, sim_v = replays.trajectory(x)
                rows.append(np.concatenate([(sim_x - run.x) / sx, (sim_v - run.v) / sv]))
            return np.array(rows)
        return Problem(options.fit, residuals, lambda x: "the trajectory does not change at "
                       + ", ".join(f"{n} = {v:.6g}" for n, v in zip(options.fit, x)),
                       subject="sample of the recorded trajectory")

    # The starts are the settings' defaults, not the file's values: those are what is in question
    # (a recording of the simulator holds the truth).
    reference = np.array([float(FITTABLE[name].default) for name in options.fit])
    dof = run.x.size + run.v.size - len(options.fit)
    first = fit(problem_in(scale_x, scale_v), options, reference, visible(False, dof)).result
    sim_x, sim_v = replays.trajectory(first.x)
    inflation = math.sqrt((run.x.size + run.v.size) / dof)  # the residuals' scatter, for the parameters fitted
    noise_x = max(scatter(sim_x - run.x) * inflation, 1e-15 * scale_x)  # (a noise-free run: rounding)
    noise_v = max(scatter(sim_v - run.v) * inflation, 1e-15 * scale_v)
    again = dataclasses.replace(options, starts=1, start_points=(dict(zip(options.fit, map(float, first.x))),))
    problem = problem_in(noise_x, noise_v)
    second = fit(problem, again, first.x, visible(True, dof)).result
    found = uncertainty(problem, second, options, True, dof)
    fitted_x, fitted_v = replays.trajectory(second.x)
    check_finite(found.estimates, np.concatenate([fitted_x, fitted_v]))
    return RunCalibration(run, found.estimates, found.correlation, replays.plant(second.x)[0], fitted_x, fitted_v,
                          scatter(fitted_x - run.x), scatter(fitted_v - run.v), replays.evaluations,
                          time.perf_counter() - started, found.profiles, dof)


__all__ = ["RunCalibration", "calibrate_run"]
