"""Offline simulation jobs on top of the exact core: schedules and mean speeds.

A :class:`Schedule` is a list of input changes at given simulation times, the
same thing a user sends over ROS topics.  :func:`run_schedule` plays one into
a :class:`~friction_sim.core.Slider` and samples the motion;
:func:`simulate` is the ``friction-sim simulate`` job: it measures the mean
velocity and the flight fraction over whole excitation periods from the
simulated motion (never from the U formula) and reports them next to the U
relation's value (Kostek's closed form where it holds, else the general mean
speed of :func:`friction_sim.core.meanspeed.general.mean_speed`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import groupby
from typing import Any

import numpy as np

from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.urelation import kostek_prediction
from friction_sim.core.model.commands import Command, take
from friction_sim.core.model.dimensionless import amplitude_ratio, drive_ratio, nondimensional_speed
from friction_sim.core.model.events import Event, EventKind, Trajectory
from friction_sim.core.model.params import Inputs, SliderParams, field_values, require_finite
from friction_sim.core.model.records import share
from friction_sim.core.physics.plant import steady_throw_number
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
                "external_force_z": -float(rng.uniform(0.0, 0.1) * weight),  # pressing (> 0 lifts)
            }))


def run_schedule(slider: Slider, schedule: Schedule, sample_times: np.ndarray) -> Trajectory:
    """Apply ``schedule`` to ``slider`` at its command times and return the
    exact state at ``sample_times`` (ascending).  A command at the same time as
    a sample is applied first; commands at the same time are taken one by one,
    each a change of its own (:func:`~friction_sim.core.model.commands.take`),
    as the slider node takes them and verify replays them.
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
        for command in group:
            take(slider, command)
    if first < sample_times.size:
        pieces.append(slider.sample(sample_times[first:]))
        events.extend(pieces[-1].events)
    return _concatenate(pieces, events)


def _concatenate(pieces: list[Trajectory], events: list[Event]) -> Trajectory:
    def joined(name: str) -> np.ndarray:
        return np.concatenate([getattr(p, name) for p in pieces])

    return Trajectory(joined("t"), joined("x"), joined("v"), joined("acceleration"), joined("friction_force"),
                      joined("normal_force"), joined("phase"), joined("mode"), events=tuple(events),
                      z=joined("z"), vz=joined("vz"))


@dataclass(frozen=True)
class SimulationResult:
    """What ``friction-sim simulate`` reports.

    ``mean_velocity`` [m/s] is measured from the simulated motion over
    ``periods`` whole excitation periods after ``settle`` seconds, and
    ``flight_fraction`` is the share of that window spent off the track;
    ``u_measured`` is the mean velocity made nondimensional, ``u_exact`` the
    U relation's value for the same plant: Kostek's closed form where it
    holds (``u_closed_form`` True), else the general mean speed of the
    periodic motion (``u_periodic`` True) or over a stated window.  In
    Kostek's model both use the effective groups, which are the paper's
    without an external force: phi = (Fd + Fx)/(mu*(m*g - Fz)),
    a = Pa/(m*g - Fz) and gravity (m*g - Fz)/m (Fz > 0 lifts); elsewhere
    the plain ones, phi = (Fd + Fx)/(mu*m*g), a = Pa/(m*g) and g.
    ``event_counts`` counts every kind of event over the whole run (zeros
    included), and ``throw_number`` is Gamma = Pa/(m*g*cos(alpha)).
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
    flight_fraction: float = 0.0
    throw_number: float = 0.0
    u_closed_form: bool = True
    u_periodic: bool = True

    def as_dict(self) -> dict[str, Any]:
        """The JSON view: full-precision numbers, no arrays."""
        return {
            **field_values(self.params, self.inputs),
            "duration": self.duration, "settle": self.settle,
            "phi": self.phi, "amplitude_ratio": self.amplitude_ratio, "throw_number": self.throw_number,
            "periods": self.periods, "mean_velocity": self.mean_velocity,
            "U": self.u_measured, "U_exact": self.u_exact,
            "U_closed_form": self.u_closed_form, "U_periodic": self.u_periodic,
            "flight_fraction": self.flight_fraction,
            "events": dict(self.event_counts), "wall_time": self.wall_time,
        }


def simulate(
    params: SliderParams, inputs: Inputs, duration: float, *, settle: float = 0.0,
    sample_rate: float | None = None,
) -> SimulationResult:
    """Simulate constant inputs for ``duration`` s and measure the mean speed.

    The mean (and the flight fraction) is taken over the whole excitation
    periods that fit between ``settle`` and ``duration``.  With
    ``sample_rate`` [Hz] the result also holds a uniformly sampled
    trajectory (with z and vz) and the event list.
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
    x_start, flight_start = slider.state().x, slider.flight_time
    slider.advance_to(min(settle + periods * period, duration))
    window = periods * period
    mean_velocity = (slider.state().x - x_start) / window
    flight_fraction = share(slider.flight_time - flight_start, window)
    slider.advance_to(max(duration, slider.t))
    wall = time.perf_counter() - started
    counts = slider.event_counts
    relation = _relation(params, inputs, mean_velocity)
    return SimulationResult(
        params=params, inputs=inputs, duration=duration, settle=settle, periods=periods,
        mean_velocity=mean_velocity, u_measured=relation.u_measured, u_exact=relation.u_exact,
        phi=relation.phi, amplitude_ratio=relation.amplitude_ratio,
        event_counts={kind.value: counts.get(kind, 0) for kind in EventKind},
        wall_time=wall, trajectory=trajectory,
        events=slider.events if sample_rate is not None else [],
        flight_fraction=flight_fraction, throw_number=steady_throw_number(params, inputs),
        u_closed_form=relation.closed_form, u_periodic=relation.periodic,
    )


@dataclass(frozen=True)
class _Relation:
    """The U relation's side of a simulation result (see :class:`SimulationResult`)."""

    u_measured: float
    u_exact: float
    phi: float
    amplitude_ratio: float
    closed_form: bool
    periodic: bool


def _relation(params: SliderParams, inputs: Inputs, mean_velocity: float) -> _Relation:
    """The measured U and the relation's U with their groups: Kostek's closed form
    (effective groups) where it holds, else the general mean speed (plain groups)."""
    f = inputs.excitation_frequency
    prediction = kostek_prediction(params, inputs)
    if prediction is not None:
        return _Relation(
            u_measured=nondimensional_speed(mean_velocity, f, prediction.effective_gravity, params.mu),
            u_exact=prediction.u, phi=prediction.effective_phi,
            amplitude_ratio=prediction.effective_amplitude_ratio, closed_form=True,
            periodic=not math.isinf(prediction.u))
    # meanspeed builds on the core's closed forms: imported where it is needed.
    from friction_sim.core.meanspeed.general import mean_speed

    general = mean_speed(params, inputs)
    return _Relation(
        u_measured=nondimensional_speed(mean_velocity, f, params.gravity, params.mu), u_exact=general.u,
        phi=drive_ratio(inputs.tangential_force, params.mu, params.weight),
        amplitude_ratio=amplitude_ratio(inputs.excitation_amplitude, params.weight), closed_form=False,
        periodic=general.periodic)


__all__ = ["Command", "Schedule", "SimulationResult", "random_schedule", "run_schedule", "simulate"]
