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
  from the recorded events (a lift-off ends a stuck stretch; a landing that
  stops the slider begins one).

This module is pure (no ROS, no matplotlib): the picture is
:func:`friction_sim.cli.figures.report_figure`, and writing the files is
:mod:`friction_sim.cli.experiments`.  The recording is read only through
:mod:`friction_sim.io`; what the experiment was (its schedule, duration and
initial target) comes from the scenario metadata record the runner wrote
(:mod:`friction_sim.experiment.job`).

A recording is streamed (:func:`run_data_from_recording`): one pass reads
the commands, a second the mean speeds and the events chunk by chunk,
keeping only what the rows depend on (:class:`_Keeper`) and a thinned curve
for the picture, so memory stays bounded whatever the length.  A recording
whose recorder dropped messages is refused with the count: its rows would
be wrong.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from friction_sim.core.meanspeed.predict import predict
from friction_sim.core.model.commands import COMMANDS, Command, in_force
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.errors import FrictionSimError
from friction_sim.experiment.job import SCENARIO_METADATA, ScenarioRecord, Series, read_scenario_metadata
from friction_sim.experiment.metrics import settling_periods
from friction_sim.experiment.scenario import Scenario, parse_scenario

TOLERANCE = 0.01
#: About how many mean-speed samples a report read from a recording keeps for its picture.
PICTURE_POINTS = 2000


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
    #: The settling band of the report.  Read from a recording, ``mean_velocity``,
    #: ``events`` and ``velocity`` hold only the samples the rows at this
    #: tolerance depend on, plus a thinned mean-speed curve for the picture.
    tolerance: float = TOLERANCE
    #: The band of the segment that starts at each key: the ``within`` its scenario's
    #: ``expect`` states for the mean speed after that change (else ``tolerance``).
    bands: dict[float, float] = field(default_factory=dict)
    #: The scenario the recording was made from, when it holds its text (to judge its ``expect``).
    scenario: Scenario | None = None
    #: Every mean-speed sample (t, v) of a recording, for the ``expect`` verdicts.
    all_mean_velocity: Series[tuple[float, float]] = field(default_factory=lambda: Series(2))

    def band(self, start: float) -> float:
        """The settling band of the segment that starts at ``start``."""
        return self.bands.get(start, self.tolerance)


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


#: A landing that leaves the slider stuck (an impulsive landing that stops it), as
#: the report names it: the recorded kind is ``landing`` whatever follows.
LANDING_STUCK = "landing_stuck"
#: Event kinds after which the slider is stuck, and after which it moves (slips or flies).
STUCK_AFTER = frozenset({"stick", LANDING_STUCK})
MOVING_AFTER = frozenset({"slip_start", "lift_off", "landing"})


def stick_fraction(events: Sequence[tuple[float, str]], start: float, end: float) -> float:
    """Share of [start, end] spent stuck, from the events (stuck at t = 0): a slip
    start or a lift-off ends a stuck stretch, a stick or a landing that stops the
    slider (:data:`LANDING_STUCK`) begins one; reversals change nothing."""
    if end <= start:
        return math.nan
    stuck, since, total = True, 0.0, 0.0
    for when, kind in list(events) + [(math.inf, "end")]:
        upto = min(when, end)
        if stuck and upto > start:
            total += upto - max(since, start)
        if when >= end:
            break
        if kind in MOVING_AFTER:
            stuck, since = False, when
        elif kind in STUCK_AFTER:
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
    if command.name not in COMMANDS:  # a parameter change: numbers, or text (landing_friction)
        return ", ".join(f"{k} = {v:g}" if isinstance(v, float | int) else f"{k} = {v}"
                         for k, v in command.values.items())
    values = [command.values.get(name, 0.0) for name in COMMANDS[command.name].fields]
    if len(values) == 1:
        return f"{command.name} = {values[0]:g}"
    return f"{command.name} = ({', '.join(f'{v:g}' for v in values)}) N"


def segments(data: RunData) -> list[tuple[float, float]]:
    """(start, end) of each segment: between scheduled commands, to the end of the run."""
    bounds = sorted({0.0, *(c.t for c in data.schedule)})
    return [(start, end) for start, end in zip(bounds, bounds[1:] + [data.duration]) if end - start > 0.0]


def segment_target(data: RunData, start: float) -> tuple[str, float]:
    """(mode, target speed) of the segment starting at ``start``: the target
    in force (closed loop), else the speed the U relation predicts for the
    scheduled inputs (open loop)."""
    target = target_at(data, start + 1e-9)
    if target is not None:
        return "closed loop", target
    return "open loop", predict(data.params, inputs_at(data, start + 1e-9, include_controller=False)).mean_velocity


def stick_window(data: RunData, end: float) -> tuple[float, float]:
    """The window of the stick fraction of a segment ending at ``end``: its last whole period."""
    return end - 1.0 / inputs_at(data, end - 1e-9).excitation_frequency, end


