"""The population engine (issue 20): N sliders at once, the single slider's physics compiled.

Independent expectations:

* the single slider itself, :class:`Slider`, one slider at a time (its cycle
  marks, event counts and :meth:`Slider.sample`): the compiled engine runs the
  same functions, so without the periodic shortcut it must give the same
  numbers bit for bit, on populations that mix every regime, chaotic bouncers
  included;
* with the periodic shortcut a repeating slider's window is extrapolated from
  the increments of one repeat instead of stepped through: the same numbers up
  to the rounding of that sum (a bound derived below, :func:`extrapolation_bound`);
* Kostek's closed form (:func:`u_map`) for the stick-slip sliders, and the
  hand calculation of test_meanspeed.py for one-period flights
  (Gamma = sqrt(1 + pi^2), plastic landings: U = cot(beta)/(2 mu));
* what must happen to a slider that never moves (nothing) and to one that
  flies away for good (it leaves at t = 0 and never lands).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from friction_sim.core.engine.population import EVENT_KINDS, BatchResult, run_batch
from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.urelation import u_map
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.errors import ParameterError

GAMMA_1 = math.sqrt(1.0 + math.pi**2)  # one-period flights with a plastic landing
SETTLE, PERIODS = 12, 24


def mixed_population(seed: int, per_regime: int) -> tuple[dict[str, Any], np.ndarray]:
    """Every regime of the general model, ``per_regime`` sliders each (with random
    mass, mu, frequency, landing law); returns the values and each slider's regime number."""
    rng = np.random.default_rng(seed)
    regimes = np.repeat(np.arange(9), per_regime)
    n = regimes.size
    m, mu, g = rng.uniform(0.5, 2.0, n), rng.uniform(0.05, 0.8, n), rng.uniform(5.0, 12.0, n)
    angle, incline, ratio = np.full(n, 90.0), np.zeros(n), np.ones(n)
    gamma, phi, e = rng.uniform(0.2, 0.95, n), rng.uniform(0.1, 0.95, n), np.zeros(n)
    phase = np.zeros(n)
    r = regimes
    # 0: Kostek stick-slip, above the motion boundary phi > 1 - a; 1: below the motion boundary (phi < 1 - a): no motion
    phi[r == 0] = 1.0 - gamma[r == 0] * rng.uniform(0.1, 0.95, per_regime)
    gamma[r == 1], phi[r == 1] = rng.uniform(0.1, 0.5, per_regime), rng.uniform(0.0, 0.4, per_regime)
    # 2: tilted vibration, in contact (Gamma < 1), some with a tangential phase
    angle[r == 2], gamma[r == 2] = rng.uniform(20.0, 85.0, per_regime), rng.uniform(0.3, 0.95, per_regime)
    phase[r == 2] = np.where(rng.random(per_regime) < 0.5, rng.uniform(-60.0, 60.0, per_regime), 0.0)
    # 3: hopping every period (1 < Gamma < 3.3), plastic
    angle[r == 3], gamma[r == 3] = rng.uniform(20.0, 70.0, per_regime), rng.uniform(1.05, 3.2, per_regime)
    phi[r == 3] = rng.uniform(-0.2, 0.2, per_regime)
    # 4: multi-period flights (Gamma > 3.3)
    angle[r == 4], gamma[r == 4] = rng.uniform(20.0, 70.0, per_regime), rng.uniform(3.4, 8.0, per_regime)
    phi[r == 4] = 0.0
    # 5: restitution, both landing laws
    angle[r == 5], gamma[r == 5] = rng.uniform(20.0, 70.0, per_regime), rng.uniform(1.1, 2.5, per_regime)
    e[r == 5], phi[r == 5] = rng.uniform(0.05, 0.6, per_regime), 0.0
    # 6: a slope, drive against it or none: backward slips and reversals
    incline[r == 6], angle[r == 6] = rng.uniform(3.0, 12.0, per_regime), rng.uniform(25.0, 60.0, per_regime)
    gamma[r == 6], phi[r == 6] = rng.uniform(0.5, 0.98, per_regime), rng.uniform(-0.5, 0.3, per_regime)
    # 7: static friction above kinetic
    ratio[r == 7], angle[r == 7] = rng.uniform(1.05, 2.0, per_regime), rng.uniform(30.0, 90.0, per_regime)
    # 8: a downhill slope with a hopping slider
    incline[r == 8], angle[r == 8] = rng.uniform(-8.0, -2.0, per_regime), rng.uniform(30.0, 60.0, per_regime)
    gamma[r == 8], phi[r == 8] = rng.uniform(1.1, 2.0, per_regime), 0.0
    weight = m * g
    values = {
        "mass": m, "mu": mu, "gravity": g, "excitation_angle": angle, "track_inclination": incline,
        "static_ratio": ratio, "excitation_phase": phase, "restitution": e,
        "landing_friction": np.where(rng.random(n) < 0.5, "impulsive", "none"),
        "excitation_amplitude": gamma * weight * np.cos(np.radians(incline)),
        "drive_force": phi * mu * weight, "excitation_frequency": rng.uniform(5.0, 120.0, n),
    }
    return values, regimes


