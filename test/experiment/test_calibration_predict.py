"""Predictions with their uncertainty (issue 31, item 5): calibrated.yaml keeps
the fit's uncertainty beside the plant, ``friction-sim predict`` reads it and
gives the mean speed at the settings asked with a 95 % band.  The band's
coverage is test_calibration_coverage's."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from friction_sim.core.model.params import plant_from
from friction_sim.experiment.calibration import Calibration, CalibrationError, FitOptions, calibrate, quantile
from friction_sim.experiment.calibration_predict import predict, read_calibrated, uncertain_from
from friction_sim.experiment.measurements import read_measurements
from friction_sim.io.paramfile import read_params_file

BIN = Path(sys.executable).parent
EXAMPLE = Path(__file__).resolve().parents[2] / "config" / "calibration_example.csv"
WINDOW = {"settle_periods": 30, "periods": 30}


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Calibration]:
    """The shipped example's calibration (mu and mu_s/mu) and its calibrated.yaml."""
    result = calibrate(read_measurements(EXAMPLE), {}, FitOptions(fit=("mu", "static_ratio"), **WINDOW))
    path = tmp_path_factory.mktemp("calibrated") / "calibrated.yaml"
    path.write_text(result.parameters_file())
    return path, result


def test_calibrated_yaml_keeps_the_uncertainty_beside_a_plant_the_slider_reads(
        calibrated: tuple[Path, Calibration]) -> None:
    path, result = calibrated
    params = plant_from(read_params_file(path, "slider"))[0]
    assert params == result.params
    kept = read_calibrated(path)
    made = uncertain_from({}, result.estimates, result.correlation, quantile(True, result.degrees_of_freedom))
    assert kept.names == ("mu", "static_ratio")
    for name in ("estimate", "below", "above", "correlation"):
        assert np.array_equal(getattr(kept, name), getattr(made, name)), name
    assert kept.plant["mu"] == params.mu and np.all(kept.below > 0.0) and np.all(kept.above > 0.0)


def test_samples_keep_within_the_bounds_and_follow_the_correlation(calibrated: tuple[Path, Calibration]) -> None:
    kept = read_calibrated(calibrated[0])
    draws = kept.samples(20_000, seed=0)
    assert np.all(draws[:, 1] >= 1.0), "mu_s/mu below 1 is no plant"
    assert np.corrcoef(draws.T)[0, 1] == pytest.approx(kept.correlation[0, 1], abs=0.02)
    assert np.quantile(draws[:, 0], [0.025, 0.975]) == pytest.approx(
        [kept.estimate[0] - 1.96 * kept.below[0], kept.estimate[0] + 1.96 * kept.above[0]], rel=1e-3)


def test_a_calibrated_parameter_is_not_set_when_predicting(calibrated: tuple[Path, Calibration]) -> None:
    with pytest.raises(CalibrationError, match="mu is calibrated"):
        predict(read_calibrated(calibrated[0]), {"mu": 0.2}, **WINDOW)


def test_the_command_predicts_along_a_sweep_with_its_band(calibrated: tuple[Path, Calibration], tmp_path: Path) -> None:
    done = subprocess.run([str(BIN / "friction-sim"), "predict", str(calibrated[0]), "--set", "drive_force=0.9",
                           "--sweep", "excitation_amplitude=5:8:7", "--settle-periods", "30", "--periods", "30",
                           "--csv", str(tmp_path / "band.csv"), "--png", str(tmp_path / "band.png")],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "95 % band" in done.stdout and (tmp_path / "band.png").stat().st_size > 10_000
    rows = np.genfromtxt(tmp_path / "band.csv", delimiter=",", names=True)
    assert rows.size == 7 and np.all(rows["band_low"] <= rows["mean_speed"])
    assert np.all(rows["mean_speed"] <= rows["band_high"]) and np.all(np.diff(rows["mean_speed"]) > 0.0)
    bare = tmp_path / "bare.yaml"
    bare.write_text("/**:\n  ros__parameters:\n    mu: 0.1\n")
    refused = subprocess.run([str(BIN / "friction-sim"), "predict", str(bare)], capture_output=True, text=True,
                             timeout=120)
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1 and "no usable 'calibration'" in refused.stderr


def test_simulate_with_params_is_the_prediction(calibrated: tuple[Path, Calibration]) -> None:
    """``simulate --params calibrated.yaml --drive-force 0.9``: predict's answer at
    drive_force 0.9 (the flags that differ from their defaults are the settings),
    the same numbers as ``predict --set drive_force=0.9``; a fitted parameter's
    flag, --duration and --csv are refused in one line, exit 2."""
    import json

    def cli(*words: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([str(BIN / "friction-sim"), *words], capture_output=True, text=True, timeout=300)

    done = cli("simulate", "--params", str(calibrated[0]), "--drive-force", "0.9", "--json")
    assert done.returncode == 0, done.stderr
    answer = json.loads(done.stdout)
    expected = predict(read_calibrated(calibrated[0]), {"drive_force": 0.9})  # predict's defaults: 400 sets, 100 + 100
    assert answer["settings"] == {"drive_force": 0.9} and answer["fitted"] == ["mu", "static_ratio"]
    assert (answer["mean_velocity"], answer["band_low"], answer["band_high"]) == (
        float(expected.speed[0]), float(expected.low[0]), float(expected.high[0]))
    assert answer["band_low"] < answer["mean_velocity"] < answer["band_high"]
    table = cli("simulate", "--params", str(calibrated[0]), "--drive-force", "0.9")
    assert table.returncode == 0 and "95 % band" in table.stdout and f"{answer['mean_velocity']:.6g}" in table.stdout
    for words, said in ((("--mu", "0.2"), "mu is calibrated"), (("--duration", "3"), "does not apply with --params"),
                        (("--csv", "x.csv"), "does not apply with --params")):
        refused = cli("simulate", "--params", str(calibrated[0]), *words)
        assert refused.returncode == 2 and refused.stderr.count("\n") == 1 and said in refused.stderr, refused.stderr