def build_report(data: RunData, tolerance: float | None = None) -> list[SegmentRow]:
    """One row per segment between scheduled commands (settling band
    ``tolerance``, by default each segment's: :meth:`RunData.band`)."""
    labels = {c.t: command_label(c) for c in data.schedule}  # the last command at a time names it
    return [_segment(data, start, end, labels.get(start, "start"), data.band(start) if tolerance is None else tolerance)
            for start, end in segments(data)]


def _segment(data: RunData, start: float, end: float, label: str, tolerance: float) -> SegmentRow:
    """The row of the segment [start, end]."""
    inputs = inputs_at(data, end - 1e-9)
    mode, target = segment_target(data, start)
    samples = [(t, v) for t, v in data.mean_velocity if start < t <= end + 1e-9]
    achieved = samples[-1][1] if samples else math.nan
    return SegmentRow(
        start=start, end=end, mode=mode, command=label, target=target, achieved=achieved,
        error=achieved / target - 1.0 if target else achieved,
        settling_periods=settling_periods(samples, start, target, inputs.excitation_frequency, tolerance),
        stick_fraction=_stick_fraction(data, *stick_window(data, end)),
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


def run_data_from_recording(path: Path, tolerance: float = TOLERANCE) -> RunData:
    """Everything a report needs, read back from an experiment's recording.

    What the experiment was (schedule, duration, initial target and the
    simulation time it started at) is in the ``friction_sim_scenario``
    metadata record; all times are made relative to that start.  A plain
    slider recording (no scenario) is reported as one segment per accepted
    command.  The file is streamed; RecordingError (one line) if the
    recorder dropped messages.
    """
    from friction_sim.experiment.verify import initial_plant, recorded_commands
    from friction_sim.io.reader import read_recording

    recording = read_recording(path)
    recording.refuse_dropped("summarised")
    meta = recording.metadata.get(SCENARIO_METADATA, {})
    start_ns = int(meta.get("start_ns", recording.start_ns))
    start = start_ns / 1e9
    params, inputs = initial_plant(recording)
    every = [c.at(c.t - start) for c in recorded_commands(recording)]
    recorded = [c for c in every if c.inputs]
    params, inputs = in_force([c for c in recorded if c.t < 0.0], params, inputs, 0.0)
    commands = [c for c in recorded if c.t >= 0.0]
    source = _recorded_scenario(meta)
    scenario = _scenario_record(meta, source)
    bands = {e.t: e.within for e in source.expect if e.quantity == "mean_speed"} if source else {}
    if scenario is not None:
        schedule, duration, name = list(scenario.schedule), scenario.duration, scenario.name
        targets = _scheduled_targets(scenario)
    else:
        schedule = [c for c in commands if c.name in COMMANDS]
        duration, name = recording.end_ns / 1e9 - start, recording.path.stem
        targets = [(c.t, c.values["target_speed"]) for c in every if "target_speed" in c.values]
    data = RunData(params=params, inputs=inputs, duration=duration, schedule=schedule, commands=commands,
                   targets=sorted(targets), name=name, tolerance=tolerance, bands=bands, scenario=source)
    _Keeper(data, recording.count("mean_velocity")).read(recording, start_ns)
    return data


_Sample = tuple[int, float, Any]  # (order read, t, value): a kept sample or event


class _Keeper:
    """Streams a recording's mean speeds and events into ``data``, keeping
    only what :func:`build_report` reads, which gives the same rows as every
    sample would:

    * settling and achieved speed of a segment depend only on its last
      sample outside the band, the first one inside after it and its last
      sample;
    * the stick fraction of a window depends only on the events inside it
      and the last stick or slip before it (or, without events, the velocity
      samples inside it);

    plus the smallest and largest mean speed of every run of samples, so
    that the picture shows the whole curve in about PICTURE_POINTS points.
    """

    def __init__(self, data: RunData, samples: int) -> None:
        self.data = data
        self.spans = [(start, end) + segment_target(data, start) for start, end in segments(data)]
        self.bands = [data.band(start) for start, _ in segments(data)]
        # per segment: the last sample outside the band, the first inside after it, the last
        self.outside: list[_Sample | None] = [None] * len(self.spans)
        self.inside: list[_Sample | None] = [None] * len(self.spans)
        self.last: list[_Sample | None] = [None] * len(self.spans)
        self.windows = [stick_window(data, end) for _, end in segments(data)]
        self.before: list[_Sample | None] = [None] * len(self.windows)  # (order, t, kind)
        self.events: list[_Sample] = []
        self.velocity: list[tuple[float, float]] = []
        self.step = max(1, -(-samples // max(1, PICTURE_POINTS // 2)))
        self.run: list[_Sample] = []
        self.curve: list[_Sample] = []
        self.count = 0

    def read(self, recording: Any, start_ns: int) -> None:
        """One pass over mean_velocity and events (velocity if no events were recorded)."""
        from friction_sim.io.cdr import stamps_ns
        from friction_sim.io.series import VELOCITY, state_values, status_names

        topics = ["mean_velocity", "events"] if recording.count("events") else ["mean_velocity", "velocity"]
        relative = {recording.topic_name(topic): topic for topic in topics}
        start = start_ns / 1e9
        for block in recording.iter_chunks(topics):
            groups: dict[str, list[Any]] = {topic: [] for topic in topics}
            for raw in block:
                groups[relative[raw.topic]].append(raw)
            if groups["mean_velocity"]:
                stamps = stamps_ns([raw.data for raw in groups["mean_velocity"]])
                _, values = state_values(recording, groups["mean_velocity"], VELOCITY)
                for stamp, v in zip(stamps.tolist(), values[:, 0].tolist()):
                    if stamp >= start_ns:
                        self.mean_speed(stamp / 1e9 - start, v)
            if groups.get("events"):
                for raw, kind in zip(groups["events"], status_names(recording, groups["events"])):
                    self.event(raw.log_time / 1e9 - start, _landing_kind(recording, raw) if kind == "landing"
                               else kind)
            if groups.get("velocity"):
                times, values = state_values(recording, groups["velocity"], VELOCITY)
                for t_ns, v in zip(times.tolist(), values[:, 0].tolist()):
                    self.velocity_sample(t_ns / 1e9 - start, v)
        self.finish()

    def mean_speed(self, t: float, v: float) -> None:
        """One mean-speed sample (time order)."""
        sample = (self.count, t, v)
        self.count += 1
        self.data.all_mean_velocity.append((t, v))
        for k, (start, end, _, target) in enumerate(self.spans):
            if start < t <= end + 1e-9:
                inside = abs(v - target) <= self.bands[k] * abs(target) if target else v == 0.0
                if not inside:
                    self.outside[k], self.inside[k] = sample, None
                elif self.inside[k] is None:
                    self.inside[k] = sample
                self.last[k] = sample
        self.run.append(sample)
        if len(self.run) >= self.step:
            self._thin()

    def _thin(self) -> None:
        """Keep the smallest and the largest sample of the run."""
        if self.run:
            self.curve += {min(self.run, key=lambda s: s[2]), max(self.run, key=lambda s: s[2])}
            self.run = []

    def event(self, t: float, kind: str) -> None:
        """One event (time order): those that decide whether the slider is stuck are kept."""
        event = (self.count, t, kind)
        self.count += 1
        for k, (low, high) in enumerate(self.windows):
            if t < low:
                if kind in STUCK_AFTER or kind in MOVING_AFTER:
                    self.before[k] = event
            elif t <= high and (not self.events or self.events[-1] is not event):
                self.events.append(event)

    def velocity_sample(self, t: float, v: float) -> None:
        """One velocity sample (only read when no events were recorded)."""
        if any(low <= t <= high for low, high in self.windows):
            self.velocity.append((t, v))

    def finish(self) -> None:
        """Put what was kept into the data, in time order (file order at one time)."""
        self._thin()
        kept = {s for s in (*self.outside, *self.inside, *self.last, *self.curve) if s is not None}
        self.data.mean_velocity = [(t, v) for _, t, v in sorted(kept, key=lambda s: (s[1], s[0]))]
        events = set(self.events) | {e for e in self.before if e is not None}
        self.data.events = [(t, kind) for _, t, kind in sorted(events, key=lambda e: (e[1], e[0]))]
        self.data.velocity = self.velocity


def _landing_kind(recording: Any, raw: Any) -> str:
    """``landing``, or :data:`LANDING_STUCK` when the recorded landing left the
    slider stuck (its message reads ``flight -> stuck``).  Decoded in full: at
    most one landing a period, so the cost stays a fraction of the read."""
    message = str(recording.decode(raw).message)
    return LANDING_STUCK if message.endswith("-> stuck") else "landing"


def _scenario_record(meta: dict[str, str], source: Scenario | None) -> ScenarioRecord | None:
    """The experiment's description: the record itself, or, for a recording
    that holds only the scenario's text, that text as parsed (``source``; parsed
    again here only to raise its error, when it could not be)."""
    record = read_scenario_metadata(meta)
    if record is not None or "scenario" not in meta:
        return record
    scenario = source or parse_scenario(meta["scenario"], meta.get("file", "<recorded scenario>"))
    return ScenarioRecord(scenario.name, scenario.duration, scenario.initial_target, scenario.schedule, None)


def _recorded_scenario(meta: dict[str, str]) -> Scenario | None:
    """The scenario whose text the recording holds (None: a plain slider recording, or a
    text this version cannot read: then nothing is judged)."""
    if "scenario" not in meta:
        return None
    try:
        return parse_scenario(meta["scenario"], meta.get("file", "<recorded scenario>"))
    except FrictionSimError:
        return None


def _scheduled_targets(scenario: ScenarioRecord) -> list[tuple[float, float]]:
    """(t, target) of the initial target and every scheduled one."""
    targets = [(0.0, scenario.initial_target)] if scenario.initial_target is not None else []
    return targets + [(c.t, c.values["target_speed"]) for c in scenario.schedule if "target_speed" in c.values]


__all__ = [
    "LANDING_STUCK", "MOVING_AFTER", "PICTURE_POINTS", "STUCK_AFTER", "TOLERANCE", "RunData", "SegmentRow",
    "build_report", "command_label", "inputs_at", "report_markdown", "run_data_from_recording", "segment_target",
    "segments", "stick_fraction", "stick_window", "table_markdown", "table_text", "target_at",
]