def extrapolation_bound(scalar: BatchResult, values: dict[str, Any]) -> dict[str, np.ndarray]:
    """How far the periodic shortcut may round differently from stepping, per slider.

    Stepped, x at period n is the double-double position rounded once; the
    shortcut adds q*(x_now - x_first) to a recorded x: one rounding of the
    difference, one of the product, one of the sum, each at most an ulp of the
    largest |x| passed, times q <= settle + periods repeats: (settle + periods +
    3) * eps * max|x|.  The mean velocity divides the difference of two such x by
    the window; the stuck and flight times, sums of durations up to the window's
    end t_end, err the same way relative to t_end."""
    eps = np.finfo(float).eps
    repeats = SETTLE + PERIODS + 3
    duration = PERIODS / np.asarray(values["excitation_frequency"])
    t_end = (SETTLE + PERIODS) / np.asarray(values["excitation_frequency"])
    travel = np.abs(scalar.mean_velocity) * duration  # |x_end - x_begin| (x starts at 0: max|x| <= that plus settle's)
    x_scale = travel * (SETTLE + PERIODS) / PERIODS + np.finfo(float).tiny
    return {"mean_velocity": 2 * repeats * eps * x_scale / duration,
            "flight_fraction": 2 * repeats * eps * t_end / duration,
            "stick_fraction": 2 * repeats * eps * t_end / duration}


@pytest.fixture(scope="module")
def mixed() -> tuple[dict[str, Any], np.ndarray, BatchResult]:
    """A mixed population and its single-slider results."""
    values, regimes = mixed_population(seed=12, per_regime=14)
    scalar = run_batch(values, settle_periods=SETTLE, periods=PERIODS, engine="scalar")
    return values, regimes, scalar


def test_the_compiled_engine_is_the_single_slider_bit_for_bit(
        mixed: tuple[dict[str, Any], np.ndarray, BatchResult]) -> None:
    """Every event computed: the same numbers to the last bit on every slider, chaotic ones too."""
    values, regimes, scalar = mixed
    batch = run_batch(values, settle_periods=SETTLE, periods=PERIODS, periodic_shortcut=False)
    assert batch.n == regimes.size and batch.settle_periods == SETTLE and batch.periods == PERIODS
    for name in ("mean_velocity", "u", "flight_fraction", "stick_fraction"):
        np.testing.assert_array_equal(getattr(batch, name), getattr(scalar, name), err_msg=name)
    for kind in EVENT_KINDS:
        np.testing.assert_array_equal(batch.event_counts[kind], scalar.event_counts[kind], err_msg=kind)
    np.testing.assert_array_equal(batch.u, batch.mean_velocity * values["excitation_frequency"]
                                  / (values["gravity"] * values["mu"]))


