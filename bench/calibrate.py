"""Benchmark of calibration (issues 22 and 31): how long ``friction-sim calibrate``
takes for 5, 12, 20 and 100 measured points, fitting mu and mu_s/mu together
with the command's defaults (4 starts screened from drawn ones, 100 + 100
periods per point, profile-likelihood intervals included; issue 31's target:
12 points in under 2 s), and the exciter (f_n, zeta, A) from a 40-point
frequency sweep with 2 % noise (target: under 1 s), and from a recording's
accelerometer (1201 readings over a drive and a frequency step, 2 % noise).

The points are synthetic (the exact model at mu = 0.12, mu_s/mu = 1.3 over drive
forces 0.6-1.0 N and amplitudes 4-8 N, plus 1 % seeded noise, given as std).  A
fit costs a number of model evaluations (parameter sets; a Jacobian's are one
population-engine run with its point, the profile's re-fits one run per step
for all of them); the baseline measured in the same run is one run over the
points, so the figures to compare between machines are the ratios.  Timings are medians
of a few fits.  Prints figures only: a benchmark never passes or fails on timing.

Run: make bench   (or .venv/bin/python bench/calibrate.py [--repeats 3])
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from friction_sim.core.engine.population import run_batch
from friction_sim.core.model import spec
from friction_sim.core.model.commands import Command
from friction_sim.core.physics.exciter import steady_response
from friction_sim.experiment.calibration import FitOptions, calibrate
from friction_sim.experiment.calibration_accel import Readings, ReadingsModel, calibrate_readings
from friction_sim.experiment.calibration_points import ONE_THREAD_BELOW
from friction_sim.experiment.calibration_sweep import Sweep, calibrate_sweep
from friction_sim.experiment.measurements import Measurements
from friction_sim.experiment.verify import RecordedRun

from _timing import median_time

TRUTH = {"mu": 0.12, "static_ratio": 1.3}
WINDOW = {"settle_periods": 100, "periods": 100}


def synthetic(count: int) -> Measurements:
    """``count`` operating points spread over drive force and amplitude, with 1 % noise."""
    rng = np.random.default_rng(count)
    amplitude = rng.uniform(4.0, 8.0, count)
    drive = rng.uniform(0.6, 1.0, count)
    values: dict[str, Any] = {name: s.default for name, s in {**spec.PLANT, **spec.INPUTS}.items()}
    values.update(TRUTH, excitation_amplitude=amplitude, drive_force=drive)
    speed = np.asarray(run_batch(values, **WINDOW).mean_velocity)
    sigma = 0.01 * float(np.max(speed))
    return Measurements({"excitation_amplitude": amplitude, "drive_force": drive},
                        speed + rng.normal(0.0, sigma, count), np.full(count, sigma), f"{count} synthetic points")


def main() -> int:
    parser = argparse.ArgumentParser(description="calibration fit time for 5, 20 and 100 points")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    options = FitOptions(fit=("mu", "static_ratio"), **WINDOW)
    print("bench/calibrate.py  fit mu and static_ratio, 4 starts, 100 + 100 periods per point, profile intervals")
    print(f"{'points':>6} {'fit [s]':>9} {'evaluations':>12} {'one evaluation [ms]':>20} {'fit / evaluation':>17}"
          f"   estimates")
    for count in (5, 12, 20, 100):
        measurements = synthetic(count)
        model_values: dict[str, Any] = {name: s.default for name, s in {**spec.PLANT, **spec.INPUTS}.items()}
        model_values.update(TRUTH, **{k: v for k, v in measurements.settings.items()})
        threads = 1 if count < ONE_THREAD_BELOW else None  # as the fit runs one evaluation
        run_batch(model_values, **WINDOW, threads=threads)  # compiled already: the first call of this size pays no more
        evaluation = median_time(
            lambda values=model_values, threads=threads: run_batch(values, **WINDOW, threads=threads), 5)
        result = calibrate(measurements, {}, options)
        fit = median_time(lambda points=measurements: calibrate(points, {}, options), args.repeats)
        words = ", ".join(f"{e.name} {e.value:.5g} +- {e.std_error:.2g}" for e in result.estimates)
        print(f"{count:>6} {fit:>9.3f} {result.evaluations:>12} {evaluation * 1e3:>20.2f} "
              f"{fit / evaluation:>17.0f}   {words}")
    sweep = noisy_sweep(40)
    calibrate_sweep(sweep, {}, EXCITER_OPTIONS)
    seconds = median_time(lambda: calibrate_sweep(sweep, {}, EXCITER_OPTIONS), args.repeats)
    result = calibrate_sweep(sweep, {}, EXCITER_OPTIONS)
    words = ", ".join(f"{e.name} {e.value:.5g} +- {e.std_error:.2g}" for e in result.estimates)
    print(f"exciter from a 40-point sweep (f_n, zeta, A; 4 starts, profile intervals): {seconds:.3f} s, "
          f"{result.evaluations} evaluations   {words}")
    recorded = recorded_readings()
    options = FitOptions(fit=EXCITER_OPTIONS.fit)
    calibrate_readings(*recorded, options)
    seconds = median_time(lambda: calibrate_readings(*recorded, options), args.repeats)
    result_r = calibrate_readings(*recorded, options)
    words = ", ".join(f"{e.name} {e.value:.5g} +- {e.std_error:.2g}" for e in result_r.estimates)
    print(f"exciter from a recording's accelerometer ({recorded[1].count} readings, a drive and a frequency step, "
          f"2 % noise; profile intervals): {seconds:.3f} s, {result_r.evaluations} evaluations   {words}")
    print(f"(measured {time.strftime('%Y-%m-%d %H:%M')}; the machine is shared: compare the ratios)")
    return 0


EXCITER_OPTIONS = FitOptions(fit=("natural_frequency", "damping_ratio", "full_drive_acceleration"))


def noisy_sweep(count: int) -> Sweep:
    """A sweep of 44-60 Hz at drive level 0.5 of f_n 52 Hz, zeta 0.03, A 12 m/s^2, 2 % noise, given as std."""
    frequency = np.linspace(44.0, 60.0, count)
    amplitude = np.array([steady_response(0.5, 12.0, f, 52.0, 0.03)[0] for f in frequency])
    sigma = 0.02 * float(np.max(amplitude))
    noisy = amplitude + np.random.default_rng(count).normal(0.0, sigma, count)
    return Sweep(frequency, np.full(count, 0.5), noisy, None, np.full(count, sigma), f"{count}-point sweep")


def recorded_readings() -> tuple[RecordedRun, Readings]:
    """A 1.2 s run at 1 kHz of f_n 52 Hz, zeta 0.05, A 20 m/s^2: drive level 0.5 -> 0.8 at
    0.4 s, 50 -> 55 Hz at 0.8 s, the readings the exact exciter gives plus 0.2 m/s^2 of
    stated noise (what a lockstep recording with the accelerometer on holds; no ROS here)."""
    initial = {**{name: s.default for name, s in spec.PLANT.items()}, **{name: s.default for name, s in
                                                                         spec.INPUTS.items()},
               "actuator": "resonant", "natural_frequency": 52.0, "damping_ratio": 0.05,
               "full_drive_acceleration": 20.0, "drive_level": 0.5, "excitation_frequency": 50.0}
    commands = (Command(0.4, "drive_level", {"drive_level": 0.8}),
                Command(0.8, "excitation_frequency", {"excitation_frequency": 55.0}))
    empty = np.zeros(0, dtype=np.int64)
    run = RecordedRun("(synthetic run)", initial, commands, 1000.0, empty, np.zeros(0), empty, np.zeros(0))
    t = np.arange(1201) / 1000.0
    exact = Readings(t, np.zeros(t.size), 0.2)
    truth = ReadingsModel(run, exact, FitOptions(fit=EXCITER_OPTIONS.fit)).normal(np.array([52.0, 0.05, 20.0]))
    return run, Readings(t, truth + np.random.default_rng(1).normal(0.0, 0.2, t.size), 0.2)


if __name__ == "__main__":
    sys.exit(main())
