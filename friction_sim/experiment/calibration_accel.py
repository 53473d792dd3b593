"""The exciter from a recording's accelerometer (``friction-sim calibrate run.mcap --fit natural_frequency,...``).

A recording made with the slider's accelerometer on (``accelerometer_rate``)
holds the slideway's acceleration at every k/rate (sensor_msgs/Imu, the track
frame: z is the normal acceleration q'' plus g*cos(alpha) and the bias), and
every drive change in force (drive level, drive frequency, a parameter set).
Between two changes the drive is a plateau; at a change the slideway's q and q'
are continuous and its motion is the new steady response plus a transient that
decays as exp(-zeta*omega_n*t) at the damped frequency
(:mod:`~friction_sim.core.physics.exciter`).

**What is fitted: every reading, the transient included.**  The exciter is a
linear oscillator whose motion is known in closed form from the drive in force,
so the readings are predicted exactly for given (f_n, zeta, A): the slideway is
followed across the recorded changes with the exciter's own rules
(:func:`~friction_sim.core.physics.exciter.followed`, the slider's), the drive
phase continuous from 0 at t = 0, and the fit minimizes the differences at
every reading.  That is exact (a noise-free recording of the simulator gives
its values back to rounding) and uses all the information: the steady
amplitude and lag of each plateau, and the transient after each change, whose
decay rate and frequency are zeta*omega_n and omega_d.  So one drive step
already determines all three, which a fit of the plateaus' steady amplitudes
alone (demodulated after the transient, as in a sweep) could not: at one
frequency those give u*A*G and the lag only, two numbers.  A recording whose
drive never changes (one plateau, steady from the start: a slider starts on a
running feeder) determines at most two, and is refused for three.

**Noise.**  With white noise on the readings whose standard deviation the
recording states (the Imu covariance, the slider's ``accelerometer_noise``),
the deviations are known (z intervals, chi2 profiles); else they are estimated
from the residuals' scatter (t intervals, the F form).  The intervals are
profile likelihood's beside the linearized ones, as for operating points.
Gravity's share and the bias are the recording's (known) values.

**Starts.**  The cost is many-valleyed in f_n (the transient oscillates), so the
starts are read off the data: each plateau's steady amplitude and lag by a
least-squares sinusoid at the drive frequency over its second half (the
transient mostly gone), and, from the plateau with the largest amplitude per
drive, for each zeta on a log grid over its range the f_n that gives its lag
(r^2 + 2 zeta cot(lag) r - 1 = 0) and the A that gives its amplitude.  Those
are screened at once on the whole cost; the best are the drawn starts (after
the user's ``--start`` points).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from friction_sim.core.model import spec
from friction_sim.core.model.commands import RESET, apply
from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.model.params import SliderParams, plant_from
from friction_sim.core.physics.exciter import Slideway, eigenvalue, followed, steady_response, steady_slideway
from friction_sim.errors import ParameterError
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
from friction_sim.experiment.calibration_fit import CalibrationError, Floats, scatter, size, words
from friction_sim.experiment.calibration_sweep import EXCITER
from friction_sim.experiment.verify import RecordedRun
from friction_sim.io.messages import ACCELEROMETER, NS_PER_S
from friction_sim.io.reader import Recording

#: Damping ratios of the starts read off the data (log grid over zeta's range), screened at once.
START_GRID = 48


@dataclass(frozen=True)
class Readings:
    """A recording's accelerometer: the sample times k/rate [s], the slideway's
    normal acceleration q'' read there [m/s^2] (the z reading less gravity's
    share and the bias) and the readings' stated noise [m/s^2] (0: not stated)."""

    t: Floats
    normal: Floats
    noise: float

    @property
    def count(self) -> int:
        return int(self.t.size)


