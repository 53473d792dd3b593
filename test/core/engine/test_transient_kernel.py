"""The compiled transient step is the plain one, bit for bit, and the switch between them is invisible.

The single slider runs the exciter's transient with the compiled step once it
is loaded (:mod:`friction_sim.core.engine.transient_kernel`), and with the
plain functions until then, so a run may switch at any instant.  That is only
right if the two give the same bits: checked here on random coupled cases
(flight, restitution, inclined tracks) event by event and state by state, on
the work the root search does, and across a switch in the middle of a run.
"""

from __future__ import annotations

import logging
import math
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference_exciter import random_case

from friction_sim.core.engine import transient_kernel as kernel
from friction_sim.core.engine.single import Slider
from friction_sim.core.engine.transient_segment import Transient
from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import plant_of
from friction_sim.core.physics.segment import FORWARD, Segment

from helpers import exciter_states

TIMES = np.linspace(0.0, 0.3, 31)[1:]


@pytest.fixture(autouse=True)
def _restore_mode() -> Iterator[None]:
    before = kernel.mode()
    yield
    kernel.use(before)


def _run(mode: str, seed: int) -> tuple[np.ndarray, list[object], int]:
    """The states at TIMES, the events, and the root search's work of one random case under ``mode``."""
    kernel.use(mode)
    before = kernel.search_steps()
    states, slider = exciter_states(random_case(np.random.default_rng(seed)), TIMES)
    return states, list(slider.events), kernel.search_steps() - before


@settings(max_examples=25, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1))
def test_the_compiled_step_is_the_plain_one_bit_for_bit(seed: int) -> None:
    plain_states, plain_events, plain_work = _run(kernel.PLAIN, seed)
    states, events, work = _run(kernel.COMPILED, seed)
    assert kernel.compiled_ready(), kernel.failure()
    assert np.array_equal(states, plain_states)  # (exact: not approx)
    assert events == plain_events
    assert work == plain_work > 0  # the same search, interval by interval


def _stepped(switch_at: float | None) -> tuple[list[object], object]:
    """A resonant plant after a step of drive to 0.3 s, plain throughout, or compiled from ``switch_at``."""
    kernel.use(kernel.PLAIN)
    slider = Slider(SliderParams(actuator="resonant", natural_frequency=52.0), Inputs(drive_level=0.3),
                    event_log_size=None)
    slider.set_inputs(drive_level=0.9)
    if switch_at is not None:
        slider.advance_to(switch_at)
        kernel.use(kernel.COMPILED)
    slider.advance_to(0.3)
    return list(slider.events), slider.state()


@pytest.mark.parametrize("switch_at", [0.0137, 0.1, 0.2999])
def test_switching_in_the_middle_of_a_run_changes_nothing(switch_at: float) -> None:
    assert _stepped(switch_at) == _stepped(None)


def test_a_plant_of_other_types_runs_the_plain_step() -> None:
    # (the compiled entry point skips Numba's type checks: a plant it was not compiled for must not reach it)
    kernel.use(kernel.COMPILED)
    p = plant_of(SliderParams(actuator="resonant"), Inputs())
    args = (p, 0.3 + 0.1j, complex(-6.5, 326.0), 0.5, 0, 0.2, 0.0, 0.0, 0.0, 0, True)
    expected = kernel.transient_step(*args)
    assert kernel.compiled_ready()
    odd = p._replace(can_slip=int(p.can_slip))  # an int where the compiled code has a bool
    assert kernel.KERNEL.entry(odd) is None
    assert kernel.transient_step(odd, *args[1:]) == expected


