"""The resonant feeder's tuning curve (``friction-sim resonance``).

A technician tunes a vibratory feeder by sweeping the drive frequency at a
fixed drive level and watching the slideway's amplitude, its phase behind
the drive and the conveying speed.  :func:`tuning_curve` computes that
curve for the resonant actuator (:mod:`friction_sim.core.physics.exciter`):
the amplitude and lag from the analytic resonance curve, the mean speed of
the part in steady state from the population engine, one slider per
frequency, each exact (the mean over whole periods after settling; periodic
motions to rounding).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from friction_sim.core.engine.population import run_batch
from friction_sim.core.meanspeed.general import DEFAULT_PERIODS, DEFAULT_SETTLE_PERIODS
from friction_sim.core.model import spec
from friction_sim.core.model.params import Inputs, SliderParams, field_values
from friction_sim.core.physics.exciter import response, steady_acceleration

Floats = NDArray[np.float64]


@dataclass(frozen=True)
class TuningCurve:
    """Along the drive ``frequency`` [Hz]: the slideway's steady normal
    acceleration ``amplitude`` [m/s^2] at the drive level in force, its
    ``lag_deg`` behind the drive, the part's ``mean_velocity`` [m/s] and
    ``flight_fraction``; ``params`` and ``inputs`` the plant (resonant)."""

    params: SliderParams
    inputs: Inputs
    frequency: Floats
    amplitude: Floats
    lag_deg: Floats
    mean_velocity: Floats
    flight_fraction: Floats

    @property
    def fastest(self) -> int:
        """The index of the fastest conveying (forward) frequency."""
        return int(np.argmax(self.mean_velocity))

    @property
    def loudest(self) -> int:
        """The index of the largest slideway amplitude."""
        return int(np.argmax(self.amplitude))


def tuning_curve(params: SliderParams, inputs: Inputs, frequencies: Floats, *,
                 settle_periods: int = DEFAULT_SETTLE_PERIODS, periods: int = DEFAULT_PERIODS,
                 threads: int | None = None) -> TuningCurve:
    """The tuning curve of ``params`` (made resonant) at ``inputs``' drive level,
    over the drive ``frequencies`` (each checked as an excitation frequency)."""
    params = params.replace(actuator="resonant")
    frequencies = np.asarray([spec.EXCITATION_FREQUENCY.check(float(f)) for f in frequencies], dtype=float)
    gains, lags = np.array([response(float(f), params.natural_frequency, params.damping_ratio)
                            for f in frequencies]).T.reshape(2, -1)
    values = {**field_values(params, inputs), "excitation_frequency": frequencies}
    batch = run_batch(values, settle_periods=settle_periods, periods=periods, threads=threads)
    return TuningCurve(params, inputs, frequencies,
                       steady_acceleration(inputs.drive_level, params.full_drive_acceleration, gains),
                       np.degrees(lags), batch.mean_velocity, batch.flight_fraction)


__all__ = ["TuningCurve", "tuning_curve"]
