"""The control law at the edges of what it accepts (issue 10, item 3).

Every accepted input keeps the law finite; samples no plant in force could
produce are refused with the value and the limit, and nothing refused or
non-finite reaches the state; legitimate samples from simulated runs (the
exact core, with changes of drive force, amplitude and frequency, runaway
included) are never refused.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from friction_sim.core.control import reach
from friction_sim.core.control.integral import RATIO_LIMITS
from friction_sim.core.control.law import ControllerConfig, MeanSpeedController
from friction_sim.core.control.reach import ControlOutput
from friction_sim.core.control.speedlimit import LIMIT_SLACK_SAMPLES, speed_limit
from friction_sim.core.model import spec
from friction_sim.core.model.commands import Command
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.errors import ParameterError

NS = 1_000_000_000
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
RUNS = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def in_range(setting: spec.Setting) -> st.SearchStrategy[float]:
    """Any float the setting accepts, its edges and subnormals included."""
    assert setting.low is not None and setting.high is not None
    return st.one_of(st.floats(setting.low, setting.high), st.sampled_from([setting.low, setting.high]))


def any_float() -> st.SearchStrategy[float]:
    return st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                     st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e300, 1e-321, -5e-324, 0.0, -0.0]))


plants = st.builds(SliderParams, mass=in_range(spec.MASS), mu=in_range(spec.MU), gravity=in_range(spec.GRAVITY))
#: Below 1 on Kostek's model the law inverts his exact map (the path of issue 10).
below_lift_off = st.one_of(st.floats(spec.MAX_AMPLITUDE_RATIO.low or 0.0, 1.0, exclude_max=True),
                           st.sampled_from([spec.MAX_AMPLITUDE_RATIO.low or 0.0, 0.9999999999999999]))
configs = st.builds(ControllerConfig, model=plants, integral_gain=in_range(spec.INTEGRAL_GAIN),
                    max_amplitude_ratio=below_lift_off,
                    mean_window_periods=st.one_of(st.integers(1, 3), st.just(spec.MAX_MEAN_WINDOW)),
                    settle_margin=in_range(spec.SETTLE_MARGIN))
#: Any model of issue 11, and any limit up to 10 (hopping): the law inverts the general mean speed.
general_plants = st.builds(
    SliderParams, mass=in_range(spec.MASS), mu=in_range(spec.MU), gravity=in_range(spec.GRAVITY),
    static_ratio=st.floats(1.0, 3.0), excitation_angle=in_range(spec.EXCITATION_ANGLE),
    excitation_phase=in_range(spec.EXCITATION_PHASE), track_inclination=in_range(spec.TRACK_INCLINATION),
    restitution=st.sampled_from([0.0, 0.2]), landing_friction=st.sampled_from(spec.LANDING_FRICTION.choices))
general_configs = st.builds(ControllerConfig, model=general_plants, integral_gain=in_range(spec.INTEGRAL_GAIN),
                            max_amplitude_ratio=in_range(spec.MAX_AMPLITUDE_RATIO),
                            mean_window_periods=st.integers(1, 3), settle_margin=in_range(spec.SETTLE_MARGIN))
GENERAL = settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def state(controller: MeanSpeedController) -> dict[str, Any]:
    """Everything the controller holds but its sample clock (observations, kept on purpose)."""
    return {k: v for k, v in vars(controller).items() if k != "clock"}


def same(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Equal, NaN equal to NaN (repr tells 0.0 from -0.0 and nan from nan alike)."""
    return repr(a) == repr(b)


def ratio(controller: MeanSpeedController) -> float:
    """The state r = U_cmd/U* (integral = U* (r - 1); read directly, for U* may be 0)."""
    value: float = vars(controller)["_ratio"]
    return value


def check_finite(controller: MeanSpeedController) -> None:
    out: ControlOutput = controller.output
    config = controller.config
    top, weight = config.max_amplitude_ratio, config.model.weight
    assert 0.0 <= out.applied_ratio <= top
    assert 0.0 <= out.amplitude <= top * weight * (1 + 1e-15)
    for value in (out.amplitude, out.u_target, out.phi, out.integral, out.target_speed):
        assert math.isfinite(value), out
    assert math.isfinite(out.feedforward_ratio) or out.unreachable or out.runaway, out
    if math.isfinite(out.feedforward_ratio):
        assert 0.0 <= out.feedforward_ratio <= top
    assert RATIO_LIMITS[0] <= ratio(controller) <= RATIO_LIMITS[1]
    assert math.isnan(controller.measured_speed) or math.isfinite(controller.measured_speed)
    assert controller.sample_limit > 0.0 or controller.drive_force == 0.0 or abs(controller.drive_force) < 1e-300


