"""Benchmark of sweeps (issue 12, item 5; issue 20): two sweeps, several ways.

The sweep (:data:`SWEEP`): 4,000 points of the general model (a grid over the
throw number and the vibration angle, level and 5-degree track, 20 parts per
cell with mu and mass drawn at random), 50 settling + 200 averaged periods
each: 1,000,000 slider-periods.  It runs

  (a) with the scalar loop: the chunks one after the other in this process,
      each a loop over the scalar core (``--workers 0 --engine scalar``);
  (b) on a local Dask cluster of 1 worker process, the compiled population engine;
  (c) on a local Dask cluster of 2 worker processes (this machine has 2 cores).

The same three runs of the irregular population of issue 20 (:data:`IRREGULAR`:
Gamma 0-4, restitution 0-0.8, vibration angle 10-90 degrees, slope +-10
degrees, mu 0-1, Fd +-1 N, 5 + 20 periods, parts that stick, slip, hop,
bounce and move chaotically, all drawn at random), whose bouncers make the
scalar loop slow: there 2 local workers must beat it a hundredfold, with
``friction-sim sweep``'s defaults (the compiled engine; a sweep never has to
be told).
Every run's rows are checked equal (to the last bit between (b) and (c), to
1e-12 against (a)).  It prints points per second, slider-periods per second and
the speedups over (a), the cluster start-up time with the workers loading the
compiled engine (about a second each, in parallel; not in the rates), and then
what a 64-core cluster would take for the shipped example
config/sweep_conveyor.yaml, from two measurements: the example cut into 64
and into 256 chunks, each chunk timed in one process, and Dask's cost per
task (no-op tasks on the 2-worker cluster: submit, run, gather); the chunks
are handed out in order to 64 workers as they free up, each also paying the
per-task cost.

Prints figures only: a benchmark never passes or fails on timing.  The
machine is shared: figures vary from run to run.

Run: make bench   (or .venv/bin/python bench/sweep.py [--quick])
"""

from __future__ import annotations

import argparse
import heapq
import math
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import numpy as np

from friction_sim.experiment.sweep import Sweep, load_sweep, parse_sweep
from friction_sim.experiment.sweep_run import DaskExecutor, Executor, SerialExecutor, run_chunk, run_sweep
from friction_sim.io.parquet import read_table

SWEEP = """\
name: bench
settle_periods: 50
periods: 200
chunk_size: 250
seed: 12
fixed: {drive_force: 0.0, gravity: 9.81}
grid:
  track_inclination: [0, 5]
  throw_number: {from: 0.4, to: 3.0, num: 10}
  excitation_angle: [20, 40, 60, 80, 90]
samples: 40
random:
  mu: {distribution: normal, mean: 0.3, std: 0.05}
  mass: {distribution: lognormal, median: 0.01, sigma: 0.3}
"""
IRREGULAR = """\
name: irregular
settle_periods: 5
periods: 20
chunk_size: 2000
seed: 20
fixed: {gravity: 10.0, mass: 1.0}
samples: 20000
random:
  throw_number: {distribution: uniform, low: 0.0, high: 4.0}
  restitution: {distribution: uniform, low: 0.0, high: 0.8}
  excitation_angle: {distribution: uniform, low: 10, high: 90}
  track_inclination: {distribution: uniform, low: -10, high: 10}
  mu: {distribution: uniform, low: 0.05, high: 1.0}
  drive_force: {distribution: uniform, low: -1.0, high: 1.0}
"""
CONVEYOR = Path(__file__).resolve().parents[1] / "config" / "sweep_conveyor.yaml"


def timed(sweep: Sweep, executor: Executor, output: Path, engine: str) -> tuple[float, dict[str, np.ndarray]]:
    """Seconds of the sweep (executor already up) and its rows."""
    start = time.perf_counter()
    run_sweep(sweep, executor, output=output, engine=engine, fresh=True)
    return time.perf_counter() - start, read_table(output)[0]


def dask_task_overhead(executor: DaskExecutor, tasks: int = 400) -> float:
    """Seconds per no-op task on the cluster: submit, run, gather (median of 3)."""
    times = []
    for repeat in range(3):
        start = time.perf_counter()
        futures = executor.client.map(abs, range(repeat * tasks, (repeat + 1) * tasks), pure=False)
        executor.client.gather(futures)
        times.append((time.perf_counter() - start) / tasks)
        del futures
    return sorted(times)[1]


