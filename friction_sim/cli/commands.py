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
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from friction_sim.core import spec
from friction_sim.core.params import Inputs, SliderParams, throw_number
from friction_sim.errors import FrictionSimError, ParameterError

MAX_GRID = 2001
#: The port ``--foxglove`` without a number serves on: Foxglove's usual one.
FOXGLOVE_DEFAULT_PORT = 8765
MAX_SAMPLES = 10_000_000
#: ``simulate`` covers at most this many excitation periods (about a minute
#: of wall time at ~130,000 periods/s); more is a typo, not a question.
MAX_PERIODS = 10_000_000
#: ``trace`` draws at most this many periods (2,000 samples each).
MAX_TRACE_PERIODS = 100.0
#: The settings ``--mass --mu --gravity --drive-force --amplitude --frequency``
#: set: the plant and the inputs the slider takes as parameters.
PLANT_OPTIONS = tuple(setting for setting in (*spec.PLANT.values(), *spec.INPUTS.values())
                      if setting.name in spec.SLIDER_NODE)
#: The plant settings ``umap`` takes (``--mu --static-ratio --angle --phase
#: --inclination --restitution --landing-friction``): U = V f/(g mu) depends on
#: them, not on the mass or g.  At their defaults U is Kostek's closed form.
MODEL_OPTIONS = tuple(setting for setting in spec.PLANT.values() if setting.name not in ("mass", "gravity"))

# The command line's own numbers, declared like the model's settings and
# checked by the same Setting.check (cross-field rules stay in the core).
# phi has no physical bound, but past |phi| = 1 + a nothing changes (the slider
# slips all the time), so a bound far beyond that only catches typos.
PHI = spec.Setting("phi", 0.7, "-", "drive ratio phi = Fd/(mu m g)", -1e6, 1e6)
# a up to the controller's largest amplitude ratio: above 1/cos(alpha) the slider hops.
AMPLITUDE_RATIO = spec.Setting("amplitude_ratio", 0.5, "-", "amplitude ratio a = Pa/(m g)", 0.0,
                               spec.MAX_AMPLITUDE_RATIO.high,
                               rule="a >= 1/cos(alpha): the slider hops (general mean speed)", flag="--ratio")
GRID = spec.Setting("grid", 101, "points", "map on N x N points of (phi, a) in (0, 1)", 2, MAX_GRID)
PERIODS = spec.Setting("periods", 2.5, "periods", "excitation periods shown", 1.0, MAX_TRACE_PERIODS)
DURATION = spec.Setting("duration", 2.0, "s", "simulated time", None, None,
                        rule=f"> 0, at least one excitation period after --settle, at most {MAX_PERIODS:.0e} periods")
SETTLE = spec.Setting("settle", 0.0, "s", "time left out before the mean is taken", 0.0, None,
                      rule="< --duration")
SAMPLE_RATE = spec.Setting("sample_rate", 10_000.0, "Hz", "samples per second in --csv", 1e-3, 1e9,
                           rule=f"at most {MAX_SAMPLES:.0e} samples")


class _NonFinite(float):
    """A NaN or inf that takes Setting.check's full path: its fast path lets inf
    through a bound left open (``low <= inf <= +inf``)."""


def flag_type(setting: spec.Setting) -> Callable[[str], Any]:
    """An argparse ``type`` that parses a flag's text and checks it with
    ``setting.check``: NaN, inf and out-of-range values are usage errors
    (one line naming the flag, the value and the limit; exit code 2)."""

    def parse(text: str) -> Any:
        try:
            value = setting.kind(text)
        except ValueError:
            value = text  # not a number: check() says what it must be
        if isinstance(value, float) and not math.isfinite(value):
            value = _NonFinite(value)
        try:
            return setting.check(value)
        except ParameterError as error:
            raise argparse.ArgumentTypeError(str(error)) from None

    parse.__name__ = setting.name
    return parse


