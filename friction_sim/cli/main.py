"""``friction-sim``: the command line.  It parses arguments and dispatches to the
jobs in the package; it holds no physics.

Subcommands::

    friction-sim umap --phi 0.7 --ratio 0.5 [--json]
    friction-sim umap --grid 101 --csv u.csv --png u.png
    friction-sim trace --png fig2.png [--periods 2] [plant options]
    friction-sim simulate [plant options] --duration 2 [--settle 0.2] [--csv out.csv] [--json]
    friction-sim slider [--params FILE] [--log run.mcap] [--ros-args ...]
    friction-sim controller [--params FILE] [--ros-args ...]
    friction-sim feeder [--slider-params FILE] [--controller-params FILE] [--ros-args ...]
    friction-sim experiment SCENARIO.yaml [--output DIR] [--attach NAMESPACE]
    friction-sim report run.mcap [--output DIR]
    friction-sim replay run.mcap [--verify] [--publish ...] [--csv DIR] [--plot PNG]

Errors are one line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any, Callable, NoReturn, Sequence

from friction_sim.errors import FrictionSimError

EXIT_USAGE = 2
EXIT_INTERRUPTED = 130
MAX_GRID = 2001
MAX_SAMPLES = 10_000_000


class _OneLineParser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr and exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see --help)\n")


def _add_plant_options(parser: argparse.ArgumentParser) -> None:
    """The model's parameters and inputs; defaults are the paper's Fig. 2 case."""
    group = parser.add_argument_group("plant (defaults: the paper's Fig. 2 case)")
    group.add_argument("--mass", type=float, default=1.0, help="slider mass m [kg] (1.0)")
    group.add_argument("--mu", type=float, default=0.1, help="Coulomb friction coefficient (0.1)")
    group.add_argument("--gravity", type=float, default=10.0, help="gravity g [m/s^2] (10.0)")
    group.add_argument("--frequency", type=float, default=50.0, help="excitation frequency f [Hz] (50.0)")
    group.add_argument("--amplitude", type=float, default=5.0, help="excitation amplitude Pa [N] (5.0)")
    group.add_argument("--drive-force", type=float, default=0.7, help="drive force Fd [N] (0.7)")


def _plant(args: argparse.Namespace) -> tuple[Any, Any]:
    from friction_sim.core.params import Inputs, SliderParams, check_contact

    params = SliderParams(mass=args.mass, mu=args.mu, gravity=args.gravity)
    inputs = Inputs(drive_force=args.drive_force, excitation_amplitude=args.amplitude,
                    excitation_frequency=args.frequency)
    check_contact(params, inputs)
    return params, inputs


def _json_ready(value: Any) -> Any:
    """JSON has no inf or NaN: write them as null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _json_ready(item) for key, item in value.items()}
    return value


def _print_json(payload: dict[str, Any]) -> None:
    print(json.dumps(_json_ready(payload), allow_nan=False))


# -- umap ---------------------------------------------------------------------


def _cmd_umap(args: argparse.Namespace) -> int:
    from friction_sim.core import urelation

    if args.grid is None:
        if args.phi is None or args.ratio is None:
            raise FrictionSimError("umap needs --phi and --ratio for one point, or --grid N for the map")
        u = urelation.u_map(args.phi, args.ratio)
        point = {
            "phi": args.phi, "amplitude_ratio": args.ratio, "U": u,
            "moves": urelation.moves(args.phi, args.ratio),
            "motion_boundary_ratio": urelation.motion_boundary(args.phi),
            "slip_start_phase": urelation.slip_start_phase(args.phi, args.ratio),
            "slip_phase_length": urelation.stop_phase_advance(args.phi, args.ratio),
        }
        if args.json:
            _print_json(point)
        else:
            print(f"U({args.phi:g}, {args.ratio:g}) = {u!r}")
        return 0
    if args.csv is None and args.png is None:
        raise FrictionSimError("umap --grid needs --csv FILE and/or --png FILE")
    if not 2 <= args.grid <= MAX_GRID:
        raise FrictionSimError(f"--grid {args.grid} rejected: must be in [2, {MAX_GRID}]")
    umap = urelation.u_grid(args.grid)
    if args.csv is not None:
        from friction_sim.io.export import write_umap_csv

        print(f"wrote {write_umap_csv(umap, args.csv)}")
    if args.png is not None:
        from friction_sim.cli.figures import u_map_figure

        _save(u_map_figure(umap), args.png)
    return 0


