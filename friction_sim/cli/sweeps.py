"""``friction-sim sweep`` and ``friction-sim sweep-report``: their options and
the two handlers.  They parse and dispatch; the work is in
:mod:`friction_sim.experiment.sweep`, :mod:`~friction_sim.experiment.sweep_run`
and :mod:`~friction_sim.experiment.sweep_report`.

::

    friction-sim sweep SWEEP.yaml [--output FILE.parquet] [--workers N | --scheduler tcp://HOST:8786]
                       [--chunk-size N] [--engine compiled|scalar] [--fresh] [--quiet]
    friction-sim sweep-report results.parquet --x PARAM --y PARAM [--value COLUMN] [--slice PARAM ...]
                       [--bins N] [--output DIR]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

from friction_sim.cli.options import Verb, add_flag
from friction_sim.cli.progress import TerminalProgress
from friction_sim.core.model import spec as settings
from friction_sim.errors import ParameterError


def _count(low: int) -> Callable[[str], int]:
    """An argparse type: an integer >= ``low``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} rejected: must be an integer >= {low}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"{value} rejected: must be an integer >= {low}")
        return value

    return parse


def add_sweep_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``sweep``."""
    parser.add_argument("sweep", type=Path, help="sweep file, e.g. config/sweep_example.yaml")
    parser.add_argument("--output", type=Path, help="results file (default: the sweep's output, "
                        "else out/sweeps/<name>.parquet)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=_count(0), metavar="N",
                       help="worker processes of the local Dask cluster (default: one per core; 0: no Dask, "
                            "in this process)")
    where.add_argument("--scheduler", metavar="tcp://HOST:8786", help="run on an existing Dask cluster")
    parser.add_argument("--connect-timeout", type=float, default=20.0, metavar="S",
                        help="seconds to wait for --scheduler (default 20)")
    add_flag(parser, settings.CHUNK_SIZE.described("points per batch-core call (default: the sweep's chunk_size)"))
    parser.add_argument("--engine", choices=("compiled", "scalar"), default="compiled",
                        help="population engine (compiled: the default, scalar: the loop over the single slider, "
                             "the reference, for comparison)")
    parser.add_argument("--fresh", action="store_true", help="discard the results or parts of an earlier run "
                        "(default: resume it, skipping the chunks already written)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def add_report_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``sweep-report``."""
    parser.add_argument("results", type=Path, help="a sweep's results (.parquet)")
    parser.add_argument("--x", required=True, metavar="PARAM", help="input column along x (e.g. throw_number)")
    parser.add_argument("--y", required=True, metavar="PARAM", help="input column along y (e.g. excitation_angle)")
    parser.add_argument("--value", default="mean_velocity", metavar="COLUMN",
                        help="output mapped: mean_velocity (default), U, flight_fraction or stick_fraction")
    parser.add_argument("--slice", action="append", metavar="PARAM", dest="slices",
                        help="one map per value of PARAM (repeatable; default: the sweep's other grid and "
                             "points keys)")
    parser.add_argument("--bins", type=_count(2), default=40, metavar="N",
                        help="cells along an axis with more distinct values (a random one; default 40)")
    parser.add_argument("--output", type=Path, metavar="DIR", help="folder of the PNG and the Markdown report "
                        "(default: beside the results)")


def sweep(args: argparse.Namespace) -> int:
    """``sweep``: validate the file completely, then run it (resuming), and say where the results are."""
    from friction_sim.experiment.sweep import load_sweep
    from friction_sim.experiment.sweep_run import DaskExecutor, SerialExecutor, SweepProgress, parts_dir, run_sweep

    spec = load_sweep(args.sweep, chunk_size=args.chunk_size)
    output = args.output or spec.output
    if output.suffix != ".parquet":
        raise ParameterError("--output", str(output), "must end in .parquet")
    executor = SerialExecutor() if args.workers == 0 \
        else DaskExecutor(args.scheduler, args.workers, connect_timeout=args.connect_timeout)
    progress = None if args.quiet else SweepProgress(spec.name, spec.chunks, spec.size, TerminalProgress(interval=2.0))
    try:
        with executor:
            print(f"{args.sweep}: {spec.size} points x {spec.settle_periods + spec.periods} periods in "
                  f"{spec.chunks} chunk(s) of {spec.chunk_size} ({executor.description})", file=sys.stderr)
            outcome = run_sweep(spec, executor, output=output, engine=args.engine, fresh=args.fresh,
                                progress=progress)
    except KeyboardInterrupt:
        print(f"friction-sim sweep: the chunks written are kept in {parts_dir(output)}: run the same command "
              "again to resume", file=sys.stderr)
        raise
    rate = f", {outcome.points / outcome.seconds:,.0f} points/s" if outcome.computed == outcome.chunks \
        and outcome.seconds > 0 else ""
    print(f"wrote {outcome.output}: {outcome.points} points, {outcome.computed} chunk(s) computed, "
          f"{outcome.reused} reused, {outcome.seconds:.1f} s{rate} ({outcome.executor})")
    return 0


def sweep_report(args: argparse.Namespace) -> int:
    """``sweep-report``: the maps (PNG) and the optimum per slice (Markdown)."""
    from friction_sim.cli.figures import save_figure
    from friction_sim.cli.sweep_figure import sweep_figure
    from friction_sim.experiment.calibration_bands import sweep_bands
    from friction_sim.experiment.sweep_report import build_maps, report_text

    if not args.results.is_file():
        raise ParameterError("results", str(args.results), "no such file")
    maps = build_maps(args.results, args.x, args.y, value=args.value, slices=args.slices, bins=args.bins)
    bands, said = sweep_bands(maps)  # a calibrated plant's 95 % band, or why there is none
    folder = args.output or args.results.parent
    stem = f"{args.results.stem}_{args.value}_{args.x}_{args.y}"
    picture = save_figure(sweep_figure(maps, bands), folder / f"{stem}.png")
    report = folder / f"{stem}.md"
    report.write_text(report_text(maps, picture))
    print(report.read_text().split("## Optimum per slice", 1)[1].strip())
    if bands is not None or "calibrates" in said:
        print(said)
    print(f"wrote {picture} and {report}")
    return 0


VERBS = (
    Verb("sweep", "run a grid, list or Monte Carlo sweep of the population engine on Dask (Parquet results, "
         "resumable)", add_sweep_arguments, sweep),
    Verb("sweep-report", "maps of a sweep's mean speed over two parameters (PNG) and the optimum per slice (Markdown)",
         add_report_arguments, sweep_report),
)

__all__ = ["VERBS", "add_report_arguments", "add_sweep_arguments", "sweep", "sweep_report"]
