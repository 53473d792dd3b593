"""The experiment job behind ``friction-sim experiment`` and ``friction-sim report``.

``run_scenario``: validate the scenario (nothing starts on a bad file), bring
up the nodes in this process, play the schedule over real topics with a live
status line, record everything to ``<output>/<name>.mcap``, then write the
report (``<name>.md`` and ``<name>.png``) from that recording alone, exactly
as ``friction-sim report`` would.
"""

from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from friction_sim.experiment.report import SegmentRow, run_data_from_recording, table_text, write_report
from friction_sim.experiment.scenario import load_scenario


@dataclass(frozen=True)
class JobOutput:
    rows: list[SegmentRow]
    recording: Path
    picture: Path
    report: Path


def run_scenario(path: Path, *, output: Path | None = None, attach: str | None = None,
                 stream: TextIO = sys.stdout, status: TextIO | None = sys.stderr) -> JobOutput:
    """Run a scenario file end to end (see the module docstring); with
    ``attach``, drive nodes already running in that namespace."""
    import rclpy

    from friction_sim.experiment.runner import Status, run_experiment

    scenario = load_scenario(path)
    folder = output or scenario.output
    folder.mkdir(parents=True, exist_ok=True)
    recording = folder / f"{scenario.name}.mcap"
    spec = dataclasses.replace(scenario.spec(), log_path=recording)
    live = _StatusLine(status) if status is not None else None
    print(f"running {path} ({scenario.duration:g} s simulated at {scenario.real_time_factor:g}x real time)",
          file=stream)
    rclpy.init(args=[])
    try:
        run_experiment(spec, namespace=attach or scenario.namespace, attach=attach is not None,
                       progress=live.show if live else None)
    finally:
        rclpy.try_shutdown()
        if live:
            live.close()
    return report_recording(recording, folder, stream=stream)


def report_recording(recording: Path, folder: Path | None = None, *, stream: TextIO = sys.stdout) -> JobOutput:
    """Build the report of a recording (``friction-sim report``) and print the table."""
    data = run_data_from_recording(recording)
    folder = folder or recording.parent
    rows, markdown, picture = write_report(data, folder, recording.stem)
    print(table_text(rows), file=stream)
    print(f"recording: {recording}\npicture:   {picture}\nreport:    {markdown}", file=stream)
    return JobOutput(rows, recording, picture, markdown)


class _StatusLine:
    """One line rewritten in place on a terminal; a line a second otherwise."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.tty = stream.isatty()
        self._last_whole = -1

    def show(self, status: object) -> None:
        line = status.line()  # type: ignore[attr-defined]
        if self.tty:
            self.stream.write("\r" + line)
            self.stream.flush()
        elif int(status.t) > self._last_whole:  # type: ignore[attr-defined]
            self._last_whole = int(status.t)  # type: ignore[attr-defined]
            print(line, file=self.stream, flush=True)

    def close(self) -> None:
        if self.tty:
            self.stream.write("\n")
