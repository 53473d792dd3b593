"""``--verify``: re-simulate a recording with the exact core and compare.

:func:`verify` rebuilds the simulation from the recorded parameters
(:func:`initial_parameters`) and the accepted commands
(:func:`recorded_commands`, applied at their recorded simulation times, one
by one in recorded order, through
:func:`friction_sim.core.model.commands.take`, the function the slider node
takes each of them with: commands recorded at one instant were as many
changes in the node, never one merged change) and compares
it with every recorded pose and velocity sample: position x, velocity v, and
in flight the height z and its rate vz.  It passes when each differs by at
most 1e-9 relative to the largest recorded magnitude of its quantity (a run
that never leaves the track has z = vz = 0 throughout, and must reproduce
exactly that).

A file written before the ``external_wrench`` convention was marked (force.z
> 0 pressed the slider on the track) is re-simulated in today's convention
(force.z > 0 lifts) with its ``external_force_z`` values turned round
(:attr:`~friction_sim.io.reader.Recording.external_force_z_sign`); plant
parameters it does not name (it predates them) take their defaults, the
paper's model it was recorded with.

The file is streamed: one pass reads the commands (few), a second the
samples chunk by chunk, re-simulating as it goes and keeping only the
largest differences, so memory stays bounded whatever the length.  A file
whose recorder dropped messages is refused (RecordingError with the count):
a re-simulation cannot tell a lost command from a wrong one.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from itertools import groupby
from typing import Any

import numpy as np

from friction_sim.core.engine.single import Slider
from friction_sim.core.model import spec
from friction_sim.core.model.commands import PARAMETERS, RESET, Command, take
from friction_sim.core.model.params import Inputs, SliderParams, plant_from
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
from friction_sim.io.series import POSITION_XZ, VELOCITY_XZ, FloatArray, IntArray, state_blocks

DEFAULT_TOLERANCE = 1e-9
#: The fields every recording names at start; the others (added later) default to the spec's.
REQUIRED_FIELDS = ("mass", "mu", "gravity", "drive_force", "excitation_amplitude", "excitation_frequency")
_EXTERNAL_Z = "external_force_z"


@dataclass(frozen=True)
class VerifyResult:
    """How a re-simulation compares with the recorded states.

    ``max_dx``/``max_dv`` are the largest absolute differences (at
    ``worst_dx_t``/``worst_dv_t`` s), ``rel_dx``/``rel_dv`` the same relative
    to the largest recorded |x| and |v|; ``max_dz``/``max_dvz`` and
    ``rel_dz``/``rel_dvz`` the same for the height z and its rate vz (0 for a
    run that never flies).  ``passed`` when all four are within ``tolerance``
    and nothing went wrong (``problems``).  ``convention`` is the file's
    ``external_wrench`` convention (``loads``: an old file, turned round).
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
    max_dz: float = 0.0
    max_dvz: float = 0.0
    z_scale: float = 0.0
    vz_scale: float = 0.0
    rel_dz: float = 0.0
    rel_dvz: float = 0.0
    worst_dz_t: float = 0.0
    worst_dvz_t: float = 0.0
    convention: str = "lifts"

    @property
    def passed(self) -> bool:
        """Within the tolerance, with samples and without problems."""
        return (not self.problems and self.samples > 0
                and all(rel <= self.tolerance for rel in (self.rel_dx, self.rel_dv, self.rel_dz, self.rel_dvz)))

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
        if self.z_scale or self.vz_scale or self.max_dz or self.max_dvz:  # the run left the track
            lines += [
                f"largest height difference: {self.max_dz:.3e} m at t = {self.worst_dz_t:.6f} s "
                f"({self.rel_dz:.3e} of max|z| = {self.z_scale:.6g} m)",
                f"largest normal velocity difference: {self.max_dvz:.3e} m/s at t = {self.worst_dvz_t:.6f} s "
                f"({self.rel_dvz:.3e} of max|vz| = {self.vz_scale:.6g} m/s)",
            ]
        if self.convention != "lifts":
            lines.append("old file: external_wrench force.z > 0 loaded the contact; re-simulated with it turned "
                         "round (today > 0 lifts)")
        lines += [f"problem: {problem}" for problem in self.problems]
        lines.append(f"{verdict} (tolerance {self.tolerance:.0e} relative)")
        return lines


