"""The mean-speed control law, offline against the exact core: no ROS."""

from __future__ import annotations

import math
from typing import Any

import pytest

from friction_sim.core.control import law
from friction_sim.core.control.law import ControllerConfig, MeanSpeedController
from friction_sim.core.control.sampleclock import SampleClock
from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.urelation import amplitude_ratio_for, u_map
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.errors import ParameterError

# -- the law, offline -----------------------------------------------------------


def closed_loop_offline(controller: MeanSpeedController, plant: SliderParams, periods: int,
                        inputs: Inputs | None = None) -> list[float]:
    """Run the controller against the exact core, one sample per period, the
    output applied right after each sample (an ideal, latency-free loop)."""
    slider = Slider(plant, inputs or Inputs(excitation_amplitude=controller.output.amplitude),
                    cycle_log_size=None)
    slider.set_inputs(excitation_amplitude=controller.output.amplitude)
    controller.clock.note_change(0)
    speeds = []
    for n in range(1, periods + 1):
        t = n / controller.frequency
        slider.advance_to(t)
        previous, mark = slider.cycle_marks[-2:]
        speed = (mark.x - previous.x) / (mark.t - previous.t)
        speeds.append(speed)
        before = controller.output.amplitude
        out = controller.on_mean_velocity(speed, mark.t, round(t * 1e9))
        if out.amplitude != before:
            controller.clock.note_change(round(t * 1e9))
        slider.set_inputs(excitation_amplitude=out.amplitude)
    return speeds


def test_feedforward_is_the_exact_inverse_of_u() -> None:
    controller = MeanSpeedController(ControllerConfig(), drive_force=0.7, frequency=50.0, target_speed=3e-4)
    out = controller.output
    u_star = 3e-4 * 50.0 / (10.0 * 0.1)
    assert out.u_target == pytest.approx(u_star)
    assert out.feedforward_ratio == pytest.approx(amplitude_ratio_for(u_star, 0.7), rel=1e-12)
    assert u_map(0.7, out.applied_ratio) == pytest.approx(u_star, rel=1e-10)
    assert out.amplitude == pytest.approx(out.applied_ratio * 10.0)
    assert not (out.saturated or out.unreachable or out.runaway)


def test_matched_model_is_exact_from_the_first_clean_period() -> None:
    controller = MeanSpeedController(ControllerConfig(), drive_force=0.7, frequency=50.0, target_speed=1.5e-4)
    speeds = closed_loop_offline(controller, SliderParams(), 6)
    assert all(v == pytest.approx(1.5e-4, rel=1e-9) for v in speeds[1:])


def test_late_delivery_does_not_make_a_mixed_window_look_clean() -> None:
    """On a loaded machine the Pa reaches the plant late (here 0.4 period,
    after the slip has begun) and the samples come back late (here every
    other one by 0.3 period).  The window right after the change then mixes
    old and new motion yet arrives 1.3 periods after it, past the fixed
    margin; integrating it would move a matched model's exact feedforward off
    target.  The delivery jitter the controller observes keeps it out."""
    frequency, period, step_at = 50.0, 0.02, 60
    controller = MeanSpeedController(ControllerConfig(), drive_force=0.7, frequency=frequency, target_speed=1e-4)
    slider = Slider(SliderParams(), Inputs(excitation_amplitude=controller.output.amplitude), cycle_log_size=None)
    controller.clock.note_change(0)
    pending: tuple[float, float] | None = None  # (simulation time the plant applies it, Pa)
    speeds, integrals, x_start = [], [], 0.0
    for n in range(1, step_at + 11):
        t = n * period
        if pending is not None and pending[0] < t:
            slider.advance_to(pending[0])
            slider.set_inputs(excitation_amplitude=pending[1])
            pending = None
        slider.advance_to(t)
        speeds.append((slider.state().x - x_start) / period)  # over period n, which ends at t
        x_start = slider.state().x
        arrival = t + (0.3 * period if n % 2 else 0.0)
        before = controller.output.amplitude
        out = controller.on_mean_velocity(speeds[-1], t, round(arrival * 1e9))
        if n == step_at:
            out = controller.set_target(3e-4)
        if out.amplitude != before:
            controller.clock.note_change(round(arrival * 1e9))
            pending = (arrival + 0.4 * period, out.amplitude)
        integrals.append(out.integral)
    assert speeds[step_at] != pytest.approx(3e-4, rel=0.01), "the window after the change is mixed"
    assert max(abs(i) for i in integrals) < 1e-12, "no mixed window was integrated"
    assert all(v == pytest.approx(3e-4, rel=1e-9) for v in speeds[step_at + 1:])


