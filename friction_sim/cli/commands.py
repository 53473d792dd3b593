"""The ``friction-sim`` subcommands: one function per command, each taking the
parsed arguments and returning the exit code.  They hold no physics: they
check what the user gave, call the package and print or write the result.
A user's mistake is a :class:`~friction_sim.errors.FrictionSimError`, which
:func:`friction_sim.cli.main.main` prints as one line.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from friction_sim.core import spec
from friction_sim.core.params import Inputs, SliderParams, check_contact
from friction_sim.errors import FrictionSimError

MAX_GRID = 2001
MAX_SAMPLES = 10_000_000
#: The settings ``--mass --mu --gravity --drive-force --amplitude --frequency``
#: set: the plant and the inputs the slider takes as parameters.
PLANT_OPTIONS = tuple(setting for setting in (*spec.PLANT.values(), *spec.INPUTS.values())
                      if setting.name in spec.SLIDER_NODE)


def add_plant_options(parser: argparse.ArgumentParser) -> None:
    """The model's parameters and inputs as options (flag, default, unit and
    meaning from :mod:`friction_sim.core.spec`); defaults are the paper's Fig. 2 case."""
    group = parser.add_argument_group("plant (defaults: the paper's Fig. 2 case)")
    for setting in PLANT_OPTIONS:
        unit = f" [{setting.unit}]" if setting.unit and setting.unit != "-" else ""
        group.add_argument(setting.option, dest=setting.name, type=setting.kind, default=setting.default,
                           metavar=setting.option.lstrip("-").replace("-", "_").upper(),
                           help=f"{setting.description}{unit} ({setting.default})")


def plant(args: argparse.Namespace) -> tuple[SliderParams, Inputs]:
    """The plant and inputs the plant options give, checked as the slider would."""
    params = SliderParams(**{name: getattr(args, name) for name in spec.PLANT})
    inputs = Inputs(**{s.name: getattr(args, s.name) for s in PLANT_OPTIONS if s.name in spec.INPUTS})
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


def _save(figure: Any, path: Path) -> None:
    """Save a figure (at the package's one resolution), creating its folder, and say where."""
    from friction_sim.cli.figures import save_figure

    print(f"wrote {save_figure(figure, path)}")


# -- umap ---------------------------------------------------------------------


def umap(args: argparse.Namespace) -> int:
    """``umap``: U at one point (``--phi --ratio``), or the map on a grid."""
    if args.grid is None:
        return _umap_point(args)
    if args.csv is None and args.png is None:
        raise FrictionSimError("umap --grid needs --csv FILE and/or --png FILE")
    if not 2 <= args.grid <= MAX_GRID:
        raise FrictionSimError(f"--grid {args.grid} rejected: must be in [2, {MAX_GRID}]")
    from friction_sim.core import urelation

    grid = urelation.u_grid(args.grid)
    if args.csv is not None:
        from friction_sim.io.export import write_umap_csv

        print(f"wrote {write_umap_csv(grid, args.csv)}")
    if args.png is not None:
        from friction_sim.cli.figures import u_map_figure

        _save(u_map_figure(grid), args.png)
    return 0


def _umap_point(args: argparse.Namespace) -> int:
    """U(phi, a) and where the slip starts and how long it lasts."""
    from friction_sim.core import urelation

    if args.phi is None or args.ratio is None:
        raise FrictionSimError("umap needs --phi and --ratio for one point, or --grid N for the map")
    u = urelation.u_map(args.phi, args.ratio)
    if not args.json:
        print(f"U({args.phi:g}, {args.ratio:g}) = {u!r}")
        return 0
    _print_json({
        "phi": args.phi, "amplitude_ratio": args.ratio, "U": u,
        "moves": urelation.moves(args.phi, args.ratio),
        "motion_boundary_ratio": urelation.motion_boundary(args.phi),
        "slip_start_phase": urelation.slip_start_phase(args.phi, args.ratio),
        "slip_phase_length": urelation.stop_phase_advance(args.phi, args.ratio),
    })
    return 0


# -- trace and simulate -----------------------------------------------------------


def trace(args: argparse.Namespace) -> int:
    """``trace``: draw the paper's Fig. 2 for the plant options."""
    from friction_sim.cli.figures import trace_figure
    from friction_sim.core.simulation import simulate as run

    params, inputs = plant(args)
    duration = args.periods / inputs.excitation_frequency
    result = run(params, inputs, duration, sample_rate=2000.0 * inputs.excitation_frequency)
    _save(trace_figure(result), args.png)
    return 0


def simulate(args: argparse.Namespace) -> int:
    """``simulate``: simulate exactly; print the mean velocity and U (or JSON), optionally write a CSV."""
    from friction_sim.core.simulation import simulate as run

    params, inputs = plant(args)
    sample_rate = args.sample_rate if args.csv is not None else None
    if sample_rate is not None and sample_rate * args.duration > MAX_SAMPLES:
        raise FrictionSimError(f"--sample-rate {sample_rate:g} x --duration {args.duration:g} rejected: "
                               f"at most {MAX_SAMPLES:.0e} samples")
    result = run(params, inputs, args.duration, settle=args.settle, sample_rate=sample_rate)
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


def slider(args: argparse.Namespace) -> int:
    """``slider``: run the real-time slider node."""
    from friction_sim.ros.slider import main as slider_main

    return slider_main(ros_args("friction-sim-slider", args))


def controller(args: argparse.Namespace) -> int:
    """``controller``: run the mean-speed controller node."""
    from friction_sim.ros.controller import main as controller_main

    return controller_main(ros_args("friction-sim-controller", args))


def feeder(args: argparse.Namespace) -> int:
    """``feeder``: slider and controller in one process."""
    from friction_sim.ros.feeder import main as feeder_main

    return feeder_main(ros_args("friction-sim-feeder", args), args.slider_params, args.controller_params)


def ros_args(prog: str, args: argparse.Namespace) -> list[str]:
    """The rclpy argument list: --params FILE becomes --ros-args --params-file FILE,
    --log FILE sets log_path, and anything after --ros-args on our command line is passed through."""
    ros: list[str] = []
    if getattr(args, "log", None) is not None:
        ros += ["-p", f"log_path:={args.log}"]
    if getattr(args, "params", None) is not None:
        if not args.params.is_file():
            raise FrictionSimError(f"--params: no such file: {args.params}")
        ros += ["--params-file", str(args.params)]
    ros += args.ros_args
    return [prog, "--ros-args", *ros] if ros else [prog]


# -- experiments and recordings ------------------------------------------------------


def experiment(args: argparse.Namespace) -> int:
    """``experiment``: run a scenario over real topics, record it, report it."""
    from friction_sim.cli.jobs import run_scenario

    run_scenario(args.scenario, output=args.output, attach=args.attach)
    return 0


def report(args: argparse.Namespace) -> int:
    """``report``: rebuild an experiment's report from its recording alone."""
    from friction_sim.cli.jobs import report_recording

    report_recording(args.recording, args.output)
    return 0


def replay(args: argparse.Namespace) -> int:
    """``replay``: verify, republish, export or plot a recording."""
    from friction_sim.cli.replay import run

    return run(args)


__all__ = [
    "MAX_GRID", "MAX_SAMPLES", "PLANT_OPTIONS", "add_plant_options", "controller", "experiment", "feeder",
    "plant", "replay", "report", "ros_args", "simulate", "slider", "trace", "umap",
]
