"""``friction-sim``: the command line.  It parses arguments and dispatches to the
jobs in the package; it holds no physics.

Subcommands::

    friction-sim umap --phi 0.7 --ratio 0.5 [--json]
    friction-sim umap --grid 101 --csv u.csv --png u.png
    friction-sim trace --png fig2.png [--periods 2] [plant options]
    friction-sim simulate [plant options] --duration 2 [--settle 0.2] [--csv out.csv] [--json]
    friction-sim conveyor --png conveyor.png [--csv conveyor.csv] [--points 101]
    friction-sim slider [--params FILE] [--log run.mcap] [--foxglove [PORT]] [--ros-args ...]
    friction-sim controller [--params FILE] [--ros-args ...]
    friction-sim feeder [--slider-params FILE] [--controller-params FILE] [--log run.mcap] [--foxglove [PORT]]
                        [--ros-args ...]
    friction-sim experiment SCENARIO.yaml [--output DIR] [--attach NAMESPACE] [--foxglove [PORT]]
    friction-sim report run.mcap [--output DIR]
    friction-sim replay run.mcap [--verify] [--publish ...] [--csv DIR] [--plot PNG]
    friction-sim sweep SWEEP.yaml [--workers N | --scheduler tcp://HOST:8786] [--output FILE.parquet]
    friction-sim sweep-report results.parquet --x PARAM --y PARAM [--output DIR]

Errors are one line on stderr and exit code 2, never a traceback.  This
module only parses and dispatches: each subcommand is a function of
:mod:`friction_sim.cli.commands` (``replay``'s options come from
:mod:`friction_sim.cli.replay`).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn, TypeAlias

from friction_sim.cli import commands
from friction_sim.core import spec
from friction_sim.errors import FrictionSimError, ParameterError

EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


#: A negative number as a value of an option: -7, -0.7, -.5, -1e-3, -inf (and -nan, refused later).
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$", re.IGNORECASE)


def _finite_float(text: str) -> float:
    """``type=float`` on every parser here: a number, and a finite one (flags
    declared by a Setting are checked further, by :func:`commands.flag_type`)."""
    value = float(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} rejected: must be a finite number")
    return value


class _OneLineParser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr and exit code 2, and
    ``type=float`` refuses NaN and inf."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.register("type", float, _finite_float)
        # argparse (before 3.13) takes "-1e-3" or "-inf" for an option, not a value.
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def error(self, message: str) -> NoReturn:
        """Exit with the usage error on one line."""
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see --help)\n")


#: What ``add_subparsers`` returns: each ``_add_*`` adds its subcommands to it.
Subcommands: TypeAlias = "argparse._SubParsersAction[_OneLineParser]"  # noqa: SLF001 - argparse names no public type


def build_parser() -> argparse.ArgumentParser:
    """The ``friction-sim`` parser with every subcommand."""
    parser = _OneLineParser(
        prog="friction-sim",
        description="Exact event-driven simulator of a vibratory-feeder slider: stick, slip and flight "
                    "(Kostek's model and its generalization).",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_OneLineParser)
    for add in (_add_umap, _add_trace, _add_simulate, _add_conveyor, _add_nodes, _add_experiment, _add_replay,
                _add_sweep):
        add(sub)
    return parser


def _add_umap(sub: Subcommands) -> None:
    umap = sub.add_parser("umap", help="the nondimensional mean speed U(phi, a): one point or the map")
    for setting in (commands.PHI, commands.AMPLITUDE_RATIO, commands.GRID):
        commands.add_flag(umap, setting)
    commands.add_model_options(umap)
    umap.add_argument("--csv", type=Path, help="write the map as CSV (phi, amplitude_ratio, U)")
    umap.add_argument("--png", type=Path, help="draw the map like the paper's Fig. 3")
    umap.add_argument("--json", action="store_true", help="print one JSON object")
    umap.set_defaults(handler=commands.umap)


def _add_trace(sub: Subcommands) -> None:
    trace = sub.add_parser("trace", help="draw the paper's Fig. 2 (forces, a, v, x with A, B, C; the height z "
                           "with lift-offs and landings when the slider flies)")
    trace.add_argument("--png", type=Path, required=True, help="output picture")
    commands.add_flag(trace, commands.PERIODS, commands.PERIODS.default)
    commands.add_plant_options(trace)
    trace.set_defaults(handler=commands.trace)


def _add_simulate(sub: Subcommands) -> None:
    simulate = sub.add_parser("simulate", help="simulate exactly and report the mean velocity and U")
    commands.add_plant_options(simulate)
    for setting in (commands.DURATION, commands.SETTLE):
        commands.add_flag(simulate, setting, setting.default)
    simulate.add_argument("--csv", type=Path, help="write the sampled trajectory and the events")
    commands.add_flag(simulate, commands.SAMPLE_RATE, commands.SAMPLE_RATE.default)
    simulate.add_argument("--json", action="store_true", help="print one JSON object")
    simulate.set_defaults(handler=commands.simulate)


def _add_conveyor(sub: Subcommands) -> None:
    from friction_sim.cli.conveyor import add_arguments

    conveyor = sub.add_parser("conveyor", help="the conveying figure: U against the throw number for vibration "
                              "angles 15-60 degrees, and against the track inclination (CSV beside the PNG)")
    add_arguments(conveyor)
    conveyor.set_defaults(handler=commands.conveyor)


def _add_foxglove(parser: argparse.ArgumentParser) -> None:
    """``--foxglove [PORT]``: serve a Foxglove live view (foxglove_port; PORT
    defaults to Foxglove's usual 8765), checked like the parameter."""
    parser.add_argument("--foxglove", nargs="?", const=commands.FOXGLOVE_DEFAULT_PORT, default=None,
                        type=commands.flag_type(spec.FOXGLOVE_PORT), metavar="PORT",
                        help="serve a Foxglove live view on ws://127.0.0.1:PORT (default PORT "
                             f"{commands.FOXGLOVE_DEFAULT_PORT}; foxglove_address sets another address)")


def _add_nodes(sub: Subcommands) -> None:
    """slider, controller and feeder: the nodes, with --ros-args passed through."""
    slider = sub.add_parser("slider", help="run the real-time slider node (as `ros2 run friction_sim slider`)")
    slider.add_argument("--params", type=Path, help="ROS 2 parameters file, e.g. config/slider.yaml")
    slider.add_argument("--log", type=Path, metavar="FILE.mcap", help="record the run to an MCAP file")
    _add_foxglove(slider)
    slider.set_defaults(handler=commands.slider, ros_args=[])

    controller = sub.add_parser("controller", help="run the mean-speed controller node "
                                "(as `ros2 run friction_sim controller`)")
    controller.add_argument("--params", type=Path, help="ROS 2 parameters file, e.g. config/controller.yaml")
    controller.set_defaults(handler=commands.controller, ros_args=[])

    feeder = sub.add_parser("feeder", help="run slider and controller in one process (one executor)")
    feeder.add_argument("--slider-params", type=Path, help="parameters file for the slider")
    feeder.add_argument("--controller-params", type=Path, help="parameters file for the controller")
    feeder.add_argument("--log", type=Path, metavar="FILE.mcap", help="record the run to an MCAP file (the slider's "
                        "log_path)")
    _add_foxglove(feeder)
    feeder.set_defaults(handler=commands.feeder, ros_args=[])


def _add_experiment(sub: Subcommands) -> None:
    """experiment and report."""
    experiment = sub.add_parser("experiment", help="run a scenario over real topics, record it, report it")
    experiment.add_argument("scenario", type=Path, help="scenario file, e.g. config/demo.yaml")
    experiment.add_argument("--output", type=Path, help="output folder (default: the scenario's output)")
    experiment.add_argument("--attach", metavar="NAMESPACE",
                            help="drive a slider (and controller) already running in NAMESPACE")
    _add_foxglove(experiment)
    experiment.set_defaults(handler=commands.experiment)

    report = sub.add_parser("report", help="rebuild an experiment's report from its recording alone")
    report.add_argument("recording", type=Path, help="the experiment's .mcap file")
    report.add_argument("--output", type=Path, help="output folder (default: beside the recording)")
    report.set_defaults(handler=commands.report)


def _add_replay(sub: Subcommands) -> None:
    from friction_sim.cli.replay import add_arguments

    replay = sub.add_parser("replay", help="verify, republish, export or plot a recording")
    add_arguments(replay)
    replay.set_defaults(handler=commands.replay)


def _add_sweep(sub: Subcommands) -> None:
    """sweep and sweep-report (options and handlers in :mod:`friction_sim.cli.sweep`)."""
    from friction_sim.cli import sweep

    run = sub.add_parser("sweep", help="run a grid, list or Monte Carlo sweep of the batch core on Dask "
                         "(Parquet results, resumable)")
    sweep.add_sweep_arguments(run)
    run.set_defaults(handler=sweep.sweep)
    report = sub.add_parser("sweep-report", help="maps of a sweep's mean speed over two parameters (PNG) and "
                            "the optimum per slice (Markdown)")
    sweep.add_report_arguments(report)
    report.set_defaults(handler=sweep.sweep_report)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``friction-sim``; returns the exit code."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    ros_args: list[str] = []
    if "--ros-args" in argv:  # everything after it belongs to ROS
        split = argv.index("--ros-args")
        argv, ros_args = argv[:split], argv[split + 1:]
    args = parser.parse_args(argv)
    if ros_args:
        if not hasattr(args, "ros_args"):
            parser.error(f"--ros-args is only for the node commands, not '{args.command}'")
        args.ros_args = ros_args
    return _dispatch(args)


def _dispatch(args: argparse.Namespace) -> int:
    """Run the subcommand; a user's error is one line on stderr and exit code 2.
    A rejected value that came from a flag names the flag, as argparse would."""
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        return handler(args)
    except FrictionSimError as error:
        flag = commands.flag_of(args, error.field) if isinstance(error, ParameterError) else None
        where = f"argument {flag}: " if flag else ""
        print(f"friction-sim {args.command}: error: {where}{error}", file=sys.stderr)
    except OSError as error:
        print(f"friction-sim {args.command}: error: {error.strerror or error}: "
              f"{error.filename or ''}".rstrip(": "), file=sys.stderr)
    except KeyboardInterrupt:
        print(f"friction-sim {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as error:  # rclpy refusing a parameter is a usage error too (re-raised otherwise)
        if not _is_ros_parameter_error(error):
            raise
        print(f"friction-sim {args.command}: error: {error}", file=sys.stderr)
    return EXIT_USAGE


def _is_ros_parameter_error(error: Exception) -> bool:
    """rclpy's ParameterException family (an out-of-range parameter override),
    recognised by name: the command line itself does not import rclpy."""
    return any(cls.__name__ == "ParameterException" and cls.__module__.startswith("rclpy")
               for cls in type(error).__mro__)


if __name__ == "__main__":
    sys.exit(main())