@pytest.mark.parametrize("mu_model", [0.08, 0.12])
@pytest.mark.parametrize("target", [1e-4, 3e-4])
def test_a_wrong_model_is_corrected_by_the_integral_action(mu_model: float, target: float) -> None:
    controller = MeanSpeedController(ControllerConfig(model=SliderParams(mu=mu_model)), drive_force=0.7,
                                     frequency=50.0, target_speed=target)
    speeds = closed_loop_offline(controller, SliderParams(), 30)
    assert abs(speeds[0] - target) > 0.05 * target, "the model really is wrong"
    assert all(abs(v - target) <= 0.02 * target for v in speeds[20:])
    assert speeds[-1] == pytest.approx(target, rel=1e-6)


def test_unreachable_target_saturates_without_windup() -> None:
    controller = MeanSpeedController(ControllerConfig(), drive_force=0.7, frequency=50.0, target_speed=5e-3)
    out = controller.output
    assert out.unreachable and out.saturated and out.amplitude == pytest.approx(9.5)
    closed_loop_offline(controller, SliderParams(), 40)
    assert controller.output.integral == 0.0, "no windup while unreachable"
    controller.set_target(3e-4)
    assert not controller.output.unreachable
    assert controller.output.applied_ratio == pytest.approx(amplitude_ratio_for(3e-4 * 50.0, 0.7), rel=1e-12)


def test_target_zero_and_runaway_and_mirror() -> None:
    controller = MeanSpeedController(ControllerConfig(), drive_force=0.7, frequency=50.0, target_speed=2e-4)
    assert controller.set_target(0.0).amplitude == 0.0
    out = controller.set_drive_force(1.2)
    assert out.runaway and out.amplitude == 0.0
    backwards = MeanSpeedController(ControllerConfig(), drive_force=-0.7, frequency=50.0, target_speed=-2e-4)
    forwards = MeanSpeedController(ControllerConfig(), drive_force=0.7, frequency=50.0, target_speed=2e-4)
    assert backwards.output.amplitude == forwards.output.amplitude


@pytest.mark.parametrize(("value", "words"), [
    (-1e-4, ("target_speed", "-0.0001", "sign of drive_force")),
    (math.nan, ("target_speed", "nan")),
    (math.inf, ("target_speed", "inf")),
])
def test_bad_targets_are_rejected_and_the_last_valid_one_kept(value: float, words: tuple[str, ...]) -> None:
    controller = MeanSpeedController(ControllerConfig(), drive_force=0.7, frequency=50.0, target_speed=2e-4)
    with pytest.raises(ParameterError) as caught:
        controller.set_target(value)
    for word in words:
        assert word in str(caught.value)
    assert controller.target_speed == 2e-4


def test_config_takes_a_ratio_above_one_and_refuses_one_beyond_its_range() -> None:
    """Since issue 11 the slider may hop: max_amplitude_ratio reaches 10 (the
    general inverse takes over at 1); beyond it, or not finite, is refused."""
    assert ControllerConfig(max_amplitude_ratio=1.0).max_amplitude_ratio == 1.0
    assert ControllerConfig(max_amplitude_ratio=10.0).max_amplitude_ratio == 10.0
    for bad in (10.5, 0.0, math.nan):
        with pytest.raises(ParameterError, match="max_amplitude_ratio") as caught:
            ControllerConfig(max_amplitude_ratio=bad)
        assert "[0.001, 10]" in str(caught.value)


def test_a_plant_at_half_speed_is_not_judged_at_full_speed_before_its_pace_is_known() -> None:
    """A controller standing by until its first target had seen no samples, took
    the plant's pace as 1 and judged the first window after its Pa change clean
    although half of it came before the change (a plant at real_time_factor
    0.5): the integral then acted on mixed motion and settling took 7 periods."""
    period, ms = 0.02, 1_000_000
    clock = SampleClock()
    clock.note_change(0)
    # 36 ms of wall time at half speed is 18 ms of simulation: less than a window.
    assert not clock.add(0.018, 36 * ms, period, 1, 0.25)
    # Samples observed while standing by teach the pace; then the judgement is right.
    paced = SampleClock()
    for n in range(4):
        paced.observe(period * n, round(2 * period * n * 1e9))
    start = round(2 * period * 3 * 1e9)
    paced.note_change(start)
    assert not paced.add(period * 3 + 0.018, start + 36 * ms, period, 1, 0.25)
    assert paced.add(period * 3 + 0.040, start + 80 * ms, period, 1, 0.25)


