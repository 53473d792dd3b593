"""Benchmark of the exact core and the U relation (issue 2).

Measures, in one run on this machine:
  (a) single-slider throughput in excitation periods per wall-clock second,
      with the inputs changed at random every few periods, against the
      scipy solve_ivp-with-events reference at rtol 1e-10 on the same
      schedule (ratio, and the largest difference of x and v);
  (b) the wall time of a 101 x 101 U map;
  (c) how well simulated mean speeds match the exact U (relative error);
  (d) the long-run phase error: after a million periods of the paper's case
      started at t0 in {0, 1e6, 2e9} s, the largest error of a slip start
      against its exact time t0 + (n + theta_A/(2 pi))/f, in units in the last
      place of t, and of the displacement per period against the exact D
      (both exact values from mpmath, see test/reference_exact.py);
  (e) a flight case of issue 11 (Gamma = 2, vibration angle 30 degrees, mu = 0.5,
      plastic landings with a Coulomb impulse: one lift-off and one landing
      every period): the core's periods per wall-clock second against the
      independent solve_ivp reference of test/reference_general.py (rtol 1e-12)
      on the same case, their ratio, and how far apart the two runs end.
Timings are medians of repeated runs; the machine is shared and noisy, so the
ratio measured in the same run is the figure to trust.  Prints figures only:
a benchmark never passes or fails on timing.

Run: make bench   (or .venv/bin/python bench/physics.py [--quick])
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import numpy as np

from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.urelation import u_grid, u_map
from friction_sim.core.model.commands import Command
from friction_sim.core.model.dimensionless import (
    amplitude_for,
    amplitude_for_throw,
    dimensional_speed,
    drive_force_for,
    throw_number,
)
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.simulation import random_schedule, run_schedule, simulate

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "test"))  # the test-only reference
from _timing import median_time
from reference import ReferenceInputs, reference_solution
from reference_exact import paper_case_slip, ulps_from_exact

PARAMS = SliderParams()
FREQUENCY = 50.0


def at_once(schedule: list[Command]) -> list[tuple[float, dict[str, float]]]:
    """The schedule's changes merged per instant (commands at one time take
    effect together, as the node and run_schedule apply them)."""
    merged: dict[float, dict[str, float]] = {}
    for command in schedule:
        merged.setdefault(command.t, {}).update(command.values)
    return sorted(merged.items())


def run_core(changes: list[tuple[float, dict[str, float]]], duration: float) -> Slider:
    slider = Slider(PARAMS, Inputs(), event_log_size=1000)
    for t, values in changes:
        slider.advance_to(t)
        slider.set_inputs(**values)
    slider.advance_to(duration)
    return slider


def reference_schedule(schedule: list[Command]) -> list[tuple[float, ReferenceInputs]]:
    pieces = [(0.0, ReferenceInputs())]
    current = Inputs()
    for t, values in at_once(schedule):
        current = current.replace(**values)
        pieces.append((t, ReferenceInputs(
            current.drive_force, current.excitation_amplitude, current.excitation_frequency,
            current.external_force_x, current.external_force_z)))
    return pieces


def moving_schedule(rng: np.random.Generator, duration: float) -> list[Command]:
    """Random commands every ~4 periods that keep the slider slipping every
    period (phi in [0.6, 0.95], a in [0.35, 0.8]): the costly case."""
    commands, t = [], 0.0
    while (t := t + rng.exponential(4.0 / FREQUENCY)) < duration:
        commands.append(Command(t, "parameters", {
            "drive_force": float(rng.uniform(0.6, 0.95)), "excitation_amplitude": float(rng.uniform(3.5, 8.0)),
            "excitation_frequency": float(rng.uniform(40.0, 60.0))}))
    return commands


def throughput(quick: bool, moving: bool) -> None:
    rng = np.random.default_rng(2026)
    periods_core = 2_000 if quick else 20_000
    periods_ref = 40 if quick else 200
    duration = periods_core / FREQUENCY
    if moving:
        schedule = moving_schedule(rng, duration)
        title = "slipping every period: phi in [0.6, 0.95], a in [0.35, 0.8], f in [40, 60] Hz"
    else:
        schedule = random_schedule(rng, duration, frequency=FREQUENCY, mean_periods=4.0)
        title = "anything goes: phi in [-1.2, 1.2], a in [0, 0.8], f in [25, 100] Hz"
    # The random frequencies make "periods" a matter of phase: count them exactly.
    changes = at_once(schedule)
    core_time = median_time(lambda: run_core(changes, duration), 3 if quick else 9)
    slider = run_core(changes, duration)
    phase_periods = _phase_periods(schedule, duration)
    counts = slider.event_counts

    ref_duration = periods_ref / FREQUENCY
    ref_sched = [c for c in schedule if c.t < ref_duration]
    grid = np.linspace(0.0, ref_duration, 20 * periods_ref + 1)
    reference_solution(1.0, 0.1, 10.0, reference_schedule(ref_sched[:3]), grid[:50], rtol=1e-10)  # warm-up
    ref_time = median_time(
        lambda: reference_solution(1.0, 0.1, 10.0, reference_schedule(ref_sched), grid, rtol=1e-10),
        1 if quick else 3,
    )
    ref = reference_solution(1.0, 0.1, 10.0, reference_schedule(ref_sched), grid, rtol=1e-10)
    exact = run_schedule(Slider(PARAMS, Inputs()), ref_sched, grid)
    ref_periods = _phase_periods(ref_sched, ref_duration)
    core_rate = phase_periods / core_time
    ref_rate = ref_periods / ref_time
    print(f"(a) single-slider throughput, inputs changed at random every ~4 periods; {title}")
    print(f"    schedule: {len(changes)} input changes over {phase_periods:.0f} excitation periods "
          f"({duration:g} s simulated); events: "
          + ", ".join(f"{k.value} {n}" for k, n in counts.items()))
    print(f"    exact core:            {core_rate:12,.0f} periods/s  (median of repeats, {core_time:.3f} s)")
    print(f"    solve_ivp reference:   {ref_rate:12,.0f} periods/s  ({ref_periods:.0f} periods, rtol 1e-10)")
    print(f"    ratio core/reference:  {core_rate / ref_rate:12,.0f} x   (targets: >= 100,000 periods/s, >= 100 x)")
    dx = np.max(np.abs(exact.x - ref.x))
    dv = np.max(np.abs(exact.v - ref.v))
    print(f"    largest difference over {grid.size} samples: |dx| = {dx:.3e} m "
          f"({dx / np.max(np.abs(ref.x)):.2e} of max|x|), |dv| = {dv:.3e} m/s "
          f"({dv / np.max(np.abs(ref.v)):.2e} of max|v|)")


def _phase_periods(schedule: list[Command], duration: float) -> float:
    """Excitation periods elapsed (phase / 2 pi) under a schedule of frequencies."""
    total, t, f = 0.0, 0.0, FREQUENCY
    for when, values in at_once(schedule):
        total += (when - t) * f
        t, f = when, values.get("excitation_frequency", f)
    return total + (duration - t) * f


def map_time() -> None:
    u_grid(101)  # warm-up (imports, allocations)
    elapsed = median_time(lambda: u_grid(101), 9)
    print(f"(b) 101 x 101 U map: {elapsed * 1e3:.1f} ms median of 9   (target <= 200 ms)")


def mean_speed_accuracy(quick: bool) -> None:
    rng = np.random.default_rng(7)
    worst = 0.0
    points = 10 if quick else 40
    checked = 0
    while checked < points:
        phi, a = rng.uniform(0.05, 0.999), rng.uniform(0.02, 0.95)
        if u_map(phi, a) < 1e-4:
            continue
        inputs = Inputs(drive_force=drive_force_for(phi, PARAMS.mu, PARAMS.weight),
                        excitation_amplitude=amplitude_for(a, PARAMS.weight), excitation_frequency=FREQUENCY)
        result = simulate(PARAMS, inputs, 1.0, settle=0.1)
        expected = dimensional_speed(u_map(phi, a), FREQUENCY, PARAMS.gravity, PARAMS.mu)
        worst = max(worst, abs(result.mean_velocity - expected) / expected)
        checked += 1
    print(f"(c) simulated mean speed vs exact U at {points} random (phi, a) with U >= 1e-4: "
          f"largest relative error {worst:.2e}   (target <= 1e-9)")


def long_run_phase_error(quick: bool) -> None:
    from friction_sim.core.model.events import EventKind

    periods = 100_000 if quick else 1_000_000
    fraction, _, travel = paper_case_slip()
    print(f"(d) long-run phase error, paper's case, {periods:,} periods from t0 "
          "(slip starts vs exact t0 + (n + theta_A/(2 pi))/f; x at the n-th start vs n*D):")
    for t0 in (0.0, 1e6, 2e9):
        slider = Slider(t0=t0, event_log_size=0)
        started = time.perf_counter()
        starts = [(e.t, e.x) for e in slider.advance_to(t0 + periods / FREQUENCY) if e.kind is EventKind.SLIP_START]
        elapsed = time.perf_counter() - started
        t, x = np.array(starts).T
        n = np.arange(t.size, dtype=float)
        ulps = ulps_from_exact(t, t0, FREQUENCY, n, fraction)
        drift = np.max(np.abs(x[1:] - n[1:] * travel) / (n[1:] * travel))
        print(f"    t0 = {t0:5g} s: {t.size:,} slip starts (expected {periods:,}); largest error "
              f"{ulps.max():.2f} ulp of t ({np.max(ulps * np.spacing(t)):.1e} s), last {ulps[-1]:.2f} ulp; "
              f"displacement per period exact to {drift:.1e} (target: a few ulp, 1e-12)  [{elapsed:.1f} s]")


#: (e): Gamma = 2 on a level track, vibration at 30 degrees, mu = 0.5, no drive, plastic landings.
FLIGHT_PARAMS = SliderParams(mass=1.0, mu=0.5, gravity=10.0, excitation_angle=30.0)
FLIGHT_INPUTS = Inputs(drive_force=0.0, excitation_amplitude=amplitude_for_throw(2.0, FLIGHT_PARAMS.normal_weight),
                       excitation_frequency=FREQUENCY)


def flight_throughput(quick: bool) -> None:
    from friction_sim.core.model.events import EventKind

    from reference_general import GeneralModel
    from reference_general import solve as reference_general_solve

    periods_core = 2_000 if quick else 20_000
    periods_ref = 5 if quick else 20
    duration = periods_core / FREQUENCY

    def run_core() -> Slider:
        slider = Slider(FLIGHT_PARAMS, FLIGHT_INPUTS, event_log_size=1000)
        slider.advance_to(duration)
        return slider

    run_core()  # warm-up
    core_time = median_time(run_core, 3 if quick else 9)
    counts = run_core().event_counts
    model = GeneralModel.from_core(FLIGHT_PARAMS, FLIGHT_INPUTS)
    ref_duration = periods_ref / FREQUENCY
    reference_general_solve(model, 1.0 / FREQUENCY)  # warm-up (imports)
    ref_time = median_time(lambda: reference_general_solve(model, ref_duration), 3)
    ref = reference_general_solve(model, ref_duration)
    check = Slider(FLIGHT_PARAMS, FLIGHT_INPUTS, event_log_size=None)
    check.advance_to(ref_duration)
    core_rate, ref_rate = periods_core / core_time, periods_ref / ref_time
    landings, lift_offs = counts[EventKind.LANDING], counts[EventKind.LIFT_OFF]
    gamma = throw_number(FLIGHT_INPUTS.excitation_amplitude, FLIGHT_PARAMS.normal_weight)
    print(f"(e) flight case: Gamma = {gamma:g}, vibration angle "
          f"{FLIGHT_PARAMS.excitation_angle:g} deg, mu = {FLIGHT_PARAMS.mu:g}, Fd = 0, e = 0, impulsive landings")
    print(f"    {periods_core:,} periods: " + ", ".join(f"{k.value} {n}" for k, n in counts.items())
          + f"  ({landings / periods_core:.3f} landings and {lift_offs / periods_core:.3f} lift-offs per period;"
          f" flight fraction {run_core().flight_time / duration:.3f})")
    print(f"    exact core:            {core_rate:12,.0f} periods/s  (median of repeats, {core_time:.3f} s)")
    print(f"    solve_ivp reference:   {ref_rate:12,.0f} periods/s  ({periods_ref} periods, rtol 1e-12, "
          f"{len(ref.events)} events)")
    print(f"    ratio core/reference:  {core_rate / ref_rate:12,.0f} x   (targets: >= 50,000 periods/s, >= 100 x)")
    t_core = [e.t for e in check.events]
    t_ref = [e.t for e in ref.events]
    if len(t_core) == len(t_ref):
        dt = max(abs(a - b) for a, b in zip(t_core, t_ref))
        end = ref.evaluate([ref_duration])["x"][0]
        print(f"    over the reference's {periods_ref} periods: {len(t_ref)} events in both, largest |dt| = "
              f"{dt:.1e} s, x at the end {end:.6e} m, |dx| = {abs(check.state().x - end):.1e} m")
    else:
        print(f"    over the reference's {periods_ref} periods: {len(t_core)} core events, "
              f"{len(t_ref)} reference events")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller runs (for a smoke test)")
    args = parser.parse_args()
    print(f"bench/physics.py  (python {sys.version.split()[0]}, numpy {np.__version__})")
    throughput(args.quick, moving=True)
    throughput(args.quick, moving=False)
    map_time()
    mean_speed_accuracy(args.quick)
    long_run_phase_error(args.quick)
    flight_throughput(args.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())
