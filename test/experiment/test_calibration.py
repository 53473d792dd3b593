"""``friction-sim calibrate`` (issue 22, items 1 and 3): the model fitted to
measured operating points, with honest uncertainty, and refused where the data
cannot determine it.  Synthetic measurements come from the exact core
(the population engine) at known parameters, plus seeded noise."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from friction_sim.core.engine.population import run_batch
from friction_sim.core.model import spec
from friction_sim.core.model.params import plant_from
from friction_sim.experiment.calibration import CalibrationError, FitOptions, calibrate
from friction_sim.experiment.measurements import Measurements, MeasurementsError, read_fixed, read_measurements
from friction_sim.experiment.scenario import parse_scenario
from friction_sim.experiment.sweep import materialize, parse_sweep
from friction_sim.io.paramfile import read_params_file

BIN = Path(sys.executable).parent
#: Averaging windows of the synthetic truth and of the fit: the same, so the model can meet the data exactly.
WINDOW = {"settle_periods": 50, "periods": 50}
TRUTH = {"mu": 0.12, "static_ratio": 1.3}
#: Operating points: Pa 5..8 N at Fd 0.7, 0.9 and 1.1 N (m = 1 kg, g = 10): every one moving.
AMPLITUDE, DRIVE = (grid.ravel() for grid in np.meshgrid(np.linspace(5.0, 8.0, 4), np.array([0.7, 0.9, 1.1])))


def speeds(**plant: Any) -> np.ndarray:
    """The exact mean speeds [m/s] of the operating points for ``plant``."""
    values: dict[str, Any] = {name: s.default for name, s in {**spec.PLANT, **spec.INPUTS}.items()}
    values.update(plant, excitation_amplitude=AMPLITUDE, drive_force=DRIVE)
    return np.asarray(run_batch(values, **WINDOW).mean_velocity)


def points(speed: np.ndarray, std: np.ndarray | None = None) -> Measurements:
    return Measurements({"excitation_amplitude": AMPLITUDE, "drive_force": DRIVE}, speed, std, "synthetic")


def test_without_noise_the_fit_returns_the_truth() -> None:
    """Two parameters from the defaults (mu 0.1, mu_s/mu 1): the truth to 1e-6
    relative (the issue's target; it comes back to about 1e-14)."""
    result = calibrate(points(speeds(**TRUTH)), {}, FitOptions(fit=("mu", "static_ratio"), **WINDOW))
    for estimate in result.estimates:
        assert estimate.value == pytest.approx(TRUTH[estimate.name], rel=1e-6)
    assert np.max(np.abs(result.residuals)) <= 1e-12 * np.max(speeds(**TRUTH))


@pytest.mark.parametrize(("name", "fixed"), [("mu", {"static_ratio": 1.3}), ("static_ratio", {"mu": 0.12})])
def test_the_95_percent_intervals_cover_the_truth_in_90_to_99_percent_of_seeds(name: str,
                                                                                fixed: dict[str, float]) -> None:
    """100 seeds of white noise, 2 % of the largest speed, given as std: the
    truth inside the 95 % interval in 90-99 % of them (binomial: 95 % +- 2.2 %
    for 100 seeds).  Joint (mu, mu_s/mu) linearized intervals are not covered
    that well: the two correlate strongly and nonlinearly over such points; their
    profile intervals are (test_calibration_coverage.py)."""
    truth = speeds(**TRUTH)
    sigma = 0.02 * float(np.max(truth))
    covered = 0
    for seed in range(100):
        noisy = truth + np.random.default_rng(seed).normal(0.0, sigma, truth.size)
        result = calibrate(points(noisy, np.full(truth.size, sigma)), fixed, FitOptions(fit=(name,), starts=1,
                                                                                      **WINDOW))
        (estimate,) = result.estimates
        covered += estimate.low <= TRUTH[name] <= estimate.high
    assert 90 <= covered <= 99, covered


def test_a_robust_loss_resists_an_outlier() -> None:
    truth = speeds(**TRUTH)
    sigma = 0.01 * float(np.max(truth))
    noisy = truth + np.random.default_rng(1).normal(0.0, sigma, truth.size)
    noisy[5] *= 3.0  # a mistimed run
    plain = calibrate(points(noisy, np.full(truth.size, sigma)), {"static_ratio": 1.3},
                      FitOptions(fit=("mu",), starts=1, **WINDOW))
    robust = calibrate(points(noisy, np.full(truth.size, sigma)), {"static_ratio": 1.3},
                       FitOptions(fit=("mu",), starts=1, loss="soft_l1", **WINDOW))
    assert abs(robust.estimates[0].value - 0.12) < abs(plain.estimates[0].value - 0.12)
    assert robust.estimates[0].low <= 0.12 <= robust.estimates[0].high


def test_each_kind_of_refusal_says_why_in_one_line() -> None:
    still = Measurements({"excitation_amplitude": np.array([0.5, 1.0, 1.5])}, np.zeros(3), None, "still.csv")
    with pytest.raises(CalibrationError, match=r"every point lies in the no-motion region.*mu not identifiable"):
        calibrate(still, {}, FitOptions(fit=("mu",), **WINDOW))
    one = Measurements({"excitation_amplitude": np.array([5.0])}, np.array([3e-4]), None, "one.csv")
    with pytest.raises(CalibrationError, match="1 points cannot determine 2 parameters"):
        calibrate(one, {}, FitOptions(fit=("mu", "static_ratio"), **WINDOW))
    only_amplitude = Measurements({"excitation_amplitude": AMPLITUDE[:4]}, speeds(**TRUTH)[:4], None, "a.csv")
    with pytest.raises(CalibrationError, match=r"mu and mass correlate [+-]0\.99\d\d.*cannot tell them apart"):
        calibrate(only_amplitude, {"drive_force": 0.7, "static_ratio": 1.3}, FitOptions(fit=("mu", "mass"), **WINDOW))
    with pytest.raises(CalibrationError, match="not a plant parameter"):
        FitOptions(fit=("friction",))
    with pytest.raises(CalibrationError, match="both fitted and given"):
        calibrate(points(speeds(**TRUTH)), {"mu": 0.1}, FitOptions(fit=("mu",), **WINDOW))


@pytest.mark.parametrize(("text", "words"), [
    ("excitation_amplitude,mean_speed\n5.0,0.0003\n6.0,fast\n", ("line 3", "mean_speed", "'fast'", "not a number")),
    ("excitation_amplitude,speed\n5.0,0.0003\n", ("line 1", "unknown column 'speed'")),
    ("excitation_amplitude\n5.0\n", ("line 1", "no 'mean_speed' column")),
    ("excitation_amplitude,mean_speed\n-5.0,0.0003\n", ("line 2", "excitation_amplitude = -5.0", "[0, 1e+06]")),
    ("excitation_amplitude,mean_speed,std\n5.0,0.0003,0\n", ("line 2", "std = 0", "[1e-12, 1000] m/s")),
    ("excitation_amplitude,mean_speed\n5.0,0.0003,1\n", ("line 2", "3 values, the header has 2")),
    ("throw_number,excitation_amplitude,mean_speed\n1,5,0.0003\n", ("excitation_amplitude is set by two columns",)),
    ("excitation_amplitude,mean_speed\n", ("no operating points",)),
])
def test_a_bad_csv_is_refused_with_its_file_line_and_reason(tmp_path: Path, text: str,
                                                             words: tuple[str, ...]) -> None:
    path = tmp_path / "points.csv"
    path.write_text(text)
    with pytest.raises(MeasurementsError) as caught:
        read_measurements(path)
    message = str(caught.value)
    assert message.startswith(str(path)) and "\n" not in message
    for word in words:
        assert word in message, message


def test_the_command_writes_a_plant_that_the_slider_scenarios_and_sweeps_read_as_it_is(tmp_path: Path) -> None:
    truth = speeds(**TRUTH)
    lines = ["excitation_amplitude,drive_force,mean_speed"] + [f"{float(a)!r},{float(d)!r},{float(v)!r}"
                                                               for a, d, v in zip(AMPLITUDE, DRIVE, truth)]
    (tmp_path / "points.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "fixed.yaml").write_text("static_ratio: 1.3\n")
    out = tmp_path / "out"
    done = subprocess.run([str(BIN / "friction-sim"), "calibrate", str(tmp_path / "points.csv"), "--fit", "mu",
                           "--fixed", str(tmp_path / "fixed.yaml"), "--settle-periods", "50", "--periods", "50",
                           "--output", str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "95 % linearized" in done.stdout and "residual" in done.stdout
    assert (out / "calibration.png").stat().st_size > 10_000 and (out / "residuals.csv").is_file()
    assert (out / "calibration_profile.png").stat().st_size > 10_000 and "95 % profile likelihood" in done.stdout
    values = read_params_file(out / "calibrated.yaml", "slider")  # the slider's --params reader
    params = plant_from(values)[0]
    assert params.mu == pytest.approx(0.12, rel=1e-6) and params.static_ratio == 1.3
    scenario = parse_scenario(f"duration: 1.0\nplant_params: {out / 'calibrated.yaml'}\n", "s.yaml")
    assert scenario.params == params
    sweep = parse_sweep(f"periods: 2\nplant_params: {out / 'calibrated.yaml'}\ngrid: {{drive_force: [0.5, 0.9]}}\n")
    columns = materialize(sweep, 0, sweep.size)
    assert np.all(columns["mu"] == params.mu) and np.all(columns["static_ratio"] == 1.3)
    assert list(columns["drive_force"]) == [0.5, 0.9], "the sweep's own sections still set what they set"


def test_fixed_settings_come_from_a_mapping_or_a_parameters_file_and_flags(tmp_path: Path) -> None:
    (tmp_path / "plain.yaml").write_text("mass: 0.02\nthrow_number: 1.5\n")
    (tmp_path / "ros.yaml").write_text("/**:\n  ros__parameters:\n    mass: 0.03\n    publish_rate: 500.0\n")
    assert read_fixed(tmp_path / "plain.yaml", ["mu=0.3"]) == {"mass": 0.02, "throw_number": 1.5, "mu": 0.3}
    assert read_fixed(tmp_path / "ros.yaml", []) == {"mass": 0.03}, "a node's other parameters are not the model's"
    with pytest.raises(MeasurementsError, match="mu = -1"):
        read_fixed(None, ["mu=-1"])


def test_the_shipped_example_loads_with_its_comment_lines_skipped() -> None:
    measurements = read_measurements(Path(__file__).resolve().parents[2] / "config" / "calibration_example.csv")
    assert measurements.count == 8 and set(measurements.settings) == {"excitation_amplitude", "drive_force"}
    assert measurements.std is not None and np.all(measurements.std == 2e-5)


# -- from a recording (issue 22, item 2) ------------------------------------------------------------------------

def _recorded(tmp_path: Path, **changes: Any) -> Any:
    """A recording of the simulator itself: a part that hops (Pa 12 -> 14 N at 80 degrees), mu 0.12, e 0.3."""
    from friction_sim.core.model.commands import Command
    from friction_sim.core.model.params import Inputs, SliderParams
    from friction_sim.experiment.offline import record_offline
    from friction_sim.experiment.verify import recorded_run
    from friction_sim.io.reader import read_recording

    schedule = [Command(0.5, "excitation_amplitude", {"excitation_amplitude": 14.0}), *changes.pop("schedule", [])]
    record_offline(tmp_path / "run.mcap", SliderParams(mu=0.12, restitution=0.3, excitation_angle=80.0),
                   Inputs(excitation_amplitude=12.0, drive_force=0.9), schedule, duration=1.0, log_rate=1000.0)
    return recorded_run(read_recording(tmp_path / "run.mcap"))


def test_a_recording_gives_back_its_parameters_with_intervals_that_hold_them(tmp_path: Path) -> None:
    """From the settings' defaults (mu 0.1, e 0), the commands in force read from
    the file: without noise the truth to 1e-6; with white noise on the recorded
    pose (1 um) and velocity (0.1 mm/s) the truth inside the 95 % intervals,
    linearized and profile likelihood, of each of 3 seeds, and the noise of each
    series estimated within 10 %."""
    import dataclasses

    from friction_sim.experiment.calibration_run import calibrate_run

    run = _recorded(tmp_path)
    options = FitOptions(fit=("mu", "restitution"), starts=2)
    exact = calibrate_run(run, options)
    assert [e.value for e in exact.estimates] == pytest.approx([0.12, 0.3], rel=1e-6)
    for seed in range(3):
        rng = np.random.default_rng(seed)
        noisy = dataclasses.replace(run, x=run.x + rng.normal(0.0, 1e-6, run.x.size),
                                    v=run.v + rng.normal(0.0, 1e-4, run.v.size))
        result = calibrate_run(noisy, options)
        for estimate, truth in zip(result.estimates, (0.12, 0.3)):
            assert estimate.low <= truth <= estimate.high, (seed, estimate)
            assert estimate.profile_low <= truth <= estimate.profile_high, (seed, estimate)  # profiled too
        assert [profile.name for profile in result.profiles] == ["mu", "restitution"]
        assert result.noise_x == pytest.approx(1e-6, rel=0.1) and result.noise_v == pytest.approx(1e-4, rel=0.1)


def test_a_recording_that_changes_a_fitted_parameter_is_refused(tmp_path: Path) -> None:
    from friction_sim.core.model.commands import PARAMETERS, Command
    from friction_sim.experiment.calibration_run import calibrate_run

    run = _recorded(tmp_path, schedule=[Command(0.7, PARAMETERS, {"mu": 0.2})])
    with pytest.raises(CalibrationError, match="changes mu during the run"):
        calibrate_run(run, FitOptions(fit=("mu",)))


def test_the_command_fits_a_recording(tmp_path: Path) -> None:
    _recorded(tmp_path)
    done = subprocess.run([str(BIN / "friction-sim"), "calibrate", str(tmp_path / "run.mcap"), "--fit", "mu",
                           "--starts", "1", "--output", str(tmp_path / "out")], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert "1001 positions and 1001 velocities" in done.stdout
    values = read_params_file(tmp_path / "out" / "calibrated.yaml", "slider")
    assert values["mu"] == pytest.approx(0.12, rel=1e-6) and values["restitution"] == 0.3
    assert (tmp_path / "out" / "calibration.png").stat().st_size > 10_000
    assert "95 % profile likelihood" in done.stdout and (tmp_path / "out" / "calibration_profile.png").is_file()
    refused = subprocess.run([str(BIN / "friction-sim"), "calibrate", str(tmp_path / "run.mcap"), "--fit", "mu",
                              "--set", "mass=2", "--output", str(tmp_path / "o2")], capture_output=True, text=True,
                             timeout=120)
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1 and "--set" in refused.stderr
