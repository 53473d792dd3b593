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
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reference_exciter import random_case

from friction_sim.core.engine import transient_kernel as kernel
from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import plant_of

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


def test_an_unknown_mode_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match="'fast' is not one of auto, compiled, plain"):
        kernel.use("fast")
    assert kernel.mode() in kernel.MODES and not math.isnan(kernel.search_steps())
