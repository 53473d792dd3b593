"""Every accepted input keeps the state finite; the root finders are safe over
the whole accepted range (issue 10, item 1, core part).

Hypothesis draws plants and inputs from the whole of the ranges in
friction_sim/core/spec.py (edges included, log-spread magnitudes), changes
them at random mid-run, jumps over huge spans where no event is due, and
asserts that nothing raises but a refusal naming a field (ParameterError),
that a refusal changes nothing, and that every number the slider reports is
finite: state, event times, period marks, samples.
"""

from __future__ import annotations

import itertools
import math
import time
import warnings
from typing import Any
from unittest import mock

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from friction_sim.core.engine.single import MAX_POSITION, MAX_TIME, Slider
from friction_sim.core.meanspeed.predict import predict
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.roots import NEVER, next_slip_start, slip_stop_delay
from friction_sim.errors import ParameterError

FUZZ = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
#: How far a run may go: beyond the end of ROS 2 time (2**31 s), with room.
T_MAX = 2.0**33
#: Events one step may take before the step is cut short (keeps a run bounded
#: where events come every period).
STEP_EVENTS = 60


def spread(low: float, high: float, *, signed: bool = False) -> st.SearchStrategy[float]:
    """Floats over [low, high] (or +-[.., high]) spread over their magnitudes,
    with the edges and zero (where inside) drawn often."""
    top = math.log10(high)
    bottom = math.log10(low) if low > 0.0 else -300.0
    magnitude = st.floats(bottom, top).map(lambda e: min(10.0**e, high))
    edges = [high] + ([low] if low > 0.0 else [0.0, 5e-324, 1e-300])
    values = st.one_of(st.sampled_from(edges), magnitude, st.floats(max(low, 0.0), high))
    if signed:
        return st.tuples(values, st.booleans()).map(lambda p: -p[0] if p[1] else p[0])
    return values


def setting_values(setting: spec.Setting) -> st.SearchStrategy[float]:
    low, high = float(setting.low), float(setting.high)  # type: ignore[arg-type]
    if low < 0.0:
        return spread(0.0, max(-low, high), signed=True).map(lambda v: min(max(v, low), high))
    return spread(low, high)


params_st = st.builds(SliderParams, mass=setting_values(spec.MASS), mu=setting_values(spec.MU),
                      gravity=setting_values(spec.GRAVITY))


@st.composite
def inputs_for(draw: st.DrawFn, params: SliderParams) -> Inputs:
    """Inputs over the spec's ranges that keep the contact (Pa < m*g - Fz)."""
    fz = draw(setting_values(spec.EXTERNAL_FORCE_Z))
    load = params.weight - fz
    if not load > 0.0:
        fz, load = 0.0, params.weight
    fraction = draw(st.one_of(st.sampled_from([0.0, 0.5, 0.999999, math.nextafter(1.0, 0.0)]),
                              st.floats(0.0, 1.0, exclude_max=True)))
    amplitude = min(fraction * load, spec.MAX_FORCE)
    if not amplitude < load:
        amplitude = 0.0
    # drive forces near the friction limits are the delicate ones: draw them often
    mu = params.mu
    near = st.sampled_from([mu * load, mu * (load - amplitude), mu * (load + amplitude)]).flatmap(
        lambda f: st.floats(-4.0, 4.0).map(lambda ulps: f + ulps * math.ulp(f)))
    drive = draw(st.one_of(setting_values(spec.DRIVE_FORCE), near, near.map(lambda f: -f)))
    drive = min(max(drive, -spec.MAX_FORCE), spec.MAX_FORCE)
    return Inputs(drive_force=drive, excitation_amplitude=amplitude,
                  excitation_frequency=draw(setting_values(spec.EXCITATION_FREQUENCY)),
                  external_force_x=draw(setting_values(spec.EXTERNAL_FORCE_X)), external_force_z=fz)


def assert_finite(slider: Slider, events: list[Any]) -> None:
    state = slider.state()
    for name in ("t", "x", "v", "acceleration", "friction_force", "normal_force", "phase"):
        value = getattr(state, name)
        assert math.isfinite(value), (name, value, slider.params, slider.inputs)
    assert 0.0 <= state.phase < TWO_PI
    assert not math.isnan(slider.next_event_time) and slider.next_event_time >= slider.t
    assert math.isfinite(slider.stuck_time) and slider.stuck_time >= 0.0
    for event in events:
        assert math.isfinite(event.t) and math.isfinite(event.x) and 0.0 <= event.phase < TWO_PI, event
    for mark in slider.cycle_marks[-3:]:
        assert math.isfinite(mark.t) and math.isfinite(mark.x) and math.isfinite(mark.stuck_time), mark


