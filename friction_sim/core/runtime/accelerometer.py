"""The slideway's accelerometer: samples on a grid of simulation time.

An industrial feeder controller measures the slideway's vibration with an
accelerometer; so can a controller of the simulated feeder.
:class:`Accelerometer` reads the exact slideway acceleration
(:meth:`~friction_sim.core.engine.single.Slider.slideway_acceleration`) at
the simulation times k/rate, as a sensor fixed to the slideway reads it: the
specific force in the track frame (gravity included, +g*cos(alpha) on z at
rest, REP 145), plus an optional bias and seeded white noise (off by default).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from friction_sim.core.engine.single import Slider
from friction_sim.core.model import spec
from friction_sim.core.model.params import SliderParams, cos_degrees, sin_degrees
from friction_sim.core.model.records import Acceleration


def grid(rate: float, next_index: int, t_from: float, t: float) -> range:
    """The points k of the time grid k/``rate`` with t_from <= k/rate <= t and
    k >= ``next_index`` (the log grid's and the accelerometer's rule)."""
    last = math.floor(t * rate)
    if (last + 1) / rate <= t:  # the rounded product may be one short ...
        last += 1
    elif last / rate > t:  # ... or one over
        last -= 1
    return range(max(next_index, math.ceil(t_from * rate * (1.0 - 1e-15))), last + 1)


#: Noise variates drawn from the generator at once: it gives the same sequence whatever the
#: block, and a draw per reading cost more than the reading (three per reading).
NOISE_BLOCK = 3 * 256


class Accelerometer:
    """Samples at k/``rate`` [Hz] with white ``noise`` (standard deviation
    [m/s^2] per axis, from a generator seeded with ``seed``) and ``bias`` [m/s^2]."""

    def __init__(self, rate: float, noise: float = 0.0, bias: float = 0.0, seed: int = 0) -> None:
        self.rate = float(spec.ACCELEROMETER_RATE.check(rate))
        self.noise = float(spec.ACCELEROMETER_NOISE.check(noise))
        self.bias = float(spec.ACCELEROMETER_BIAS.check(bias))
        self._random = np.random.default_rng(int(spec.ACCELEROMETER_SEED.check(seed)))
        self._block: list[float] = []  # standard normal variates drawn, the first ``_used`` of them used
        self._used = 0
        self.next_index = 0  # the next grid point k not sampled yet

    def due(self, t_from: float, t: float) -> range:
        """The grid points not sampled yet from ``t_from`` to ``t`` (none when off)."""
        return grid(self.rate, self.next_index, t_from, t) if self.rate > 0.0 else range(0)

    def read(self, slider: Slider, k: int) -> Acceleration:
        """The sample of grid point ``k``; the slider stands at its time."""
        [sample] = self.readings(slider.params, [k], [slider.t], [slider.slideway_acceleration()])
        return sample

    def readings(self, params: SliderParams, points: Sequence[int], times: Sequence[float],
                 slideway: Sequence[Sequence[float]]) -> list[Acceleration]:
        """The samples of grid ``points`` (ascending) at ``times``, where the slideway's
        acceleration in the track frame is (along, normal) of ``slideway`` under ``params``."""
        gravity = params.gravity
        gravity_x = gravity * sin_degrees(params.track_inclination)
        gravity_z = gravity * cos_degrees(params.track_inclination)
        bias, noisy = self.bias, self.noise > 0.0
        samples: list[Acceleration] = []
        for k, t, (along, normal) in zip(points, times, slideway, strict=True):
            self.next_index = k + 1
            x, y, z = along + gravity_x, 0.0, normal + gravity_z
            if noisy:
                dx, dy, dz = self._normal()
                x, y, z = x + dx, y + dy, z + dz
            samples.append(Acceleration(t, x + bias, y + bias, z + bias))
        return samples

    def _normal(self) -> tuple[float, float, float]:
        """Three normal variates of standard deviation :attr:`noise`: the generator's next
        three, as its ``normal(0.0, noise, 3)`` computes them (0 + noise*z, bit for bit)."""
        if self._used + 3 > len(self._block):
            self._block, self._used = self._random.standard_normal(NOISE_BLOCK).tolist(), 0
        block, first, noise = self._block, self._used, self.noise
        self._used = first + 3
        return 0.0 + noise * block[first], 0.0 + noise * block[first + 1], 0.0 + noise * block[first + 2]


__all__ = ["NOISE_BLOCK", "Accelerometer", "grid"]
