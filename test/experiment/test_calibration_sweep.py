"""The exciter from a frequency sweep (issue 31, item 4): f_n, zeta and A from a
technician's sweep of the drive frequency, exactly from an exact curve and with
honest intervals from a noisy one.  Curves come from the core's steady
response (:func:`friction_sim.core.physics.exciter.steady_response`) and from
``friction-sim resonance``'s CSV."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from friction_sim.core.meanspeed.tuning import tuning_curve
from friction_sim.core.model.params import Inputs, SliderParams, plant_from
from friction_sim.core.physics.exciter import steady_response
from friction_sim.experiment.calibration import CalibrationError, FitOptions
from friction_sim.experiment.calibration_sweep import Sweep, calibrate_sweep, read_sweep
from friction_sim.experiment.measurements import MeasurementsError
from friction_sim.io.export import write_tuning_csv
from friction_sim.io.paramfile import read_params_file

BIN = Path(sys.executable).parent
EXCITER = ("natural_frequency", "damping_ratio", "full_drive_acceleration")
TRUTH = {"natural_frequency": 52.0, "damping_ratio": 0.03, "full_drive_acceleration": 12.0}
LEVEL = 0.5
#: A 40-point sweep across the resonance, 44-60 Hz.
FREQUENCY = np.linspace(44.0, 60.0, 40)


def curve() -> tuple[np.ndarray, np.ndarray]:
    """The exact amplitude [m/s^2] and lag [deg] of the sweep."""
    amplitude, lag = np.array([steady_response(LEVEL, TRUTH["full_drive_acceleration"], f, TRUTH["natural_frequency"],
                                               TRUTH["damping_ratio"]) for f in FREQUENCY]).T
    return amplitude, np.degrees(lag)


@pytest.mark.parametrize("lags", [False, True])
def test_an_exact_curve_gives_back_fn_zeta_and_a_to_1e_9(lags: bool) -> None:
    amplitude, lag = curve()
    sweep = Sweep(FREQUENCY, None, amplitude, lag if lags else None, None, "exact")
    result = calibrate_sweep(sweep, {"drive_level": LEVEL}, FitOptions(fit=EXCITER))
    assert [e.value for e in result.estimates] == pytest.approx(list(TRUTH.values()), rel=1e-9)
    assert result.params.actuator == "resonant" and result.params.natural_frequency == pytest.approx(52.0, rel=1e-9)


def test_the_csv_friction_sim_resonance_writes_is_a_sweep(tmp_path: Path) -> None:
    """Its columns (drive_frequency, amplitude, lag_deg, mean_velocity,
    flight_fraction), the drive level a fixed setting: the exciter back to 1e-9."""
    params = SliderParams(actuator="resonant", **TRUTH)
    write_tuning_csv(tuning_curve(params, Inputs(drive_level=LEVEL), FREQUENCY, settle_periods=2, periods=2),
                     tmp_path / "tuning.csv")
    result = calibrate_sweep(read_sweep(tmp_path / "tuning.csv"), {"drive_level": LEVEL}, FitOptions(fit=EXCITER))
    assert [e.value for e in result.estimates] == pytest.approx(list(TRUTH.values()), rel=1e-9)


@pytest.mark.parametrize("given_std", [True, False])
def test_noisy_sweeps_intervals_cover_the_truth_in_90_to_99_percent_of_seeds(given_std: bool) -> None:
    """White noise of 2 % of the peak amplitude, 100 seeds (0-99, derandomized):
    each parameter's 95 % profile interval holds the truth in 90-99 of them,
    with the std column (z) and without it (the F/t form from the scatter)."""
    amplitude, _ = curve()
    sigma = 0.02 * float(np.max(amplitude))
    covered = dict.fromkeys(TRUTH, 0)
    for seed in range(100):
        noisy = amplitude + np.random.default_rng(seed).normal(0.0, sigma, amplitude.size)
        sweep = Sweep(FREQUENCY, np.full(FREQUENCY.size, LEVEL), noisy, None,
                      np.full(FREQUENCY.size, sigma) if given_std else None, f"seed {seed}")
        result = calibrate_sweep(sweep, {}, FitOptions(fit=EXCITER, starts=1))
        for e in result.estimates:
            covered[e.name] += e.profile_low <= TRUTH[e.name] <= e.profile_high
    assert all(90 <= count <= 99 for count in covered.values()), covered


@pytest.mark.parametrize(("text", "words"), [
    ("excitation_frequency,amplitud\n50,1\n", ("line 1", "unknown column 'amplitud'", "did you mean amplitude?")),
    ("excitation_frequency,drive_frequency,amplitude\n50,50,1\n", ("one frequency column",)),
    ("excitation_frequency,lag_deg\n50,90\n", ("no 'amplitude' column",)),
    ("excitation_frequency,amplitude,lag_deg\n50,1,190\n", ("line 2", "lag_deg = 190", "[0, 180] deg")),
    ("excitation_frequency,amplitude,std\n50,1,1e308\n", ("line 2", "std = 1e+308", "[1e-12, 1e+06] m/s^2")),
])
def test_a_bad_sweep_is_refused_with_its_file_line_and_reason(tmp_path: Path, text: str,
                                                             words: tuple[str, ...]) -> None:
    path = tmp_path / "sweep.csv"
    path.write_text(text)
    with pytest.raises(MeasurementsError) as caught:
        read_sweep(path)
    assert "\n" not in str(caught.value) and all(word in str(caught.value) for word in words), str(caught.value)


def test_a_sweep_determines_the_exciter_only() -> None:
    amplitude, _ = curve()
    with pytest.raises(CalibrationError, match="a frequency sweep determines the exciter's data only"):
        calibrate_sweep(Sweep(FREQUENCY, None, amplitude, None, None, "s"), {}, FitOptions(fit=("mu",)))


def test_the_command_fits_a_sweep_and_writes_a_resonant_plant(tmp_path: Path) -> None:
    amplitude, lag = curve()
    rows = ["excitation_frequency,drive_level,amplitude,lag_deg"] + [
        f"{f!r},{LEVEL!r},{a!r},{g!r}" for f, a, g in zip(FREQUENCY.tolist(), amplitude.tolist(), lag.tolist())]
    (tmp_path / "sweep.csv").write_text("\n".join(rows) + "\n")
    done = subprocess.run([str(BIN / "friction-sim"), "calibrate", str(tmp_path / "sweep.csv"), "--fit",
                           ",".join(EXCITER), "--output", str(tmp_path / "out")], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert "exciter calibrated from 40 frequencies" in done.stdout
    params = plant_from(read_params_file(tmp_path / "out" / "calibrated.yaml", "slider"))[0]
    assert params.actuator == "resonant"
    assert [getattr(params, name) for name in EXCITER] == pytest.approx(list(TRUTH.values()), rel=1e-9)
    for picture in ("calibration.png", "calibration_profile.png"):
        assert (tmp_path / "out" / picture).stat().st_size > 10_000