def test_inputs_of_one_instant_are_judged_in_order_and_decided_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """A batch of commands (the node takes them so under a flood): each is
    judged against the state the ones before it left, as if they came one by
    one, and the law decides once for all of them."""
    controller = MeanSpeedController(ControllerConfig(), drive_force=0.7, frequency=50.0, target_speed=2e-4)
    decisions = []
    decide = law.decide  # the one decision of the law (core/control/reach.py)

    def counted(*args: Any) -> Any:
        decisions.append(1)
        return decide(*args)

    monkeypatch.setattr(law, "decide", counted)
    verdicts = controller.take([("target_speed", -2e-4), ("drive_force", -0.7), ("excitation_frequency", math.nan),
                                ("target_speed", -3e-4), ("excitation_frequency", 60.0)])
    assert [v is None for v in verdicts] == [False, True, False, True, True]
    assert "sign of drive_force = 0.7" in str(verdicts[0]) and "excitation_frequency = nan" in str(verdicts[2])
    assert len(decisions) == 1
    monkeypatch.undo()
    same = MeanSpeedController(ControllerConfig(), drive_force=-0.7, frequency=60.0, target_speed=-3e-4)
    assert controller.output == same.output
    assert controller.take([("target_speed", math.inf)])[0] is not None and controller.output == same.output


# -- the general model (issue 11) ---------------------------------------------------------

TILTED = SliderParams(mu=0.5, excitation_angle=60.0)  # vibration at 60 degrees to the track: it conveys on its own


def general_loop(model: SliderParams, plant: SliderParams, target: float, periods: int,
                 drive_force: float = 0.0, top: float = 3.0) -> tuple[MeanSpeedController, list[float]]:
    controller = MeanSpeedController(ControllerConfig(model=model, max_amplitude_ratio=top),
                                     drive_force=drive_force, frequency=50.0, target_speed=target)
    speeds = closed_loop_offline(controller, plant, periods, Inputs(drive_force=drive_force))
    return controller, speeds


@pytest.mark.parametrize("u_star", [0.02, 0.2])  # stick-slip, and hopping (Gamma ~ 1.5)
def test_a_matched_general_model_is_exact_after_the_transient(u_star: float) -> None:
    target = u_star * 10.0 * 0.5 / 50.0  # V* = U* g mu / f
    controller, speeds = general_loop(TILTED, TILTED, target, 12)
    out = controller.output
    assert not (out.saturated or out.unreachable or out.runaway)
    assert out.applied_ratio == pytest.approx(out.feedforward_ratio, rel=1e-9)  # no correction needed
    assert all(v == pytest.approx(target, rel=1e-9) for v in speeds[3:])


@pytest.mark.parametrize("mu_model", [0.4, 0.6])
def test_a_wrong_general_model_is_corrected_by_the_integral_action(mu_model: float) -> None:
    target = 0.01  # U* = 0.1 for the plant (mu = 0.5)
    _, speeds = general_loop(TILTED.replace(mu=mu_model), TILTED, target, 40)
    assert abs(speeds[1] - target) > 0.05 * target, "the model really is wrong"
    assert all(abs(v - target) <= 0.02 * target for v in speeds[25:])
    assert speeds[-1] == pytest.approx(target, rel=1e-6)


def test_a_general_target_beyond_the_branch_is_unreachable_and_saturates_at_its_end() -> None:
    """At 60 degrees and mu = 0.5 U peaks near cot(60)/(2 mu) = 0.577 (Gamma ~ 3.3):
    with max_amplitude_ratio 6 the branch ends there, not at 6."""
    too_fast = 0.6 * 10.0 * 0.5 / 50.0  # U* = 0.6
    controller = MeanSpeedController(ControllerConfig(model=TILTED, max_amplitude_ratio=6.0), drive_force=0.0,
                                     frequency=50.0, target_speed=too_fast)
    out = controller.output
    assert out.unreachable and out.saturated and math.isnan(out.feedforward_ratio)
    assert 3.0 < out.applied_ratio < 4.5, "the branch's end, not max_amplitude_ratio"
    closed_loop_offline(controller, TILTED, 10, Inputs(drive_force=0.0))
    assert controller.output.integral == 0.0, "no windup while unreachable"
    reachable = controller.set_target(0.5 * 10.0 * 0.5 / 50.0)
    assert not reachable.unreachable and reachable.applied_ratio < out.applied_ratio
    backwards = controller.set_target(-1e-3)  # the tilted vibration conveys forwards only: no branch backwards
    assert backwards.unreachable and backwards.amplitude == 0.0


def test_kostek_above_lift_off_uses_the_general_inverse() -> None:
    """max_amplitude_ratio >= 1 on Kostek's model: a target beyond U(0.7, 0.95)
    becomes reachable by hopping."""
    u_star = 0.08  # above u_map(0.7, 0.95) = 0.0604
    target = u_star * 10.0 * 0.1 / 50.0
    low = MeanSpeedController(ControllerConfig(), drive_force=0.7, frequency=50.0, target_speed=target)
    assert low.output.unreachable
    high = MeanSpeedController(ControllerConfig(max_amplitude_ratio=3.0), drive_force=0.7, frequency=50.0,
                               target_speed=target)
    out = high.output
    assert not out.unreachable and out.applied_ratio > 1.0
    speeds = closed_loop_offline(high, SliderParams(), 8)
    assert speeds[-1] == pytest.approx(target, rel=1e-9)
    with pytest.raises(ParameterError, match="sign of drive_force"):
        high.set_target(-target)  # Kostek's model conveys along the drive only, hopping or not


