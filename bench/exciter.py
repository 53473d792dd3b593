"""Benchmark of the resonant exciter (issue 21): what it costs, and how exact it is.

Measures, in one run on this machine:
  (a) the single slider's throughput in excitation periods per wall-clock
      second, the paper's case with the force actuator against the resonant
      actuator in steady state at resonance (the same motion, a quarter period
      later), and against the resonant actuator during the transient after a
      step of drive level (f_n = 52 Hz, zeta = 0.02, driven at 50 Hz), its root
      search interpreted (plain) and compiled (the same bits);
  (b) the population engine's throughput (compiled, every event computed, and
      with the periodic shortcut) on the paper's case, force against resonant;
  (c) the agreements: the resonance curve against 50-digit mpmath, and the
      part's motion after a step of drive against the independent coupled
      solve_ivp reference (test/reference_exciter.py) on random cases with
      flight.
Timings are medians; the ratios measured in the same run are the figures to
trust.  Prints figures only: a benchmark never passes or fails on timing.

Run: make bench   (or .venv/bin/python bench/exciter.py [--quick])
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import mpmath
import numpy as np

from friction_sim.core.engine import transient_kernel
from friction_sim.core.engine.population import run_batch
from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.exciter import response

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))
from reference_exciter import random_case, solve

from _timing import median_time
from helpers import exciter_states

RESONANT = SliderParams(actuator="resonant")


def single_rate(params: SliderParams, inputs: Inputs, periods: int, repeats: int, step: float | None = None) -> float:
    """Periods per second of one slider over ``periods`` periods (``step``: drive level set at the start)."""
    def run() -> None:
        slider = Slider(params, inputs, event_log_size=0)
        if step is not None:
            slider.set_inputs(drive_level=step)
        slider.advance_to(periods / inputs.excitation_frequency)

    return periods / median_time(run, repeats)


def population_rate(actuator: str, n: int, periods: int, shortcut: bool, repeats: int) -> float:
    columns = {"actuator": [actuator] * n, "drive_force": np.linspace(0.5, 0.9, n)}
    run_batch(columns, settle_periods=1, periods=1)  # load the compiled engine
    seconds = median_time(lambda: run_batch(columns, settle_periods=5, periods=periods,
                                            periodic_shortcut=shortcut), repeats)
    return n * (periods + 5) / seconds


def resonance_agreement() -> float:
    mpmath.mp.dps = 50
    worst = 0.0
    for zeta in (1e-4, 0.02, 0.1, 0.7):
        for f in np.linspace(1.0, 150.0, 301):
            r, z = mpmath.mpf(float(f) / 50.0), mpmath.mpf(zeta)
            exact = 2 * z * r**2 / mpmath.mpc(1 - r**2, 2 * z * r)
            gain, lag = response(float(f), 50.0, zeta)
            worst = max(worst, abs(gain / float(abs(exact)) - 1), abs(lag - float(-mpmath.arg(exact))))
    return worst


def reference_agreement(cases: int) -> tuple[float, int, int]:
    """Largest error of x, v, z, vz (relative to each one's range) over ``cases`` random cases,
    the events compared and the cases with flight."""
    worst, events, flying = 0.0, 0, 0
    for seed in range(cases):
        case = random_case(np.random.default_rng(seed))
        reference = solve(case, 0.4)
        times = np.linspace(0.0, 0.4, 81)[1:]
        ours, slider = exciter_states(case, times)
        theirs = np.array([reference.at(float(t))[2:6] for t in times])
        scale = np.maximum(np.max(np.abs(theirs), axis=0), 1e-300)
        worst = max(worst, float(np.max(np.abs(ours - theirs) / scale)))
        events += len(reference.events)
        flying += slider.flight_time > 0.0
    return worst, events, flying


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller runs (for a smoke test)")
    args = parser.parse_args()
    periods, repeats, n = (200, 3, 2000) if args.quick else (2000, 5, 10_000)
    print("(a) single slider, periods per wall-clock second (median):")
    force = single_rate(SliderParams(), Inputs(), periods, repeats)
    steady = single_rate(RESONANT, Inputs(), periods, repeats)
    plant = RESONANT.replace(natural_frequency=52.0)
    transient_periods = 300  # the transient of zeta = 0.02 at 52 Hz settles below rounding in ~320 periods
    transient_kernel.use(transient_kernel.PLAIN)
    plain = single_rate(plant, Inputs(drive_level=0.3), transient_periods, repeats, step=0.9)
    transient_kernel.use(transient_kernel.COMPILED)
    single_rate(plant, Inputs(drive_level=0.3), 1, 1, step=0.9)  # (load or compile it first)
    stepped = single_rate(plant, Inputs(drive_level=0.3), transient_periods, repeats, step=0.9)
    print(f"    force actuator (paper's case)              {force:12,.0f}")
    print(f"    resonant, steady at resonance               {steady:12,.0f}   ({steady / force:.2f} x force)")
    print(f"    resonant, transient after a step, plain     {plain:12,.0f}   ({plain / force:.4f} x force)")
    print(f"    resonant, transient after a step, compiled  {stepped:12,.0f}   ({stepped / force:.4f} x force, "
          f"{stepped / plain:.1f} x plain)")
    print(f"(b) population engine, N = {n}, slider-periods per second (median):")
    for shortcut in (False, True):
        off = population_rate("force", n, 20, shortcut, repeats)
        on = population_rate("resonant", n, 20, shortcut, repeats)
        label = "periodic shortcut" if shortcut else "every event      "
        print(f"    {label}  force {off:14,.0f}   resonant {on:14,.0f}   ({on / off:.2f} x)")
    print("(c) agreements:")
    print(f"    resonance curve against 50-digit mpmath: largest error {resonance_agreement():.1e}")
    worst, events, flying = reference_agreement(4 if args.quick else 12)
    print(f"    motion after a step of drive against the coupled solve_ivp reference: largest error "
          f"{worst:.1e} of each quantity's range ({events} events, {flying} cases with flight)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
