"""Benchmark of the batch core (issue 12, item 1).

Measures, in one run on this machine, slider-periods per wall-clock second of
:func:`friction_sim.core.batch.run_batch` for N = 1, 10, ..., 10^5 sliders in
two cases, against the scalar core looped over the same sliders:

* Kostek's case: normal vibration, level track, stick-slip every period
  (phi in [0.3, 0.9], a in [0.3, 0.9], spread over the population);
* the flight case: Gamma in [1.9, 2.1], vibration angle 30 degrees, mu = 0.5,
  Fd = 0, plastic impulsive landings: one lift-off and one landing every period.

A slider-period is one slider advanced by one excitation period; a run of N
sliders over settle + periods periods does N*(settle + periods) of them.
Three figures per N:

* ``numpy``: the default engine, whose sliders extrapolate their window once
  their period-start state repeats bit for bit (exact: the state decides the
  future), so its cost is the transient, not the window;
* ``stepping``: the same engine with that shortcut off, every event of every
  period computed (what an irregular motion costs), on a shorter window;
* ``scalar``: the loop over :class:`Slider` (the batch core's "scalar" engine),
  timed on 200 sliders and counted per slider-period (it is linear in N).

The ratios are against the scalar loop measured in the same run on the same
window (its own memo makes it faster on a long periodic window).  Memory per
slider: the tracemalloc peak of a run divided by N.  Timings are medians of
repeated runs (fewer for the large N); the machine is shared and noisy.
Prints figures only: a benchmark never passes or fails on timing.

Run: .venv/bin/python bench/batch.py [--quick]
"""

from __future__ import annotations

import argparse
import os
import tracemalloc
from collections.abc import Callable
from typing import Any

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

import numpy as np

from friction_sim.core.batch import run_batch

from _timing import median_time

SCALAR_SLIDERS = 200


def kostek_case(n: int) -> dict[str, Any]:
    rng = np.random.default_rng(1)
    a = rng.uniform(0.3, 0.9, n)
    phi = np.maximum(rng.uniform(0.3, 0.9, n), 1.05 - a)  # above the motion boundary phi = 1 - a
    return {"drive_force": phi * 0.1 * 10.0, "excitation_amplitude": a * 10.0}


def flight_case(n: int) -> dict[str, Any]:
    rng = np.random.default_rng(2)
    return {"mu": 0.5, "excitation_angle": 30.0, "drive_force": 0.0,
            "excitation_amplitude": rng.uniform(1.9, 2.1, n) * 10.0}


def rate(case: Callable[[int], dict[str, Any]], n: int, settle: int, periods: int, repeats: int,
         **options: Any) -> float:
    """Slider-periods per second of one run_batch call."""
    values = case(n)
    seconds = median_time(lambda: run_batch(values, settle_periods=settle, periods=periods, **options), repeats)
    return n * (settle + periods) / seconds


def memory_per_slider(case: Callable[[int], dict[str, Any]], n: int, settle: int, periods: int,
                      **options: Any) -> float:
    values = case(n)
    tracemalloc.start()
    run_batch(values, settle_periods=settle, periods=periods, **options)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / n


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller runs (for a smoke test)")
    args = parser.parse_args()
    sizes = (1, 10, 100, 1000, 10_000) if args.quick else (1, 10, 100, 1000, 10_000, 100_000)
    settle, periods = (20, 100) if args.quick else (100, 1000)
    step_settle, step_periods = (5, 15) if args.quick else (10, 40)
    step_largest = 10_000
    print(f"batch core: slider-periods per second (window: settle {settle} + {periods} periods; "
          f"stepping: {step_settle} + {step_periods})")
    for name, case in (("Kostek stick-slip", kostek_case), ("flight every period", flight_case)):
        scalar_n = SCALAR_SLIDERS if not args.quick else 50
        scalar = rate(case, scalar_n, settle, periods, 1, engine="scalar")
        scalar_short = rate(case, scalar_n, step_settle, step_periods, 1, engine="scalar")
        print(f"\n{name}: scalar loop {scalar:,.0f} slider-periods/s over {scalar_n} sliders "
              f"({scalar_short:,.0f} on the stepping window)")
        print(f"{'N':>8} {'numpy':>16} {'x scalar':>9} {'stepping':>14} {'x scalar':>9} {'bytes/slider':>13}")
        for n in sizes:
            repeats = 5 if n <= 1000 else (3 if n <= 10_000 else 1)
            fast = rate(case, n, settle, periods, repeats)
            stepping = (rate(case, n, step_settle, step_periods, max(1, repeats // 2), periodic_shortcut=False)
                        if n <= step_largest else float("nan"))
            memory = memory_per_slider(case, n, settle, periods) if n >= 1000 else float("nan")
            print(f"{n:>8} {fast:>16,.0f} {fast / scalar:>9.1f} {stepping:>14,.0f} {stepping / scalar_short:>9.1f} "
                  f"{memory:>13,.0f}")
        if not args.quick:
            memory = memory_per_slider(case, 10_000, step_settle, step_periods, periodic_shortcut=False)
            print(f"stepping memory at N = 10000: {memory:,.0f} bytes/slider")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
