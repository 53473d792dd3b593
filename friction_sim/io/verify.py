"""``--verify``: re-simulate a recording with the exact core and compare.

:func:`verify` rebuilds the simulation from the recorded parameters
(:func:`initial_parameters`) and the accepted commands
(:func:`recorded_commands`, applied at their recorded simulation times
through :func:`friction_sim.core.commands.apply`, the one gate) and compares
it with every recorded pose and velocity sample; it passes when both differ
by at most 1e-9 relative to the largest recorded |x| and |v|.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from itertools import groupby
from typing import Any

import numpy as np

from friction_sim.core.commands import PARAMETERS, Command, apply
from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.slider import Slider
from friction_sim.errors import ParameterError, RecordingError
from friction_sim.io.messages import (
    COMMAND_TOPICS,
    NS_PER_S,
    command_from_message,
    ns_to_seconds,
    parameter_event_values,
    seconds_to_ns,
)
from friction_sim.io.reader import Recording
from friction_sim.io.recorder import INPUT_FIELDS, METADATA_NAME, PLANT_FIELDS
from friction_sim.io.series import FloatArray, IntArray, state_series

DEFAULT_TOLERANCE = 1e-9


@dataclass(frozen=True)
class VerifyResult:
    """How a re-simulation compares with the recorded states.

    ``max_dx``/``max_dv`` are the largest absolute differences (at
    ``worst_dx_t``/``worst_dv_t`` s), ``rel_dx``/``rel_dv`` the same relative
    to the largest recorded |x| and |v|.  ``passed`` when both are within
    ``tolerance`` and nothing went wrong (``problems``).
    """

    samples: int
    commands: int
    max_dx: float
    max_dv: float
    x_scale: float
    v_scale: float
    rel_dx: float
    rel_dv: float
    worst_dx_t: float
    worst_dv_t: float
    tolerance: float
    problems: tuple[str, ...] = ()

    @property
    def passed(self) -> bool:
        """Within the tolerance, with samples and without problems."""
        return (not self.problems and self.samples > 0
                and self.rel_dx <= self.tolerance and self.rel_dv <= self.tolerance)

    def lines(self) -> list[str]:
        """The report ``--verify`` prints."""
        verdict = "reproducible" if self.passed else "NOT reproducible"
        lines = [
            f"re-simulated {self.samples} samples with {self.commands} recorded commands",
            f"largest position difference: {self.max_dx:.3e} m at t = {self.worst_dx_t:.6f} s "
            f"({self.rel_dx:.3e} of max|x| = {self.x_scale:.6g} m)",
            f"largest velocity difference: {self.max_dv:.3e} m/s at t = {self.worst_dv_t:.6f} s "
            f"({self.rel_dv:.3e} of max|v| = {self.v_scale:.6g} m/s)",
        ]
        lines += [f"problem: {problem}" for problem in self.problems]
        lines.append(f"{verdict} (tolerance {self.tolerance:.0e} relative)")
        return lines


def initial_parameters(recording: Recording) -> dict[str, Any]:
    """The parameters at start: the first ParameterEvent's new_parameters on
    ``parameters``, else the plant and input fields of the ``friction_sim``
    metadata record."""
    for raw in recording.messages_on(PARAMETERS):
        new, _ = parameter_event_values(recording.decode(raw))
        if new:
            return new
    meta = recording.metadata.get(METADATA_NAME, {})
    values: dict[str, Any] = {}
    for name in (*PLANT_FIELDS, *INPUT_FIELDS):
        if name in meta:
            with contextlib.suppress(ValueError):
                values[name] = float(meta[name])
    return values


def recorded_commands(recording: Recording) -> list[Command]:
    """Every accepted command in the recording, at its log time, sorted by
    time (ties in file order): the command topics (target_speed included,
    which changes no slider) and every ParameterEvent on ``parameters`` after
    the initial one that changes a plant or input field."""
    order = {id(raw): i for i, raw in enumerate(recording.messages)}
    found: list[tuple[int, int, Command]] = []
    initial_seen = False
    for topic in COMMAND_TOPICS:
        for raw in recording.messages_on(topic):
            msg = recording.decode(raw)
            if topic == PARAMETERS and not initial_seen and parameter_event_values(msg)[0]:
                initial_seen = True
                continue
            command = command_from_message(topic, msg, ns_to_seconds(raw.log_time))
            if command.values:
                found.append((raw.log_time, order[id(raw)], command))
    return [command for _, _, command in sorted(found, key=lambda item: item[:2])]


def verify(recording: Recording, tolerance: float = DEFAULT_TOLERANCE) -> VerifyResult:
    """Re-simulate the recording with the exact core and compare it with the
    recorded pose and velocity samples (see :class:`VerifyResult`)."""
    values = initial_parameters(recording)
    slider = _initial_slider(recording, values)
    commands = [command for command in recorded_commands(recording) if command.for_slider]
    pose_ns, pose = state_series(recording, "pose", lambda m: (m.pose.position.x,), 1)
    vel_ns, vel = state_series(recording, "velocity", lambda m: (m.twist.linear.x,), 1)
    times_ns = np.unique(np.concatenate([pose_ns, vel_ns]))
    x_sim, v_sim, problems = _resimulate(slider, commands, times_ns, sample_times(times_ns, _log_rate(recording,
                                                                                                      values)))
    dx, dx_t = _largest_difference(times_ns, x_sim, pose_ns, pose[:, 0])
    dv, dv_t = _largest_difference(times_ns, v_sim, vel_ns, vel[:, 0])
    x_scale = float(np.max(np.abs(pose[:, 0]))) if pose.size else 0.0
    v_scale = float(np.max(np.abs(vel[:, 0]))) if vel.size else 0.0
    if recording.dropped:
        problems.append(f"the recorder dropped {recording.dropped} messages")
    return VerifyResult(
        samples=int(pose_ns.size), commands=len(commands), max_dx=dx, max_dv=dv, x_scale=x_scale, v_scale=v_scale,
        rel_dx=_relative(dx, x_scale), rel_dv=_relative(dv, v_scale), worst_dx_t=dx_t, worst_dv_t=dv_t,
        tolerance=tolerance, problems=tuple(problems),
    )


def _initial_slider(recording: Recording, values: dict[str, Any]) -> Slider:
    """The slider the run started with; RecordingError if the values are missing or invalid."""
    missing = [name for name in (*PLANT_FIELDS, *INPUT_FIELDS[:3]) if name not in values]
    if missing:
        raise RecordingError(f"{recording.path}: no initial value of {', '.join(missing)} "
                             f"(neither on 'parameters' nor in the friction_sim metadata)")
    try:
        params = SliderParams(**{name: float(values[name]) for name in PLANT_FIELDS})
        inputs = Inputs(**{name: float(values.get(name, 0.0)) for name in INPUT_FIELDS})
        return Slider(params, inputs, event_log_size=0)
    except ParameterError as error:
        raise RecordingError(f"{recording.path}: recorded initial parameters are invalid: {error}") from None


def _resimulate(slider: Slider, commands: list[Command], times_ns: IntArray,
                times: FloatArray) -> tuple[FloatArray, FloatArray, list[str]]:
    """(x, v) of ``slider`` at ``times`` with ``commands`` applied at their
    times (a sample at a command's time is taken before it, as the node logs
    it), and the commands that could not be applied.  Commands recorded at
    one instant were one batch in the node: they take effect together."""
    x_sim = np.empty(times_ns.size)
    v_sim = np.empty(times_ns.size)
    problems: list[str] = []
    first = 0
    for t_ns, batch in groupby(commands, key=lambda command: seconds_to_ns(command.t)):
        last = int(np.searchsorted(times_ns, t_ns, side="right"))
        if last > first:
            trajectory = slider.sample(np.maximum(times[first:last], slider.t))
            x_sim[first:last], v_sim[first:last] = trajectory.x, trajectory.v
            first = last
        _apply_batch(slider, list(batch), problems)
    if first < times_ns.size:
        trajectory = slider.sample(np.maximum(times[first:], slider.t))
        x_sim[first:], v_sim[first:] = trajectory.x, trajectory.v
    return x_sim, v_sim, problems


def _apply_batch(slider: Slider, batch: list[Command], problems: list[str]) -> None:
    """Advance to the batch's time and apply its commands as one change
    (each through the core's gate; one that cannot be applied is reported)."""
    slider.advance_to(max(batch[0].t, slider.t))
    params, inputs = slider.params, slider.inputs
    changed: set[str] = set()
    for command in batch:
        try:
            params, inputs = apply(command, params, inputs)
            changed.update(command.values)
        except ParameterError as error:
            problems.append(f"the command recorded at t = {command.t:.9f} s cannot be applied: {error}")
    if changed:
        slider.set_plant(params, inputs, changed)


def _log_rate(recording: Recording, initial: dict[str, Any]) -> float | None:
    """The recording's log rate [Hz] (initial parameters, else metadata), or None."""
    for source in (initial, recording.metadata.get(METADATA_NAME, {})):
        try:
            rate = float(source["log_rate"])
        except (KeyError, TypeError, ValueError):
            continue
        if math.isfinite(rate) and rate > 0.0:
            return rate
    return None


def sample_times(times_ns: IntArray, log_rate: float | None) -> FloatArray:
    """Simulation times [s] of recorded samples: the grid time k / log_rate
    where the log time [ns] is that grid point rounded (the exact time the
    state was computed for), else log time / 1e9."""
    seconds: FloatArray = times_ns / NS_PER_S
    if log_rate is None or times_ns.size == 0:
        return seconds
    grid: FloatArray = np.rint(times_ns * (log_rate / NS_PER_S)) / log_rate
    on_grid = np.rint(grid * NS_PER_S).astype(np.int64) == times_ns
    return np.where(on_grid, grid, seconds)


def _largest_difference(sim_ns: IntArray, sim: FloatArray, rec_ns: IntArray,
                        rec: FloatArray) -> tuple[float, float]:
    """(largest |sim - rec| at the recorded times, the time [s] where it is)."""
    if rec_ns.size == 0:
        return 0.0, 0.0
    diff = np.abs(sim[np.searchsorted(sim_ns, rec_ns)] - rec)
    worst = int(np.argmax(diff))
    return float(diff[worst]), ns_to_seconds(int(rec_ns[worst]))


def _relative(difference: float, scale: float) -> float:
    """``difference`` relative to ``scale`` (inf for a difference against zero)."""
    if difference == 0.0:
        return 0.0
    return difference / scale if scale > 0.0 else math.inf


__all__ = [
    "DEFAULT_TOLERANCE", "VerifyResult", "initial_parameters", "recorded_commands", "sample_times", "verify",
]
