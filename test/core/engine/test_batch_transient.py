"""The population engine runs the resonant exciter's transient as the single slider runs it (issue 30, item 6).

A population member whose exciter starts from rest, or from the steady state
of another drive level or frequency, runs the start-up's transient compiled.
The independent expectation is the single slider itself, one member at a
time: :meth:`Population.slider` builds it in the steady state of the initial
inputs and steps it to the member's own at t = 0 (:meth:`Slider.set_inputs`),
and the single slider then runs the transient with its own segment handling.
Both run the same plain functions (the stepper, the transient's root search),
so positions, velocities, the booked stuck and flight times, the event counts
and the states at the single slider's own event times must be equal, bit for
bit: no tolerance.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from friction_sim.core.engine import transient_kernel as kernel
from friction_sim.core.engine.population import BatchResult, population, run_batch
from friction_sim.core.model import spec
from friction_sim.errors import ParameterError

#: Resonant members, each started off its steady state: from rest (drive 0), by a step of drive,
#: by a step of frequency, by both; with flight, bounces, reversals and stick-slip among them.
#: The well-damped ones settle inside the window, so it covers the cut where the transient is dropped.
VALUES: dict[str, Any] = {
    "actuator": "resonant",
    "natural_frequency": [52.0, 50.0, 48.0, 55.0, 50.0, 50.0],
    "damping_ratio": [0.02, 0.05, 0.02, 0.3, 0.03, 0.2],
    "drive_level": [0.9, 0.5, 0.7, 1.0, 0.6, 0.8],
    "full_drive_acceleration": [15.0, 10.0, 20.0, 30.0, 12.0, 8.0],
    "excitation_angle": [30.0, 90.0, 45.0, 20.0, 60.0, 90.0],
    "restitution": [0.3, 0.0, 0.5, 0.2, 0.0, 0.0],
    "drive_force": [0.0, 0.7, 0.0, 0.0, 0.5, 0.6],
}
INITIAL: dict[str, Any] = {"drive_level": [0.0, 0.2, 0.0, 0.5, 0.6, 0.0],
                           "excitation_frequency": [50.0, 50.0, 45.0, 50.0, 52.0, 50.0]}
SETTLE, PERIODS = 4, 40
TIMES = np.linspace(0.0005, 0.6, 41)


@pytest.fixture(autouse=True)
def _plain_single_slider() -> Iterator[None]:
    """The single slider's transient runs plain here (the reference, no compiling of its own)."""
    before = kernel.mode()
    kernel.use(kernel.PLAIN)
    yield
    kernel.use(before)


def _windows(result: BatchResult) -> tuple[np.ndarray, ...]:
    counts = np.stack([result.event_counts[kind] for kind in sorted(result.event_counts)])
    return result.mean_velocity, result.flight_fraction, result.stick_fraction, counts


@pytest.fixture(scope="module")
def compiled() -> tuple[BatchResult, BatchResult]:
    """The population compiled, without and with the periodic shortcut."""
    exact = run_batch(VALUES, settle_periods=SETTLE, periods=PERIODS, initial=INITIAL, sample_times=TIMES,
                      periodic_shortcut=False)
    shortcut = run_batch(VALUES, settle_periods=SETTLE, periods=PERIODS, initial=INITIAL, sample_times=TIMES)
    return exact, shortcut


@pytest.fixture(scope="module")
def reference() -> BatchResult:
    """The population run member by member by the single slider."""
    return run_batch(VALUES, settle_periods=SETTLE, periods=PERIODS, initial=INITIAL, sample_times=TIMES,
                     engine="scalar")


def test_the_compiled_transient_is_the_single_slider_s_bit_for_bit(compiled: tuple[BatchResult, BatchResult],
                                                                     reference: BatchResult) -> None:
    exact = compiled[0]
    for got, want in zip(_windows(exact), _windows(reference)):
        assert np.array_equal(got, want)
    assert exact.samples is not None and reference.samples is not None
    for name in ("x", "v", "z", "vz", "mode"):
        assert np.array_equal(getattr(exact.samples, name), getattr(reference.samples, name)), name


