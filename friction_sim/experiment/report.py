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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

from friction_sim.experiment.runner import settling_periods
from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.urelation import predict

if TYPE_CHECKING:
    from matplotlib.figure import Figure

TOLERANCE = 0.01


@dataclass
class RunData:
    """What a report needs from a run (simulation times in s, SI units).

    ``schedule`` holds the scheduled commands (segment boundaries);
    ``commands`` every command the slider accepted (the schedule's and the
    controller's), ``targets`` the target speeds the controller got.
    """

    params: SliderParams
    inputs: Inputs
    duration: float
    schedule: list[tuple[float, str, Any]]
    commands: list[tuple[float, str, Any]] = field(default_factory=list)
    targets: list[tuple[float, float]] = field(default_factory=list)
    mean_velocity: list[tuple[float, float]] = field(default_factory=list)
    events: list[tuple[float, str]] = field(default_factory=list)
    name: str = "experiment"
    #: (t, v) samples, used for the stick fraction when the events were not
    #: recorded (a recording made with ``experiment --attach``).
    velocity: list[tuple[float, float]] = field(default_factory=list)


@dataclass(frozen=True)
class SegmentRow:
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
    """The slider's inputs in force at ``t`` (after commands at exactly ``t``)."""
    inputs = data.inputs
    source = data.commands if include_controller and data.commands else data.schedule
    for when, topic, value in source:
        if when > t:
            break
        inputs = _apply(inputs, topic, value)
    return inputs


def _apply(inputs: Inputs, topic: str, value: Any) -> Inputs:
    """Inputs after a command: a recorded change (its input fields) or a
    scheduled one (topic and value, as in a scenario)."""
    if isinstance(value, dict):
        return inputs.replace(**value)
    if topic == "external_wrench":
        return inputs.replace(external_force_x=value[0], external_force_z=value[1])
    if topic in ("drive_force", "excitation_amplitude", "excitation_frequency"):
        return inputs.replace(**{topic: float(value)})
    return inputs


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
    if data.events or not data.velocity:
        return stick_fraction(data.events, start, end)
    window = [v for t, v in data.velocity if start <= t <= end]
    return sum(1 for v in window if v == 0.0) / len(window) if window else math.nan


def build_report(data: RunData, tolerance: float = TOLERANCE) -> list[SegmentRow]:
    """One row per segment between scheduled commands."""
    bounds = sorted({0.0, *(t for t, _, _ in data.schedule)})
    labels = {t: _fmt(value) if isinstance(value, dict) else f"{topic} = {_fmt(value)}"
              for t, topic, value in data.schedule}
    rows = []
    for start, end in zip(bounds, bounds[1:] + [data.duration]):
        if end - start <= 0.0:
            continue
        inputs = inputs_at(data, end - 1e-9)
        period = 1.0 / inputs.excitation_frequency
        target = target_at(data, start + 1e-9)
        mode = "closed loop" if target is not None else "open loop"
        if target is None:
            target = predict(data.params, inputs_at(data, start + 1e-9, include_controller=False)).mean_velocity
        samples = [(t, v) for t, v in data.mean_velocity if start < t <= end + 1e-9]
        achieved = samples[-1][1] if samples else math.nan
        error = achieved / target - 1.0 if target else achieved
        rows.append(SegmentRow(
            start=start, end=end, mode=mode, command=labels.get(start, "start"), target=target,
            achieved=achieved, error=error,
            settling_periods=settling_periods(samples, start, target, inputs.excitation_frequency, tolerance),
            stick_fraction=_stick_fraction(data, end - period, end),
        ))
    return rows


def _fmt(value: Any) -> str:
    if isinstance(value, dict):
        return ", ".join(f"{k} = {v:g}" for k, v in value.items())
    if isinstance(value, tuple):
        return f"({value[0]:g}, {value[1]:g}) N"
    return f"{value:g}"


