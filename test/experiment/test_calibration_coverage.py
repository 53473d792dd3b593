"""Honest intervals for correlated parameters (issue 31, items 2 and 5): mu and mu_s/mu
fitted together over the calibration issue's 12 operating points with 2 %
noise; the 95 % profile-likelihood intervals cover the truth in 90-99 % of 100
seeds (binomial: 95 % +- 2.2 % for 100 seeds): 92 and 94.  Derandomized: the
seeds are 0-99, the same every run.  The linearized intervals of the same fits
cover 86 and 85 (the calibration issue measured 69 and 68 with the fit of
then, which could stop at a kink of the model or be refused there).

The predictions of the same 100 calibrations at settings inside, at the edge
of and beyond the measured ones hold the true speed inside their 95 % bands
in 90-99 % of them too.

The 100 fits are made once for the module (each starts at the truth: the
question here is the interval, not the search, which test_calibration_starts
asks from the defaults)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from friction_sim.core.engine.population import run_batch
from friction_sim.core.model import spec
from friction_sim.experiment.calibration import Calibration, FitOptions, calibrate, quantile
from friction_sim.experiment.calibration_predict import predict, uncertain_from
from friction_sim.experiment.measurements import Measurements

#: Averaging windows of the synthetic truth and of the fit: the same, so the model can meet the data exactly.
WINDOW = {"settle_periods": 50, "periods": 50}
TRUTH = {"mu": 0.12, "static_ratio": 1.3}
#: The calibration issue's operating points: Pa 5..8 N at Fd 0.7, 0.9 and 1.1 N (m = 1 kg, g = 10).
AMPLITUDE, DRIVE = (grid.ravel() for grid in np.meshgrid(np.linspace(5.0, 8.0, 4), np.array([0.7, 0.9, 1.1])))
SEEDS = range(100)


def speeds(**plant: Any) -> np.ndarray:
    values: dict[str, Any] = {name: s.default for name, s in {**spec.PLANT, **spec.INPUTS}.items()}
    values.update(plant, excitation_amplitude=AMPLITUDE, drive_force=DRIVE)
    return np.asarray(run_batch(values, **WINDOW).mean_velocity)


@pytest.fixture(scope="module")
def joint_fits() -> list[Calibration]:
    """mu and mu_s/mu fitted to 100 noisy copies of the truth (2 % of the largest speed, given as std)."""
    truth = speeds(**TRUTH)
    sigma = 0.02 * float(np.max(truth))
    options = FitOptions(fit=("mu", "static_ratio"), starts=1, start_points=(dict(TRUTH),), **WINDOW)
    fits = []
    for seed in SEEDS:
        noisy = truth + np.random.default_rng(seed).normal(0.0, sigma, truth.size)
        fits.append(calibrate(Measurements({"excitation_amplitude": AMPLITUDE, "drive_force": DRIVE}, noisy,
                                           np.full(truth.size, sigma), f"seed {seed}"), {}, options))
    return fits


def coverage(fits: list[Calibration]) -> dict[str, tuple[int, int]]:
    """Per parameter: how many profile and how many linearized intervals hold the truth."""
    counts = {}
    for i, name in enumerate(TRUTH):
        estimates = [fit.estimates[i] for fit in fits]
        counts[name] = (sum(e.profile_low <= TRUTH[name] <= e.profile_high for e in estimates),
                        sum(e.low <= TRUTH[name] <= e.high for e in estimates))
    return counts


def test_joint_profile_intervals_cover_the_truth_in_90_to_99_percent_of_seeds(joint_fits: list[Calibration]) -> None:
    counts = coverage(joint_fits)
    for name, (profile, _) in counts.items():
        assert 90 <= profile <= 99, (name, counts)


def test_a_profile_end_at_a_bound_is_flagged_open(joint_fits: list[Calibration]) -> None:
    """mu_s/mu >= 1: where the data allow mu_s = mu, the interval's lower end is the
    bound itself, marked open; elsewhere the ends are the profile's crossings."""
    ratios = [fit.estimates[1] for fit in joint_fits]
    opened = [e for e in ratios if e.open_low]
    assert opened, "some seeds' data allow mu_s = mu"
    assert all(e.profile_low == 1.0 for e in opened)
    assert all(e.profile_low > 1.0 for e in ratios if not e.open_low)
    assert not any(e.open_high for e in ratios)
    for fit in joint_fits:
        for estimate, profile in zip(fit.estimates, fit.profiles):
            assert estimate.profile_low <= estimate.value <= estimate.profile_high
            assert profile.low == estimate.profile_low and profile.high == estimate.profile_high


#: Settings to predict at: inside the measured ones, at their corner, and beyond them (Pa 9 N).
ASKED = {"excitation_amplitude": np.array([6.5, 8.0, 9.0]), "drive_force": np.array([0.8, 1.1, 1.0])}


def test_prediction_bands_cover_the_true_speed_in_90_to_99_percent_of_calibrations(
        joint_fits: list[Calibration]) -> None:
    """Each calibration's uncertainty as calibrated.yaml keeps it, carried through
    the model by 400 parameter sets on the population engine."""
    values: dict[str, Any] = {name: s.default for name, s in {**spec.PLANT, **spec.INPUTS}.items()}
    values.update(TRUTH, **ASKED)
    true = np.asarray(run_batch(values, **WINDOW).mean_velocity)
    assert np.all(true > 0.0)
    covered = np.zeros(true.size, dtype=int)
    for fit in joint_fits:
        plant = {name: getattr(fit.params, name) for name in spec.PLANT}
        uncertain = uncertain_from(plant, fit.estimates, fit.correlation,
                                   quantile(fit.known_deviations, fit.degrees_of_freedom))
        band = predict(uncertain, ASKED, **WINDOW)
        assert np.all(band.low <= band.speed) and np.all(band.speed <= band.high)
        covered += (band.low <= true) & (true <= band.high)
    assert np.all((covered >= 90) & (covered <= 99)), covered
