"""``friction-sim``: the command line.  It parses arguments and dispatches to the
jobs in the package; it holds no physics.

Subcommands::

    friction-sim umap --phi 0.7 --ratio 0.5 [--json]
    friction-sim umap --grid 101 --csv u.csv --png u.png
    friction-sim trace --png fig2.png [--periods 2] [plant options]
    friction-sim simulate [plant options] --duration 2 [--settle 0.2] [--csv out.csv] [--json]
    friction-sim conveyor --png conveyor.png [--csv conveyor.csv] [--points 101]
    friction-sim resonance --png tuning.png [--from 40 --to 60] [--natural-frequency 52 --drive-level 0.5]
    friction-sim reduction --png reduction.png [--ratios 0.2,0.6 --speeds 0.0005] [--angle 60]
    friction-sim calibrate measurements.csv --fit mu,static_ratio [--fixed plant.yaml] [--set mass=0.02]
    friction-sim predict calibrated.yaml [--set drive_force=0.9] [--sweep excitation_amplitude=4:8:21 --png band.png]
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
module only parses and dispatches: every verb is a
:class:`~friction_sim.cli.options.Verb` (its options and the function that
runs it) declared by its own module of :data:`VERB_MODULES`.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from collections.abc import Callable, Sequence
from typing import Any, NoReturn

from friction_sim.cli import (
    calibrate,
    conveyor,
    experiments,
    motion,
    nodes,
    predict,
    reduction,
    relation,
    replay,
    resonance,
    sweeps,
)
from friction_sim.cli.options import Verb, flag_of
from friction_sim.errors import FrictionSimError, ParameterError
from friction_sim.ros.heap import limit_heap_arenas

EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


#: A negative number as a value of an option: -7, -0.7, -.5, -1e-3, -inf (and -nan, refused later).
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$", re.IGNORECASE)


def _finite_float(text: str) -> float:
    """``type=float`` on every parser here: a number, and a finite one (flags
    declared by a Setting are checked further, by :func:`options.flag_type`)."""
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


#: The modules that declare the verbs (``VERBS``), in the order ``--help`` lists them.
VERB_MODULES = (relation, motion, conveyor, resonance, reduction, nodes, experiments, replay, sweeps, calibrate,
                predict)


def verbs() -> tuple[Verb, ...]:
    """Every verb of ``friction-sim``."""
    return tuple(verb for module in VERB_MODULES for verb in module.VERBS)


def build_parser() -> argparse.ArgumentParser:
    """The ``friction-sim`` parser with every verb."""
    parser = _OneLineParser(
        prog="friction-sim",
        description="Exact event-driven simulator of a vibratory-feeder slider: stick, slip and flight "
                    "(Kostek's model and its generalization).",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_OneLineParser)
    for verb in verbs():
        # (argparse formats a help text with %: a literal one, "95 % intervals", must be doubled)
        verb_parser = sub.add_parser(verb.name, help=verb.help.replace("%", "%%"), description=verb.help)
        verb.add_arguments(verb_parser)
        verb_parser.set_defaults(handler=verb.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``friction-sim``; returns the exit code."""
    limit_heap_arenas()  # (a command may run nodes: before their threads start)
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
        flag = flag_of(args, error.field) if isinstance(error, ParameterError) else None
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
