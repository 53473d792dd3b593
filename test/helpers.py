"""Helpers shared by the core tests: a time limit that turns a hang into a
test failure (some inputs once looped forever at the edges of the slip
window), the mirror image of a command schedule, the paper's slider and the
comparisons of two sliders' states and events, and the core's run of a case
of the exciter's reference (test/reference_exciter.py)."""

from __future__ import annotations

import contextlib
import ctypes
import signal
import time
from collections.abc import Iterator
from typing import Any

from friction_sim.core.model.commands import Command


class EndlessLoop(AssertionError):
    """A call that should take microseconds did not return."""


@contextlib.contextmanager
def time_limit(seconds: float, what: str) -> Iterator[None]:
    """Raise EndlessLoop if the block uses more than ``seconds`` of CPU time.

    CPU time (ITIMER_PROF), not wall time: an endless loop burns CPU, while a
    process that a loaded machine merely holds back does not; and SIGPROF
    leaves pytest-timeout's SIGALRM alone."""

    def on_alarm(signum: int, frame: object) -> None:
        raise EndlessLoop(f"{what} did not return within {seconds} s of CPU time")

    old_handler = signal.signal(signal.SIGPROF, on_alarm)
    signal.setitimer(signal.ITIMER_PROF, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, old_handler)


def mirrored(schedule: list[Command]) -> list[Command]:
    """The schedule with every tangential force reversed (Fd -> -Fd, Fx -> -Fx)."""
    out = []
    for command in schedule:
        values = dict(command.values)
        for name in ("drive_force", "external_force_x"):
            if name in values:
                values[name] = -values[name]
        out.append(Command(command.t, command.name, values))
    return out


def rescaled_drive(schedule: list[Command], factor: float) -> list[Command]:
    """The schedule with every drive force multiplied by ``factor`` (random_schedule
    draws drive forces for mu ~ 0.1; a plant with another mu needs them scaled)."""
    return [Command(c.t, c.name, {"drive_force": c.values["drive_force"] * factor}) if c.name == "drive_force" else c
            for c in schedule]


def grouped(schedule: list[Command]) -> list[Command]:
    """The schedule with the commands at one time merged into one ``parameters``
    command, in time order: commands at the same instant take effect together
    (as the node and run_schedule take them), so a test that applies a schedule
    by hand with set_inputs must apply each instant's values at once."""
    merged: dict[float, dict[str, float]] = {}
    for command in sorted(schedule, key=lambda c: c.t):
        merged.setdefault(command.t, {}).update(command.values)
    return [Command(t, "parameters", values) for t, values in merged.items()]


def paper_slider(**kwargs: Any) -> Any:
    """A slider of the paper's Fig. 2 case (the defaults), with Slider's keyword arguments."""
    from friction_sim.core.engine.single import Slider
    from friction_sim.core.model.params import Inputs, SliderParams

    return Slider(SliderParams(), Inputs(), **kwargs)


def rel_close(actual: float, expected: float, rel: float) -> bool:
    """|actual - expected| <= rel*|expected|."""
    return abs(actual - expected) <= rel * abs(expected)


def assert_states_close(a: Any, b: Any, rel: float = 1e-12) -> None:
    """Two SliderStates: x and v within ``rel`` of the larger, the same mode."""
    scale_x = max(abs(a.x), abs(b.x), 1e-300)
    scale_v = max(abs(a.v), abs(b.v), 1e-300)
    assert abs(a.x - b.x) <= rel * scale_x, (a, b)
    assert abs(a.v - b.v) <= rel * scale_v, (a, b)
    assert a.mode == b.mode


def assert_events_close(ev_a: Any, ev_b: Any, rel: float = 1e-12) -> None:
    """Two event lists: the same kinds and modes, times within ``rel``."""
    import numpy as np

    assert [(e.kind, e.before, e.after) for e in ev_a] == [(e.kind, e.before, e.after) for e in ev_b]
    ta = np.array([e.t for e in ev_a])
    tb = np.array([e.t for e in ev_b])
    assert np.all(np.abs(ta - tb) <= rel * np.maximum(np.abs(tb), 1e-300))


#: A drive force the core made to fail by :func:`fail_on_poison` takes half-way, then fails on.
POISON = 0.8123


def fail_on_poison(monkeypatch: Any) -> None:
    """Make ``Slider.set_plant`` really take drive_force :data:`POISON`, then
    raise, as a root finder overflowing half-way through a new segment did:
    only a full restore undoes it."""
    from friction_sim.core.engine.single import Slider

    real = Slider.set_plant

    def set_plant(self: Any, params: Any, inputs: Any) -> None:
        real(self, params, inputs)
        if inputs.drive_force == POISON:
            raise OverflowError("cannot convert float infinity to integer")

    monkeypatch.setattr(Slider, "set_plant", set_plant)


def exciter_states(case: Any, times: Any) -> Any:
    """The core's (x, v, z, vz) of a case of test/reference_exciter.py at ``times``
    (ascending, > 0), its drive level steps taken at their times; and the slider."""
    import numpy as np

    from friction_sim.core.engine.single import Slider
    from friction_sim.core.model.params import Inputs, SliderParams

    params = SliderParams(
        mass=case.mass, mu=case.mu, gravity=case.gravity, static_ratio=case.static_ratio,
        excitation_angle=case.excitation_angle, track_inclination=case.track_inclination,
        restitution=case.restitution, landing_friction="impulsive" if case.impulsive else "none",
        actuator="resonant", natural_frequency=case.natural_frequency, damping_ratio=case.damping_ratio,
        full_drive_acceleration=case.full_drive_acceleration)
    slider = Slider(params, Inputs(drive_force=case.drive_force, excitation_frequency=case.frequency,
                                   drive_level=case.drive_level), event_log_size=None)
    rows = []
    for t in times:
        for when, level in case.changes:
            if slider.t < when <= t:
                slider.advance_to(when)
                slider.set_inputs(drive_level=level)
        slider.advance_to(float(t))
        state = slider.state()
        rows.append((state.x, state.v, state.z, state.vz))
    return np.array(rows), slider


def hold_the_interpreter(seconds: float) -> float:
    """Stall every Python thread of the process for ``seconds`` of wall time, as a
    garbage collection does: a C call that sleeps with the GIL held (ctypes' PyDLL
    keeps it; libc's usleep).  Returns the wall time it held it.  (It replaced a
    calibrated amount of C work, whose length followed the machine's load: one
    loaded CI run stalled 0.147 s for the 0.4 asked.)"""
    start = time.perf_counter()
    ctypes.PyDLL(None).usleep(round(seconds * 1e6))
    return time.perf_counter() - start
