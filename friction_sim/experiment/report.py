"""The experiment report: one row per schedule segment, a table and a picture.

It is built from the recording alone (``friction-sim report run.mcap``), so a
report can always be rebuilt and checked later.  Per segment (between two
scheduled commands):

* target: closed loop, the target speed in force; open loop, the mean speed
  the exact U relation predicts for the inputs in force;
* achieved: the last whole-period mean speed measured in the segment;
* error: achieved / target - 1;
* settling: whole excitation periods from the segment's start until the mean
  speed stays within ``tolerance`` of the target (inf: it never did);
* stick fraction: the share of the segment's last whole period spent stuck,
  from the recorded stick/slip events.

This module is pure (no ROS, no matplotlib): the picture is
:func:`friction_sim.cli.figures.report_figure`, and writing the files is
:mod:`friction_sim.cli.jobs`.  The recording is read only through
:mod:`friction_sim.io`; what the experiment was (its schedule, duration and
initial target) comes from the scenario metadata record the runner wrote
(:mod:`friction_sim.experiment.spec`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from friction_sim.core import spec as settings
from friction_sim.core.commands import COMMANDS, Command, in_force
from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.urelation import predict
from friction_sim.experiment.metrics import settling_periods
from friction_sim.experiment.spec import SCENARIO_METADATA, ScenarioRecord, read_scenario_metadata

TOLERANCE = 0.01


@dataclass
class RunData:
    """What a report needs from a run (simulation times in s from its start, SI units).

    ``schedule`` holds the scheduled commands (segment boundaries);
    ``commands`` every command the slider accepted (the schedule's and the
    controller's), ``targets`` the target speeds the controller got.
    """

    params: SliderParams
    inputs: Inputs
    duration: float
    schedule: list[Command]
    commands: list[Command] = field(default_factory=list)
    targets: list[tuple[float, float]] = field(default_factory=list)
    mean_velocity: list[tuple[float, float]] = field(default_factory=list)
    events: list[tuple[float, str]] = field(default_factory=list)
    name: str = "experiment"
    #: (t, v) samples, used for the stick fraction when the events were not
    #: recorded (a recording made with ``experiment --attach``).
    velocity: list[tuple[float, float]] = field(default_factory=list)


@dataclass(frozen=True)
class SegmentRow:
    """One row of the report: the segment between two scheduled commands."""

    start: float
    end: float
    mode: str  # "open loop" or "closed loop"
    command: str  # what started the segment
    target: float
    achieved: float
    error: float
    settling_periods: float
    stick_fraction: float


def inputs_at(data: RunData, t: float, include_controller: bool = True) -> Inputs:
    """The slider's inputs in force at ``t`` (after commands at exactly ``t``):
    from every accepted command, or (``include_controller`` false, or none
    recorded) from the schedule alone."""
    source = data.commands if include_controller and data.commands else data.schedule
    return in_force(source, data.params, data.inputs, t)[1]


def target_at(data: RunData, t: float) -> float | None:
    """The target speed in force at ``t`` (None: open loop)."""
    target = None
    for when, value in data.targets:
        if when > t:
            break
        target = value
    return target


def stick_fraction(events: Sequence[tuple[float, str]], start: float, end: float) -> float:
    """Share of [start, end] spent stuck, from the stick/slip events (stuck at t = 0)."""
    if end <= start:
        return math.nan
    stuck, since, total = True, 0.0, 0.0
    for when, kind in list(events) + [(math.inf, "end")]:
        upto = min(when, end)
        if stuck and upto > start:
            total += upto - max(since, start)
        if when >= end:
            break
        if kind == "slip_start":
            stuck, since = False, when
        elif kind == "stick":
            stuck, since = True, when
    return total / (end - start)


def _stick_fraction(data: RunData, start: float, end: float) -> float:
    """From the events if recorded, else the share of velocity samples at rest."""
    if data.events or not data.velocity:
        return stick_fraction(data.events, start, end)
    window = [v for t, v in data.velocity if start <= t <= end]
    return sum(1 for v in window if v == 0.0) / len(window) if window else math.nan


def command_label(command: Command) -> str:
    """A command as the report names it: ``drive_force = 0.8``,
    ``external_wrench = (0, -2) N``; a parameter change lists its fields."""
    if command.name not in COMMANDS:
        return ", ".join(f"{k} = {v:g}" for k, v in command.values.items())
    values = [command.values.get(name, 0.0) for name in COMMANDS[command.name].fields]
    if len(values) == 1:
        return f"{command.name} = {values[0]:g}"
    return f"{command.name} = ({', '.join(f'{v:g}' for v in values)}) N"


def build_report(data: RunData, tolerance: float = TOLERANCE) -> list[SegmentRow]:
    """One row per segment between scheduled commands."""
    bounds = sorted({0.0, *(c.t for c in data.schedule)})
    labels = {c.t: command_label(c) for c in data.schedule}  # the last command at a time names it
    rows = []
    for start, end in zip(bounds, bounds[1:] + [data.duration]):
        if end - start > 0.0:
            rows.append(_segment(data, start, end, labels.get(start, "start"), tolerance))
    return rows


def _segment(data: RunData, start: float, end: float, label: str, tolerance: float) -> SegmentRow:
    """The row of the segment [start, end]."""
    inputs = inputs_at(data, end - 1e-9)
    target = target_at(data, start + 1e-9)
    mode = "closed loop" if target is not None else "open loop"
    if target is None:
        target = predict(data.params, inputs_at(data, start + 1e-9, include_controller=False)).mean_velocity
    samples = [(t, v) for t, v in data.mean_velocity if start < t <= end + 1e-9]
    achieved = samples[-1][1] if samples else math.nan
    return SegmentRow(
        start=start, end=end, mode=mode, command=label, target=target, achieved=achieved,
        error=achieved / target - 1.0 if target else achieved,
        settling_periods=settling_periods(samples, start, target, inputs.excitation_frequency, tolerance),
        stick_fraction=_stick_fraction(data, end - 1.0 / inputs.excitation_frequency, end),
    )


def table_markdown(rows: Sequence[SegmentRow], title: str = "") -> str:
    """The report table as Markdown (speeds in mm/s)."""
    lines = [f"## {title}", ""] if title else []
    lines += [
        "| segment [s] | command | mode | target [mm/s] | achieved [mm/s] | error | settling [periods] "
        "| stick fraction |",
        "|---|---|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r.start:g}-{r.end:g} | {r.command} | {r.mode} | {r.target * 1e3:.6f} | {r.achieved * 1e3:.6f} "
            f"| {r.error:+.2e} | {_settling(r)} | {r.stick_fraction:.3f} |")
    return "\n".join(lines) + "\n"


def table_text(rows: Sequence[SegmentRow]) -> str:
    """The report table for a terminal."""
    header = (f"{'segment [s]':>13} {'mode':>11} {'target':>10} {'achieved':>10} {'error':>9} {'settle':>6} "
              f"{'stick':>6}  command")
    lines = [header, f"{'':>13} {'':>11} {'[mm/s]':>10} {'[mm/s]':>10} {'':>9} {'[per]':>6} {'':>6}"]
    for r in rows:
        lines.append(f"{f'{r.start:g}-{r.end:g}':>13} {r.mode:>11} {r.target * 1e3:10.5f} {r.achieved * 1e3:10.5f} "
                     f"{r.error:+9.1e} {_settling(r):>6} {r.stick_fraction:6.3f}  {r.command}")
    return "\n".join(lines)


def _settling(row: SegmentRow) -> str:
    return "never" if math.isinf(row.settling_periods) else f"{row.settling_periods:.0f}"


def report_markdown(data: RunData, rows: Sequence[SegmentRow], picture: str) -> str:
    """The report file's text: title, the picture ``picture`` and the table."""
    return f"# {data.name}\n\n![report]({picture})\n\n" + table_markdown(rows)


# -- from a recording --------------------------------------------------------------


def run_data_from_recording(path: Path) -> RunData:
    """Everything a report needs, read back from an experiment's recording.

    What the experiment was (schedule, duration, initial target and the
    simulation time it started at) is in the ``friction_sim_scenario``
    metadata record; all times are made relative to that start.  A plain
    slider recording (no scenario) is reported as one segment per accepted
    command.
    """
    from friction_sim.io.messages import stamp_ns
    from friction_sim.io.reader import read_recording
    from friction_sim.io.verify import initial_parameters, recorded_commands

    recording = read_recording(path)
    meta = recording.metadata.get(SCENARIO_METADATA, {})
    start_ns = int(meta.get("start_ns", recording.start_ns))
    start = start_ns / 1e9
    params, inputs = _initial_state(initial_parameters(recording))
    recorded = [c.at(c.t - start) for c in recorded_commands(recording) if c.inputs]
    params, inputs = in_force([c for c in recorded if c.t < 0.0], params, inputs, 0.0)
    commands = [c for c in recorded if c.t >= 0.0]
    scenario = _scenario_record(meta)
    if scenario is not None:
        schedule, duration, name = list(scenario.schedule), scenario.duration, scenario.name
        targets = _scheduled_targets(scenario)
    else:
        schedule = [c for c in commands if c.name in COMMANDS]
        duration, name = recording.end_ns / 1e9 - start, recording.path.stem
        targets = [(t / 1e9 - start, msg.data) for t, msg in recording.decoded("target_speed")]
    mean_velocity = [(stamp_ns(m.header.stamp) / 1e9 - start, m.twist.linear.x)
                     for _, m in recording.decoded("mean_velocity") if stamp_ns(m.header.stamp) >= start_ns]
    velocity = [] if recording.messages_on("events") else [
        (t / 1e9 - start, m.twist.linear.x) for t, m in recording.decoded("velocity")]
    return RunData(
        params=params, inputs=inputs, duration=duration, schedule=schedule, commands=commands,
        targets=sorted(targets), mean_velocity=mean_velocity,
        events=[(t / 1e9 - start, m.name) for t, m in recording.decoded("events")], name=name, velocity=velocity,
    )


def _initial_state(initial: dict[str, Any]) -> tuple[SliderParams, Inputs]:
    """The plant and inputs a recording started with (defaults for what it lacks)."""
    params = SliderParams(**{k: float(initial[k]) for k in settings.PLANT if k in initial})
    inputs = Inputs(**{k: float(initial[k]) for k in settings.INPUTS if k in initial})
    return params, inputs


def _scenario_record(meta: dict[str, str]) -> ScenarioRecord | None:
    """The experiment's description: the record itself, or, for a recording
    that holds only the scenario's text, that text parsed again."""
    record = read_scenario_metadata(meta)
    if record is not None or "scenario" not in meta:
        return record
    from friction_sim.experiment.scenario import parse_scenario

    scenario = parse_scenario(meta["scenario"], meta.get("file", "<recorded scenario>"))
    return ScenarioRecord(scenario.name, scenario.duration, scenario.initial_target, scenario.schedule, None)


def _scheduled_targets(scenario: ScenarioRecord) -> list[tuple[float, float]]:
    """(t, target) of the initial target and every scheduled one."""
    targets = [(0.0, scenario.initial_target)] if scenario.initial_target is not None else []
    return targets + [(c.t, c.values["target_speed"]) for c in scenario.schedule if "target_speed" in c.values]


__all__ = [
    "TOLERANCE", "RunData", "SegmentRow", "build_report", "command_label", "inputs_at", "report_markdown",
    "run_data_from_recording", "stick_fraction", "table_markdown", "table_text", "target_at",
]
