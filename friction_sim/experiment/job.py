"""What an experiment is and what it yields, without ROS.

:class:`ExperimentSpec` is everything :func:`friction_sim.experiment.runner.run_experiment`
needs: the plant, its initial inputs, a schedule of
:class:`~friction_sim.core.model.commands.Command` records and the node settings.
:class:`ExperimentResult` holds the time series a run yields, :class:`Status`
the live view for a status line.

The runner writes a *scenario metadata record* into the recording
(:func:`scenario_metadata`): the experiment's name, duration, initial target,
the schedule as JSON and the simulation time it started at, plus the scenario
file's text for humans.  :func:`read_scenario_metadata` reads it back, so a
report is rebuilt from the recording alone without parsing the scenario file.
This module imports neither rclpy nor the message packages: the scenario
parser and the report depend on it, not on the runner.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from friction_sim.core.model import spec as settings
from friction_sim.core.model.commands import Command
from friction_sim.core.model.params import Inputs, SliderParams

#: Name of the MCAP metadata record that describes an experiment's scenario.
SCENARIO_METADATA = "friction_sim_scenario"


@dataclass(frozen=True)
class OperatorAction:
    """What an operator does at simulation time ``t`` (relative to the start),
    beside the schedule: ``send`` publishes a command as it is, one the slider
    refuses (its refusal is recorded on rejected_commands); ``calls`` calls the
    slider's simulation-control services (pause, step, resume, reset) in order.
    Neither changes the inputs the report's segments are made of."""

    t: float
    send: Command | None = None
    calls: tuple[str, ...] = ()


@dataclass(frozen=True)
class ExperimentSpec:
    """Everything an experiment needs (see ``run_experiment``).

    ``schedule`` holds the commands to publish, at simulation times relative
    to the experiment's start; ``log_path`` records the run (the slider's
    recording) to that MCAP file; ``notes`` are extra text entries of the
    scenario metadata record (the scenario file's text, say); ``operator``
    holds what an operator does beside the schedule (:class:`OperatorAction`).
    """

    duration: float
    schedule: Sequence[Command] = ()
    plant: SliderParams = SliderParams()
    inputs: Inputs = Inputs()
    controller: bool = False
    controller_parameters: dict[str, Any] = field(default_factory=dict)
    slider_parameters: dict[str, Any] = field(default_factory=dict)
    real_time_factor: float = float(settings.REAL_TIME_FACTOR.default)
    log_path: Path | None = None
    log_rate: float = float(settings.LOG_RATE.default)
    name: str = "experiment"
    notes: dict[str, str] = field(default_factory=dict)
    operator: Sequence[OperatorAction] = ()
    #: Lockstep: the slider advances only when this driver and the controller have answered.
    lockstep: bool = False

    @property
    def initial_target(self) -> float | None:
        """The target the controller starts with (None: open loop, or it stands by)."""
        if not self.controller or "target_speed" not in self.controller_parameters:
            return None
        return float(self.controller_parameters["target_speed"])


@dataclass(frozen=True)
class Status:
    """A live view of a running experiment (for the status line)."""

    t: float
    duration: float
    target: float | None
    mean_speed: float
    amplitude: float
    drive_force: float
    frequency: float

    def line(self) -> str:
        """One line for a terminal: time, target, mean speed and the inputs in force."""
        target = "open loop" if self.target is None else f"{self.target * 1e3:.3f} mm/s"
        return (f"t {self.t:6.2f}/{self.duration:g} s | target {target:>12} | mean speed "
                f"{self.mean_speed * 1e3:8.4f} mm/s | Pa {self.amplitude:6.3f} N | Fd {self.drive_force:6.3f} N "
                f"| f {self.frequency:g} Hz")


@dataclass
class ExperimentResult:
    """Time series of one run (simulation time in s relative to its start; speeds in m/s, forces in N).

    ``amplitude`` is the controller's output at the time it decided;
    ``drive`` (resonant actuator) its drive commands then: (t, drive level,
    drive frequency [Hz], the latest window's slideway amplitude per unit drive
    [m/s^2], nan until one is read); ``commands`` are the scheduled commands as
    the driver published them, at the time it did.
    """

    mean_velocity: list[tuple[float, float]] = field(default_factory=list)
    amplitude: list[tuple[float, float]] = field(default_factory=list)
    drive: list[tuple[float, float, float, float]] = field(default_factory=list)
    commands: list[Command] = field(default_factory=list)
    duration: float = 0.0


# -- the scenario metadata record ----------------------------------------------------


@dataclass(frozen=True)
class ScenarioRecord:
    """What a recording's scenario metadata record says (times relative to ``start_ns``)."""

    name: str
    duration: float
    initial_target: float | None
    schedule: tuple[Command, ...]
    start_ns: int | None


def schedule_json(schedule: Sequence[Command]) -> str:
    """A schedule as JSON: a list of ``[t, name, {field: value}]`` (full float precision)."""
    return json.dumps([[command.t, command.name, dict(command.values)] for command in schedule])


def schedule_from_json(text: str) -> tuple[Command, ...]:
    """The schedule :func:`schedule_json` wrote (a ParameterError on an unknown command)."""
    return tuple(Command(float(t), str(name), {str(k): float(v) for k, v in values.items()})
                 for t, name, values in json.loads(text))


def scenario_metadata(spec: ExperimentSpec, start_ns: int) -> dict[str, str]:
    """The scenario metadata record of a run that started at simulation time ``start_ns``."""
    target = spec.initial_target
    return {
        **spec.notes, "name": spec.name, "duration": repr(float(spec.duration)),
        "initial_target": "" if target is None else repr(target), "schedule": schedule_json(spec.schedule),
        "start_ns": str(int(start_ns)),
    }


def read_scenario_metadata(meta: Mapping[str, str]) -> ScenarioRecord | None:
    """The record :func:`scenario_metadata` wrote, or None if ``meta`` has no
    schedule (a recording made before the record carried one)."""
    if "schedule" not in meta or "duration" not in meta:
        return None
    target = meta.get("initial_target", "")
    start = meta.get("start_ns")
    return ScenarioRecord(
        name=meta.get("name", "experiment"), duration=float(meta["duration"]),
        initial_target=float(target) if target else None, schedule=schedule_from_json(meta["schedule"]),
        start_ns=int(start) if start else None,
    )


__all__ = [
    "SCENARIO_METADATA", "ExperimentResult", "ExperimentSpec", "OperatorAction", "ScenarioRecord", "Status",
    "read_scenario_metadata", "scenario_metadata", "schedule_from_json", "schedule_json",
]