def add_flag(parser: Any, setting: spec.Setting, default: Any = None) -> None:
    """Add ``setting`` as the option ``setting.option`` (dest: its name), parsed
    by :func:`flag_type`; the help gives its meaning, unit, range and default."""
    unit = f" [{setting.unit}]" if setting.unit and setting.unit != "-" else ""
    limits = "; ".join(part for part in (setting.range_text().replace("\\|", "|"), setting.rule) if part)
    shown = "" if default is None else f"; default {default}" if isinstance(default, str) else f"; default {default:g}"
    metavar = ("{" + ",".join(setting.choices) + "}" if setting.choices
               else setting.option.lstrip("-").replace("-", "_").upper())
    parser.add_argument(setting.option, dest=setting.name, type=flag_type(setting), default=default,
                        metavar=metavar,
                        help=f"{setting.description}{unit}" + (f" ({limits}{shown})" if limits or shown else ""))
    parser.set_defaults(flags={**(parser.get_default("flags") or {}), setting.name: setting.option})


def flag_of(args: argparse.Namespace, name: str) -> str | None:
    """The option that set the value ``name`` (``amplitude_ratio`` -> ``--ratio``), if a flag did."""
    flags: dict[str, str] = getattr(args, "flags", None) or {}
    return flags.get(name)


def add_plant_options(parser: argparse.ArgumentParser) -> None:
    """The model's parameters and inputs as options (flag, default, unit, range
    and meaning from :mod:`friction_sim.core.spec`); defaults are the paper's Fig. 2 case."""
    group = parser.add_argument_group("plant (defaults: the paper's Fig. 2 case)")
    for setting in PLANT_OPTIONS:
        add_flag(group, setting, setting.default)


def add_model_options(parser: argparse.ArgumentParser) -> None:
    """The plant settings U depends on (:data:`MODEL_OPTIONS`) as options, at their defaults."""
    group = parser.add_argument_group("model (defaults: Kostek's model, where U has its closed form)")
    for setting in MODEL_OPTIONS:
        add_flag(group, setting, setting.default)


def model(args: argparse.Namespace) -> SliderParams:
    """The plant the model options give (mass and g at their defaults: U does not depend on them)."""
    return SliderParams(**{s.name: getattr(args, s.name) for s in MODEL_OPTIONS})


def plant(args: argparse.Namespace) -> tuple[SliderParams, Inputs]:
    """The plant and inputs the plant options give, checked as the slider would."""
    params = SliderParams(**{name: getattr(args, name) for name in spec.PLANT})
    inputs = Inputs(**{s.name: getattr(args, s.name) for s in PLANT_OPTIONS if s.name in spec.INPUTS})
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
    from friction_sim.core import urelation

    params = model(args)
    grid = urelation.u_grid(args.grid) if params.is_kostek else _general_grid(args.grid, params)
    if args.csv is not None:
        from friction_sim.io.export import write_umap_csv

        print(f"wrote {write_umap_csv(grid, args.csv)}")
    if args.png is not None:
        from friction_sim.cli.figures import u_map_figure

        _save(u_map_figure(grid), args.png)
    return 0


def _general_grid(points: int, params: SliderParams) -> Any:
    """The map of the general model on the grid of :func:`urelation.u_grid` (one
    mean-speed simulation per point where the closed form does not hold)."""
    from friction_sim.core import urelation
    from friction_sim.core.meanspeed import u_general

    axis = np.arange(1, points + 1) / (points + 1.0)
    phi, a = np.meshgrid(axis, axis)
    return urelation.UMap(phi=axis, amplitude_ratio=axis.copy(), u=np.asarray(u_general(phi, a, params)))


