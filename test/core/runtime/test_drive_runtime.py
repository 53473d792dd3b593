"""The inner loop's runtime without ROS (core/runtime/drive.py, and its part of
core/runtime/controller.py): the exact resonant slider sampled as the slider
node samples it, fed as the node feeds it."""

from __future__ import annotations

import math
from typing import Any

import pytest

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.model.spec import CONTROLLER_NODE, DRIVE_LEVEL, defaults
from friction_sim.core.physics.exciter import steady_response
from friction_sim.core.runtime.accelerometer import Accelerometer
from friction_sim.core.runtime.controller import RealtimeController
from friction_sim.core.runtime.drive import DriveCommand, DriveRuntime, outer_model
from friction_sim.errors import ParameterError

PLANT = SliderParams(actuator="resonant", natural_frequency=52.0, damping_ratio=0.02, full_drive_acceleration=20.0)


def values(**changes: Any) -> dict[str, Any]:
    model = {name: getattr(PLANT, name) for name in ("actuator", "natural_frequency", "damping_ratio",
                                                       "full_drive_acceleration")}
    return {**defaults(CONTROLLER_NODE), **model, "plant_node": "", **changes}


def drive(runtime: DriveRuntime, periods: int, wanted: float, *, cycles: int = 1,
          level: float = 0.6) -> list[DriveCommand]:
    """The exact plant in steady state at ``level``, a boundary every ``cycles``
    periods, the accelerometer at 1 kHz; the commands of the boundaries."""
    slider = Slider(PLANT, Inputs(drive_level=level))
    sensor, commands = Accelerometer(1000.0), []
    t = 0.0
    for _ in range(periods):
        command = runtime.boundary(t, wanted)
        commands.append(command)
        slider.set_inputs(drive_level=command.level, excitation_frequency=command.frequency)
        end = t + cycles / command.frequency
        for k in sensor.due(t, end):
            slider.advance_to(max(k / 1000.0, slider.t))
            sample = sensor.read(slider, k)
            assert runtime.take_acceleration(sample.t, sample.z) == ""
        slider.advance_to(end)
        t = end
    return commands