def step(slider: Slider, target: float) -> list[Any]:
    """advance_to(target), cut short after STEP_EVENTS events (then to the last one)."""
    events: list[Any] = []
    while len(events) < STEP_EVENTS and slider.next_event_time <= target:
        events.extend(slider.advance_to(slider.next_event_time))
    events.extend(slider.advance_to(target if slider.next_event_time > target else slider.t))
    assert all(a.t <= b.t for a, b in itertools.pairwise(events))
    # progress: a step cut short by its event budget still moved on in time
    assert len(events) < STEP_EVENTS or events[-1].t > events[0].t, events[:4]
    return events


change_st = st.one_of(
    st.tuples(st.just("inputs"), st.data()),
    st.tuples(st.just("params"), params_st),
)


@FUZZ
@given(params=params_st, data=st.data(), t0=st.sampled_from([0.0, 1e6, 2e9]) | spread(1e-9, 2.0**31),
       phase0=st.floats(0.0, TWO_PI), marks=st.booleans(), moves=st.lists(st.tuples(
           st.one_of(st.floats(0.0, 3.0), spread(1e-12, T_MAX)), st.booleans(), st.booleans()),
           min_size=1, max_size=8))
def test_any_accepted_run_stays_finite(params: SliderParams, data: st.DataObject, t0: float, phase0: float,
                                       marks: bool, moves: list[tuple[float, bool, bool]]) -> None:
    slider = Slider(params, data.draw(inputs_for(params)), t0=t0, phase0=phase0, event_log_size=50,
                    cycle_log_size=4 if marks else 0)
    assert_finite(slider, [])
    for span_periods, change, params_change in moves:
        # a span in periods when events may be due (each one costs), else any length of
        # time (without period marks: there is one per period)
        period = 1.0 / slider.inputs.excitation_frequency
        span = span_periods if span_periods > 3.0 and not marks else min(span_periods, 3.0) * period
        target = min(slider.t + span, t0 + T_MAX)
        assert_finite(slider, step(slider, target))
        if change:
            before = (slider.params, slider.inputs, slider.state())
            try:
                if params_change and data.draw(st.booleans()):  # plant and inputs at once
                    new_params = data.draw(params_st)
                    slider.set_plant(new_params, data.draw(inputs_for(new_params)))
                elif params_change:
                    slider.set_params(data.draw(params_st))
                else:
                    slider.set_inputs(data.draw(inputs_for(slider.params)))
            except ParameterError as refused:  # lift-off under the other half of the plant: refused whole
                assert refused.field
                assert (slider.params, slider.inputs, slider.state()) == before
            assert_finite(slider, [])
    times = np.linspace(slider.t, slider.t + 2.0 / slider.inputs.excitation_frequency, 7)
    if slider.next_event_time > times[-1] or len(slider.events) < 40:
        trajectory = slider.sample(times)
        for column in (trajectory.x, trajectory.v, trajectory.acceleration, trajectory.phase):
            assert np.all(np.isfinite(column))


# --------------------------------------------------------------------------
# the root finders alone, over every coefficient the accepted ranges can make
# --------------------------------------------------------------------------

#: |b0|, b1 = forces over a mass: up to (2e6 + 10*(1e6*1e3 + 1e6))/1e-6 ~ 1e16 m/s^2.
coefficients = spread(1e-300, 1e17)
omegas = spread(TWO_PI * spec.EXCITATION_FREQUENCY.low, TWO_PI * spec.EXCITATION_FREQUENCY.high)  # type: ignore[operator]


@FUZZ
@given(b0=coefficients, negative=st.booleans(), b1=st.just(0.0) | coefficients, phase=st.floats(0.0, TWO_PI),
       closing=st.booleans())
@example(b0=1e-300, negative=False, b1=1e17, phase=4.0, closing=False)  # asin(-1e-317) % 2*pi == 2*pi
def test_next_slip_start_is_safe(b0: float, negative: bool, b1: float, phase: float, closing: bool) -> None:
    b0 = -b0 if negative else b0
    phase = phase % TWO_PI
    delta, start = next_slip_start(phase, b0, b1, closing)
    assert delta == NEVER or (0.0 <= delta <= TWO_PI and 0.0 <= start < TWO_PI), (delta, start)