def _umap_point(args: argparse.Namespace) -> int:
    """U(phi, a) and what the slider does there: never moves, sticks and slips
    once a period (where the slip starts and how long it lasts), or slips all the time.
    Off Kostek's model (or with a hop) the general mean speed, and its kind of motion."""
    from friction_sim.core import urelation

    phi, ratio = args.phi, args.amplitude_ratio
    if phi is None or ratio is None:
        raise FrictionSimError("umap needs --phi and --ratio for one point, or --grid N for the map")
    params = model(args)
    if not (params.is_kostek and ratio < 1.0):
        return _general_point(args, params)
    u = urelation.u_map(phi, ratio) + 0.0  # + 0.0: no '-0.0' where a backward drive stands still
    motion, why = motion_regime(phi, ratio)
    periodic = motion == STICK_SLIP
    start = urelation.slip_start_phase(phi, ratio) if periodic else None
    length = urelation.stop_phase_advance(phi, ratio) if periodic else None
    if args.json:
        _print_json({
            "phi": phi, "amplitude_ratio": ratio, "U": u, "motion": motion,
            "moves": urelation.moves(phi, ratio), "motion_boundary_ratio": urelation.motion_boundary(phi),
            "slip_start_phase": start, "slip_phase_length": length,
        })
        return 0
    print(f"U({phi:g}, {ratio:g}) = {u!r}")
    print(f"{motion}: {why}")
    return 0


def _general_point(args: argparse.Namespace, params: SliderParams) -> int:
    """``umap`` off the closed form: the general mean speed at (phi, a) for the model options."""
    from friction_sim.core.meanspeed import mean_speed

    phi, ratio = args.phi, args.amplitude_ratio
    inputs = Inputs(drive_force=phi * params.mu * params.weight, excitation_amplitude=ratio * params.weight)
    result = mean_speed(params, inputs)
    u = result.u + 0.0
    motion = general_motion(result)
    if args.json:
        _print_json({
            "phi": phi, "amplitude_ratio": ratio, "throw_number": throw_number(params, inputs), "U": u,
            "motion": motion, "periodic": result.periodic, "period_multiple": result.period_multiple,
            "settle_periods": result.settle_periods, "periods": result.periods,
            "flight_fraction": result.flight_fraction, "stick_fraction": result.stick_fraction,
            "exact": result.exact, "runaway": result.runaway,
            **{s.name: getattr(params, s.name) for s in MODEL_OPTIONS},
        })
        return 0
    print(f"U({phi:g}, {ratio:g}) = {u!r}  (Gamma = {throw_number(params, inputs):g})")
    print(motion)
    return 0


def general_motion(result: Any) -> str:
    """What a :class:`~friction_sim.core.meanspeed.MeanSpeed` says the slider does, in words."""
    if result.runaway:
        return "slips all the time and speeds up without bound"
    if result.stick_fraction >= 1.0:
        return NEVER_MOVES
    parts = []
    if result.flight_fraction > 0.0:
        parts.append(f"hops: off the track {result.flight_fraction:.4g} of the time")
    if result.stick_fraction > 0.0:
        parts.append(f"stuck {result.stick_fraction:.4g} of the time")
    elif result.flight_fraction == 0.0:
        parts.append("slips all the time")
    if result.periodic:
        every = "every period" if result.period_multiple == 1 else f"every {result.period_multiple} periods"
        parts.append(f"periodic, repeating {every} (mean exact to rounding)")
    else:
        parts.append(f"not periodic within {result.settle_periods} periods: "
                     f"the mean is over the {result.periods} periods after them")
    return "; ".join(parts)


NEVER_MOVES, STICK_SLIP, SLIPS_ALWAYS = "never moves", "sticks and slips once a period", "slips all the time"