def initial_parameters(recording: Recording) -> dict[str, Any]:
    """The parameters at start: the first ParameterEvent's new_parameters on
    ``parameters``, else the plant and input fields of the ``friction_sim``
    metadata record; ``external_force_z`` in today's convention (> 0 lifts)."""
    sign = recording.external_force_z_sign
    for raw in recording.iter_messages([PARAMETERS]):
        new, _ = parameter_event_values(recording.decode(raw))
        if new:
            return _turned(new, sign)
    meta = recording.metadata.get(METADATA_NAME, {})
    values: dict[str, Any] = {}
    for name in (*PLANT_FIELDS, *INPUT_FIELDS):
        if name in meta:
            if spec.PLANT.get(name, spec.EXTERNAL_FORCE_X).kind is str:
                values[name] = meta[name]
                continue
            with contextlib.suppress(ValueError):
                values[name] = float(meta[name])
    return _turned(values, sign)


def _turned(values: dict[str, Any], sign: float) -> dict[str, Any]:
    """``values`` with ``external_force_z`` multiplied by ``sign`` (-1: an old
    file's value in today's convention; 0.0 stays 0.0, not -0.0)."""
    value = values.get(_EXTERNAL_Z)
    if sign < 0.0 and isinstance(value, (int, float)) and not isinstance(value, bool):
        values = {**values, _EXTERNAL_Z: 0.0 - value}
    return values


def recorded_commands(recording: Recording) -> list[Command]:
    """Every accepted command in the recording, at its log time, sorted by
    time (ties in file order): the command topics (target_speed included,
    which changes no slider) and every ParameterEvent on ``parameters`` after
    the initial one that changes a plant or input field, and every reset
    (pause, resume and step move no slider); ``external_force_z`` in today's
    convention (> 0 lifts; an old file's is turned round)."""
    sign = recording.external_force_z_sign
    stored = {topic: recording.topic_name(topic) for topic in COMMAND_TOPICS}
    topics = {name: topic for topic, name in stored.items() if name is not None}
    found: list[tuple[int, int, Command]] = []
    initial_seen = False
    for order, raw in enumerate(recording.iter_messages(COMMAND_TOPICS)):
        topic = topics[raw.topic]
        msg = recording.decode(raw)
        if topic == PARAMETERS and not initial_seen and parameter_event_values(msg)[0]:
            initial_seen = True
            continue
        command = command_from_message(topic, msg, ns_to_seconds(raw.log_time))
        if sign < 0.0 and _EXTERNAL_Z in command.values:
            command = Command(command.t, command.name, _turned(dict(command.values), sign))
        if (command.values and not command.is_control) or command.name == RESET:
            found.append((raw.log_time, order, command))
    return [command for _, _, command in sorted(found, key=lambda item: item[:2])]


def verify(recording: Recording, tolerance: float = DEFAULT_TOLERANCE) -> VerifyResult:
    """Re-simulate the recording with the exact core and compare it with the
    recorded pose and velocity samples (see :class:`VerifyResult`), chunk by
    chunk.  RecordingError if the recorder dropped messages or the file's
    external_wrench convention is not known."""
    recording.refuse_dropped("verified")
    values = initial_parameters(recording)
    slider = Slider(*initial_plant(recording, values), event_log_size=0)
    commands = [command for command in recorded_commands(recording) if command.for_slider]
    replay = _Replay(slider, commands, _log_rate(recording, values))
    x, v, z, vz = _Largest(), _Largest(), _Largest(), _Largest()
    samples = 0
    for block in state_blocks(recording, {"pose": POSITION_XZ, "velocity": VELOCITY_XZ}):
        (pose_ns, pose), (vel_ns, vel) = block["pose"], block["velocity"]
        times_ns = replay.in_order(np.unique(np.concatenate([pose_ns, vel_ns])))
        if times_ns.size == 0:
            continue
        x_sim, v_sim, z_sim, vz_sim = replay.states(times_ns)
        x.add(times_ns, x_sim, pose_ns, pose[:, 0])
        z.add(times_ns, z_sim, pose_ns, pose[:, 2])
        v.add(times_ns, v_sim, vel_ns, vel[:, 0])
        vz.add(times_ns, vz_sim, vel_ns, vel[:, 2])
        samples += int(pose_ns.size)
    replay.finish()
    return VerifyResult(
        samples=samples, commands=len(commands), max_dx=x.difference, max_dv=v.difference, x_scale=x.scale,
        v_scale=v.scale, rel_dx=_relative(x.difference, x.scale), rel_dv=_relative(v.difference, v.scale),
        worst_dx_t=x.t, worst_dv_t=v.t, tolerance=tolerance, problems=tuple(replay.problems),
        max_dz=z.difference, max_dvz=vz.difference, z_scale=z.scale, vz_scale=vz.scale,
        rel_dz=_relative(z.difference, z.scale), rel_dvz=_relative(vz.difference, vz.scale),
        worst_dz_t=z.t, worst_dvz_t=vz.t, convention=recording.external_force_z_convention,
    )