# -- trace --------------------------------------------------------------------


def _cmd_trace(args: argparse.Namespace) -> int:
    from friction_sim.cli.figures import trace_figure
    from friction_sim.core.simulation import simulate

    params, inputs = _plant(args)
    duration = args.periods / inputs.excitation_frequency
    result = simulate(params, inputs, duration, sample_rate=2000.0 * inputs.excitation_frequency)
    _save(trace_figure(result), args.png)
    return 0


# -- simulate -------------------------------------------------------------------


def _cmd_simulate(args: argparse.Namespace) -> int:
    from friction_sim.core.simulation import simulate

    params, inputs = _plant(args)
    sample_rate = args.sample_rate if args.csv is not None else None
    if sample_rate is not None and sample_rate * args.duration > MAX_SAMPLES:
        raise FrictionSimError(f"--sample-rate {sample_rate:g} x --duration {args.duration:g} rejected: "
                               f"at most {MAX_SAMPLES:.0e} samples")
    result = simulate(params, inputs, args.duration, settle=args.settle, sample_rate=sample_rate)
    if args.csv is not None:
        from friction_sim.io.export import write_trajectory_csv

        assert result.trajectory is not None
        write_trajectory_csv(result.trajectory, result.events, args.csv)
    if args.json:
        _print_json(result.as_dict())
        return 0
    counts = ", ".join(f"{kind} {n}" for kind, n in result.event_counts.items())
    print(f"phi = {result.phi!r}, a = {result.amplitude_ratio!r}")
    print(f"mean velocity over {result.periods} periods after {result.settle:g} s: "
          f"{result.mean_velocity!r} m/s")
    print(f"U measured = {result.u_measured!r}, U exact = {result.u_exact!r}")
    print(f"events: {counts}; wall time {result.wall_time * 1e3:.2f} ms")
    if args.csv is not None:
        print(f"wrote {args.csv}")
    return 0


# -- nodes ----------------------------------------------------------------------


def _cmd_slider(args: argparse.Namespace) -> int:
    from friction_sim.ros.slider import main as slider_main

    return slider_main(_ros_args("friction-sim-slider", args))


def _cmd_controller(args: argparse.Namespace) -> int:
    from friction_sim.ros.controller import main as controller_main

    return controller_main(_ros_args("friction-sim-controller", args))


def _cmd_feeder(args: argparse.Namespace) -> int:
    from friction_sim.ros.feeder import main as feeder_main

    return feeder_main(_ros_args("friction-sim-feeder", args), args.slider_params, args.controller_params)


def _cmd_experiment(args: argparse.Namespace) -> int:
    from friction_sim.cli.jobs import run_scenario

    run_scenario(args.scenario, output=args.output, attach=args.attach)
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from friction_sim.cli.jobs import report_recording

    report_recording(args.recording, args.output)
    return 0


def _cmd_replay(args: argparse.Namespace) -> int:
    from friction_sim.io.replay import run

    return run(args)


def _ros_args(prog: str, args: argparse.Namespace) -> list[str]:
    """The rclpy argument list: --params FILE becomes --ros-args --params-file FILE,
    and anything after --ros-args on our command line is passed through."""
    ros: list[str] = []
    if getattr(args, "log", None) is not None:
        ros += ["-p", f"log_path:={args.log}"]
    if getattr(args, "params", None) is not None:
        if not args.params.is_file():
            raise FrictionSimError(f"--params: no such file: {args.params}")
        ros += ["--params-file", str(args.params)]
    ros += args.ros_args
    return [prog, "--ros-args", *ros] if ros else [prog]


def _save(figure: Any, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=120)
    print(f"wrote {path}")