@FUZZ
@given(w0=st.just(0.0) | spread(1e-300, 1e22), b0=coefficients, negative=st.booleans(),
       b1=st.just(0.0) | coefficients, phase=st.floats(0.0, TWO_PI), omega=omegas)
# a fast slip that a tiny drift stops only after 1e322 s (sin(inf): domain error) ...
@example(w0=1e22, b0=1e-300, negative=True, b1=1e-300, phase=0.0, omega=125663.70614359173)
# ... or after more periods than an int holds (math.ceil(inf): OverflowError)
@example(w0=1e22, b0=1e-300, negative=True, b1=1e17, phase=0.0, omega=125663.70614359173)
# ... or with a drift so small (a subnormal, from a start at the slip window's edge) that
# it rounds to nothing over a period (a division by zero)
@example(w0=0.0, b0=1e17, negative=True, b1=1.0, phase=5e-324, omega=125663.70614359173)
def test_slip_stop_delay_is_safe(w0: float, b0: float, negative: bool, b1: float, phase: float,
                                 omega: float) -> None:
    b0 = -b0 if negative else b0
    phase = phase % TWO_PI
    delay = slip_stop_delay(w0, b0, b1, phase, omega)
    assert delay == NEVER or (math.isfinite(delay) and delay >= 0.0), delay


def test_a_change_after_a_long_stuck_run_keeps_the_phase_in_range() -> None:
    """Stuck for 2**33 s at 20 kHz (1.7e14 periods: the phase is a float near 1e15
    rad), then light enough to slip at once: the slip starts at a phase in [0, 2*pi)."""
    slider = Slider(SliderParams(mass=1e6, mu=10.0, gravity=1e3),
                    Inputs(drive_force=1e6, excitation_amplitude=0.0, excitation_frequency=2e4,
                           external_force_x=1e6))
    t = 8589937592.369  # (2**33 + 3000.369 s: theta/(2*pi) rounds up here)
    slider.advance_to(t)
    slider.set_params(SliderParams(mass=1e6, mu=10.0, gravity=1e-6))
    events = slider.advance_to(t)
    assert [e.kind.value for e in events] == ["slip_start"]
    assert 0.0 <= events[0].phase < TWO_PI
    assert_finite(slider, events)


def test_the_hardest_corner_runs_to_the_end_of_ros_time_and_stays_finite() -> None:
    """Largest drive over the lightest, least loaded slider at the slowest
    excitation: it accelerates at 2e12 m/s^2 for 2**33 s and stays finite."""
    slider = Slider(SliderParams(mass=1e-6, mu=1e-6, gravity=1e-6),
                    Inputs(drive_force=1e6, excitation_amplitude=0.0, excitation_frequency=1e-3,
                           external_force_x=1e6, external_force_z=-1e6), event_log_size=10)
    slider.advance_to(2.0**33)
    assert_finite(slider, slider.events)
    assert slider.state().x > 1e30
    slider.set_inputs(drive_force=-1e6, external_force_x=-1e6)  # brake hard: stops, then slides back
    events = step(slider, 2.0**34)
    assert [e.kind.value for e in events[:1]] == ["reversal"]
    assert_finite(slider, events)


def test_the_latest_time_keeps_the_fastest_slider_finite_and_later_is_refused() -> None:
    slider = Slider(SliderParams(mass=1e-6, mu=1e-6, gravity=1e-6),
                    Inputs(drive_force=1e6, excitation_amplitude=0.0, excitation_frequency=2e4,
                           external_force_x=1e6, external_force_z=-1e6), x0=MAX_POSITION)
    slider.advance_to(MAX_TIME)
    assert_finite(slider, [])
    for bad in (math.nextafter(MAX_TIME, math.inf), 1e300, math.inf, math.nan):
        try:
            slider.advance_to(bad)
        except ParameterError as refused:
            assert refused.field == "t" and f"{MAX_TIME:g}" in str(refused)
        else:
            raise AssertionError(f"advance_to({bad!r}) was accepted")
    assert slider.t == MAX_TIME
    for field, kwargs in (("t0", {"t0": 1e300}), ("x0", {"x0": -1e300})):
        try:
            Slider(**kwargs)  # type: ignore[arg-type]
        except ParameterError as refused:
            assert refused.field == field
        else:
            raise AssertionError(f"Slider({kwargs}) was accepted")