def test_the_types_are_checked_per_shape_of_plant_and_a_number_numba_types_otherwise_is_caught() -> None:
    """The compiled types are checked once per shape of plant (classes and leaf types), not per
    plant: a controller that sets the drive level makes a plant a period.  What Numba would type
    differently is still caught: an int beyond 64 bits, a float where an int was."""
    kernel.use(kernel.COMPILED)
    p = plant_of(SliderParams(actuator="resonant"), Inputs())
    args = (p, 0.3 + 0.1j, complex(-6.5, 326.0), 0.5, 0, 0.2, 0.0, 0.0, 0.0, 0, True)
    kernel.transient_step(*args)
    assert kernel.compiled_ready()
    other = plant_of(SliderParams(actuator="resonant", mass=2.0), Inputs(drive_level=0.7))
    assert other != p and kernel.KERNEL.entry(other) is not None
    assert kernel.KERNEL.entry(p._replace(direction=2**64)) is None
    assert kernel.KERNEL.entry(p._replace(direction=float(p.direction))) is None
    assert kernel.KERNEL.entry(p) is not None


def test_a_failed_compile_leaves_the_plain_step_and_says_why_once(monkeypatch: pytest.MonkeyPatch,
                                                                 caplog: pytest.LogCaptureFixture) -> None:
    def broken(args: object) -> kernel.CompiledStep:
        raise RuntimeError("no LLVM here")

    monkeypatch.setattr(kernel, "compile_step", broken)
    fresh = kernel.Kernel()
    with caplog.at_level(logging.WARNING, logger=kernel.__name__):
        thread = fresh.start(())
        assert thread is not None
        thread.join()
        assert fresh.start(()) is thread  # (tried once, never again)
    assert fresh.failure == "RuntimeError: no LLVM here"
    assert fresh.entry(plant_of(SliderParams(), Inputs())) is None
    [record] = caplog.records
    assert "interpreted" in record.getMessage() and "no LLVM here" in record.getMessage()


class _CompilesAfter:
    """A compile_step that raises ``failures`` in turn, then gives ``result``; it counts its calls."""

    def __init__(self, failures: list[Exception]) -> None:
        self.failures, self.calls, self.result = failures, 0, object()

    def __call__(self, args: object) -> object:
        self.calls += 1
        if self.failures:
            raise self.failures.pop(0)
        return self.result


def _compile_with(monkeypatch: pytest.MonkeyPatch, step: _CompilesAfter) -> kernel.Kernel:
    """A fresh kernel that has compiled with ``step`` (on its thread, joined)."""
    monkeypatch.setattr(kernel, "compile_step", step)
    fresh = kernel.Kernel()
    thread = fresh.start(())
    assert thread is not None
    thread.join()
    return fresh


def test_a_compile_that_lost_a_race_with_the_environment_is_tried_again(monkeypatch: pytest.MonkeyPatch,
                                                                        caplog: pytest.LogCaptureFixture) -> None:
    # (Numba iterates os.environ at every compile: a variable removed meanwhile, as pytest removes
    # PYTEST_CURRENT_TEST between the phases of a test, raises a KeyError naming it; the compile is sound)
    monkeypatch.delenv("FRICTION_SIM_GONE", raising=False)
    step = _CompilesAfter([KeyError("FRICTION_SIM_GONE"), KeyError("FRICTION_SIM_GONE")])
    with caplog.at_level(logging.WARNING, logger=kernel.__name__):
        fresh = _compile_with(monkeypatch, step)
    assert step.calls == 3 and fresh.compiled is step.result and fresh.failure is None
    assert not caplog.records


def test_a_compile_that_keeps_failing_is_tried_a_bounded_number_of_times(monkeypatch: pytest.MonkeyPatch,
                                                                         caplog: pytest.LogCaptureFixture) -> None:
    monkeypatch.delenv("FRICTION_SIM_GONE", raising=False)
    step = _CompilesAfter([KeyError("FRICTION_SIM_GONE")] * (kernel.COMPILE_ATTEMPTS + 1))
    with caplog.at_level(logging.WARNING, logger=kernel.__name__):
        fresh = _compile_with(monkeypatch, step)
    assert step.calls == kernel.COMPILE_ATTEMPTS and fresh.compiled is None
    assert fresh.failure == "KeyError: 'FRICTION_SIM_GONE'"
    [record] = caplog.records
    assert "interpreted" in record.getMessage() and "FRICTION_SIM_GONE" in record.getMessage()


