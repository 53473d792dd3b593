"""``friction-sim trace`` and ``simulate``: the exact motion of one slider, drawn or measured.

``trace`` draws the paper's Fig. 2 (forces, acceleration, speed and position
with the points A, B, C; the height when the slider flies); ``simulate``
measures the mean velocity and U of a run and compares them with the U
relation, and writes the sampled trajectory and events as CSV.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from friction_sim.cli.options import Verb, add_flag, add_plant_options, plant, print_json, say_saved
from friction_sim.core.model import spec
from friction_sim.errors import ParameterError

MAX_SAMPLES = 10_000_000
#: ``simulate`` covers at most this many excitation periods (about a minute
#: of wall time at ~130,000 periods/s); more is a typo, not a question.
MAX_PERIODS = 10_000_000
#: ``trace`` draws at most this many periods (2,000 samples each).
MAX_TRACE_PERIODS = 100.0
PERIODS = spec.Setting("periods", 2.5, "periods", "excitation periods shown", 1.0, MAX_TRACE_PERIODS)
DURATION = spec.Setting("duration", 2.0, "s", "simulated time", None, None,
                        rule=f"> 0, at least one excitation period after --settle, at most {MAX_PERIODS:.0e} periods")
SETTLE = spec.Setting("settle", 0.0, "s", "time left out before the mean is taken", 0.0, None,
                      rule="< --duration")
SAMPLE_RATE = spec.Setting("sample_rate", 10_000.0, "Hz", "samples per second in --csv", 1e-3, 1e9,
                           rule=f"at most {MAX_SAMPLES:.0e} samples")


def add_trace_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``trace`` options."""
    parser.add_argument("--png", type=Path, required=True, help="output picture")
    add_flag(parser, PERIODS, PERIODS.default)
    add_plant_options(parser)


def add_simulate_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``simulate`` options."""
    add_plant_options(parser)
    for setting in (DURATION, SETTLE):
        add_flag(parser, setting, setting.default)
    parser.add_argument("--csv", type=Path, help="write the sampled trajectory and the events")
    add_flag(parser, SAMPLE_RATE, SAMPLE_RATE.default)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--params", type=Path, help="a calibrated plant (friction-sim calibrate's calibrated.yaml): "
                                                    "print the mean speed with its 95 %% band, as friction-sim "
                                                    "predict does, the flags that differ from their defaults "
                                                    "setting the prediction's settings")


def trace(args: argparse.Namespace) -> int:
    """``trace``: draw the paper's Fig. 2 for the plant options."""
    from friction_sim.cli.figures import trace_figure
    from friction_sim.core.runtime.simulation import simulate as run

    params, inputs = plant(args)
    duration = args.periods / inputs.excitation_frequency
    result = run(params, inputs, duration, sample_rate=2000.0 * inputs.excitation_frequency)
    say_saved(trace_figure(result), args.png)
    return 0


def simulate(args: argparse.Namespace) -> int:
    """``simulate``: simulate exactly; print the mean velocity and U (or JSON), optionally write a CSV."""
    from friction_sim.core.runtime.simulation import simulate as run

    if args.params is not None:  # a calibrated plant: the prediction with its band
        from friction_sim.cli.predict import from_simulate

        for setting, given in ((DURATION, args.duration), (SETTLE, args.settle)):
            if given != setting.default:
                raise ParameterError(setting.name, given, "does not apply with --params: the prediction averages "
                                                          "100 whole periods after 100")
        if args.csv is not None:
            raise ParameterError("csv", str(args.csv), "does not apply with --params: a prediction has no trajectory")
        return from_simulate(args)
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
        print_json(result.as_dict())
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


VERBS = (
    Verb("trace", "draw the paper's Fig. 2 (forces, a, v, x with A, B, C; the height z with lift-offs and "
         "landings when the slider flies)", add_trace_arguments, trace),
    Verb("simulate", "simulate exactly and report the mean velocity and U", add_simulate_arguments, simulate),
)

__all__ = ["DURATION", "MAX_PERIODS", "MAX_SAMPLES", "MAX_TRACE_PERIODS", "PERIODS", "SAMPLE_RATE", "SETTLE", "VERBS",
           "simulate", "trace"]
