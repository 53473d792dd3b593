"""Offline simulation jobs on top of the exact core: schedules and mean speeds.

A :class:`Schedule` is a list of input changes at given simulation times, the
same thing a user sends over ROS topics.  :func:`run_schedule` plays one into
a :class:`~friction_sim.core.Slider` and samples the motion;
:func:`simulate` is the ``friction-sim simulate`` job: it measures the mean
velocity over whole excitation periods from the simulated motion (never from
the U formula) and reports it next to the exact U.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import groupby
from typing import Any

import numpy as np

from friction_sim.core.commands import Command, apply_all
from friction_sim.core.events import Event, Trajectory
from friction_sim.core.params import Inputs, SliderParams, require_finite
from friction_sim.core.slider import Slider
from friction_sim.core.urelation import nondimensional_speed, predict
from friction_sim.errors import ParameterError

Schedule = Sequence[Command]


def random_schedule(
    rng: np.random.Generator, duration: float, *, frequency: float = 50.0,
    mean_periods: float = 4.0, weight: float = 10.0, external: bool = False,
) -> list[Command]:
    """Random input changes every few excitation periods, for tests and the
    benchmark: drive force of either sign, amplitude in [0, 0.95*weight),
    frequency within a factor of two of ``frequency``, optionally an
    external force.  Times are random, not on the period grid."""
    commands: list[Command] = []
    t = 0.0
    while True:
        t += rng.exponential(mean_periods / frequency)
        if t >= duration:
            return commands
        commands.append(Command(t, "drive_force", {"drive_force": float(rng.uniform(-1.0, 1.0) * 0.12 * weight)}))
        commands.append(Command(t, "excitation_amplitude",
                                {"excitation_amplitude": float(rng.uniform(0.0, 0.8) * weight)}))
        commands.append(Command(t, "excitation_frequency",
                                {"excitation_frequency": float(frequency * rng.uniform(0.5, 2.0))}))
        if external:
            commands.append(Command(t, "external_wrench", {
                "external_force_x": float(rng.uniform(-0.02, 0.02) * weight),
                "external_force_z": float(rng.uniform(-0.1, 0.0) * weight),
            }))


def run_schedule(slider: Slider, schedule: Schedule, sample_times: np.ndarray) -> Trajectory:
    """Apply ``schedule`` to ``slider`` at its command times and return the
    exact state at ``sample_times`` (ascending).  A command at the same time as
    a sample is applied first; commands at the same time take effect together
    (validated in order, one new segment), as the slider node takes a batch.
    The trajectory's events are every event the slider went through, in time
    order: those between samples, and those between the last sample before a
    command and the command (or after the last sample, up to the last command)."""
    sample_times = np.asarray(sample_times, dtype=float)
    pieces: list[Trajectory] = []
    events: list[Event] = []
    first = 0
    for t, group in groupby(sorted(schedule, key=lambda c: c.t), key=lambda c: c.t):
        last = int(np.searchsorted(sample_times, t, side="left"))
        if last > first:
            pieces.append(slider.sample(sample_times[first:last]))
            events.extend(pieces[-1].events)
            first = last
        events.extend(slider.advance_to(t))
        commands = list(group)
        params, inputs = apply_all(commands, slider.params, slider.inputs)
        slider.set_plant(params, inputs, {name for c in commands for name in c.values})
    if first < sample_times.size:
        pieces.append(slider.sample(sample_times[first:]))
        events.extend(pieces[-1].events)
    return _concatenate(pieces, events)


def _concatenate(pieces: list[Trajectory], events: list[Event]) -> Trajectory:
    def joined(name: str) -> np.ndarray:
        return np.concatenate([getattr(p, name) for p in pieces])

    return Trajectory(joined("t"), joined("x"), joined("v"), joined("acceleration"), joined("friction_force"),
                      joined("normal_force"), joined("phase"), joined("mode"), events=tuple(events))


@dataclass(frozen=True)
class SimulationResult:
    """What ``friction-sim simulate`` reports.

    ``mean_velocity`` [m/s] is measured from the simulated motion over
    ``periods`` whole excitation periods after ``settle`` seconds;
    ``u_measured`` is it made nondimensional, ``u_exact`` the U relation's
    value for the same (phi, a).  Both use the effective groups, which are
    the paper's without an external force: phi = (Fd + Fx)/(mu*(m*g + Fz)),
    a = Pa/(m*g + Fz) and gravity (m*g + Fz)/m.
    """

    params: SliderParams
    inputs: Inputs
    duration: float
    settle: float
    periods: int
    mean_velocity: float
    u_measured: float
    u_exact: float
    phi: float
    amplitude_ratio: float
    event_counts: dict[str, int]
    wall_time: float
    trajectory: Trajectory | None = None
    events: list[Event] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        """The JSON view: full-precision numbers, no arrays."""
        return {
            "mass": self.params.mass, "mu": self.params.mu, "gravity": self.params.gravity,
            "drive_force": self.inputs.drive_force,
            "excitation_amplitude": self.inputs.excitation_amplitude,
            "excitation_frequency": self.inputs.excitation_frequency,
            "duration": self.duration, "settle": self.settle,
            "phi": self.phi, "amplitude_ratio": self.amplitude_ratio,
            "periods": self.periods, "mean_velocity": self.mean_velocity,
            "U": self.u_measured, "U_exact": self.u_exact,
            "events": dict(self.event_counts), "wall_time": self.wall_time,
        }


def simulate(
    params: SliderParams, inputs: Inputs, duration: float, *, settle: float = 0.0,
    sample_rate: float | None = None,
) -> SimulationResult:
    """Simulate constant inputs for ``duration`` s and measure the mean speed.

    The mean is taken over the whole excitation periods that fit between
    ``settle`` and ``duration``.  With ``sample_rate`` [Hz] the result also
    holds a uniformly sampled trajectory and the event list.
    """
    duration = require_finite("duration", duration)
    settle = require_finite("settle", settle)
    if duration <= 0.0:
        raise ParameterError("duration", duration, "must be > 0 s")
    if not 0.0 <= settle < duration:
        raise ParameterError("settle", settle, f"must be in [0, duration = {duration!r}) s")
    period = 1.0 / inputs.excitation_frequency
    periods = math.floor((duration - settle) / period * (1.0 + 1e-12))
    if periods < 1:
        raise ParameterError(
            "duration", duration, f"must cover at least one excitation period ({period!r} s) after settle"
        )
    started = time.perf_counter()
    slider = Slider(params, inputs, event_log_size=None)
    trajectory = None
    if sample_rate is not None:
        rate = require_finite("sample_rate", sample_rate)
        if rate <= 0.0:
            raise ParameterError("sample_rate", rate, "must be > 0 Hz")
        trajectory = slider.sample(np.arange(math.floor(duration * rate) + 1) / rate)
        slider = Slider(params, inputs, event_log_size=None)
    slider.advance_to(settle)
    x_start = slider.state().x
    slider.advance_to(min(settle + periods * period, duration))
    mean_velocity = (slider.state().x - x_start) / (periods * period)
    slider.advance_to(max(duration, slider.t))
    wall = time.perf_counter() - started
    prediction = predict(params, inputs)
    return SimulationResult(
        params=params, inputs=inputs, duration=duration, settle=settle, periods=periods,
        mean_velocity=mean_velocity,
        u_measured=nondimensional_speed(mean_velocity, inputs.excitation_frequency, prediction.effective_gravity,
                                        params.mu),
        u_exact=prediction.u, phi=prediction.effective_phi, amplitude_ratio=prediction.effective_amplitude_ratio,
        event_counts={kind.value: n for kind, n in slider.event_counts.items()},
        wall_time=wall, trajectory=trajectory,
        events=slider.events if sample_rate is not None else [],
    )


__all__ = ["Command", "Schedule", "SimulationResult", "random_schedule", "run_schedule", "simulate"]