def test_a_key_error_that_is_no_race_is_not_tried_again(monkeypatch: pytest.MonkeyPatch) -> None:
    # (a variable that is still set was not removed beneath the compile: its KeyError is the compile's own)
    monkeypatch.setenv("FRICTION_SIM_HERE", "1")
    step = _CompilesAfter([KeyError("FRICTION_SIM_HERE"), KeyError("never reached")])
    fresh = _compile_with(monkeypatch, step)
    assert step.calls == 1 and fresh.failure == "KeyError: 'FRICTION_SIM_HERE'"
    assert not kernel.environment_changed(KeyError("FRICTION_SIM_HERE"))
    assert not kernel.environment_changed(RuntimeError("FRICTION_SIM_GONE"))


#: Compiles the step from scratch while Numba's 30th read of the environment loses the race
#: (as the KeyError of a removed variable), then prints whether it is ready and plain's bits.
_RACE = """
from numba.core import config
from friction_sim.core.engine import transient_kernel as kernel
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import plant_of

reads, reload = [0], config.reload_config
def racing():
    reads[0] += 1
    if reads[0] == 30:
        raise KeyError("FRICTION_SIM_GONE")
    reload()
config.reload_config = racing
kernel.use(kernel.COMPILED)
args = (plant_of(SliderParams(actuator="resonant"), Inputs()), 0.3 + 0.1j, complex(-6.5, 326.0), 0.5, 0, 0.2,
        0.0, 0.0, 0.0, 0, True)
compiled = kernel.transient_step(*args)
kernel.use(kernel.PLAIN)
print(reads[0] > 30, kernel.compiled_ready(), kernel.failure(), compiled == kernel.transient_step(*args))
"""


def test_numba_compiles_soundly_after_losing_a_race_with_the_environment(tmp_path: Path) -> None:
    # (a fresh cache, so Numba compiles and reads the environment: a load from the cache does not)
    env = os.environ | {"NUMBA_CACHE_DIR": str(tmp_path)}
    env.pop("FRICTION_SIM_GONE", None)
    done = subprocess.run([sys.executable, "-c", _RACE], env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "True", "None", "True"], done.stdout + done.stderr


def test_an_unknown_mode_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match="'fast' is not one of auto, compiled, plain"):
        kernel.use("fast")
    assert kernel.mode() in kernel.MODES and not math.isnan(kernel.search_steps())


def _slider_of(case: object) -> tuple[Slider, float, float]:
    """A slider of a random case of test/reference_exciter.py before its drive step, the step's time and level."""
    from helpers import exciter_states

    _, slider = exciter_states(case, np.array([1e-3]))
    [(when, level)] = case.changes  # type: ignore[attr-defined]
    return slider, when, level


def _grids_by_points(slider: Slider, state_times: list[float], reading_times: list[float]) -> tuple[list, list, list]:
    """The reference: advance to each time of the two grids in turn, then read the state or the slideway."""
    states, readings, events = [], [], []
    for when, kind in sorted([(t, 0) for t in state_times] + [(t, 1) for t in reading_times]):
        events.extend(slider.advance_to(when))
        if kind:
            readings.append(list(slider.slideway_acceleration()))
        else:
            states.append(slider.state())
    return states, readings, events


@settings(max_examples=20, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), mode=st.sampled_from([kernel.PLAIN, kernel.COMPILED]))
def test_sampling_the_log_grids_a_segment_at_a_time_is_advancing_point_by_point_bit_for_bit(seed: int,
                                                                                           mode: str) -> None:
    # (the log grid's hot path: the segment's states and readings in one call, compiled once ready)
    kernel.use(mode)
    case = random_case(np.random.default_rng(seed))
    log_rate, reading_rate = 1000.0, float(np.random.default_rng(seed).choice([1000.0, 1300.0, 370.0]))
    by_grid, when, level = _slider_of(case)
    by_point, _, _ = _slider_of(case)
    for start, stop in ((by_grid.t, when), (when, 0.25)):
        states = [k / log_rate for k in range(math.ceil(start * log_rate), math.floor(stop * log_rate) + 1)]
        readings = [k / reading_rate for k in range(math.ceil(start * reading_rate),
                                                    math.floor(stop * reading_rate) + 1)]
        states, readings = [t for t in states if t >= by_grid.t], [t for t in readings if t >= by_grid.t]
        assert by_grid.sample_grids(states, readings) == _grids_by_points(by_point, states, readings)
        assert by_grid.t == by_point.t
        by_grid.set_inputs(drive_level=level)
        by_point.set_inputs(drive_level=level)
    assert by_grid.state() == by_point.state()
    if mode == kernel.COMPILED:
        assert kernel.compiled_ready(), kernel.failure()