def table_markdown(rows: Sequence[SegmentRow], title: str = "") -> str:
    """The report table as Markdown (speeds in mm/s)."""
    lines = [f"## {title}", ""] if title else []
    lines += [
        "| segment [s] | command | mode | target [mm/s] | achieved [mm/s] | error | settling [periods] "
        "| stick fraction |",
        "|---|---|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        settling = "never" if math.isinf(r.settling_periods) else f"{r.settling_periods:.0f}"
        lines.append(
            f"| {r.start:g}-{r.end:g} | {r.command} | {r.mode} | {r.target * 1e3:.6f} | {r.achieved * 1e3:.6f} "
            f"| {r.error:+.2e} | {settling} | {r.stick_fraction:.3f} |")
    return "\n".join(lines) + "\n"


def table_text(rows: Sequence[SegmentRow]) -> str:
    """The report table for a terminal."""
    header = f"{'segment [s]':>13} {'mode':>11} {'target':>10} {'achieved':>10} {'error':>9} {'settle':>6} {'stick':>6}  command"
    lines = [header, f"{'':>13} {'':>11} {'[mm/s]':>10} {'[mm/s]':>10} {'':>9} {'[per]':>6} {'':>6}"]
    for r in rows:
        settling = "never" if math.isinf(r.settling_periods) else f"{r.settling_periods:.0f}"
        lines.append(f"{f'{r.start:g}-{r.end:g}':>13} {r.mode:>11} {r.target * 1e3:10.5f} {r.achieved * 1e3:10.5f} "
                     f"{r.error:+9.1e} {settling:>6} {r.stick_fraction:6.3f}  {r.command}")
    return "\n".join(lines)


def report_figure(data: RunData, rows: Sequence[SegmentRow]) -> Figure:
    """Target and measured mean speed, Pa, Fd and f against time."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 9.0), layout="constrained")
    ax_v, ax_pa, ax_fd, ax_f = fig.subplots(4, 1, sharex=True)
    ax_v.plot([t for t, _ in data.mean_velocity], [v * 1e3 for _, v in data.mean_velocity], ".-",
              markersize=2, linewidth=0.7, label="measured mean speed")
    for r in rows:
        ax_v.plot([r.start, r.end], [r.target * 1e3] * 2, "k--" if r.mode == "closed loop" else "g:",
                  linewidth=1.2)
    ax_v.plot([], [], "k--", label="target (closed loop)")
    ax_v.plot([], [], "g:", label="U-relation prediction (open loop)")
    ax_v.set_ylabel("mean speed [mm/s]")
    ax_v.legend(loc="upper left", fontsize=8)
    times = [0.0] + [t for t, _, _ in data.commands] + [data.duration]
    states = [data.inputs] + [inputs_at(data, t) for t, _, _ in data.commands]
    for axis, name, label in ((ax_pa, "excitation_amplitude", "Pa [N]"), (ax_fd, "drive_force", "Fd [N]"),
                              (ax_f, "excitation_frequency", "f [Hz]")):
        axis.step(times, [getattr(s, name) for s in states] + [getattr(states[-1], name)], where="post")
        axis.set_ylabel(label)
    for r in rows[1:]:
        for axis in (ax_v, ax_pa, ax_fd, ax_f):
            axis.axvline(r.start, color="0.8", linewidth=0.7, zorder=0)
    ax_f.set_xlabel("simulation time [s]")
    fig.suptitle(data.name)
    return fig


def write_report(data: RunData, folder: Path, stem: str) -> tuple[list[SegmentRow], Path, Path]:
    """Write <stem>.md and <stem>.png into ``folder``; return rows and paths."""
    rows = build_report(data)
    folder.mkdir(parents=True, exist_ok=True)
    markdown = folder / f"{stem}.md"
    markdown.write_text(f"# {data.name}\n\n![report]({stem}.png)\n\n" + table_markdown(rows))
    picture = folder / f"{stem}.png"
    report_figure(data, rows).savefig(picture, dpi=110)
    return rows, markdown, picture


def run_data_from_recording(path: Path) -> RunData:
    """Everything a report needs, read back from an experiment's recording.

    The scenario (its YAML text and the simulation time the experiment started
    at) is in the ``friction_sim_scenario`` metadata record; all times are
    made relative to that start.  A plain slider recording (no scenario) is
    reported as one segment per accepted command.
    """
    from friction_sim.experiment.runner import SCENARIO_METADATA
    from friction_sim.io.messages import stamp_ns
    from friction_sim.io.replay import initial_parameters, read_recording, recorded_changes
    from friction_sim.experiment.scenario import parse_scenario

    recording = read_recording(path)
    meta = recording.metadata.get(SCENARIO_METADATA, {})
    start_ns = int(meta.get("start_ns", recording.start_ns))
    start = start_ns / 1e9
    initial = initial_parameters(recording)
    params = SliderParams(**{k: float(initial[k]) for k in ("mass", "mu", "gravity") if k in initial})
    inputs = Inputs(**{k: float(initial[k]) for k in ("drive_force", "excitation_amplitude",
                                                       "excitation_frequency") if k in initial})
    commands: list[tuple[float, str, Any]] = [
        (change.t_ns / 1e9 - start, change.topic, change.inputs)
        for change in recorded_changes(recording) if change.inputs
    ]
    inputs = _inputs_before(inputs, commands)
    commands = [c for c in commands if c[0] >= 0.0]
    if "scenario" in meta:
        scenario = parse_scenario(meta["scenario"], meta.get("file", "<recorded scenario>"))
        schedule = [(c.t, c.topic, c.value) for c in scenario.schedule]
        duration, name = scenario.duration, scenario.name
        targets = [(0.0, scenario.initial_target)] if scenario.initial_target is not None else []
        targets += [(t, value) for t, topic, value in schedule if topic == "target_speed"]
    else:
        schedule = [c for c in commands if c[1] != "parameters"]
        duration, name = recording.end_ns / 1e9 - start, recording.path.stem
        targets = [(t / 1e9 - start, msg.data) for t, msg in recording.decoded("target_speed")]
    return RunData(
        params=params, inputs=inputs, duration=duration, schedule=schedule, commands=commands,
        targets=sorted(targets),
        mean_velocity=[(stamp_ns(m.header.stamp) / 1e9 - start, m.twist.linear.x)
                       for _, m in recording.decoded("mean_velocity") if stamp_ns(m.header.stamp) >= start_ns],
        events=[(t / 1e9 - start, m.name) for t, m in recording.decoded("events")],
        name=name,
        velocity=[] if recording.messages_on("events") else [
            (t / 1e9 - start, m.twist.linear.x) for t, m in recording.decoded("velocity")],
    )


def _inputs_before(inputs: Inputs, commands: list[tuple[float, str, Any]]) -> Inputs:
    """Apply the commands that came before the experiment's start."""
    for t, topic, value in commands:
        if t < 0.0:
            inputs = _apply(inputs, topic, value)
    return inputs
