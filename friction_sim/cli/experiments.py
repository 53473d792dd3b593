"""``friction-sim experiment`` and ``report``: a scenario run over real topics, and its report.

``run_scenario``: validate the scenario (nothing starts on a bad file), bring
up the nodes in this process, play the schedule over real topics with a live
status line, record everything to ``<output>/<name>.mcap``, then write the
report (``<name>.md`` and ``<name>.png``) from that recording alone, exactly
as ``friction-sim report`` would.

``report_recording``: that report, from any recording (``friction-sim report``).

Both judge the scenario's ``expect`` entries (the recording holds the
scenario's text), print a line for each with PASS or FAIL and what was
measured, add them to the Markdown report, and exit 1 when one fails, so a
scenario stands in CI as a test.  The table's settling column uses the band
each segment's ``expect`` states.  An expectation on the amplitude per unit
drive needs the controller's drive readings, which the live run has and a
recording does not: ``report`` says NOT JUDGED for it.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from friction_sim.cli.options import Verb, add_foxglove
from friction_sim.cli.progress import TerminalProgress
from friction_sim.core.runtime.progress import Progress
from friction_sim.errors import FrictionSimError
from friction_sim.experiment.acceptance import Verdict, judge, judged, verdict_line
from friction_sim.experiment.job import ExperimentResult
from friction_sim.experiment.report import (
    RunData,
    SegmentRow,
    build_report,
    report_markdown,
    run_data_from_recording,
    table_text,
)
from friction_sim.experiment.scenario import load_scenario

#: The exit status of ``experiment`` and ``report`` when an ``expect`` entry was judged and failed.
EXIT_EXPECTATION_FAILED = 1


@dataclass(frozen=True)
class JobOutput:
    """What a job wrote: the report's rows, the recording, the picture and the Markdown report."""

    rows: list[SegmentRow]
    recording: Path
    picture: Path
    report: Path
    #: The scenario's ``expect`` judged (empty: it states none, or the recording holds no scenario).
    verdicts: list[Verdict] = dataclasses.field(default_factory=list)

    @property
    def failed(self) -> bool:
        """Whether an expectation was judged and not met."""
        return any(not verdict.met for verdict in judged(self.verdicts))


def run_scenario(path: Path, *, output: Path | None = None, attach: str | None = None,
                 foxglove_port: int | None = None, stream: TextIO = sys.stdout,
                 status: Progress | None = None, lockstep: bool | None = None) -> JobOutput:
    """Run a scenario file end to end (see the module docstring); with
    ``attach``, drive nodes already running in that namespace; with
    ``foxglove_port``, the slider serves a Foxglove live view there.  The live
    status goes to ``status`` (default: the terminal's progress line), a line
    per simulated second where it is not redrawn.  ``lockstep`` overrides the
    scenario's key of that name (True: in lockstep; False: in real time)."""
    from friction_sim.experiment.runner import run_standalone

    scenario = load_scenario(path)
    folder = output or scenario.output
    folder.mkdir(parents=True, exist_ok=True)
    recording = folder / f"{scenario.name}.mcap"
    spec = dataclasses.replace(scenario.spec(), log_path=recording)
    if lockstep is not None:
        spec = dataclasses.replace(spec, lockstep=lockstep)
    if foxglove_port is not None:
        spec = dataclasses.replace(spec, slider_parameters={**spec.slider_parameters, "foxglove_port": foxglove_port})
    live = status if status is not None else TerminalProgress()
    pace = "in lockstep, as fast as it computes" if spec.lockstep else f"at {scenario.real_time_factor:g}x real time"
    print(f"running {path} ({scenario.duration:g} s simulated {pace})", file=stream)
    try:
        result = run_standalone(spec, namespace=attach or scenario.namespace, attach=attach is not None,
                                progress=lambda now: live.show(now.line(), step=int(now.t)))
    finally:
        live.close()
    return report_recording(recording, folder, stream=stream, live=result)