@given(params=params_st, data=st.data())
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@example(params=SliderParams(), data=None).via("issue 10 fuzz: Pa = 1e-300 printed numpy overflow warnings")
def test_the_prediction_is_quiet_and_sane_over_the_accepted_range(params: SliderParams, data: Any) -> None:
    """The node computes the U relation's prediction for every accepted input
    (diagnostics): it must neither print numpy warnings on the node's stderr
    nor give a negative or NaN speed."""
    inputs = Inputs(excitation_amplitude=1e-300) if data is None else data.draw(inputs_for(params))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        prediction = predict(params, inputs)
    assert prediction.u >= 0.0 or math.isinf(prediction.u) or inputs.tangential_force < 0.0
    assert not math.isnan(prediction.u)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.floats(0.05, 1.0), st.floats(0.0, TWO_PI, exclude_max=True), st.floats(0.0, 3.0), st.floats(0.0, 1e-3),
       st.sampled_from([2.0, 20.0, 300.0]))
def test_a_long_flight_skips_its_safe_stretch_and_lands_where_the_full_walk_does(
        pull: float, phase0: float, speed: float, height: float, throw: float) -> None:
    """landing_delay skips the stretch where a long flight is surely in the air;
    the landing is bit for bit the one the turning-point walk finds without
    the skip (the same final bracket), for flights of one to ~2000 periods."""
    from friction_sim.core.physics import roots

    omega, g = TWO_PI * 50.0, 10.0
    b1 = throw * g
    b0 = -pull * g  # a weak pull back: long flights
    vz0 = speed * b1 / omega
    skipped = roots.landing_delay(vz0, b0, b1, phase0, omega, height)
    with mock.patch.object(roots, "_safe_stretch", lambda h: (math.inf, -math.inf)):
        walked = roots.landing_delay(vz0, b0, b1, phase0, omega, height)
    assert skipped == walked


def test_a_huge_throw_number_lands_without_walking_every_period() -> None:
    """Throw number 1e11 (the lightest slider, the largest amplitude): the flight
    lasts ~1e10 periods; its landing is found in milliseconds, and z is 0 there."""
    from friction_sim.core.physics.roots import harmonic, harmonic_height, harmonic_speed, landing_delay

    omega, b1, b0 = TWO_PI * 50.0, 1e12, -10.0
    started = time.process_time()
    delay = landing_delay(0.0, b0, b1, 1e-11, omega, 0.0)
    # A hang guard, not a speed test: walking ~1e10 periods would take hours of
    # CPU; 5 s is >1000x below that and >100x above the search's milliseconds.
    assert time.process_time() - started < 5.0
    assert 1e7 < delay * 50.0 < 1e12
    h = harmonic(0.0, b0, b1, 1e-11, omega, 0.0)
    scale = b1 / omega * delay
    assert abs(harmonic_height(h, delay)) <= 1e-12 * scale and harmonic_speed(h, delay) < 0.0


@pytest.mark.parametrize("phase", [-180.0, -90.0, 90.0, 180.0])
def test_a_change_high_in_a_huge_flight_lands_within_rounding(phase: float) -> None:
    """The lightest slider under the largest amplitude at the slowest
    excitation (z oscillates by ~1e16 m): a change in the air starts a flight
    whose height near its landing is below its own rounding error.  The
    landing is then taken where rounding puts z at 0 (it divided by zero)."""
    slider = Slider(SliderParams(mass=1e-6), Inputs(drive_force=-3.0, excitation_amplitude=1e6,
                                                    excitation_frequency=1e-3))
    slider.advance_to(32.359475578712505)
    slider.set_params(slider.params.replace(excitation_phase=phase))
    slider.advance_to(32.659475578712505)
    state = slider.state()
    assert state.z >= 0.0 and math.isfinite(state.x) and math.isfinite(state.vz)


def test_a_landing_far_beyond_the_rounding_of_its_apex_time_is_found() -> None:
    """A flight whose apex is 4.7e13 s away (g = 1e-6, thrown at 4.7e7 m/s:
    found by the fuzz test above) hung the landing search: apex + 1/omega
    rounds to apex there, so doubling the bracket never widened it.  The
    landing is found, at once, where z = 0."""
    from friction_sim.core.physics.roots import harmonic, harmonic_height, landing_delay

    args = (47052513.009696074, -1e-6, 5.922808296637097e-09, 4.472895919311327, 125663.70614359173,
            7671491218.478284)
    started = time.process_time()
    tau = landing_delay(*args)
    # A hang guard (the bug never returned): >100x the search's CPU time.
    assert time.process_time() - started < 5.0
    assert 9e13 < tau < 1e14
    height = harmonic(*args)
    assert harmonic_height(height, tau) <= 0.0 < harmonic_height(height, tau * (1.0 - 1e-9))