# -- the parser ---------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    parser = _OneLineParser(
        prog="friction-sim",
        description="Exact stick-slip simulator of a vibratory-feeder slider (Kostek's model).",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_OneLineParser)

    umap = sub.add_parser("umap", help="the nondimensional mean speed U(phi, a): one point or the map")
    umap.add_argument("--phi", type=float, help="drive ratio phi = Fd/(mu m g)")
    umap.add_argument("--ratio", type=float, help="amplitude ratio a = Pa/(m g)")
    umap.add_argument("--grid", type=int, help="map on N x N points of (phi, a) in (0, 1), N <= 2001")
    umap.add_argument("--csv", type=Path, help="write the map as CSV (phi, amplitude_ratio, U)")
    umap.add_argument("--png", type=Path, help="draw the map like the paper's Fig. 3")
    umap.add_argument("--json", action="store_true", help="print one JSON object")
    umap.set_defaults(handler=_cmd_umap)

    trace = sub.add_parser("trace", help="draw the paper's Fig. 2 (forces, a, v, x with A, B, C)")
    trace.add_argument("--png", type=Path, required=True, help="output picture")
    trace.add_argument("--periods", type=float, default=2.5, help="excitation periods shown (2.5)")
    _add_plant_options(trace)
    trace.set_defaults(handler=_cmd_trace)

    simulate = sub.add_parser("simulate", help="simulate exactly and report the mean velocity and U")
    _add_plant_options(simulate)
    simulate.add_argument("--duration", type=float, default=2.0, help="simulated time [s] (2.0)")
    simulate.add_argument("--settle", type=float, default=0.0,
                          help="time [s] left out before the mean is taken (0.0)")
    simulate.add_argument("--csv", type=Path, help="write the sampled trajectory and the events")
    simulate.add_argument("--sample-rate", type=float, default=10_000.0,
                          help="samples per second in --csv (10000)")
    simulate.add_argument("--json", action="store_true", help="print one JSON object")
    simulate.set_defaults(handler=_cmd_simulate)

    slider = sub.add_parser("slider", help="run the real-time slider node (as `ros2 run friction_sim slider`)")
    slider.add_argument("--params", type=Path, help="ROS 2 parameters file, e.g. config/slider.yaml")
    slider.add_argument("--log", type=Path, metavar="FILE.mcap", help="record the run to an MCAP file")
    slider.set_defaults(handler=_cmd_slider, ros_args=[])

    controller = sub.add_parser("controller", help="run the mean-speed controller node "
                                "(as `ros2 run friction_sim controller`)")
    controller.add_argument("--params", type=Path, help="ROS 2 parameters file, e.g. config/controller.yaml")
    controller.set_defaults(handler=_cmd_controller, ros_args=[])

    feeder = sub.add_parser("feeder", help="run slider and controller in one process (one executor)")
    feeder.add_argument("--slider-params", type=Path, help="parameters file for the slider")
    feeder.add_argument("--controller-params", type=Path, help="parameters file for the controller")
    feeder.set_defaults(handler=_cmd_feeder, ros_args=[])

    experiment = sub.add_parser("experiment", help="run a scenario over real topics, record it, report it")
    experiment.add_argument("scenario", type=Path, help="scenario file, e.g. config/demo.yaml")
    experiment.add_argument("--output", type=Path, help="output folder (default: the scenario's output)")
    experiment.add_argument("--attach", metavar="NAMESPACE",
                            help="drive a slider (and controller) already running in NAMESPACE")
    experiment.set_defaults(handler=_cmd_experiment)

    report = sub.add_parser("report", help="rebuild an experiment's report from its recording alone")
    report.add_argument("recording", type=Path, help="the experiment's .mcap file")
    report.add_argument("--output", type=Path, help="output folder (default: beside the recording)")
    report.set_defaults(handler=_cmd_report)

    from friction_sim.io.replay import add_arguments

    replay = sub.add_parser("replay", help="verify, republish, export or plot a recording")
    add_arguments(replay)
    replay.set_defaults(handler=_cmd_replay)
    return parser


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
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        return handler(args)
    except FrictionSimError as error:
        print(f"friction-sim {args.command}: error: {error}", file=sys.stderr)
    except OSError as error:
        print(f"friction-sim {args.command}: error: {error.strerror or error}: "
              f"{error.filename or ''}".rstrip(": "), file=sys.stderr)
    except KeyboardInterrupt:
        print(f"friction-sim {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as error:  # noqa: BLE001 - rclpy refusing a parameter is a usage error too
        if not _is_ros_parameter_error(error):
            raise
        print(f"friction-sim {args.command}: error: {error}", file=sys.stderr)
    return EXIT_USAGE


def _is_ros_parameter_error(error: Exception) -> bool:
    """rclpy's ParameterException family (an out-of-range parameter override)."""
    from rclpy.exceptions import ParameterException

    return isinstance(error, ParameterException)


if __name__ == "__main__":
    sys.exit(main())