def report_recording(recording: Path, folder: Path | None = None, *, stream: TextIO = sys.stdout,
                     live: ExperimentResult | None = None) -> JobOutput:
    """Build the report of a recording (``friction-sim report``), print the table and
    the ``expect`` verdicts (judged on ``live``, the run's own series, when given;
    else on the recording's mean speeds)."""
    data = run_data_from_recording(recording)
    verdicts = [] if data.scenario is None else judge(data.scenario, live or ExperimentResult(
        mean_velocity=data.all_mean_velocity, duration=data.duration))
    rows, markdown, picture = write_report(data, folder or recording.parent, recording.stem, verdicts)
    print(table_text(rows), file=stream)
    for verdict in verdicts:
        print(verdict_line(verdict), file=stream)
    print(f"recording: {recording}\npicture:   {picture}\nreport:    {markdown}", file=stream)
    return JobOutput(rows, recording, picture, markdown, verdicts)


def write_report(data: RunData, folder: Path, stem: str,
                 verdicts: list[Verdict] | None = None) -> tuple[list[SegmentRow], Path, Path]:
    """Write <stem>.md and <stem>.png into ``folder``; return rows and paths."""
    from friction_sim.cli.figures import report_figure, save_figure

    rows = build_report(data)
    folder.mkdir(parents=True, exist_ok=True)
    markdown = folder / f"{stem}.md"
    text = report_markdown(data, rows, f"{stem}.png")
    if verdicts:
        text += "\n## Expectations\n\n" + "".join(f"- {verdict_line(v)}\n" for v in verdicts)
    markdown.write_text(text)
    picture = folder / f"{stem}.png"
    save_figure(report_figure(data, rows), picture)
    return rows, markdown, picture


def add_experiment_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``experiment`` options."""
    parser.add_argument("scenario", type=Path, help="scenario file, e.g. config/demo.yaml")
    parser.add_argument("--output", type=Path, help="output folder (default: the scenario's output)")
    parser.add_argument("--attach", metavar="NAMESPACE",
                        help="drive a slider (and controller) already running in NAMESPACE")
    pace = parser.add_mutually_exclusive_group()
    pace.add_argument("--lockstep", action="store_true", default=None,
                      help="run in lockstep: the slider advances when this driver and the controller have answered "
                           "(the same numbers every run, as fast as the CPU allows; overrides the scenario)")
    pace.add_argument("--real-time", dest="lockstep", action="store_false",
                      help="run against the wall clock at the scenario's real_time_factor (overrides the scenario)")
    add_foxglove(parser)


def add_report_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``report`` options."""
    parser.add_argument("recording", type=Path, help="the experiment's .mcap file")
    parser.add_argument("--output", type=Path, help="output folder (default: beside the recording)")


def experiment(args: argparse.Namespace) -> int:
    """``experiment``: run a scenario over real topics, record it, report it."""
    if args.foxglove is not None and args.attach is not None:
        raise FrictionSimError("--foxglove with --attach: the slider runs elsewhere; start it with "
                               "--foxglove (or foxglove_port) instead")
    job = run_scenario(args.scenario, output=args.output, attach=args.attach, foxglove_port=args.foxglove,
                       lockstep=args.lockstep)
    return EXIT_EXPECTATION_FAILED if job.failed else 0


def report(args: argparse.Namespace) -> int:
    """``report``: rebuild an experiment's report from its recording alone."""
    return EXIT_EXPECTATION_FAILED if report_recording(args.recording, args.output).failed else 0


VERBS = (
    Verb("experiment", "run a scenario over real topics, record it, report it", add_experiment_arguments, experiment),
    Verb("report", "rebuild an experiment's report from its recording alone", add_report_arguments, report),
)



__all__ = ["EXIT_EXPECTATION_FAILED", "VERBS", "JobOutput", "experiment", "report", "report_recording", "run_scenario",
           "write_report"]