def motion_regime(phi: float, ratio: float) -> tuple[str, str]:
    """What a slider started at rest at phase 0 does at (phi, a), and why, in words.

    |phi| <= 1 - a: mu R never drops below |Fd|, it never moves.  1 - a < |phi| < 1:
    one slip per period (points A to C).  |phi| >= 1: |Fd| is at least the mean
    friction mu m g, it slips from the start and never sticks again (its speed
    grows without bound for |phi| > 1; at |phi| = 1 it only touches zero once a period).
    """
    size, way = abs(phi), "" if phi >= 0.0 else ", backwards (along -x)"
    if size <= 1.0 - ratio:
        return NEVER_MOVES, (f"phi <= 1 - a: the friction limit mu R never drops below |Fd| "
                             f"(motion needs a > {max(1.0 - size, 0.0):g})")
    if size < 1.0:
        from friction_sim.core import urelation

        start, length = urelation.slip_start_phase(size, ratio), urelation.stop_phase_advance(size, ratio)
        return STICK_SLIP, f"the slip starts at phase {start:.6g} rad (A) and lasts {length:.6g} rad (to C){way}"
    if size == 1.0:
        return SLIPS_ALWAYS, f"|phi| = 1: never sticks; its speed only touches zero once a period{way}"
    every = " (|Fd| > mu R at every phase)" if size > 1.0 + ratio else ""
    return SLIPS_ALWAYS, (f"|phi| > 1: |Fd| exceeds the mean friction mu m g{every}, so it never sticks "
                          f"and speeds up without bound{way}")


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
    f = inputs.excitation_frequency
    if args.duration * f > MAX_PERIODS:
        raise ParameterError("duration", args.duration, f"must be at most {MAX_PERIODS:.0e} excitation periods "
                                                        f"({MAX_PERIODS / f:g} s at f = {f:g} Hz)")
    sample_rate = args.sample_rate if args.csv is not None else None
    if sample_rate is not None and sample_rate * args.duration > MAX_SAMPLES:
        raise ParameterError("sample_rate", sample_rate, f"must be at most {MAX_SAMPLES / args.duration:g} Hz "
                                                         f"with --duration {args.duration:g} s "
                                                         f"(at most {MAX_SAMPLES:.0e} samples)")
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
    relation = ("closed form" if result.u_closed_form else
                "general mean speed, " + ("periodic" if result.u_periodic else "not periodic: a window's mean"))
    print(f"U measured = {result.u_measured!r}, U relation = {result.u_exact!r} ({relation})")
    print(f"throw number Gamma = {result.throw_number:g}, flight fraction {result.flight_fraction!r}")
    print(f"events: {counts}; wall time {result.wall_time * 1e3:.2f} ms")
    if args.csv is not None:
        print(f"wrote {args.csv}")
    return 0


def conveyor(args: argparse.Namespace) -> int:
    """``conveyor``: the conveying figure (U against Gamma and against the inclination) and its CSV."""
    from friction_sim.cli.conveyor import run as run_conveyor

    return run_conveyor(args)


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
    if getattr(args, "foxglove", None) is not None:
        ros += ["-p", f"foxglove_port:={args.foxglove}"]
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

    if args.foxglove is not None and args.attach is not None:
        raise FrictionSimError("--foxglove with --attach: the slider runs elsewhere; start it with "
                               "--foxglove (or foxglove_port) instead")
    run_scenario(args.scenario, output=args.output, attach=args.attach, foxglove_port=args.foxglove)
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
    "AMPLITUDE_RATIO", "DURATION", "FOXGLOVE_DEFAULT_PORT", "GRID", "MAX_GRID", "MAX_PERIODS", "MAX_SAMPLES",
    "MAX_TRACE_PERIODS", "MODEL_OPTIONS", "NEVER_MOVES", "PERIODS", "PHI", "PLANT_OPTIONS", "SAMPLE_RATE", "SETTLE",
    "SLIPS_ALWAYS",
    "STICK_SLIP", "add_flag", "add_model_options", "add_plant_options", "controller", "conveyor", "experiment",
    "feeder", "flag_of", "flag_type", "general_motion", "model", "motion_regime", "plant", "replay", "report",
    "ros_args", "simulate", "slider", "trace", "umap",
]
