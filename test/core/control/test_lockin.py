"""The lock-in reading of the slideway's vibration (issue 21, item 3): a period's
fit against a sinusoid it must recover to rounding, against the exact resonant
slider (amplitude and lag of the analytic resonance curve), in whatever order
the two topics deliver, and its scatter under the accelerometer's noise."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from friction_sim.core.control.lockin import MIN_SAMPLES, LockIn, Vibration, fit_period
from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.exciter import response
from friction_sim.core.runtime.accelerometer import Accelerometer
from friction_sim.errors import ParameterError


@pytest.mark.parametrize("lag", [0.1, math.pi / 2, 2.9, -1.0])
def test_a_period_of_a_sinusoid_is_read_to_rounding(lag: float) -> None:
    """Irregular sample times, an offset: the three-term fit is exact for them
    (a dozen roundings per sample and a 3x3 least-squares solve: 1e-12)."""
    rng = np.random.default_rng(7)
    t0, t1 = 0.3, 0.32
    times = np.sort(rng.uniform(t0, t1, 23))
    theta = 2 * math.pi * (times - t0) / (t1 - t0)
    amplitude, offset = 4.7, 9.81
    reading = fit_period(times, offset - amplitude * np.sin(theta - lag), t0, t1)
    assert reading.amplitude == pytest.approx(amplitude, rel=1e-12)
    assert math.remainder(reading.lag - lag, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    assert reading.offset == pytest.approx(offset, rel=1e-12) and reading.samples == 23


def test_too_few_samples_are_refused_naming_the_count() -> None:
    with pytest.raises(ParameterError, match="samples"):
        fit_period([0.0, 0.01, 0.02], [1.0, 2.0, 3.0], 0.0, 0.02)
    with pytest.raises(ParameterError, match="period"):
        fit_period([0.0] * MIN_SAMPLES, [1.0] * MIN_SAMPLES, 0.02, 0.02)


def _resonant_readings(frequency: float, natural: float, rate: float, periods: int,
                       noise: float = 0.0) -> tuple[list[tuple[float, float]], list[float]]:
    """Accelerometer samples (t, z) of a resonant slider in steady state, and its period ends."""
    params = SliderParams(actuator="resonant", natural_frequency=natural, damping_ratio=0.02,
                          full_drive_acceleration=10.0)
    slider = Slider(params, Inputs(excitation_frequency=frequency, drive_level=0.5))
    sensor = Accelerometer(rate, noise=noise, seed=3)
    samples = []
    for k in sensor.due(0.0, periods / frequency):
        slider.advance_to(max(k / rate, slider.t))
        reading = sensor.read(slider, k)
        samples.append((reading.t, reading.z))
    return samples, [n / frequency for n in range(periods + 1)]


def _read_all(samples: list[tuple[float, float]], bounds: list[float]) -> list[Vibration]:
    """Every sample, then every boundary, then the readings."""
    lockin = LockIn()
    for t, z in samples:
        lockin.add_sample(t, z)
    for t in bounds:
        lockin.add_boundary(t)
    return lockin.readings()


@pytest.mark.parametrize(("frequency", "natural"), [(50.0, 50.0), (50.0, 52.0), (47.0, 44.0)])
def test_the_exact_resonant_slider_is_read_as_its_resonance_curve(frequency: float, natural: float) -> None:
    """Steady state from the start: every period reads u*A*G and the lag of the
    analytic curve (the sensor's samples carry the core's rounding: 1e-12)."""
    samples, bounds = _resonant_readings(frequency, natural, 1000.0, 6)
    readings = _read_all(samples, bounds)
    gain, lag = response(frequency, natural, 0.02)
    # a period is read once a sample at or after its end has come
    assert len(readings) == sum(1 for end in bounds[1:] if end <= samples[-1][0]) >= 5
    for reading in readings:
        assert reading.amplitude == pytest.approx(0.5 * 10.0 * gain, rel=1e-12)
        assert reading.lag == pytest.approx(lag, abs=1e-12)
        assert reading.offset == pytest.approx(10.0, rel=1e-12)


def test_the_order_in_which_the_topics_arrive_does_not_matter() -> None:
    samples, bounds = _resonant_readings(50.0, 52.0, 1000.0, 8)
    expected = _read_all(samples, bounds)
    late_bounds = LockIn()  # each boundary a period late, readings taken as they come
    got = []
    for t, z in samples:
        late_bounds.add_sample(t, z)
        for b in bounds:
            if b + 0.02 <= t:
                late_bounds.add_boundary(b)
        got.extend(late_bounds.readings())
    for b in bounds:
        late_bounds.add_boundary(b)
    got.extend(late_bounds.readings())
    assert got == expected and len(expected) == 8


def test_noise_scatters_the_amplitude_as_least_squares_says() -> None:
    """White noise sigma per sample, N samples a period: the amplitude's error
    has a standard deviation of about sigma*sqrt(2/N) (and no bias at a
    signal far above it).  400 periods: the measured scatter within 15 %."""
    sigma, rate, frequency = 0.05, 1000.0, 50.0
    samples, bounds = _resonant_readings(frequency, 52.0, rate, 401, noise=sigma)
    readings = _read_all(samples, bounds)
    exact = 0.5 * 10.0 * response(frequency, 52.0, 0.02).gain
    errors = np.array([r.amplitude - exact for r in readings])
    expected = sigma * math.sqrt(2.0 / (rate / frequency))
    assert len(errors) >= 400
    assert abs(errors.mean()) < 4 * expected / math.sqrt(len(errors))
    assert errors.std() == pytest.approx(expected, rel=0.15)


@pytest.mark.parametrize("swap", [None, 37])
def test_a_period_reads_exactly_the_samples_inside_it_in_the_order_they_came(swap: int | None) -> None:
    """Each reading is the fit of the samples with start <= t <= end, taken in the order they
    arrived: found from the newest back while they come in time order, by a scan once one came
    out of order (``swap``: two neighbours exchanged).  Samples on a boundary count in both periods."""
    samples, bounds = _resonant_readings(50.0, 52.0, 1000.0, 6)
    samples.insert(46, (samples[45][0], 1.5))  # (two samples at one time)
    if swap is not None:
        samples[swap], samples[swap + 1] = samples[swap + 1], samples[swap]
    lockin, got = LockIn(), []
    for t, z in samples:  # readings asked for as the samples come, boundaries on time
        lockin.add_sample(t, z)
        for b in bounds:
            if b <= t:
                lockin.add_boundary(b)
        got.extend(lockin.readings())
    expected = []
    for start, end in itertools.pairwise(bounds):
        inside = [(t, z) for t, z in samples if start <= t <= end]
        if end <= samples[-1][0]:
            expected.append(fit_period([t for t, _ in inside], [z for _, z in inside], start, end))
    assert len(got) == len(expected) >= 5
    assert got == expected


def test_samples_at_two_phases_of_the_drive_are_no_reading() -> None:
    """An accelerometer at twice the drive frequency over two-period windows samples
    only the phases 0 and pi, where the sine is zero: its amplitude and lag cannot be
    read.  fit_period refuses, naming the samples; the lock-in skips the window, as one
    with too few samples, and reads the next one that can be read."""
    times = [0.0, 0.01, 0.02, 0.03, 0.04]
    normal = [9.81 + math.cos(math.pi * k) for k in range(5)]
    with pytest.raises(ParameterError, match=r"samples = 5 rejected: .*too few phases"):
        fit_period(times, normal, 0.0, 0.04, cycles=2)
    lockin = LockIn(cycles=2)
    for t, z in zip(times, normal, strict=True):
        lockin.add_sample(t, z)
    for t in (0.0, 0.04):
        lockin.add_boundary(t)
    assert lockin.readings() == []
    later = [0.04 + 0.04 * k / 7 for k in range(1, 8)]
    for t in later:
        lockin.add_sample(t, 9.81 + math.cos(2 * math.pi * t / 0.02))  # the same vibration, at 7 more phases
    lockin.add_boundary(later[-1])
    (reading,) = lockin.readings()
    assert reading.t_start == 0.04 and reading.amplitude == pytest.approx(1.0, rel=1e-12)
