"""The accelerometer (issue 21): seeded white noise of its standard deviation, and a bias."""

from __future__ import annotations

import math

import numpy as np

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.accelerometer import NOISE_BLOCK, Accelerometer

RATE = 1000.0
PLANT = SliderParams(actuator="resonant", natural_frequency=52.0, excitation_angle=60.0, track_inclination=3.0)


def test_the_noise_is_seeded_white_and_of_its_standard_deviation() -> None:
    def readings(seed: int, noise: float, bias: float) -> np.ndarray:
        slider = Slider(PLANT, Inputs())
        sensor = Accelerometer(RATE, noise, bias, seed)
        rows = []
        for k in range(4000):
            slider.advance_to(k / RATE)
            sample = sensor.read(slider, k)
            rows.append((sample.x, sample.y, sample.z))
        return np.array(rows)

    exact = readings(0, 0.0, 0.0)
    noisy = readings(7, 0.05, 0.01)
    assert np.array_equal(noisy, readings(7, 0.05, 0.01)), "the same seed, the same noise"
    assert not np.array_equal(noisy, readings(8, 0.05, 0.01))
    residual = noisy - exact
    n = residual.shape[0]
    # the sample mean and standard deviation of n normal draws: within 5 standard errors
    assert np.all(np.abs(residual.mean(axis=0) - 0.01) <= 5 * 0.05 / math.sqrt(n))
    assert np.all(np.abs(residual.std(axis=0) / 0.05 - 1) <= 5 / math.sqrt(2 * n))
    lagged = np.corrcoef(residual[1:, 2], residual[:-1, 2])[0, 1]
    assert abs(lagged) <= 5 / math.sqrt(n), "white: no correlation from one sample to the next"


def test_the_noise_is_the_generators_normal_draws_three_at_a_time() -> None:
    """Drawn in blocks (:data:`NOISE_BLOCK`), the noise is bit for bit what the seeded generator's
    ``normal(0, noise, 3)`` gives reading by reading, across block ends and a change of the noise."""
    slider = Slider(PLANT, Inputs())
    sensor, exact = Accelerometer(RATE, 0.05, 0.0, 11), Accelerometer(RATE)
    generator = np.random.default_rng(11)
    for k in range(NOISE_BLOCK + 7):
        if k == NOISE_BLOCK // 2:
            sensor.noise = 0.2
        slider.advance_to(k / RATE)
        noisy, plain = sensor.read(slider, k), exact.read(slider, k)
        dx, dy, dz = generator.normal(0.0, sensor.noise, 3)
        assert (noisy.x, noisy.y, noisy.z) == (plain.x + dx, plain.y + dy, plain.z + dz)
        assert all(type(value) is float for value in (noisy.x, noisy.y, noisy.z))