# -- the cases of the issue ---------------------------------------------------------


def test_a_target_below_floating_point_resolution_asks_for_standing_still() -> None:
    """f = 1 mHz, Fd = 0.01 N, V* = 1e-321 m/s were all in range and raised
    ZeroDivisionError (U* is 0 in floating point, and so was U at the top)."""
    controller = MeanSpeedController(ControllerConfig(), drive_force=0.01, frequency=0.001, target_speed=1e-321)
    out = controller.output
    assert out.u_target == 0.0 and out.amplitude == 0.0 and not out.unreachable
    check_finite(controller)
    controller.clock.note_change(0)
    for n in range(1, 6):  # clean samples: nothing to integrate for a zero U*
        controller.on_mean_velocity(0.0, n * 1000.0, n * 1000 * NS)
    check_finite(controller)
    assert controller.set_target(2e-8).u_target > 0.0


def test_samples_no_plant_could_produce_are_refused_and_the_state_stays() -> None:
    """-1e300 then 1e308 made the integral NaN for good, and no new target
    revived it; now both are refused with the limit, nothing changes, and the
    next real sample is integrated as before."""
    controller = MeanSpeedController(ControllerConfig(model=SliderParams(mu=0.12)), drive_force=0.7,
                                     frequency=50.0, target_speed=2e-4)
    controller.clock.note_change(0)
    for n in range(1, 4):
        controller.on_mean_velocity(1.5e-4, 0.1 * n, n * NS // 10)
    before = state(controller)
    limit = 2 * 0.7 / (1.0 * 50.0)
    for value in (-1e300, 1e308, math.nan, math.inf, -math.inf, limit * 1.0001, -limit * 1.0001):
        with pytest.raises(ParameterError) as caught:
            controller.on_mean_velocity(value, 0.5, NS // 2)
        assert "mean_velocity" in str(caught.value) and repr(value) in str(caught.value)
        if math.isfinite(value):
            assert "0.028 m/s" in str(caught.value) and "Fd = 0.7 N" in str(caught.value)
        assert same(state(controller), before)
    controller.on_mean_velocity(-limit, 0.6, 6 * NS // 10)  # backwards as fast as forwards: possible, not clean
    integral = controller.output.integral
    controller.on_mean_velocity(1.5e-4, 0.7, 7 * NS // 10)
    assert controller.output.integral != integral and math.isfinite(controller.output.integral)
    check_finite(controller)


def test_the_state_cannot_sink_to_zero_and_stay_there() -> None:
    """Hundreds of samples far too fast shrink r by up to 4 each; r used to
    underflow to 0, from which no multiplicative step brings it back (Pa
    stuck at 0).  It stops at the lower bound and climbs back."""
    controller = MeanSpeedController(ControllerConfig(), drive_force=0.7, frequency=50.0, target_speed=2e-4)
    controller.clock.note_change(0)
    fast = 0.9 * speed_limit(0.7, SliderParams(), 50.0)
    n = 0
    for n in range(1, 700):
        controller.on_mean_velocity(fast, 0.02 * n, n * 20_000_000)
    assert ratio(controller) == RATIO_LIMITS[0]
    check_finite(controller)
    for m in range(n + 1, n + 60):
        controller.on_mean_velocity(0.0, 0.02 * m, m * 20_000_000)
    assert controller.output.applied_ratio > 0.5, "back up from the bottom"


def test_a_fault_in_the_relation_leaves_the_controller_as_it_was(monkeypatch: pytest.MonkeyPatch) -> None:
    controller = MeanSpeedController(ControllerConfig(), drive_force=0.7, frequency=50.0, target_speed=2e-4)
    before = state(controller)

    def broken(u: float, phi: float, top: float) -> float:
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(reach, "inverse", broken)
    for change in (lambda: controller.set_target(3e-4), lambda: controller.set_drive_force(0.75),
                   lambda: controller.set_frequency(60.0)):
        with pytest.raises(ZeroDivisionError):
            change()
        assert same(state(controller), before)


# -- the whole accepted range ---------------------------------------------------------


@FUZZ
@given(config=configs, drive=in_range(spec.DRIVE_FORCE), frequency=in_range(spec.EXCITATION_FREQUENCY),
       target=in_range(spec.TARGET_SPEED), data=st.data())
def test_the_law_stays_finite_over_the_whole_accepted_range(config: ControllerConfig, drive: float, frequency: float,
                                                             target: float, data: st.DataObject) -> None:
    exercise(config, drive, frequency, target, data, configs, 25)


@GENERAL
@given(config=general_configs, drive=st.one_of(in_range(spec.DRIVE_FORCE), st.floats(-1.0, 1.0)),
       frequency=in_range(spec.EXCITATION_FREQUENCY), target=in_range(spec.TARGET_SPEED), data=st.data())
def test_the_general_law_stays_finite_over_the_whole_accepted_range(
        config: ControllerConfig, drive: float, frequency: float, target: float, data: st.DataObject) -> None:
    """The same on any model of issue 11 (the rising branch of the general
    mean speed: a_start <= a <= a_end <= max_amplitude_ratio)."""
    exercise(config, drive, frequency, target, data, st.one_of(configs, general_configs), 10)


def exercise(config: ControllerConfig, drive: float, frequency: float, target: float, data: st.DataObject,
             new_configs: st.SearchStrategy[ControllerConfig], steps: int) -> None:
    """Random inputs, samples and configurations: every refusal changes
    nothing, and the law stays finite throughout."""
    controller = MeanSpeedController(config, drive_force=drive, frequency=frequency)
    try:
        controller.set_target(target)
    except ParameterError as error:
        assert "target_speed" in str(error)
    check_finite(controller)
    controller.clock.note_change(0)
    for n in range(1, steps):
        kind = data.draw(st.sampled_from(["sample", "sample", "sample", "legit", "legit", "legit", "target",
                                          "drive", "frequency", "config"]))
        before = state(controller)
        try:
            if kind == "legit":  # within what the plant can do: mostly clean samples, integrated
                limit = controller.sample_limit
                scale = limit if math.isfinite(limit) else 1.0
                value = data.draw(st.floats(-1.0, 1.0)) * scale
                controller.on_mean_velocity(value, 1000.0 * n, n * 1000 * NS)
            elif kind == "sample":
                value = data.draw(any_float())
                accepted = math.isfinite(value) and abs(value) <= controller.sample_limit
                try:
                    controller.on_mean_velocity(value, 1000.0 * n, n * 1000 * NS)
                except ParameterError:
                    assert not accepted, "a sample within the limit is taken"
                    raise
                assert accepted, "a sample beyond the limit is refused"
            elif kind == "target":
                controller.set_target(data.draw(st.one_of(in_range(spec.TARGET_SPEED), any_float())))
            elif kind == "drive":
                controller.set_drive_force(data.draw(st.one_of(in_range(spec.DRIVE_FORCE), any_float())))
            elif kind == "frequency":
                controller.set_frequency(data.draw(st.one_of(in_range(spec.EXCITATION_FREQUENCY), any_float())))
            else:
                controller.config = data.draw(new_configs)
        except ParameterError:
            assert same(state(controller), before), "a refusal changes nothing"
        check_finite(controller)


# -- legitimate samples from simulated runs -------------------------------------------------


@dataclass(frozen=True)
class Change:
    at: float  # in periods from the start
    field: str
    value: float  # phi, a, or a factor of the frequency


changes = st.one_of(
    st.builds(Change, st.floats(0.0, 60.0), st.just("drive_force"), st.floats(-1.4, 1.4)),
    st.builds(Change, st.floats(0.0, 60.0), st.just("excitation_amplitude"), st.floats(0.0, 0.99)),
    st.builds(Change, st.floats(0.0, 60.0), st.just("excitation_frequency"), st.floats(0.05, 20.0)),
)


def simulated_run(plant: SliderParams, frequency: float, phi: float, a: float, window: int,
                  schedule: list[Change], periods: int = 80,
                  top: float = 0.95) -> tuple[MeanSpeedController, list[float]]:
    """The exact core in simulated real time (ticks four per period), the
    controller following its drive force and frequency and judging every
    mean_velocity it publishes; returns the controller and the samples."""
    weight = plant.weight
    inputs = Inputs(drive_force=phi * plant.mu * weight, excitation_amplitude=a * weight,
                    excitation_frequency=frequency)
    rt = RealtimeSlider(plant, inputs, wall_ns=0, mean_window_periods=window, publish_rate=1000.0)
    controller = MeanSpeedController(ControllerConfig(model=plant, mean_window_periods=window, max_amplitude_ratio=top),
                                     drive_force=inputs.drive_force, frequency=frequency)
    samples: list[float] = []
    pending = sorted(schedule, key=lambda c: c.at)
    t, period = 0.0, 1.0 / frequency
    for _ in range(4 * periods):
        t += period / 4
        wall = round(t * NS)
        while pending and pending[0].at * period <= t:
            change = pending.pop(0)
            value = {"drive_force": change.value * plant.mu * weight, "excitation_amplitude": change.value * weight,
                     "excitation_frequency": min(rt.slider.inputs.excitation_frequency * change.value, 2e4)}
            command = Command(rt.now(wall), change.field, {change.field: value[change.field]})
            if rt.command(command, wall).accepted:
                controller.set_drive_force(rt.slider.inputs.drive_force)
                controller.set_frequency(rt.slider.inputs.excitation_frequency)
                period = 1.0 / rt.slider.inputs.excitation_frequency
        for summary in rt.tick(wall).periods:
            samples.append(summary.mean_velocity)
            controller.on_mean_velocity(summary.mean_velocity, summary.t, wall)  # raises if refused
    return controller, samples


@RUNS
@given(mass=st.floats(1e-3, 1e3), mu=st.floats(0.01, 2.0), gravity=st.floats(0.1, 100.0),
       frequency=st.floats(0.5, 500.0), phi=st.floats(-0.99, 0.99), a=st.floats(0.0, 0.99),
       window=st.integers(1, 4), schedule=st.lists(changes, max_size=6))
def test_no_simulated_plant_has_a_sample_refused(mass: float, mu: float, gravity: float, frequency: float,
                                                  phi: float, a: float, window: int,
                                                  schedule: list[Change]) -> None:
    plant = SliderParams(mass=mass, mu=mu, gravity=gravity)
    controller, samples = simulated_run(plant, frequency, phi, a, window, schedule)
    assert len(samples) > 10
    check_finite(controller)


general_changes = st.one_of(
    st.builds(Change, st.floats(0.0, 40.0), st.just("drive_force"), st.floats(-0.5, 0.5)),
    st.builds(Change, st.floats(0.0, 40.0), st.just("excitation_amplitude"), st.floats(0.0, 3.0)),
    st.builds(Change, st.floats(0.0, 40.0), st.just("excitation_frequency"), st.floats(0.2, 5.0)),
)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mu=st.floats(0.1, 1.0), angle=st.floats(20.0, 90.0), phase=st.floats(-180.0, 180.0),
       inclination=st.floats(-10.0, 10.0), static=st.floats(1.0, 2.0), restitution=st.sampled_from([0.0, 0.2]),
       landing=st.sampled_from(spec.LANDING_FRICTION.choices), a=st.floats(0.0, 3.0),
       schedule=st.lists(general_changes, max_size=4))
def test_no_simulated_hopping_plant_has_a_sample_refused(mu: float, angle: float, phase: float, inclination: float,
                                                         static: float, restitution: float, landing: str, a: float,
                                                         schedule: list[Change]) -> None:
    """The general sample limit (issue 11) holds for every window of a real
    run: a tilted vibration, a slope, mu_s > mu, bounces, Pa up to 3 m g."""
    plant = SliderParams(mu=mu, excitation_angle=angle, excitation_phase=phase, track_inclination=inclination,
                         static_ratio=static, restitution=restitution, landing_friction=landing)
    controller, samples = simulated_run(plant, 20.0, 0.0, a, 1, schedule, periods=50, top=3.0)
    assert len(samples) > 10
    check_finite(controller)


def test_windows_from_before_a_frequency_rise_are_still_taken() -> None:
    """At 1 Hz the slider creeps faster than the limit at 100 Hz allows;
    windows that began before the change arrive after it, and the slip under
    way carries its speed on for a while."""
    plant = SliderParams()
    controller, samples = simulated_run(plant, 1.0, 0.7, 0.5, 3, [Change(10.3, "excitation_frequency", 100.0)],
                                        periods=200)
    new_limit = speed_limit(0.7 * plant.mu * plant.weight, plant, 100.0)
    assert max(abs(v) for v in samples) > new_limit, "samples beyond the new limit came"
    assert controller.sample_limit == new_limit, "then it shrank"


def test_a_slider_coming_back_from_a_runaway_is_followed() -> None:
    """phi 1.3 for 80 periods: the slider gains speed without bound, and after
    the drive drops it needs about as long to come back: every sample holds."""
    plant = SliderParams()
    controller, samples = simulated_run(plant, 50.0, 0.7, 0.5, 1,
                                        [Change(5.0, "drive_force", 1.3), Change(85.0, "drive_force", 0.7)],
                                        periods=300)
    limit = speed_limit(0.7 * plant.mu * plant.weight, plant, 50.0)
    assert max(samples) > 10 * limit, "the runaway went far beyond the periodic limit"
    assert controller.sample_limit == limit, "and the limit came back with the plant"
    with pytest.raises(ParameterError):
        controller.on_mean_velocity(1.01 * limit, 10.0, 10 * NS)


def test_the_limit_stays_for_the_windows_on_their_way() -> None:
    """After a change the old limit holds for the window plus the queued samples."""
    controller = MeanSpeedController(ControllerConfig(mean_window_periods=2), drive_force=0.7, frequency=10.0)
    old = controller.sample_limit
    controller.set_frequency(100.0)
    assert controller.sample_limit == old
    for n in range(2 + LIMIT_SLACK_SAMPLES):
        controller.on_mean_velocity(0.9 * old, 0.01 * n, n)
    assert controller.sample_limit == old, "not before a sample within the new limit"
    controller.on_mean_velocity(0.0, 1.0, 100)
    assert controller.sample_limit == speed_limit(0.7, SliderParams(), 100.0) < old


def _refusal(config: ControllerConfig, drive_force: float, frequency: float) -> tuple[str, float]:
    """The words of a refused sample and the limit in force."""
    controller = MeanSpeedController(config, drive_force=drive_force, frequency=frequency,
                                     target_speed=math.copysign(1e-4, drive_force))
    limit = controller.sample_limit
    with pytest.raises(ParameterError) as refused:
        controller.on_mean_velocity(2.0 * limit, 0.1, NS)
    return str(refused.value), limit


def _number(text: str) -> float:
    return float(text.rstrip("."))


@pytest.mark.parametrize("drive_force, frequency", [(0.8, 50.0), (0.3, 100.0), (-0.5, 20.0)])
def test_a_refusal_prints_the_formula_it_applied_in_kostek_s_model(drive_force: float, frequency: float) -> None:
    """Issue 23, defect 3: the printed formula, evaluated with the printed
    numbers, gives the printed limit, and that is the limit in force."""
    words, limit = _refusal(ControllerConfig(), drive_force, frequency)
    found = re.search(r"(\S+) \|Fd\|/\(m f\) = (\S+) m/s for Fd = (\S+) N, m = (\S+) kg, f = (\S+) Hz", words)
    assert found, words
    factor, value, force, mass, freq = (_number(group) for group in found.groups())
    assert force == pytest.approx(drive_force, rel=1e-6) and freq == frequency and mass == 1.0
    assert value == pytest.approx(factor * abs(force) / (mass * freq), rel=1e-5)  # 6 printed digits
    assert value == pytest.approx(limit, rel=1e-5)


def test_a_refusal_prints_the_formula_it_applied_beyond_kostek_s_model() -> None:
    """The hopping run of defect 3 (max_amplitude_ratio above 1: the general
    model's limit): the words name the max(...) rule that gave 0.06 m/s at
    Fd = 0.8 N, not 2 |Fd|/(m f) = 0.032 m/s."""
    words, limit = _refusal(ControllerConfig(max_amplitude_ratio=2.0), 0.8, 50.0)
    found = re.search(r"= max\((\S+), (\S+)\) = (\S+) m/s for \|Fd - m g sin\(alpha\)\| \+ Pt = (\S+) N", words)
    assert found, words
    by_pull, by_model, value, pull = (_number(group) for group in found.groups())
    assert by_pull == pytest.approx(2.0 * pull / (1.0 * 50.0), rel=1e-5)
    assert value == pytest.approx(max(by_pull, by_model), rel=1e-5) and value == pytest.approx(limit, rel=1e-5)
    assert "2 |Fd|/(m f) =" not in words