def test_back_to_kostek_a_target_against_the_drive_becomes_zero() -> None:
    """A backward target is fine on a tilted vibration; on Kostek's model it is
    one no plant reaches, so a change of model drops it, as a change of drive does."""
    controller = MeanSpeedController(ControllerConfig(model=TILTED), drive_force=0.7, frequency=50.0,
                                     target_speed=-1e-4)
    assert controller.target_speed == -1e-4 and controller.output.unreachable
    controller.config = ControllerConfig()
    assert controller.target_speed == 0.0 and controller.output.amplitude == 0.0
    still = MeanSpeedController(ControllerConfig(model=TILTED), drive_force=0.0, frequency=50.0, target_speed=1e-3)
    still.config = ControllerConfig()  # no drive at all: nothing to creep along
    assert still.target_speed == 0.0


def test_a_change_right_after_a_frequency_step_is_timed_by_the_samples_spacing() -> None:
    """The frequency doubles (50 -> 100 Hz) and the controller answers 19 ms
    of simulation after the last 50 Hz sample: the change is timed there,
    not capped one new (10 ms) period after that sample, so the window
    [0.10, 0.11], which begins 1 ms after the change (less than the margin),
    is not taken for clean (acceptance case 5 overshot when it was)."""
    ms = 1_000_000
    clock = SampleClock()
    for n in range(5):
        clock.observe(0.02 * n, 20 * ms * n)
    clock.note_change(80 * ms + 19 * ms, period=0.01)  # at 0.099 s of simulation
    assert not clock.add(0.10, 100 * ms, 0.01, 1, 0.25), "its window [0.09, 0.10] began before the change"
    assert not clock.add(0.11, 110 * ms, 0.01, 1, 0.25), "its window began 1 ms after the change: within the margin"
    assert clock.add(0.12, 120 * ms, 0.01, 1, 0.25)


def test_at_phi_one_the_excitation_still_sets_the_speed_and_only_beyond_it_runs_away() -> None:
    """phi = 1 (Fd = mu m g: 1 N with the defaults) is the runaway boundary, not beyond it: the slider
    slides on at U = a/(2 pi) (its speed touches zero once a period), so the law inverts that and the
    loop holds the target on the exact core; one ulp more drive runs away (no control over the speed)."""
    target = 2e-4  # U* = V f/(g mu) = 0.01, so a = 2 pi U*
    controller = MeanSpeedController(ControllerConfig(), drive_force=1.0, frequency=50.0, target_speed=target)
    out = controller.output
    assert not (out.runaway or out.unreachable or out.saturated)
    assert out.feedforward_ratio == 2.0 * math.pi * out.u_target
    assert u_map(1.0, out.applied_ratio) == pytest.approx(out.u_target, rel=1e-15)
    speeds = closed_loop_offline(controller, SliderParams(), 40, Inputs(drive_force=1.0))
    assert speeds[-1] == pytest.approx(target, rel=1e-9)
    beyond = MeanSpeedController(ControllerConfig(), drive_force=math.nextafter(1.0, 2.0), frequency=50.0,
                                 target_speed=target)
    assert beyond.output.runaway and beyond.output.amplitude == 0.0


def test_the_runaway_rule_is_strict() -> None:
    """beats_friction, the one runaway rule: beyond mu times the load, in either direction, not at it."""
    from friction_sim.core.control.relation import runs_away
    from friction_sim.core.model.dimensionless import beats_friction

    assert not beats_friction(1.0, 10.0, 0.1) and not beats_friction(-1.0, 10.0, 0.1)
    assert beats_friction(math.nextafter(1.0, 2.0), 10.0, 0.1) and beats_friction(-math.nextafter(1.0, 2.0), 10.0, 0.1)
    assert not runs_away(1.0, SliderParams()) and runs_away(math.nextafter(1.0, 2.0), SliderParams())
    assert amplitude_ratio_for(0.01, 1.0, 0.95) == 2.0 * math.pi * 0.01
    assert math.isnan(amplitude_ratio_for(0.2, 1.0, 0.95))  # a/(2 pi) <= 0.95/(2 pi) < 0.2: too fast
    assert math.isnan(amplitude_ratio_for(-0.01, 1.0, 0.95))  # a backward speed from a forward drive