def compare(name: str, sweep: Sweep, scalar_sweep: Sweep) -> None:
    """The three runs of ``sweep`` (the scalar loop on ``scalar_sweep``, a part of it
    when it would take too long, timed per point), their rates, and their rows checked."""
    work = sweep.slider_periods
    print(f"\n{name}: {sweep.size} points x {sweep.settle_periods + sweep.periods} periods = {work:,} "
          f"slider-periods, {sweep.chunks} chunks of {sweep.chunk_size}")
    rows: list[tuple[str, float, float]] = []
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder)
        seconds, reference = timed(scalar_sweep, SerialExecutor(), out / "scalar.parquet", "scalar")
        scalar_rate = scalar_sweep.slider_periods / seconds
        rows.append((f"(a) scalar loop, 1 process ({scalar_sweep.size} points)", work / scalar_rate, 0.0))
        results = {}
        overhead = math.nan
        for workers in (1, 2):
            start = time.perf_counter()
            with DaskExecutor(workers=workers) as executor:
                executor.load_engine()  # what a sweep does before its first chunk
                startup = time.perf_counter() - start
                seconds, results[workers] = timed(sweep, executor, out / f"dask{workers}.parquet", "compiled")
                if workers == 2:
                    overhead = dask_task_overhead(executor)
            rows.append((f"({'b' if workers == 1 else 'c'}) compiled engine, Dask {workers} worker(s)", seconds,
                         startup))
    for column, values in results[1].items():
        assert np.array_equal(values, results[2][column]), column
    share = reference["point"].size
    worst = float(np.max(np.abs(results[1]["mean_velocity"][:share] - reference["mean_velocity"])
                         / np.maximum(np.abs(reference["mean_velocity"]), 1e-300)))
    base = rows[0][1]
    print(f"{'run':52s} {'seconds':>8s} {'points/s':>10s} {'slider-periods/s':>17s} {'speedup':>8s} "
          f"{'cluster start':>14s}")
    for label, seconds, startup in rows:
        print(f"{label:52s} {seconds:8.2f} {sweep.size / seconds:10,.0f} {work / seconds:17,.0f} "
              f"{base / seconds:7.1f}x {startup:13.1f}s")
    print(f"rows equal: (b) == (c) bit for bit; (b) vs (a) largest relative difference of the mean speed "
          f"{worst:.1e} (the periodic shortcut's rounding)")
    print(f"Dask per-task overhead (no-op tasks, 2 workers, submit + run + gather): {overhead * 1e3:.2f} ms")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="sweeps 10 times smaller (a smoke run)")
    args = parser.parse_args()
    text = SWEEP.replace("samples: 40", "samples: 4") if args.quick else SWEEP
    sweep = parse_sweep(text, "bench/sweep.py")
    compare("grid sweep", sweep, sweep)
    irregular_text = IRREGULAR.replace("samples: 20000", "samples: 2000") if args.quick else IRREGULAR
    irregular = parse_sweep(irregular_text, "bench/sweep.py")
    # the scalar loop on the first chunk only (same points, same order): it takes minutes per chunk
    first = parse_sweep(irregular_text.replace("samples: 20000", "samples: 2000"), "bench/sweep.py")
    compare("irregular population", irregular, first)
    project(dask_overhead_of_two())


def dask_overhead_of_two() -> float:
    """Dask's per-task cost on a local cluster of 2 workers (for the 64-core projection)."""
    with DaskExecutor(workers=2) as executor:
        return dask_task_overhead(executor)


def makespan(costs: list[float], cores: int, overhead: float) -> float:
    """Wall time of tasks of ``costs`` handed out in order to ``cores`` workers as
    they free up, each task also costing ``overhead`` (Dask's own, per task)."""
    free = [0.0] * cores
    for cost in costs:
        heapq.heapreplace(free, free[0] + cost + overhead)
    return max(free)


def project(overhead: float, cores: int = 64) -> None:
    """The shipped example on ``cores`` cores: cut into ``cores`` and into
    4 x ``cores`` chunks, each chunk timed in this process, then handed out
    to ``cores`` workers as they free up (:func:`makespan`)."""
    size = load_sweep(CONVEYOR).size
    for tasks in (cores, 4 * cores):
        example = load_sweep(CONVEYOR, chunk_size=math.ceil(size / tasks))
        costs = []
        for index in range(example.chunks):
            start = time.perf_counter()
            run_chunk(example, index, "compiled")
            costs.append(time.perf_counter() - start)
        total = sum(costs)
        estimate = makespan(costs, cores, overhead)
        print(f"shipped example {CONVEYOR.name}, {example.size} points in {example.chunks} chunks of "
              f"{example.chunk_size}: {total:.2f} s in one process (chunk mean {total / example.chunks:.3f} s, "
              f"slowest {max(costs):.3f} s); on {cores} cores about {estimate:.2f} s "
              f"({total / estimate:.0f}x), plus cluster start-up and the Parquet join")


if __name__ == "__main__":
    main()