@dataclass(frozen=True)
class RecordedRun:
    """A recording as a calibration fits to it: where it came from, its initial
    values, the slider's accepted commands (in force at their recorded times),
    the log rate, and the recorded samples: position x [m] at ``pose_ns`` and
    velocity v [m/s] at ``velocity_ns`` (log times, ascending)."""

    path: str
    initial: dict[str, Any]
    commands: tuple[Command, ...]
    log_rate: float | None
    pose_ns: IntArray
    x: FloatArray
    velocity_ns: IntArray
    v: FloatArray


def recorded_run(recording: Recording) -> RecordedRun:
    """Read what a calibration needs from ``recording`` (refused, as by verify, if
    the recorder dropped messages: a lost command would be fitted as physics)."""
    recording.refuse_dropped("calibrated against")
    values = initial_parameters(recording)
    initial_plant(recording, values)  # refuse missing or invalid initial values here, naming the file
    commands = tuple(command for command in recorded_commands(recording) if command.for_slider)
    pose: list[tuple[IntArray, FloatArray]] = []
    velocity: list[tuple[IntArray, FloatArray]] = []
    for block in state_blocks(recording, {"pose": POSITION_XZ, "velocity": VELOCITY_XZ}):
        pose.append((block["pose"][0], block["pose"][1][:, 0]))
        velocity.append((block["velocity"][0], block["velocity"][1][:, 0]))
    pose_ns, x = _joined(pose)
    velocity_ns, v = _joined(velocity)
    return RecordedRun(str(recording.path), values, commands, _log_rate(recording, values), pose_ns, x,
                       velocity_ns, v)


def _joined(blocks: list[tuple[IntArray, FloatArray]]) -> tuple[IntArray, FloatArray]:
    """One series from the chunks' pieces, in time order."""
    if not blocks:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    times = np.concatenate([t for t, _ in blocks])
    values = np.concatenate([v for _, v in blocks])
    order = np.argsort(times, kind="stable")
    return times[order], values[order]


def resimulate(run: RecordedRun, params: SliderParams, inputs: Inputs) -> tuple[FloatArray, FloatArray]:
    """The exact re-simulation of ``run`` from the plant ``params`` and ``inputs``
    (its commands applied at their times, as verify applies them): x at the
    pose samples' times and v at the velocity samples'."""
    replay = _Replay(Slider(params, inputs, event_log_size=0), list(run.commands), run.log_rate)
    times_ns = np.unique(np.concatenate([run.pose_ns, run.velocity_ns]))
    x, v, _, _ = replay.states(times_ns)
    return x[np.searchsorted(times_ns, run.pose_ns)], v[np.searchsorted(times_ns, run.velocity_ns)]


def initial_plant(recording: Recording, values: dict[str, Any] | None = None) -> tuple[SliderParams, Inputs]:
    """The plant and inputs the run started with (``values``: its initial values,
    default :func:`initial_parameters`), what verify and the report re-simulate
    from; RecordingError, naming the file, if the values are missing or invalid."""
    values = initial_parameters(recording) if values is None else values
    missing = [name for name in REQUIRED_FIELDS if name not in values]
    if missing:
        raise RecordingError(f"{recording.path}: no initial value of {', '.join(missing)} "
                             f"(neither on 'parameters' nor in the friction_sim metadata)")
    try:
        return plant_from(values)
    except ParameterError as error:
        raise RecordingError(f"{recording.path}: recorded initial parameters are invalid: {error}") from None


