"""Pictures of a calibration beyond the check of :func:`~friction_sim.cli.figures.calibration_figure`.

* :func:`sweep_figure` (``calibration.png`` of a frequency sweep): the
  measured amplitude (and lag) against the drive frequency, the fitted curve
  through them, and the amplitude's residuals.
* :func:`readings_figure` (``calibration.png`` of the exciter fitted to a
  recording's accelerometer): the readings and the fitted normal acceleration
  against time, and the residuals.
* :func:`band_figure` (``friction-sim predict --sweep ... --png``): the
  predicted mean speed along a swept setting with its 95 % band.
* :func:`profile_figure` (``calibration_profile.png``): each fitted
  parameter's profile, the signed root r of the cost's rise with the others
  re-fitted, against the parameter; the 95 % interval where |r| <= q, beside
  the linearized interval (where r is taken as the straight line).

Matplotlib is reached through :func:`~friction_sim.cli.figures.pyplot_free_figure`
only (imported when a figure is drawn), as every figure of the package.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from friction_sim.cli.figures import pyplot_free_figure
from friction_sim.experiment.calibration_accel import ReadingsCalibration
from friction_sim.experiment.calibration_fit import Estimate
from friction_sim.experiment.calibration_predict import BAND, Prediction
from friction_sim.experiment.calibration_profile import Profile
from friction_sim.experiment.calibration_sweep import SweepCalibration


def profile_figure(estimates: tuple[Estimate, ...], profiles: tuple[Profile, ...], q: float) -> Any:
    """One panel per parameter: the profile's signed root r against the parameter
    (points where the search evaluated it), the lines r = +-q, the linearized r
    (the straight line through the estimate of slope 1/standard error), the
    profile interval as a band and the linearized one's ends."""
    fig = pyplot_free_figure(figsize=(5.0 * len(profiles), 4.4), layout="constrained")
    axes_list = np.atleast_1d(fig.subplots(1, len(profiles)))
    for axes, estimate, profile in zip(axes_list, estimates, profiles):
        axes.axhspan(-q, q, color="0.93")
        axes.axvspan(profile.low, profile.high, color="tab:blue", alpha=0.15, label="95 % profile likelihood")
        for end, label in ((estimate.low, "95 % linearized"), (estimate.high, None)):
            axes.axvline(end, color="tab:red", linestyle="-.", linewidth=1.0, label=label)
        axes.plot(profile.values, profile.root, "o-", color="tab:blue", markersize=3.5, linewidth=1.2,
                  label="profile r")
        if estimate.std_error > 0.0:
            span = np.array([min(profile.values.min(), estimate.low), max(profile.values.max(), estimate.high)])
            axes.plot(span, (span - estimate.value) / estimate.std_error, "--", color="tab:red", linewidth=1.0,
                      label="linearized r")
        for level in (-q, q):
            axes.axhline(level, color="0.4", linestyle=":", linewidth=0.9)
        axes.axvline(estimate.value, color="black", linewidth=0.8)
        axes.set_ylim(-2.5 * q, 2.5 * q)
        axes.set_xlabel(estimate.name)
        axes.set_ylabel(r"signed root $r$ of the cost's rise")
        axes.grid(alpha=0.3)
        axes.set_title(f"{estimate.name} = {estimate.value:.6g}: [{profile.low:.6g}, {profile.high:.6g}]", fontsize=9)
    axes_list[0].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"Profiles: each parameter with the others re-fitted; 95 % where |r| <= {q:.4g}", fontsize=10)
    return fig