def accelerometer_readings(recording: Recording, initial: dict[str, Any]) -> Readings:
    """The accelerometer's readings of ``recording`` (``initial``: its initial
    values, the rate, bias and geometry); a CalibrationError if it has none."""
    topic = recording.topic_name(ACCELEROMETER)
    rate = float(initial.get("accelerometer_rate", 0.0) or 0.0)
    if topic is None or recording.count(topic) == 0 or rate <= 0.0:
        raise CalibrationError(f"{recording.path}: no accelerometer readings (record with accelerometer_rate > 0) "
                               "to fit the exciter to")
    stamps, normal, variance = [], [], 0.0
    for _, message in recording.iter_decoded(topic):
        stamps.append(message.header.stamp.sec * NS_PER_S + message.header.stamp.nanosec)
        normal.append(message.linear_acceleration.z)
        variance = max(variance, float(message.linear_acceleration_covariance[8]))
    ns = np.asarray(stamps, dtype=np.int64)
    k = np.rint(ns * (rate / NS_PER_S))  # the grid point of each stamp (stamps are k/rate to the nanosecond)
    t = k / rate
    order = np.argsort(t, kind="stable")
    params = plant_from(initial)[0]
    offset = params.gravity * math.cos(math.radians(params.track_inclination)) + float(
        initial.get("accelerometer_bias", 0.0))
    return Readings(t[order], np.asarray(normal, dtype=float)[order] - offset, math.sqrt(variance))


@dataclass(frozen=True)
class Plateau:
    """The drive from ``t`` [s] on: drive level, drive frequency [Hz] and the
    exciter's data in force (f_n [Hz], zeta, A [m/s^2])."""

    t: float
    drive_level: float
    frequency: float
    exciter: tuple[float, float, float]


def plateaus(run: RecordedRun, fitted: tuple[str, ...]) -> list[Plateau]:
    """The drive in force across ``run``: its initial values, then each recorded
    command that changes the drive or the exciter's data (a command that changes
    nothing starts no plateau).  Refused: a reset (the slideway restarts with the
    part), an actuator that is not resonant, a fitted parameter the run changes."""
    try:
        params, inputs = plant_from(run.initial)
    except ParameterError as error:
        raise CalibrationError(f"{run.path}: {error}") from None

    def plateau(t: float, p: SliderParams, u: float, f: float) -> Plateau:
        if p.actuator != "resonant":
            raise CalibrationError(f"{run.path}: the actuator is {p.actuator} at t = {t:.6g} s: the exciter's "
                                   "data are fitted to a resonant actuator's readings")
        return Plateau(t, u, f, (p.natural_frequency, p.damping_ratio, p.full_drive_acceleration))

    found = [plateau(0.0, params, inputs.drive_level, inputs.excitation_frequency)]
    for command in run.commands:
        if command.name == RESET:
            raise CalibrationError(f"{run.path}: a reset at t = {command.t:.6g} s: the exciter is fitted to a run "
                                   "without one")
        try:
            params, inputs = apply(command, params, inputs)
        except ParameterError:
            continue  # (the slider refused it too: it is not in force)
        new = plateau(command.t, params, inputs.drive_level, inputs.excitation_frequency)
        last = found[-1]
        changed = [name for name, a, b in zip(EXCITER, last.exciter, new.exciter) if a != b and name in fitted]
        if changed:
            raise CalibrationError(f"{run.path}: the recording changes {', '.join(changed)} at t = "
                                   f"{command.t:.6g} s: it has no one value of it to fit")
        if (new.drive_level, new.frequency, new.exciter) != (last.drive_level, last.frequency, last.exciter):
            found.append(new)
    return found


