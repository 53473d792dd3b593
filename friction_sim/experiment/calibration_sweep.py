"""The exciter from a frequency sweep (``friction-sim calibrate sweep.csv``).

A technician tunes a resonant feeder by sweeping the drive frequency at a
drive level and reading the slideway's vibration off an accelerometer: its
normal acceleration amplitude and, with a two-channel instrument, its lag
behind the drive.  The exciter's data (f_n, zeta, A) follow from that curve,
the steady response of :mod:`~friction_sim.core.physics.exciter`:

    amplitude = u*A*G(f/f_n),  lag = atan2(2 zeta r, 1 - r^2)   (r = f/f_n).

The CSV has one row per frequency: ``excitation_frequency`` [Hz] (or
``drive_frequency``, as ``friction-sim resonance`` writes it), ``amplitude``
[m/s^2], optionally ``drive_level`` (else the fixed settings'), ``lag_deg``
and ``std`` (the amplitude's standard deviation [m/s^2]); the resonance
CSV's ``mean_velocity`` and ``flight_fraction`` are read and left out.

The fit is calibration's (:func:`~friction_sim.experiment.calibration.fit`),
from a start read off the curve (the peak, or the lag's 90 degree crossing,
for f_n; the half-power width for zeta; the peak over the drive level for A)
and draws around it, screened at once.  Without lags the amplitude's
deviations are the std column's (known) or estimated from the scatter (t
intervals).  With lags, whose deviation no column gives, the fit runs twice,
as a recording's does: each series first in units of its own size, then each
in units of its residuals' scatter (the amplitude's std where given), the
deviations then taken as known.  The intervals are profile likelihood's
beside the linearized ones.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from friction_sim.core.model import spec
from friction_sim.core.model.params import SliderParams, plant_from
from friction_sim.core.physics.exciter import steady_response
from friction_sim.experiment.calibration import (
    Estimate,
    FitOptions,
    Problem,
    Profile,
    check_finite,
    estimate_lines,
    fit,
    parameters_file,
    quantile,
    uncertainty,
    visible,
)
from friction_sim.experiment.calibration_fit import CalibrationError, Floats, closest, scatter, size
from friction_sim.experiment.measurements import MeasurementsError, read_csv_rows, read_table

#: What a sweep determines: the exciter's data.
EXCITER = tuple(spec.EXCITER)
FREQUENCY, ALIAS, LEVEL, AMPLITUDE, LAG, STD = ("excitation_frequency", "drive_frequency", "drive_level",
                                                "amplitude", "lag_deg", "std")
#: The sweep's columns and their ranges (the frequency and drive level are the model's settings).
COLUMNS: dict[str, spec.Setting] = {
    FREQUENCY: spec.EXCITATION_FREQUENCY, ALIAS: spec.EXCITATION_FREQUENCY.described("drive frequency", flag=None),
    LEVEL: spec.DRIVE_LEVEL,
    AMPLITUDE: spec.Setting(AMPLITUDE, 0.0, "m/s^2", "the slideway's normal acceleration amplitude", 0.0, 1e6),
    LAG: spec.Setting(LAG, 90.0, "deg", "the slideway's lag behind the drive", 0.0, 180.0),
    STD: spec.Setting(STD, 0.1, "m/s^2", "standard deviation of a measured amplitude", 1e-12, 1e6),
    "mean_velocity": spec.Setting("mean_velocity", 0.0, "m/s", "(friction-sim resonance's; not used)", -1e3, 1e3),
    "flight_fraction": spec.Setting("flight_fraction", 0.0, "-", "(friction-sim resonance's; not used)", 0.0, 1.0),
}
#: Drawn starts screened at once (the model is closed-form: cheap).
SCREEN = 64

_steady = np.vectorize(steady_response, otypes=[float, float])


def is_sweep(path: Path) -> bool:
    """Whether a CSV is a frequency sweep (an ``amplitude`` column), not operating points."""
    try:
        return AMPLITUDE in read_csv_rows(path, "frequency")[1]
    except MeasurementsError:
        return False


@dataclass(frozen=True)
class Sweep:
    """A measured sweep: drive ``frequency`` [Hz], ``drive_level`` (None: the fixed
    settings'), ``amplitude`` [m/s^2], ``lag_deg`` and ``std`` (None: not given)."""

    frequency: Floats
    drive_level: Floats | None
    amplitude: Floats
    lag_deg: Floats | None
    std: Floats | None
    source: str

    @property
    def count(self) -> int:
        return int(self.frequency.size)


def read_sweep(path: Path) -> Sweep:
    """A sweep CSV, each value checked against its column's range."""
    columns = read_table(path, "frequency", _check_header, COLUMNS.__getitem__)

    def column(name: str) -> Floats | None:
        return np.asarray(columns[name], dtype=float) if name in columns else None

    frequency = column(FREQUENCY)
    amplitude = column(AMPLITUDE)
    assert amplitude is not None  # (the header check)
    return Sweep(frequency if frequency is not None else np.asarray(columns[ALIAS], dtype=float), column(LEVEL),
                 amplitude, column(LAG), column(STD), str(path))


def _check_header(where: str, line: int, names: list[str]) -> None:
    unknown = next((name for name in names if name not in COLUMNS), None)
    if unknown is not None:
        raise MeasurementsError(f"{where}: line {line}: unknown column '{unknown}' (a sweep's columns: "
                                f"{FREQUENCY} [Hz], {AMPLITUDE} [m/s^2], optionally {LEVEL}, {LAG} and {STD} "
                                f"[m/s^2]){closest(unknown, list(COLUMNS))}")
    repeated = next((name for name in names if names.count(name) > 1), None)
    if repeated:
        raise MeasurementsError(f"{where}: line {line}: column '{repeated}' given twice")
    if (FREQUENCY in names) == (ALIAS in names):
        raise MeasurementsError(f"{where}: line {line}: one frequency column, {FREQUENCY} or {ALIAS} [Hz]")
    if AMPLITUDE not in names:
        raise MeasurementsError(f"{where}: line {line}: no '{AMPLITUDE}' column (the slideway's normal "
                                "acceleration amplitude [m/s^2])")


class SweepModel:
    """The steady amplitude and lag at every frequency for rows of fitted values."""

    def __init__(self, sweep: Sweep, fixed: dict[str, Any], options: FitOptions) -> None:
        wrong = [name for name in options.fit if name not in EXCITER]
        if wrong:
            raise CalibrationError(f"--fit {wrong[0]}: a frequency sweep determines the exciter's data only "
                                   f"({', '.join(EXCITER)})")
        if sweep.drive_level is not None and LEVEL in fixed:
            raise CalibrationError(f"{LEVEL} is both a column of {sweep.source} and a fixed setting")
        clash = next((name for name in options.fit if name in fixed), None)
        if clash:
            raise CalibrationError(f"{clash} is both fitted and given: give a starting value with --start instead")
        self.sweep, self.options = sweep, options
        level = float(fixed.get(LEVEL, spec.DRIVE_LEVEL.default))
        self.level = sweep.drive_level if sweep.drive_level is not None else np.full(sweep.count, level)
        self.base = {name: float(fixed.get(name, spec.EXCITER[name].default)) for name in EXCITER}

    def exciter(self, xs: Floats) -> dict[str, Floats]:
        """Each exciter setting for each row of ``xs`` (a column vector each)."""
        values = {name: np.full((xs.shape[0], 1), value) for name, value in self.base.items()}
        for i, name in enumerate(self.options.fit):
            values[name] = xs[:, i:i + 1]
        return values

    def curves(self, xs: Floats) -> tuple[Floats, Floats]:
        """(amplitude [m/s^2], lag [deg]) at every frequency (columns) for each row of ``xs`` (rows)."""
        xs = np.atleast_2d(np.asarray(xs, dtype=float))
        e = self.exciter(xs)
        amplitude, lag = _steady(self.level[None, :], e["full_drive_acceleration"], self.sweep.frequency[None, :],
                                 e["natural_frequency"], e["damping_ratio"])
        return np.asarray(amplitude), np.degrees(lag)

    @property
    def reference(self) -> Floats:
        """A start read off the curve (see the module doc), the given values for the others."""
        s = self.sweep
        order = np.argsort(s.frequency, kind="stable")
        f, level = s.frequency[order], self.level[order]
        per_drive = np.where(level > 0.0, s.amplitude[order] / np.where(level > 0.0, level, 1.0), 0.0)
        peak = int(np.argmax(per_drive))
        guess = dict(self.base)
        guess["natural_frequency"] = _crossing(s.frequency, s.lag_deg) if s.lag_deg is not None else float(f[peak])
        guess["full_drive_acceleration"] = float(per_drive[peak])
        half = np.nonzero(per_drive >= per_drive[peak] / math.sqrt(2.0))[0]
        if half.size > 1 and half.min() > 0 and half.max() < s.count - 1:  # both half-power points inside
            guess["damping_ratio"] = float(f[half.max()] - f[half.min()]) / (2.0 * float(f[peak]))
        return np.array([min(max(guess[name], spec.EXCITER[name].low or 0.0), spec.EXCITER[name].high or math.inf)
                         for name in self.options.fit])


def _crossing(frequency: Floats, lag: Floats) -> float:
    """Where the lag crosses 90 degrees (resonance), linearly between the sweep's
    frequencies; the frequency nearest to 90 degrees where it does not."""
    order = np.argsort(frequency)
    f, g = frequency[order], lag[order] - 90.0
    above = np.nonzero((g[:-1] <= 0.0) & (g[1:] > 0.0))[0]
    if above.size:
        k = int(above[0])
        return float(f[k] + (f[k + 1] - f[k]) * (-g[k]) / (g[k + 1] - g[k]))
    return float(f[int(np.argmin(np.abs(g)))])


@dataclass(frozen=True)
class SweepCalibration:
    """The exciter fitted to a sweep: the estimates, their correlation and
    profiles, the fitted curve at the measured frequencies, the calibrated plant
    (resonant), the deviations used (``known``: given or estimated in a first
    pass) and the lag's scatter estimated (0 without lags)."""

    sweep: Sweep
    estimates: tuple[Estimate, ...]
    correlation: Floats
    profiles: tuple[Profile, ...]
    fitted_amplitude: Floats
    fitted_lag: Floats
    params: SliderParams
    known_deviations: bool
    degrees_of_freedom: int
    lag_noise: float
    evaluations: int
    seconds: float
    notes: tuple[str, ...] = ()

    def parameters_file(self) -> str:
        """The calibrated (resonant) plant as a ROS 2 parameters file, with the fit's uncertainty."""
        return parameters_file(self.params, self.estimates, self.sweep.source, self.correlation,
                               quantile(self.known_deviations, self.degrees_of_freedom))

    def summary(self) -> list[str]:
        """The estimates and how well the curve is met, as lines of text."""
        s = self.sweep
        origin = (f"the std column and the lags' scatter ({self.lag_noise:.3g} deg, estimated)"
                  if s.lag_deg is not None and s.std is not None else
                  f"the amplitudes' and the lags' scatter (lags {self.lag_noise:.3g} deg), estimated"
                  if s.lag_deg is not None else "the std column (known deviations, z intervals)"
                  if self.known_deviations else
                  f"the residuals' scatter ({self.degrees_of_freedom} degrees of freedom, t intervals)")
        residual = s.amplitude - self.fitted_amplitude
        return [f"exciter calibrated from {s.count} frequencies of {s.source} in {self.seconds:.2f} s "
                f"({self.evaluations} evaluations); uncertainty from {origin}", *self.notes,
                *estimate_lines(self.estimates, self.correlation),
                f"amplitude residual RMS {scatter(residual):.3g} m/s^2 of a largest "
                f"{float(np.max(s.amplitude)):.4g} m/s^2"]


def calibrate_sweep(sweep: Sweep, fixed: dict[str, Any], options: FitOptions) -> SweepCalibration:
    """Fit ``options.fit`` (of f_n, zeta, A) to the sweep (see the module doc)."""
    started = time.perf_counter()
    model = SweepModel(sweep, fixed, options)
    n = sweep.count * (2 if sweep.lag_deg is not None else 1)
    p = len(options.fit)
    known = sweep.std is not None or sweep.lag_deg is not None
    if n < p or (n == p and sweep.std is None):
        raise CalibrationError(f"{sweep.count} frequencies cannot determine {p} parameters ({', '.join(options.fit)})")
    dof = n - p
    amplitude_scale = sweep.std if sweep.std is not None else np.full(sweep.count, size(sweep.amplitude))

    def problem_in(lag_scale: float) -> Problem:
        def residuals(xs: Floats) -> Floats:
            amplitude, lag = model.curves(xs)
            rows = (amplitude - sweep.amplitude[None, :]) / amplitude_scale[None, :]
            if sweep.lag_deg is None:
                return np.asarray(rows)
            return np.hstack([rows, (lag - sweep.lag_deg[None, :]) / lag_scale])
        return Problem(options.fit, residuals, lambda x: "the curve does not change at " + ", ".join(
            f"{name} = {value:.6g}" for name, value in zip(options.fit, x)), subject="frequency's amplitude",
            screen=SCREEN)

    lag_noise = 0.0
    problem = problem_in(size(sweep.lag_deg) if sweep.lag_deg is not None else 1.0)
    fitted = fit(problem, options, model.reference, visible(sweep.std is not None, dof))
    evaluations = fitted.evaluations
    if sweep.lag_deg is not None:  # the lags' deviation, and the amplitudes' where no column gives it, from pass 1
        amplitude, lag = model.curves(fitted.result.x)
        inflation = math.sqrt(n / dof)
        lag_noise = max(scatter(lag[0] - sweep.lag_deg) * inflation, 1e-12)
        if sweep.std is None:
            amplitude_scale = np.full(sweep.count, max(scatter(amplitude[0] - sweep.amplitude) * inflation,
                                                       1e-15 * size(sweep.amplitude)))
        problem = problem_in(lag_noise)
        again = dataclasses.replace(options, starts=1, start_points=(dict(zip(options.fit, map(float,
                                                                                              fitted.result.x))),))
        fitted = fit(problem, again, fitted.result.x, visible(True, dof))
        evaluations += fitted.evaluations
    found = uncertainty(problem, fitted.result, options, known, dof)
    amplitude, lag = model.curves(fitted.result.x)
    check_finite(found.estimates, amplitude)
    exciter = {name: float(values[0, 0]) for name, values in model.exciter(np.atleast_2d(fitted.result.x)).items()}
    plant = {name: value for name, value in fixed.items() if name in spec.PLANT}
    params = plant_from({**plant, **exciter, "actuator": "resonant"})[0]
    return SweepCalibration(sweep, found.estimates, found.correlation, found.profiles, amplitude[0], lag[0], params,
                            known, dof, lag_noise, evaluations, time.perf_counter() - started, fitted.notes)


__all__ = ["COLUMNS", "EXCITER", "SCREEN", "Sweep", "SweepCalibration", "SweepModel", "calibrate_sweep", "is_sweep",
           "read_sweep"]