def test_the_periodic_shortcut_rounds_within_its_bound(mixed: tuple[dict[str, Any], np.ndarray, BatchResult]) -> None:
    values, regimes, scalar = mixed
    batch = run_batch(values, settle_periods=SETTLE, periods=PERIODS)
    bound = extrapolation_bound(scalar, values)
    for name in ("mean_velocity", "flight_fraction", "stick_fraction"):
        error = np.abs(getattr(batch, name) - getattr(scalar, name))
        assert np.all(error <= bound[name]), (name, int(np.argmax(error / bound[name])))
    for kind in EVENT_KINDS:
        np.testing.assert_array_equal(batch.event_counts[kind], scalar.event_counts[kind], err_msg=kind)
    extrapolated = np.flatnonzero(batch.mean_velocity != scalar.mean_velocity)
    assert extrapolated.size > regimes.size // 4, "the shortcut was taken (else this test checks nothing)"


def test_the_mixed_population_covers_every_regime(
        mixed: tuple[dict[str, Any], np.ndarray, BatchResult]) -> None:
    """The agreement above means something only if every regime actually ran."""
    _, regimes, scalar = mixed
    counts = scalar.event_counts
    moving = scalar.mean_velocity != 0.0
    assert np.all(~moving[regimes == 1])
    np.testing.assert_allclose(scalar.stick_fraction[regimes == 1], 1.0, rtol=1e-12)
    assert np.all(counts["stick"][regimes == 0] == PERIODS)  # Kostek: one slip per period
    assert np.all(scalar.flight_fraction[regimes == 2] == 0.0) and np.any(moving[regimes == 2])
    assert np.all(counts["lift_off"][regimes == 3] == PERIODS)  # hopping every period
    multi = (regimes == 4) & (counts["lift_off"] < PERIODS) & (scalar.flight_fraction > 0.9)
    assert multi.sum() >= 3  # flights over several periods
    bouncing = (regimes == 5) & (counts["landing"] > counts["lift_off"])
    assert bouncing.sum() >= 3
    impulsive = np.asarray(mixed[0]["landing_friction"]) == "impulsive"
    assert np.any(bouncing & impulsive) and np.any(bouncing & ~impulsive)
    assert np.any(scalar.mean_velocity[regimes == 6] < 0.0)  # backward slips on the slope
    assert np.any(counts["reversal"] > 0)
    assert np.any(moving[regimes == 7])


def test_one_slider_equals_the_slider_itself() -> None:
    """run_batch of one slider against Slider run by hand, with its cycle marks: bit for bit."""
    params, inputs = SliderParams(mu=0.4, excitation_angle=40.0, restitution=0.3), Inputs(
        drive_force=0.2, excitation_amplitude=18.0, excitation_frequency=30.0)
    values = {name: getattr(params, name) for name in ("mu", "excitation_angle", "restitution")}
    values |= {"drive_force": 0.2, "excitation_amplitude": 18.0, "excitation_frequency": 30.0}
    slider = Slider(params, inputs, event_log_size=None, cycle_log_size=None)
    slider.advance_to(9.5 / 30.0)
    marks = {mark.n: mark for mark in slider.cycle_marks}
    begin, end = marks[3], marks[9]
    result = run_batch(values, settle_periods=3, periods=6, periodic_shortcut=False)
    duration = 6 / 30.0
    assert result.n == 1
    assert result.mean_velocity[0] == (end.x - begin.x) / duration
    assert result.flight_fraction[0] == (end.flight_time - begin.flight_time) / duration
    assert result.stick_fraction[0] == (end.stuck_time - begin.stuck_time) / duration
    window = [event for event in slider.events if begin.t <= event.t < end.t]
    for kind in EVENT_KINDS:
        assert result.event_counts[kind][0] == sum(event.kind.value == kind for event in window)