def sweep_figure(result: SweepCalibration) -> Any:
    """The sweep's amplitudes (error bars: the std column) and lags against the
    drive frequency, with the fitted exciter's steady response, and the
    amplitude's residuals."""
    s = result.sweep
    lags = s.lag_deg is not None
    fig = pyplot_free_figure(figsize=(8.0, 7.0 if lags else 5.6), layout="constrained")
    panels = fig.subplots(3 if lags else 2, 1, sharex=True, height_ratios=[3, 2, 1] if lags else [3, 1])
    order = np.argsort(s.frequency)
    f = s.frequency[order]
    top = panels[0]
    top.errorbar(f, s.amplitude[order], yerr=None if s.std is None else s.std[order], fmt="o", color="black",
                 markersize=3.5, label="measured")
    top.plot(f, result.fitted_amplitude[order], "-", color="tab:red", linewidth=1.3, label="fitted")
    top.set_ylabel(r"amplitude [m/s$^2$]")
    top.legend(fontsize=8)
    if lags and s.lag_deg is not None:
        panels[1].plot(f, s.lag_deg[order], "o", color="black", markersize=3.5)
        panels[1].plot(f, result.fitted_lag[order], "-", color="tab:red", linewidth=1.3)
        panels[1].axhline(90.0, color="0.5", linestyle=":", linewidth=0.9)
        panels[1].set_ylabel("lag [deg]")
    panels[-1].plot(f, (s.amplitude - result.fitted_amplitude)[order], ".", color="tab:blue")
    panels[-1].axhline(0.0, color="black", linewidth=0.6)
    panels[-1].set_ylabel(r"residual [m/s$^2$]")
    panels[-1].set_xlabel("drive frequency f [Hz]")
    for axes in panels:
        axes.grid(alpha=0.3)
    fig.suptitle("Exciter from a frequency sweep\n" + ", ".join(
        f"{e.name} = {e.value:.6g} ± {e.std_error:.2g}" for e in result.estimates), fontsize=9)
    return fig


def readings_figure(result: ReadingsCalibration) -> Any:
    """The accelerometer's normal readings (gravity's share and the bias taken
    off) and the fitted exciter's acceleration against time, each drive change
    marked, and the residuals."""
    r = result.readings
    fig = pyplot_free_figure(figsize=(9.0, 5.6), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[3, 1])
    top.plot(r.t, r.normal, ".", color="black", markersize=1.5, label="readings")
    top.plot(r.t, result.fitted, "-", color="tab:red", linewidth=0.8, label="fitted")
    top.set_ylabel(r"normal acceleration $q''$ [m/s$^2$]")
    top.legend(fontsize=8, loc="upper right")
    bottom.plot(r.t, r.normal - result.fitted, ".", color="tab:blue", markersize=1.5)
    bottom.axhline(0.0, color="black", linewidth=0.6)
    bottom.set_ylabel(r"residual [m/s$^2$]")
    bottom.set_xlabel("t [s]")
    for axes in (top, bottom):
        axes.grid(alpha=0.3)
    fig.suptitle(f"Exciter from {result.plateau_count} drive plateaus of a recording's accelerometer\n" + ", ".join(
        f"{e.name} = {e.value:.6g} ± {e.std_error:.2g}" for e in result.estimates), fontsize=9)
    return fig


def band_figure(prediction: Prediction, name: str) -> Any:
    """The mean speed at the calibrated estimates along the swept setting ``name``,
    and the band the calibration's uncertainty gives it."""
    fig = pyplot_free_figure(figsize=(7.5, 4.6), layout="constrained")
    axes = fig.subplots()
    x = np.asarray(prediction.settings[name], dtype=float)
    order = np.argsort(x)
    axes.fill_between(x[order], prediction.low[order] * 1e3, prediction.high[order] * 1e3, color="tab:blue",
                      alpha=0.25, label=f"{BAND[1] - BAND[0]:g} % band ({prediction.samples} parameter sets)")
    axes.plot(x[order], prediction.speed[order] * 1e3, "-", color="tab:blue", linewidth=1.4,
              label="at the estimates")
    axes.set_xlabel(name)
    axes.set_ylabel("mean speed V [mm/s]")
    axes.grid(alpha=0.3)
    axes.legend(fontsize=8)
    others = [f"{n} = {_value(v[0])}" for n, v in prediction.settings.items() if n != name]
    axes.set_title("Prediction of the calibrated plant" + (f" ({', '.join(others)})" if others else ""),
                   fontsize=9)
    return fig


def _value(value: Any) -> str:
    return str(value) if isinstance(value, str) else f"{float(value):g}"


__all__ = ["band_figure", "profile_figure", "readings_figure", "sweep_figure"]