@pytest.mark.parametrize("cycles", [1, 3])
def test_the_loop_holds_the_amplitude_asked_for_over_windows_of_several_periods(cycles: int) -> None:
    """A mean window of ``cycles`` periods: the lock-in reads each window over its
    whole number of drive periods, and the level settles on the one whose steady
    amplitude is the one asked for (the lock-in's reading per unit drive is the
    resonance curve's)."""
    per_level = steady_response(1.0, 20.0, 50.0, 52.0, 0.02)[0]
    runtime = DriveRuntime(PLANT, 50.0, 5.0, inner_loop=True, tracking=False, cycles=cycles, level=0.6)
    drive(runtime, 120 // cycles, 5.0, cycles=cycles)
    assert runtime.loop.drive_level == pytest.approx(5.0 / per_level, rel=1e-6)
    assert runtime.per_drive == pytest.approx(per_level, rel=1e-6)
    assert runtime.last_reading is not None and runtime.last_reading.cycles == cycles
    assert runtime.windows_read >= 120 // cycles - 2 and runtime.loop.steady


def test_an_echo_of_a_published_frequency_is_not_a_command() -> None:
    runtime = DriveRuntime(PLANT, 50.0, 5.0, inner_loop=True, tracking=True, cycles=1, level=0.6)
    published = [c.frequency for c in drive(runtime, 30, 5.0) if c.frequency_changed]
    moved = runtime.frequency
    assert moved > 50.5 and len(published) > 2, "tracking moved toward f_n = 52 Hz"
    runtime.follow_frequency(published[-2])  # an earlier step of its own, arriving late: ignored
    assert runtime.frequency == moved
    runtime.follow_frequency(40.0)  # a frequency it never published: a command
    assert runtime.frequency == 40.0


def test_a_stamp_that_goes_back_starts_the_loop_afresh() -> None:
    """A reset of the slider: the model restarts at the level in force and the lock-in forgets."""
    runtime = DriveRuntime(PLANT, 50.0, 5.0, inner_loop=True, tracking=False, cycles=1, level=0.6)
    drive(runtime, 10, 5.0)
    level = runtime.loop.drive_level
    before = runtime.loop
    runtime.boundary(0.0, 5.0)
    assert runtime.loop is not before and runtime.lockin.readings() == []
    assert runtime.loop.drive_level != level or runtime.loop.gain_ratio == 1.0


def test_a_sample_that_is_not_finite_is_refused_and_counted() -> None:
    runtime = RealtimeController(values())
    assert runtime.drive is not None
    with pytest.raises(ParameterError, match="accelerometer"):
        runtime.take_acceleration(0.1, math.nan)
    assert runtime.rejected == 1 and "nan" in runtime.last_rejection
    assert runtime.drive.samples_refused == 1 and runtime.drive.samples == 0
    runtime.take_acceleration(0.1, 9.0)
    assert runtime.drive.samples == 1


def test_the_law_sees_the_plant_as_a_force_actuator_and_the_runtime_follows_the_actuator() -> None:
    """The outer law inverts Pa (its model's actuator is the force one, so the
    general mean speed never reads a drive level); the inner loop exists while
    the model's actuator is resonant, and a set of parameters switches it."""
    runtime = RealtimeController(values())
    assert runtime.control.config.model == outer_model(PLANT) and runtime.plant_actuator == "resonant"
    assert not runtime.control.config.secant, "behind the inner loop the law takes plain integral steps"
    current = values()
    change = {"actuator": "force"}
    runtime.adopt(runtime.with_parameters(change, current), change, current)
    assert runtime.drive is None and runtime.plant_actuator == "force" and runtime.control.config.secant
    assert runtime.drive_boundary(0.02) is None and runtime.steady_drive() is None


def test_without_the_inner_loop_each_level_is_the_steady_gain_s() -> None:
    runtime = RealtimeController(values(inner_loop=False))
    assert runtime.drive is not None and runtime.control.config.secant
    command = runtime.drive_boundary(0.02)
    assert command is not None and not command.frequency_changed
    per_level = steady_response(1.0, 20.0, 50.0, 52.0, 0.02)[0]
    assert command.level == pytest.approx(runtime.control.output.amplitude / per_level, rel=1e-12)
    assert runtime.drive.lockin.readings() == [], "no lock-in without the inner loop"


def test_the_loop_starts_from_the_level_the_plant_was_read_to_run_at() -> None:
    """A controller whose own parameters already name the resonant actuator adopts the
    plant's drive level when it takes the plant's model (once); later rebuilds keep the
    level the loop drove."""
    runtime = RealtimeController(values())
    assert runtime.drive is not None and runtime.drive.loop.drive_level != 0.6
    runtime.plant_drive_level = 0.6
    current = values()
    change = {"natural_frequency": 51.0}
    runtime.adopt(runtime.with_parameters(change, current), change, current)
    assert runtime.drive.start_level == 0.6 and runtime.plant_drive_level is None
    runtime.drive.loop.drive_level = 0.55
    change = {"damping_ratio": 0.03}
    runtime.adopt(runtime.with_parameters(change, {**current, "natural_frequency": 51.0}), change, current)
    assert runtime.drive.loop.drive_level == 0.55


def _garbage(runtime: RealtimeController, t: float, z: float, count: int) -> list[str]:
    """``count`` samples of ``z`` stamped from ``t`` on at 1 kHz; the reasons of those refused."""
    reasons = []
    for k in range(count):
        try:
            runtime.take_acceleration(t + k / 1000.0, z)
        except ParameterError as error:
            reasons.append(str(error))
    return reasons


@pytest.mark.parametrize("z", [1e300, 10.0])
def test_samples_stamped_ahead_of_the_plant_are_refused_not_held_for_later(z: float) -> None:
    """Issue 28, finding 5: 200 samples stamped 1 s ahead of the plant (absurd,
    1e300, or plausible, 10 m/s^2) are refused at once and counted; when the
    plant's time reaches their stamps the lock-in reads the plant alone."""
    runtime = RealtimeController(values())
    drive_runtime = runtime.drive
    assert drive_runtime is not None
    slider = Slider(PLANT, Inputs(drive_level=drive_runtime.loop.drive_level))
    sensor = Accelerometer(1000.0)
    per_level = steady_response(1.0, 20.0, 50.0, 52.0, 0.02)[0]
    t = 0.0
    for period in range(100):
        if period == 20:
            reasons = _garbage(runtime, t + 1.0, z, 200)
            assert len(reasons) == 200 and drive_runtime.samples_refused == 200
            why = "linear_acceleration.z" if z > 1e6 else "stamped ahead of the plant"
            assert runtime.rejected == 200 and all(why in reason for reason in reasons), reasons[0]
        command = runtime.drive_boundary(t)
        assert command is not None
        slider.set_inputs(drive_level=command.level)
        end = t + 1.0 / 50.0
        for k in sensor.due(t, end):
            slider.advance_to(max(k / 1000.0, slider.t))
            sample = sensor.read(slider, k)
            runtime.take_acceleration(sample.t, sample.z)
        slider.advance_to(end)
        t = end
    # the windows at 1.0-1.2 s, where the garbage was stamped, were read from the plant's samples alone
    assert drive_runtime.per_drive == pytest.approx(per_level, rel=1e-6)
    assert drive_runtime.loop.gain_ratio == pytest.approx(1.0, rel=1e-6)


def test_a_reading_no_slideway_of_the_model_gives_is_refused_even_before_the_first_window() -> None:
    runtime = RealtimeController(values())
    assert runtime.drive is not None
    limit = runtime.drive.plausible_reading
    # g + 2 A G_peak, G_peak = 1/sqrt(1 - zeta^2) (the acceleration's resonance curve normalized at f_n)
    assert limit == pytest.approx(100.0 * (10.0 + 2.0 * 20.0 / math.sqrt(1.0 - 0.02**2)), rel=1e-15)
    with pytest.raises(ParameterError, match=r"linear_acceleration\.z"):
        runtime.take_acceleration(0.0, 1.0001 * limit)
    runtime.take_acceleration(0.0, -0.999 * limit)
    assert runtime.drive.samples == 1 and runtime.drive.samples_refused == 1 and runtime.rejected == 1


def test_a_level_worked_out_saturates_at_the_specs_drive_range() -> None:
    """The levels the runtime works out (the start, the steady gain's, each boundary's)
    saturate at drive_level's bounds as the spec declares them (a control law's
    saturation: the actuator gives no more, and no less)."""
    low, high = DRIVE_LEVEL.low, DRIVE_LEVEL.high
    per_level, _ = steady_response(1.0, PLANT.full_drive_acceleration, 50.0, PLANT.natural_frequency,
                                   PLANT.damping_ratio)
    beyond = 3.0 * per_level  # three times the amplitude at full drive
    runtime = DriveRuntime(PLANT, 50.0, beyond, inner_loop=False, tracking=False, cycles=1)
    assert runtime.start_level == high
    assert runtime.steady(-beyond).level == low and runtime.steady(beyond).level == high
    assert runtime.steady(0.5 * per_level).level == pytest.approx(0.5, rel=1e-12)
    looped = DriveRuntime(PLANT, 50.0, 0.5 * per_level, inner_loop=True, tracking=False, cycles=1)
    levels = [looped.boundary(k / 50.0, beyond).level for k in range(1, 40)]
    assert max(levels) == high and min(levels) >= low


def test_a_window_of_readings_taken_at_once_is_taken_as_one_at_a_time() -> None:
    """take_accelerations (a window's readings at once, as a linked controller takes them)
    refuses, counts and feeds the lock-in exactly as taking each in turn does: the refused
    ones' errors in order, each naming its reading, the others in the lock-in in order."""
    batch, single = RealtimeController(values()), RealtimeController(values())
    assert batch.drive is not None and single.drive is not None
    limit = batch.drive.plausible_reading
    readings = [(0.001, 9.0), (0.002, math.nan), (0.003, 2.0 * limit), (0.004, 9.5), (math.inf, 9.0),
                (0.003, 9.25)]  # (the last out of order: the lock-in notes it)
    errors = batch.take_accelerations(readings)
    expected = []
    for t, normal in readings:
        try:
            single.take_acceleration(t, normal)
        except ParameterError as error:
            expected.append(str(error))
    assert [str(error) for error in errors] == expected and len(expected) == 3
    assert "nan" in expected[0] and "linear_acceleration.z" in expected[1] and "inf" in expected[2]
    for runtime in (batch, single):
        assert runtime.drive is not None
        assert (runtime.drive.samples, runtime.drive.samples_refused, runtime.rejected) == (3, 3, 3)
    assert batch.last_rejection == single.last_rejection
    assert batch.drive.lockin._samples == single.drive.lockin._samples  # noqa: SLF001 (what the lock-in keeps)
    assert batch.drive.lockin._in_order is single.drive.lockin._in_order is False  # noqa: SLF001
    assert batch.take_accelerations([]) == []