def test_kostek_sliders_convey_at_the_closed_form() -> None:
    phi = np.array([0.7, 0.3, 0.95, 0.5, -0.7, 0.2])
    a = np.array([0.5, 0.75, 0.1, 0.5, 0.6, 0.3])
    result = run_batch({"drive_force": phi * 1.0, "excitation_amplitude": a * 10.0}, settle_periods=5, periods=50)
    np.testing.assert_allclose(result.u, u_map(phi, a), rtol=1e-9, atol=0.0)
    moves = np.abs(phi) > 1.0 - a
    assert list(moves) == [True, True, True, False, True, False]  # (0.5, 0.5): on the boundary
    np.testing.assert_array_equal(result.event_counts["slip_start"], np.where(moves, 50, 0))
    np.testing.assert_array_equal(result.event_counts["stick"], np.where(moves, 50, 0))


@pytest.mark.parametrize("engine", ["compiled", "scalar"])
def test_one_period_flights_convey_at_cot_beta_over_two_mu(engine: str) -> None:
    beta = np.array([30.0, 45.0, 60.0, 30.0])
    mu = np.array([0.3, 0.5, 0.3, 0.5])
    result = run_batch({"excitation_angle": beta, "mu": mu, "drive_force": 0.0,
                        "excitation_amplitude": GAMMA_1 * 10.0}, settle_periods=4, periods=20, engine=engine)
    cot = np.cos(np.radians(beta)) / np.sin(np.radians(beta))
    np.testing.assert_allclose(result.u, cot / (2.0 * mu), rtol=1e-9)
    np.testing.assert_allclose(result.flight_fraction, 1.0, atol=1e-9)
    assert np.all(result.event_counts["lift_off"] == 20) and np.all(result.event_counts["landing"] == 20)


def test_sliders_that_never_move_or_fly_away_for_good_finish() -> None:
    """No event ever (stuck for good) and one lift-off at t = 0 with no landing
    (Fz above the weight): both are done at once, whatever the window."""
    values = {"drive_force": [0.0, 0.1, 0.7, 0.0], "excitation_amplitude": [0.0, 2.0, 5.0, 3.0],
              "external_force_z": [0.0, 0.0, 0.0, 12.0]}
    for periods in (10, 1_000_000):
        result = run_batch(values, settle_periods=10, periods=periods, sample_times=[0.0, 0.01, 1.0])
        np.testing.assert_array_equal(result.mean_velocity[[0, 1, 3]], 0.0)
        # (stuck time at the end - at the start)/window: three roundings, <= 2 ulp (4.4e-16) from 1
        np.testing.assert_allclose(result.stick_fraction[:2], 1.0, rtol=1e-15)
        assert result.flight_fraction[3] == pytest.approx(1.0, rel=1e-15) and result.stick_fraction[3] == 0.0
        assert result.mean_velocity[2] > 0.0
        for kind in EVENT_KINDS:
            assert result.event_counts[kind][0] == result.event_counts[kind][1] == result.event_counts[kind][3] == 0
        assert result.samples is not None
        assert result.samples.z[3, 2] > 1.0  # (Fz - m g)/m * t^2/2 = 1 m at 1 s, plus the oscillation
        assert list(result.samples.mode[3]) == [2, 2, 2]


