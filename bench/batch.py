"""Benchmark of the population engine (issue 20): the compiled engine against the scalar loop.

Measures, in one run on this machine, slider-periods per wall-clock second of
:func:`friction_sim.core.engine.population.run_batch` with the compiled engine
and with the scalar loop (``engine="scalar"``: a loop over the single slider,
which runs the same physics interpreted), in three populations:

* Kostek's case: normal vibration, level track, stick-slip every period
  (phi in [0.3, 0.9], a in [0.3, 0.9], spread over the population);
* the flight case: Gamma in [1.9, 2.1], vibration angle 30 degrees, mu = 0.5,
  Fd = 0, plastic impulsive landings: one lift-off and one landing every period;
* the irregular population of issue 20 (seeded): Gamma 0-4, restitution 0-0.8,
  vibration angle 10-90 degrees, slope +-10 degrees, mu 0.05-1, Fd +-1 N,
  5 + 20 periods: stick-slip, hopping, bouncing and chaotic sliders mixed.

A slider-period is one slider advanced by one excitation period; a run of N
sliders over settle + periods periods does N*(settle + periods) of them.
Per case and N = 1 ... 10^5, on one core: ``shortcut`` (the default: a slider
whose period-start state repeats bit for bit extrapolates the rest of its
window, exactly), ``every event`` (the shortcut off: every event of every
period computed, a memo of worked-out steps as the single slider keeps), both
against the scalar loop on the same window; then the irregular population on
one and on two cores; the memory per slider (tracemalloc peak over N at
N = 10^5: the engine's own per-core work arrays, a few KB a core, are not in
it); and the compile time: the first call with an empty cache, and a new
process's first call with the cache filled (both in fresh processes).
Timings are medians of repeated runs; the machine is shared and noisy.  Prints
figures only: a benchmark never passes or fails on timing.

Run: make bench   (or .venv/bin/python bench/batch.py [--quick])
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import tracemalloc
from collections.abc import Callable
from typing import Any

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

import numpy as np

from friction_sim.core.engine.population import run_batch

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


def irregular_case(n: int) -> dict[str, Any]:
    """Issue 20's irregular population (g = 10, m = 1: Pa = Gamma m g cos(alpha))."""
    rng = np.random.default_rng(20)
    gamma, slope = rng.uniform(0.0, 4.0, n), rng.uniform(-10.0, 10.0, n)
    return {"excitation_amplitude": gamma * 10.0 * np.cos(np.radians(slope)), "restitution": rng.uniform(0.0, 0.8, n),
            "excitation_angle": rng.uniform(10.0, 90.0, n), "track_inclination": slope,
            "mu": rng.uniform(0.05, 1.0, n), "drive_force": rng.uniform(-1.0, 1.0, n)}


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


def compile_times() -> tuple[float, float]:
    """(seconds of the first call with an empty cache, of a new process's first call with it filled)."""
    script = ("import time; t = time.perf_counter(); "
              "from friction_sim.core.engine.population import run_batch; "
              "run_batch({'drive_force': [0.7]}, settle_periods=1, periods=1); print(time.perf_counter() - t)")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        first, again = (float(subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True,
                                             check=True).stdout) for _ in range(2))
    return first, again


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller runs (for a smoke test)")
    args = parser.parse_args()
    sizes = (1, 10, 100, 1000, 10_000) if args.quick else (1, 10, 100, 1000, 10_000, 100_000)
    settle, periods = (20, 100) if args.quick else (100, 1000)
    run_batch(kostek_case(2), settle_periods=1, periods=1)  # load (or compile) once before timing
    print(f"population engine, one core: slider-periods per second (window: settle {settle} + {periods} periods)")
    for name, case in (("Kostek stick-slip", kostek_case), ("flight every period", flight_case)):
        scalar_n = SCALAR_SLIDERS if not args.quick else 50
        scalar = rate(case, scalar_n, settle, periods, 1, engine="scalar")
        print(f"\n{name}: scalar loop {scalar:,.0f} slider-periods/s over {scalar_n} sliders")
        print(f"{'N':>8} {'shortcut':>16} {'x scalar':>9} {'every event':>14} {'x scalar':>9}")
        for n in sizes:
            repeats = 5 if n <= 1000 else (3 if n <= 10_000 else 1)
            fast = rate(case, n, settle, periods, repeats, threads=1)
            stepping = rate(case, n, settle, periods, max(1, repeats // 2), periodic_shortcut=False, threads=1)
            print(f"{n:>8} {fast:>16,.0f} {fast / scalar:>9.1f} {stepping:>14,.0f} {stepping / scalar:>9.1f}")
        largest = sizes[-1]
        print(f"memory per slider at N = {largest}: {memory_per_slider(case, largest, settle, periods):,.0f} bytes "
              f"(shortcut), {memory_per_slider(case, largest, 5, 20, periodic_shortcut=False):,.0f} (every event)")
    n_irregular = 1000 if args.quick else 4000
    scalar = rate(irregular_case, 100 if args.quick else 400, 5, 20, 1 if args.quick else 3, engine="scalar")
    print(f"\nirregular population, 5 + 20 periods: scalar loop {scalar:,.0f} slider-periods/s")
    for threads in (1, 2):
        for shortcut in (True, False):
            fast = rate(irregular_case, n_irregular, 5, 20, 3, threads=threads, periodic_shortcut=shortcut)
            print(f"  N = {n_irregular}, {threads} core(s), shortcut {'on ' if shortcut else 'off'}: "
                  f"{fast:>12,.0f} slider-periods/s = {fast / scalar:6.1f} x the scalar loop")
    first, again = compile_times()
    print(f"\ncompile: first call with an empty cache {first:.1f} s; a new process's first call with the cache "
          f"filled {again:.2f} s (import included)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
