"""``friction-sim umap``: the nondimensional mean speed U(phi, a), at one point or as the map.

On Kostek's model below lift-off U is the paper's closed form (its Fig. 3);
elsewhere (any other model option, or a hop) the general mean speed of the
exact motion.  One point says what the slider does there, in words.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from friction_sim.cli.options import MODEL_OPTIONS, Verb, add_flag, add_model_options, model, print_json, say_saved
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import amplitude_for, drive_force_for, throw_number
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import closed_form_applies, is_kostek
from friction_sim.errors import FrictionSimError

MAX_GRID = 2001
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
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``umap`` options."""
    for setting in (PHI, AMPLITUDE_RATIO, GRID):
        add_flag(parser, setting)
    add_model_options(parser)
    parser.add_argument("--csv", type=Path, help="write the map as CSV (phi, amplitude_ratio, U)")
    parser.add_argument("--png", type=Path, help="draw the map like the paper's Fig. 3")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def umap(args: argparse.Namespace) -> int:
    """``umap``: U at one point (``--phi --ratio``), or the map on a grid."""
    if args.grid is None:
        return _umap_point(args)
    if args.csv is None and args.png is None:
        raise FrictionSimError("umap --grid needs --csv FILE and/or --png FILE")
    from friction_sim.core.meanspeed import urelation

    params = model(args)
    grid = urelation.u_grid(args.grid) if is_kostek(params) else _general_grid(args.grid, params)
    if args.csv is not None:
        from friction_sim.io.export import write_umap_csv

        print(f"wrote {write_umap_csv(grid, args.csv)}")
    if args.png is not None:
        from friction_sim.cli.figures import u_map_figure

        say_saved(u_map_figure(grid), args.png)
    return 0


def _general_grid(points: int, params: SliderParams) -> Any:
    """The map of the general model on the grid of :func:`urelation.u_grid` (one
    mean-speed simulation per point where the closed form does not hold)."""
    from friction_sim.core.meanspeed import urelation
    from friction_sim.core.meanspeed.general import u_general

    axis = np.arange(1, points + 1) / (points + 1.0)
    phi, a = np.meshgrid(axis, axis)
    return urelation.UMap(phi=axis, amplitude_ratio=axis.copy(), u=np.asarray(u_general(phi, a, params)))


def _umap_point(args: argparse.Namespace) -> int:
    """U(phi, a) and what the slider does there: never moves, sticks and slips
    once a period (where the slip starts and how long it lasts), or slips all the time.
    Off Kostek's model (or with a hop) the general mean speed, and its kind of motion."""
    from friction_sim.core.meanspeed import urelation

    phi, ratio = args.phi, args.amplitude_ratio
    if phi is None or ratio is None:
        raise FrictionSimError("umap needs --phi and --ratio for one point, or --grid N for the map")
    params = model(args)
    inputs = Inputs(drive_force=drive_force_for(phi, params.mu, params.weight),
                    excitation_amplitude=amplitude_for(ratio, params.weight))
    if not closed_form_applies(params, inputs):
        return _general_point(args, params, inputs)
    u = urelation.u_map(phi, ratio) + 0.0  # + 0.0: no '-0.0' where a backward drive stands still
    motion, why = motion_regime(phi, ratio)
    periodic = motion == STICK_SLIP
    start = urelation.slip_start_phase(phi, ratio) if periodic else None
    length = urelation.stop_phase_advance(phi, ratio) if periodic else None
    if args.json:
        print_json({
            "phi": phi, "amplitude_ratio": ratio, "U": u, "motion": motion,
            "moves": urelation.moves(phi, ratio), "motion_boundary_ratio": urelation.motion_boundary(phi),
            "slip_start_phase": start, "slip_phase_length": length,
        })
        return 0
    print(f"U({phi:g}, {ratio:g}) = {u!r}")
    print(f"{motion}: {why}")
    return 0


def _general_point(args: argparse.Namespace, params: SliderParams, inputs: Inputs) -> int:
    """``umap`` off the closed form: the general mean speed at (phi, a) for the model options."""
    from friction_sim.core.meanspeed.general import mean_speed

    phi, ratio = args.phi, args.amplitude_ratio
    result = mean_speed(params, inputs)
    gamma = throw_number(inputs.excitation_amplitude, params.normal_weight)
    u = result.u + 0.0
    motion = general_motion(result)
    if args.json:
        print_json({
            "phi": phi, "amplitude_ratio": ratio, "throw_number": gamma, "U": u,
            "motion": motion, "periodic": result.periodic, "period_multiple": result.period_multiple,
            "settle_periods": result.settle_periods, "periods": result.periods,
            "flight_fraction": result.flight_fraction, "stick_fraction": result.stick_fraction,
            "exact": result.exact, "runaway": result.runaway,
            **{s.name: getattr(params, s.name) for s in MODEL_OPTIONS},
        })
        return 0
    print(f"U({phi:g}, {ratio:g}) = {u!r}  (Gamma = {gamma:g})")
    print(motion)
    return 0


def general_motion(result: Any) -> str:
    """What a :class:`~friction_sim.core.meanspeed.general.MeanSpeed` says the slider does, in words."""
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
    from friction_sim.core.meanspeed import urelation

    size, way = abs(phi), "" if phi >= 0.0 else ", backwards (along -x)"
    if not urelation.moves(phi, ratio):  # the one rule of the motion boundary (exact where it is close)
        return NEVER_MOVES, (f"phi <= 1 - a: the friction limit mu R never drops below |Fd| "
                             f"(motion needs a > {max(1.0 - size, 0.0):g})")
    if size < 1.0:
        start, length = urelation.slip_start_phase(size, ratio), urelation.stop_phase_advance(size, ratio)
        return STICK_SLIP, f"the slip starts at phase {start:.6g} rad (A) and lasts {length:.6g} rad (to C){way}"
    if size == 1.0:
        return SLIPS_ALWAYS, f"|phi| = 1: never sticks; its speed only touches zero once a period{way}"
    every = " (|Fd| > mu R at every phase)" if size > 1.0 + ratio else ""
    return SLIPS_ALWAYS, (f"|phi| > 1: |Fd| exceeds the mean friction mu m g{every}, so it never sticks "
                          f"and speeds up without bound{way}")


VERBS = (Verb("umap", "the nondimensional mean speed U(phi, a): one point or the map", add_arguments, umap),)

__all__ = ["AMPLITUDE_RATIO", "GRID", "NEVER_MOVES", "PHI", "SLIPS_ALWAYS", "STICK_SLIP", "VERBS", "general_motion",
           "motion_regime", "umap"]