class ReadingsModel:
    """The normal acceleration at every reading for rows of fitted values (see the module doc)."""

    def __init__(self, run: RecordedRun, readings: Readings, options: FitOptions) -> None:
        wrong = [name for name in options.fit if name not in EXCITER]
        if wrong:
            raise CalibrationError(f"--fit {wrong[0]}: an accelerometer's readings determine the exciter's data "
                                   f"only ({', '.join(EXCITER)}); fit the plant to the trajectory separately")
        self.names = options.fit
        self.readings = readings
        self.plateaus = plateaus(run, options.fit)
        if len(self.plateaus) == 1 and len(options.fit) == len(EXCITER):
            raise CalibrationError(f"{run.path}: one plateau (the drive never changes): its steady amplitude and "
                                   f"lag cannot determine {', '.join(options.fit)}; record a drive level or "
                                   "frequency step")
        starts = np.array([p.t for p in self.plateaus])
        self.bounds = np.searchsorted(readings.t, starts, side="right")  # a reading at a change is before it
        self.bounds[0] = 0

    def exciter(self, plateau: Plateau, x: Floats) -> tuple[float, float, float]:
        """(f_n, zeta, A) on ``plateau``, the fitted ones from ``x``."""
        values = dict(zip(EXCITER, plateau.exciter))
        values.update(zip(self.names, (float(v) for v in x)))
        return values["natural_frequency"], values["damping_ratio"], values["full_drive_acceleration"]

    def normal(self, x: Floats) -> Floats:
        """q'' at every reading for the fitted values ``x``."""
        t = self.readings.t
        out = np.empty(t.size)
        way: Slideway | None = None
        theta = t_start = 0.0
        for k, plateau in enumerate(self.plateaus):
            f_n, zeta, full = self.exciter(plateau, x)
            amplitude, lag = steady_response(plateau.drive_level, full, plateau.frequency, f_n, zeta)
            omega, lam = TWO_PI * plateau.frequency, eigenvalue(f_n, zeta)
            if way is None:
                way = steady_slideway(amplitude, lag, omega, lam)
            else:
                tau = plateau.t - t_start
                theta += way.omega * tau  # the drive phase is continuous
                way = followed(way, theta, tau, amplitude, lag, omega, lam)
                t_start = plateau.t
            end = self.bounds[k + 1] if k + 1 < len(self.plateaus) else t.size
            tau_s = t[self.bounds[k]:end] - t_start
            values = -way.amplitude * np.sin(theta + way.omega * tau_s - way.lag)
            if way.d != 0j:
                values += (way.lam * way.lam * way.d * np.exp(way.lam * tau_s)).real
            out[self.bounds[k]:end] = values
        return out

    def rows(self, xs: Floats) -> Floats:
        return np.array([self.normal(x) for x in np.atleast_2d(xs)])

    def steady(self) -> list[tuple[Plateau, float, float]]:
        """Each plateau's steady amplitude [m/s^2] and lag [rad] read off its second
        half by a least-squares sinusoid at the drive frequency (NaN: under a period)."""
        t, normal = self.readings.t, self.readings.normal
        found = []
        theta = 0.0
        for k, plateau in enumerate(self.plateaus):
            end_t = self.plateaus[k + 1].t if k + 1 < len(self.plateaus) else (t[-1] if t.size else plateau.t)
            mid = 0.5 * (plateau.t + end_t)
            chosen = (t >= mid) & (t <= end_t)
            phase = theta + TWO_PI * plateau.frequency * (t[chosen] - plateau.t)
            theta += TWO_PI * plateau.frequency * (end_t - plateau.t)
            if (end_t - mid) * plateau.frequency < 1.0 or np.count_nonzero(chosen) < 4:
                found.append((plateau, math.nan, math.nan))
                continue
            basis = np.column_stack([np.sin(phase), np.cos(phase), np.ones(phase.size)])
            (p, q, _), *_ = np.linalg.lstsq(basis, normal[chosen], rcond=None)
            found.append((plateau, math.hypot(p, q), math.atan2(q, -p)))  # -a sin(theta - lag)
        return found

    def read_off(self) -> Floats:
        """Starts consistent with the steadiest plateau's amplitude and lag, one per zeta of a log grid."""
        usable = [(p, a, lag) for p, a, lag in self.steady() if math.isfinite(a) and p.drive_level > 0.0 and a > 0.0]
        if not usable:
            return np.zeros((0, len(self.names)))
        plateau, amplitude, lag = max(usable, key=lambda item: item[1] / item[0].drive_level)
        low, high = spec.DAMPING_RATIO.low or 1e-4, spec.DAMPING_RATIO.high or 0.7
        rows = []
        for zeta in np.geomspace(low, high, START_GRID):
            cot = math.cos(lag) / max(math.sin(lag), 1e-12)
            r = -zeta * cot + math.hypot(zeta * cot, 1.0)
            f_n = plateau.frequency / r
            gain = steady_response(1.0, 1.0, plateau.frequency, f_n, zeta)[0]
            values = {"natural_frequency": f_n, "damping_ratio": float(zeta),
                      "full_drive_acceleration": amplitude / (plateau.drive_level * gain)}
            rows.append([values[name] for name in self.names])
        x = np.array(rows)
        lows = np.array([spec.EXCITER[name].low or 0.0 for name in self.names])
        highs = np.array([spec.EXCITER[name].high or math.inf for name in self.names])
        return np.clip(x, lows, highs)