def test_samples_equal_slider_sample() -> None:
    values, _ = mixed_population(seed=5, per_regime=3)
    times = np.concatenate(([0.0], np.sort(np.random.default_rng(3).uniform(0.0, 0.4, 60)), [0.4]))
    result = run_batch(values, settle_periods=2, periods=3, sample_times=times)
    assert result.samples is not None
    np.testing.assert_array_equal(result.samples.t, times)
    batch = result.samples
    for i in range(batch.x.shape[0]):
        params = SliderParams(**{name: (str(v[i]) if name == "landing_friction" else float(v[i]))
                                 for name, v in values.items() if name in SliderParams.__dataclass_fields__})
        inputs = Inputs(**{name: float(v[i]) for name, v in values.items() if name in Inputs.__dataclass_fields__})
        reference = Slider(params, inputs).sample(times)
        np.testing.assert_array_equal(batch.mode[i], reference.mode)
        for name in ("x", "v", "z", "vz"):
            # The same closed forms at the same times, with libm's sin (compiled) against numpy's
            # (Slider.sample): each within an ulp or so of the true value, and a state sums a few
            # sinusoids of the segment's scale, so they agree within 16 ulp of that scale.
            want, got = getattr(reference, name), getattr(batch, name)[i]
            scale = max(float(np.max(np.abs(want))), 1e-300)
            assert np.max(np.abs(got - want)) <= 16 * np.finfo(float).eps * scale, (i, name)


def test_scalars_broadcast_and_missing_fields_take_their_defaults() -> None:
    one = run_batch({}, settle_periods=2, periods=4)
    assert one.n == 1
    many = run_batch({"mu": 0.1, "drive_force": [0.7, 0.7, 0.7]}, settle_periods=2, periods=4)
    assert many.n == 3
    np.testing.assert_array_equal(many.mean_velocity, np.repeat(one.mean_velocity, 3))
    assert set(many.event_counts) == set(EVENT_KINDS)


@pytest.mark.parametrize(("values", "words"), [
    ({"mu": [0.1, 0.2, -1.0, 20.0]}, ["mu = -1.0", "[1e-06, 10]", "index 2"]),
    ({"excitation_angle": np.array([90.0, 0.0])}, ["excitation_angle = 0.0", "[0.1, 90]", "index 1"]),
    ({"mass": [1.0, float("nan")]}, ["mass = nan", "finite", "index 1"]),
    ({"landing_friction": ["none", "sticky"]}, ["landing_friction = 'sticky'", "impulsive, none", "index 1"]),
    ({"mu": [0.1, "a"]}, ["mu = 'a'", "index 1"]),
    ({"mu": [0.1, True]}, ["mu = True", "index 1"]),
    ({"gravity": 0.0}, ["gravity = 0.0", "[1e-06, 1000]"]),
    ({"friction": 0.1}, ["friction", "unknown field", "mu"]),
    ({"mu": [0.1, 0.2], "mass": [1.0, 2.0, 3.0]}, ["mass", "length of mu (2)"]),
    ({"mu": [[0.1]]}, ["mu", "1-d"]),
    ({"mu": []}, ["mu", "one value per slider"]),
])
def test_a_bad_value_is_refused_naming_field_value_index_and_limit(values: dict[str, Any], words: list[str]) -> None:
    with pytest.raises(ParameterError) as caught:
        run_batch(values, settle_periods=1, periods=1)
    for word in words:
        assert word in str(caught.value)


@pytest.mark.parametrize(("kwargs", "words"), [
    ({"settle_periods": -1}, ["settle_periods = -1", ">= 0"]),
    ({"periods": 0}, ["periods = 0", ">= 1"]),
    ({"engine": "gpu"}, ["engine = 'gpu'", "compiled, scalar"]),
    ({"engine": "numpy"}, ["engine = 'numpy'", "compiled, scalar"]),
    ({"sample_times": [0.2, 0.1]}, ["sample_times = 0.1", "ascend", "index 1"]),
    ({"sample_times": [-1.0]}, ["sample_times = -1.0", "index 0"]),
    ({"threads": 0}, ["threads = 0", ">= 1"]),
])
def test_bad_run_arguments_are_refused(kwargs: dict[str, Any], words: list[str]) -> None:
    arguments: dict[str, Any] = {"settle_periods": 1, "periods": 1} | kwargs
    with pytest.raises(ParameterError) as caught:
        run_batch({}, **arguments)
    for word in words:
        assert word in str(caught.value)