def test_the_shortcut_waits_for_the_transient_to_settle(compiled: tuple[BatchResult, BatchResult],
                                                        reference: BatchResult) -> None:
    """Under the transient no state repeats (its force differs from period to period),
    so the shortcut is taken only once it has settled: then it extrapolates within the
    rounding bound of test_batch.py's extrapolation_bound (each of the q <= SETTLE +
    PERIODS repeats adds a difference, a product and a sum, an ulp of max|x| each)."""
    shortcut = compiled[1]
    frequency = 50.0
    duration, repeats = PERIODS / frequency, SETTLE + PERIODS + 3
    x_scale = np.abs(reference.mean_velocity) * duration * (SETTLE + PERIODS) / PERIODS
    bound = 2 * repeats * np.finfo(float).eps * x_scale / duration
    assert np.all(np.abs(shortcut.mean_velocity - reference.mean_velocity) <= bound)
    assert np.array_equal(_windows(shortcut)[3], _windows(reference)[3])
    assert shortcut.samples is not None and reference.samples is not None
    assert np.array_equal(shortcut.samples.x, reference.samples.x)
    settled = np.flatnonzero(shortcut.mean_velocity != reference.mean_velocity)
    assert settled.size >= 1, "a member settled inside the window and took the shortcut (else this checks nothing)"


def test_the_states_at_the_single_slider_s_event_times_are_its_own() -> None:
    """Sampled at the single slider's own event times, the compiled members are where it was:
    the same events at the same times (a sample at an event's time is the state just after it)."""
    pop = population(VALUES, INITIAL)
    for i in range(pop.n):
        slider = pop.slider(i, event_log_size=None)
        events = slider.advance_to(0.8)
        times = np.unique([event.t for event in events if event.t > 0.0])
        assert times.size > 3, i
        want = pop.slider(i, event_log_size=0).sample(times)
        one = {name: (column[i] if isinstance(column, list) else column) for name, column in VALUES.items()}
        start = {name: column[i] for name, column in INITIAL.items()}
        got = run_batch(one, settle_periods=0, periods=1, initial=start, sample_times=times,
                        periodic_shortcut=False).samples
        assert got is not None
        for name in ("x", "v", "z", "vz", "mode"):
            assert np.array_equal(getattr(got, name)[0], getattr(want, name)), (i, name)
        last = {event.t: event.x for event in events}  # (the last event at each instant: the state after it)
        assert np.array_equal(got.x[0], [last[t] for t in times.tolist()]), i


def test_a_start_from_rest_is_not_the_steady_start(compiled: tuple[BatchResult, BatchResult]) -> None:
    steady = run_batch(VALUES, settle_periods=SETTLE, periods=PERIODS, periodic_shortcut=False)
    assert not np.array_equal(steady.mean_velocity, compiled[0].mean_velocity)


def test_a_start_in_the_slider_s_own_steady_state_changes_nothing() -> None:
    values = {name: column for name, column in VALUES.items()}
    own = {"drive_level": VALUES["drive_level"]}
    assert np.array_equal(run_batch(values, settle_periods=2, periods=5, initial=own).mean_velocity,
                          run_batch(values, settle_periods=2, periods=5).mean_velocity)


def test_the_force_actuator_has_no_exciter_to_start() -> None:
    values = {"drive_force": [0.2, 0.5], "excitation_amplitude": [8.0, 12.0]}
    rest = spec.INITIAL_INPUTS["rest"]
    assert np.array_equal(run_batch(values, settle_periods=2, periods=5, initial=rest).mean_velocity,
                          run_batch(values, settle_periods=2, periods=5).mean_velocity)


@pytest.mark.parametrize(("initial", "words"), [
    ({"mass": 0.1}, ["initial.mass", "drive_level", "excitation_frequency"]),
    ({"drive_level": 1.5}, ["initial.drive_level", "1.5"]),
    ({"drive_level": [0.1, 0.2]}, ["initial.drive_level", "length"]),
    ([0.1], ["initial", "mapping"]),
])
def test_a_bad_start_is_refused_naming_field_and_value(initial: Any, words: list[str]) -> None:
    with pytest.raises(ParameterError) as caught:
        run_batch({"drive_level": [0.1, 0.2, 0.3], "actuator": "resonant"}, settle_periods=1, periods=1,
                  initial=initial)
    for word in words:
        assert word in str(caught.value)