@dataclass(frozen=True)
class ReadingsCalibration:
    """The exciter fitted to a recording's accelerometer: the estimates, their
    correlation and profiles, the fitted normal acceleration at every reading,
    the calibrated (resonant) plant, whether the deviations were known (the
    recording states the noise) and the noise estimated from the residuals."""

    path: str
    readings: Readings
    plateau_count: int
    estimates: tuple[Estimate, ...]
    correlation: Floats
    profiles: tuple[Profile, ...]
    fitted: Floats
    params: SliderParams
    known_deviations: bool
    degrees_of_freedom: int
    noise: float
    evaluations: int
    seconds: float
    notes: tuple[str, ...] = ()

    def parameters_file(self) -> str:
        """The calibrated plant as a ROS 2 parameters file, with the fit's uncertainty."""
        return parameters_file(self.params, self.estimates, self.path, self.correlation,
                               quantile(self.known_deviations, self.degrees_of_freedom))

    def summary(self) -> list[str]:
        """The estimates and how well the readings are met, as lines of text."""
        origin = (f"the recorded noise ({self.readings.noise:.3g} m/s^2, known deviations, z intervals)"
                  if self.known_deviations else
                  f"the residuals' scatter ({self.degrees_of_freedom} degrees of freedom, t intervals)")
        return [f"exciter calibrated from {self.readings.count} accelerometer readings over {self.plateau_count} "
                f"drive plateaus of {self.path} in {self.seconds:.2f} s ({self.evaluations} evaluations); "
                f"uncertainty from {origin}", *self.notes, *estimate_lines(self.estimates, self.correlation),
                f"normal acceleration residual RMS {self.noise:.3g} m/s^2 of a largest "
                f"{float(np.max(np.abs(self.readings.normal))):.4g} m/s^2"]


def calibrate_readings(run: RecordedRun, readings: Readings, options: FitOptions) -> ReadingsCalibration:
    """Fit ``options.fit`` (of f_n, zeta, A) to the accelerometer's readings (see the module doc)."""
    started = time.perf_counter()
    model = ReadingsModel(run, readings, options)
    n, p = readings.count, len(options.fit)
    known = readings.noise > 0.0
    if n <= p:
        raise CalibrationError(f"{run.path}: {n} accelerometer readings cannot determine {p} parameters")
    dof = n - p
    scale = readings.noise if known else size(readings.normal)
    problem = Problem(options.fit, lambda xs: (model.rows(xs) - readings.normal[None, :]) / scale,
                      lambda x: "the readings do not change at " + words(options.fit, x),
                      subject="accelerometer reading")
    candidates = model.read_off()
    reference = np.array([float(spec.EXCITER[name].default) for name in options.fit])
    if candidates.shape[0]:
        cost = np.sum(problem.residuals(candidates) ** 2, axis=1)
        ranked = candidates[np.argsort(np.where(np.isfinite(cost), cost, np.inf), kind="stable")]
        reference = ranked[0]
        drawn = tuple(dict(zip(options.fit, map(float, row))) for row in ranked[:options.starts])
        options = dataclasses.replace(options, start_points=(*options.start_points, *drawn)[
            :max(options.starts, len(options.start_points))])
    fitted = fit(problem, options, reference, visible(known, dof))
    found = uncertainty(problem, fitted.result, options, known, dof)
    normal = model.normal(fitted.result.x)
    check_finite(found.estimates, normal)
    values = {**run.initial, **dict(zip(options.fit, map(float, fitted.result.x)))}
    params = plant_from({name: value for name, value in values.items() if name in spec.PLANT})[0]
    return ReadingsCalibration(run.path, readings, len(model.plateaus), found.estimates, found.correlation,
                               found.profiles, normal, params, known, dof, scatter(normal - readings.normal),
                               fitted.evaluations + candidates.shape[0], time.perf_counter() - started,
                               fitted.notes)


def fits_exciter(names: tuple[str, ...]) -> bool:
    """Whether a recording's fit is the exciter's to the accelerometer (every fitted name an exciter datum)."""
    return all(name in EXCITER for name in names)


__all__ = ["START_GRID", "Plateau", "Readings", "ReadingsCalibration", "ReadingsModel",
           "accelerometer_readings", "calibrate_readings", "fits_exciter", "plateaus"]