def test_the_grids_of_kostek_s_case_are_its_states_bit_for_bit() -> None:
    kernel.use(kernel.COMPILED)
    by_grid, by_point = Slider(SliderParams(), Inputs()), Slider(SliderParams(), Inputs())
    times = [k / 1000.0 for k in range(101)]
    assert by_grid.sample_grids(times, times[::3]) == _grids_by_points(by_point, times, times[::3])


def test_a_segment_of_other_types_is_sampled_plain() -> None:
    # (the compiled samplers' entry point skips Numba's type checks, as the step's does)
    kernel.use(kernel.COMPILED)
    p = plant_of(SliderParams(actuator="resonant"), Inputs())
    seg = Segment(FORWARD, 0.2, 0.01, 0.0, 0.0, 0, True, 0.0, 0.5, 0.001, 0.0, 25, 0.1, 0.0, 0)
    transient = Transient(0.3 + 0.1j, complex(-6.5, 326.0), 0.6)
    kernel.transient_step(p, transient.c, transient.lam, 0.5, FORWARD, 0.2, 0.01, 0.0, 0.0, 0, True)  # (compiles)
    taus = [1e-4, 2e-4]
    expected = kernel.states_at(p, seg, transient.c, transient.lam, taus)
    compiled = kernel.KERNEL.compiled
    assert compiled is not None and compiled.segment_fits(seg)
    odd = seg._replace(closing=float(seg.closing))  # a float where the compiled code has an int
    assert not compiled.segment_fits(odd)
    assert not compiled.segment_fits(seg._replace(cycles=2**64))  # (beyond Numba's int64)
    assert not compiled.segment_fits(seg._replace(grounded=1))  # an int where the compiled code has a bool
    assert compiled.segment_fits(seg._replace(cycles=2**63 - 1))
    assert kernel.states_at(p, odd, transient.c, transient.lam, taus) == expected


@settings(max_examples=30, deadline=None, derandomize=True)
@given(amplitude=st.floats(0.0, 50.0), lag=st.floats(0.0, 3.1), natural=st.floats(30.0, 70.0),
       zeta=st.floats(0.005, 0.2), d=st.complex_numbers(max_magnitude=1e-3), start=st.floats(0.0, 100.0))
def test_a_drive_model_s_accelerometer_reading_is_the_same_compiled(amplitude: float, lag: float, natural: float,
                                                                    zeta: float, d: complex, start: float) -> None:
    # (the drive loop reads its model at a window's sample times: compiled once ready, the plain slideway_state's bits)
    from friction_sim.core.physics.exciter import Slideway, eigenvalue, slideway_state

    way = Slideway(amplitude, lag, TWO_PI * 50.0, eigenvalue(natural, zeta), d)
    times = [start + k / 1000.0 for k in range(21)]
    plain = [slideway_state(way, TWO_PI * 50.0 * (t - start), t - start)[2] for t in times]
    kernel.use(kernel.COMPILED)
    p = plant_of(SliderParams(actuator="resonant"), Inputs())
    kernel.transient_step(p, 0.3 + 0.1j, complex(-6.5, 326.0), 0.5, FORWARD, 0.2, 0.01, 0.0, 0.0, 0, True)  # (compiles)
    assert kernel.compiled_ready(), kernel.failure()
    assert kernel.normal_accelerations(way, 50.0, start, times) == plain
    odd = way._replace(amplitude=int(amplitude))  # an int where the compiled code has a float: plain
    assert kernel.normal_accelerations(odd, 50.0, start, times) == [
        slideway_state(odd, TWO_PI * 50.0 * (t - start), t - start)[2] for t in times]
