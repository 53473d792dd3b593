"""The experiment job behind ``friction-sim experiment`` and ``friction-sim report``.

``run_scenario``: validate the scenario (nothing starts on a bad file), bring
up the nodes in this process, play the schedule over real topics with a live
status line, record everything to ``<output>/<name>.mcap``, then write the
report (``<name>.md`` and ``<name>.png``) from that recording alone, exactly
as ``friction-sim report`` would.

``report_recording``: that report, from any recording (``friction-sim report``).
"""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from friction_sim.experiment.report import (
    RunData,
    SegmentRow,
    build_report,
    report_markdown,
    run_data_from_recording,
    table_text,
)
from friction_sim.experiment.scenario import load_scenario
from friction_sim.experiment.spec import Status


@dataclass(frozen=True)
class JobOutput:
    """What a job wrote: the report's rows, the recording, the picture and the Markdown report."""

    rows: list[SegmentRow]
    recording: Path
    picture: Path
    report: Path


def run_scenario(path: Path, *, output: Path | None = None, attach: str | None = None,
                 foxglove_port: int | None = None, stream: TextIO = sys.stdout,
                 status: TextIO | None = sys.stderr) -> JobOutput:
    """Run a scenario file end to end (see the module docstring); with
    ``attach``, drive nodes already running in that namespace; with
    ``foxglove_port``, the slider serves a Foxglove live view there."""
    from friction_sim.experiment.runner import run_standalone

    scenario = load_scenario(path)
    folder = output or scenario.output
    folder.mkdir(parents=True, exist_ok=True)
    recording = folder / f"{scenario.name}.mcap"
    spec = dataclasses.replace(scenario.spec(), log_path=recording)
    if foxglove_port is not None:
        spec = dataclasses.replace(spec, slider_parameters={**spec.slider_parameters, "foxglove_port": foxglove_port})
    live = _StatusLine(status) if status is not None else None
    print(f"running {path} ({scenario.duration:g} s simulated at {scenario.real_time_factor:g}x real time)",
          file=stream)
    try:
        run_standalone(spec, namespace=attach or scenario.namespace, attach=attach is not None,
                       progress=live.show if live else None)
    finally:
        if live:
            live.close()
    return report_recording(recording, folder, stream=stream)


def report_recording(recording: Path, folder: Path | None = None, *, stream: TextIO = sys.stdout) -> JobOutput:
    """Build the report of a recording (``friction-sim report``) and print the table."""
    data = run_data_from_recording(recording)
    rows, markdown, picture = write_report(data, folder or recording.parent, recording.stem)
    print(table_text(rows), file=stream)
    print(f"recording: {recording}\npicture:   {picture}\nreport:    {markdown}", file=stream)
    return JobOutput(rows, recording, picture, markdown)


def write_report(data: RunData, folder: Path, stem: str) -> tuple[list[SegmentRow], Path, Path]:
    """Write <stem>.md and <stem>.png into ``folder``; return rows and paths."""
    from friction_sim.cli.figures import report_figure, save_figure

    rows = build_report(data)
    folder.mkdir(parents=True, exist_ok=True)
    markdown = folder / f"{stem}.md"
    markdown.write_text(report_markdown(data, rows, f"{stem}.png"))
    picture = folder / f"{stem}.png"
    save_figure(report_figure(data, rows), picture)
    return rows, markdown, picture


class _StatusLine:
    """One line rewritten in place on a terminal; a line a second otherwise."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.tty = stream.isatty()
        self._last_whole = -1

    def show(self, status: Status) -> None:
        """Show ``status``: rewrite the line on a terminal, else print one a simulated second."""
        line = status.line()
        if self.tty:
            self.stream.write("\r" + line)
            self.stream.flush()
        elif int(status.t) > self._last_whole:
            self._last_whole = int(status.t)
            print(line, file=self.stream, flush=True)

    def close(self) -> None:
        """End the rewritten line."""
        if self.tty:
            self.stream.write("\n")