def test_a_slider_s_result_does_not_depend_on_the_others_in_its_batch() -> None:
    """Bit for bit, in any split and order (a sweep's results must not depend on its chunking)."""
    values, regimes = mixed_population(seed=3, per_regime=6)
    times = np.linspace(0.0, 0.3, 7)
    whole = run_batch(values, settle_periods=6, periods=10, sample_times=times)
    order = np.random.default_rng(0).permutation(regimes.size)
    for part in (order[:7], order[7:30], order[30:]):
        piece = run_batch({name: (column[part] if np.ndim(column) else column) for name, column in values.items()},
                          settle_periods=6, periods=10, sample_times=times)
        for name in ("mean_velocity", "u", "flight_fraction", "stick_fraction"):
            np.testing.assert_array_equal(getattr(piece, name), getattr(whole, name)[part])
        for kind in EVENT_KINDS:
            np.testing.assert_array_equal(piece.event_counts[kind], whole.event_counts[kind][part])
        assert piece.samples is not None and whole.samples is not None
        for name in ("x", "v", "z", "vz", "mode"):
            np.testing.assert_array_equal(getattr(piece.samples, name), getattr(whole.samples, name)[part])


@st.composite
def populations(draw: st.DrawFn) -> dict[str, Any]:
    """A few sliders drawn over every regime: any angle, phase, slope, static ratio,
    restitution and landing law, drive forces both ways, throw numbers from 0 to 5."""
    n = draw(st.integers(1, 6))

    def column(low: float, high: float) -> list[float]:
        return draw(st.lists(st.floats(low, high, allow_nan=False), min_size=n, max_size=n))

    mass, gravity = column(0.2, 3.0), column(1.0, 20.0)
    gamma, incline = column(0.0, 5.0), column(-10.0, 10.0)
    weight = np.asarray(mass) * np.asarray(gravity)
    return {
        "mass": mass, "gravity": gravity, "mu": column(0.05, 1.0), "static_ratio": column(1.0, 2.0),
        "excitation_angle": draw(st.lists(st.sampled_from([90.0, 60.0, 30.0, 12.5]) | st.floats(10.0, 90.0),
                                          min_size=n, max_size=n)),
        "excitation_phase": draw(st.lists(st.sampled_from([0.0, 90.0, -45.0]) | st.floats(-180.0, 180.0),
                                          min_size=n, max_size=n)),
        "track_inclination": incline, "restitution": column(0.0, 0.9),
        "landing_friction": draw(st.lists(st.sampled_from(["impulsive", "none"]), min_size=n, max_size=n)),
        "excitation_amplitude": np.asarray(gamma) * weight * np.cos(np.radians(incline)),
        "drive_force": np.asarray(column(-1.5, 1.5)) * weight * 0.5, "excitation_frequency": column(5.0, 200.0),
    }


@settings(max_examples=30, deadline=None)
@given(populations())
def test_any_population_runs_compiled_as_the_single_slider_runs_it(values: dict[str, Any]) -> None:
    """Hypothesis over every regime: every event computed, the compiled engine is the
    single slider bit for bit, samples included up to numpy's sin (see above)."""
    times = np.linspace(0.0, 0.05, 5)
    scalar = run_batch(values, settle_periods=2, periods=6, engine="scalar", sample_times=times)
    compiled = run_batch(values, settle_periods=2, periods=6, periodic_shortcut=False, sample_times=times)
    for name in ("mean_velocity", "flight_fraction", "stick_fraction"):
        np.testing.assert_array_equal(getattr(compiled, name), getattr(scalar, name), err_msg=name)
    for kind in EVENT_KINDS:
        np.testing.assert_array_equal(compiled.event_counts[kind], scalar.event_counts[kind], err_msg=kind)
    assert compiled.samples is not None and scalar.samples is not None
    np.testing.assert_array_equal(compiled.samples.mode, scalar.samples.mode)