class _Replay:
    """The exact re-simulation, fed the recorded sample times in ascending
    blocks.  A sample at a command's time is taken before it, as the node
    logs it, so the commands recorded at one instant are applied once a later
    sample comes (or at the end), each as a change of its own, in recorded
    order, as the node took them (:func:`_apply_batch`)."""

    def __init__(self, slider: Slider, commands: list[Command], log_rate: float | None) -> None:
        self.slider = slider
        self.log_rate = log_rate
        self.batches = [(t_ns, list(batch)) for t_ns, batch in
                        groupby(commands, key=lambda command: seconds_to_ns(command.t))]
        self.next = 0
        self.last_ns = -1
        self.problems: list[str] = []

    def in_order(self, times_ns: IntArray) -> IntArray:
        """``times_ns`` from the last time sampled on (a sample recorded out of
        order cannot be re-simulated: it is left out and said once)."""
        late = times_ns < self.last_ns
        if late.any():
            if not any(p.startswith("samples out of time order") for p in self.problems):
                self.problems.append(f"samples out of time order (t = {ns_to_seconds(int(times_ns[late][0])):.9f} s "
                                     f"after {ns_to_seconds(self.last_ns):.9f} s) were not compared")
            times_ns = times_ns[~late]
        return times_ns

    def states(self, times_ns: IntArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(x, v, z, vz) at ``times_ns`` (ascending, from the last time sampled on)."""
        times = sample_times(times_ns, self.log_rate)
        out = np.empty((4, times_ns.size))
        first = 0
        while first < times_ns.size and self.next < len(self.batches):
            t_ns, batch = self.batches[self.next]
            last = int(np.searchsorted(times_ns, t_ns, side="right"))
            if last == times_ns.size:
                break  # a later block may still hold samples at or before this batch
            self._sample(times, first, last, out)
            first = last
            _apply_batch(self.slider, batch, self.problems)
            self.next += 1
        self._sample(times, first, times_ns.size, out)
        self.last_ns = int(times_ns[-1])
        return out[0], out[1], out[2], out[3]

    def _sample(self, times: FloatArray, first: int, last: int, out: FloatArray) -> None:
        """The re-simulated x, v, z, vz at ``times[first:last]`` into ``out[:, first:last]``."""
        if last > first:
            trajectory = self.slider.sample(np.maximum(times[first:last], self.slider.t))
            for row, values in enumerate((trajectory.x, trajectory.v, trajectory.z, trajectory.vz)):
                out[row, first:last] = values

    def finish(self) -> None:
        """Apply the commands after the last sample (to report those that cannot be)."""
        for _, batch in self.batches[self.next:]:
            _apply_batch(self.slider, batch, self.problems)
        self.next = len(self.batches)


class _Largest:
    """The largest |sim - rec| so far (the first time it occurs) and the largest |rec|."""

    def __init__(self) -> None:
        self.difference = 0.0
        self.t = 0.0
        self.scale = 0.0

    def add(self, sim_ns: IntArray, sim: FloatArray, rec_ns: IntArray, rec: FloatArray) -> None:
        """Compare the recorded samples ``rec`` at ``rec_ns`` with ``sim`` at ``sim_ns``."""
        inside = np.isin(rec_ns, sim_ns)  # samples left out as out of order are not compared
        rec_ns, rec = rec_ns[inside], rec[inside]
        if rec_ns.size == 0:
            return
        diff = np.abs(sim[np.searchsorted(sim_ns, rec_ns)] - rec)
        worst = int(np.argmax(diff))
        if diff[worst] > self.difference:
            self.difference, self.t = float(diff[worst]), ns_to_seconds(int(rec_ns[worst]))
        self.scale = max(self.scale, float(np.max(np.abs(rec))))


def _apply_batch(slider: Slider, batch: list[Command], problems: list[str]) -> None:
    """Advance to the time of ``batch`` (the commands recorded at one instant)
    and apply its commands one by one in recorded order, each as a change of
    its own, through :func:`~friction_sim.core.model.commands.take`, as the
    node took them (with the resonant exciter, two changes at one instant are
    not their merged change); one that cannot be applied is reported."""
    slider.advance_to(max(batch[0].t, slider.t))
    for command in batch:
        try:
            take(slider, command)
        except ParameterError as error:
            problems.append(f"the command recorded at t = {command.t:.9f} s cannot be applied: {error}")


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


def _relative(difference: float, scale: float) -> float:
    """``difference`` relative to ``scale`` (inf for a difference against zero)."""
    if difference == 0.0:
        return 0.0
    return difference / scale if scale > 0.0 else math.inf


__all__ = [
    "DEFAULT_TOLERANCE", "RecordedRun", "VerifyResult", "initial_parameters", "recorded_commands", "recorded_run",
    "resimulate", "sample_times", "verify",
]
