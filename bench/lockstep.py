"""Benchmark of lockstep runs: how fast, and whether every run is the same run.

In lockstep the slider advances simulation time only when its participants
(the controller, and the experiment driver as ``scheduler``) have answered, so
a scenario runs as fast as the CPU allows and gives the same recording every
time.  For config/acceptance_7_resonant_steps.yaml and config/demo.yaml, each
forced into lockstep and run ``--repeats`` times in this process (slider,
controller and driver on one executor, one fixed namespace, so the recordings'
topic names agree), it prints:

  * the run phase's achieved factor: simulated seconds / wall seconds from the
    first progress call (t = 0, the nodes up and connected) to the return of
    ``run_experiment`` (the recording finished): median, min and max;
  * the end-to-end factor (node start-up and discovery included): median;
  * the same-run baseline: ``record_offline`` of the same plant, initial
    inputs, slider commands of the schedule, duration and log rate: the
    open-loop core and the recorder, with neither ROS nor controller nor
    accelerometer, measured in the same process just after; its median factor
    and the ratio lockstep / offline (what the nodes, DDS and the controller
    cost on top of the core);
  * each repeat's ``run_digest`` and whether they are all identical (else the
    topics whose digests differ).

Prints figures only: timing never passes or fails (the machine is shared and
noisy).  A digest mismatch is a correctness failure, not a timing one: it is
printed loudly and the exit code is 1.

Run: make bench   (or .venv/bin/python bench/lockstep.py [--repeats 3])
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import random
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(1, 100)))

import rclpy

from friction_sim.core.model.commands import CONTROLS, RESET
from friction_sim.experiment.job import ExperimentSpec, Status
from friction_sim.experiment.offline import record_offline
from friction_sim.experiment.runner import run_experiment
from friction_sim.experiment.scenario import load_scenario
from friction_sim.io.digest import differences, recording_digest, run_digest
from friction_sim.ros.heap import limit_heap_arenas

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = (ROOT / "config" / "acceptance_7_resonant_steps.yaml", ROOT / "config" / "demo.yaml")
#: One namespace for every run: the digests include the topic names.
NAMESPACE = "/bench_lockstep"


@dataclasses.dataclass(frozen=True)
class Repeat:
    """One lockstep run: its wall times [s] and its recording."""

    run_wall: float  # first progress call (t = 0) to the return of run_experiment
    total_wall: float  # the call of run_experiment to its return (start-up and discovery included)
    path: Path
    digest: str


def lockstep_run(spec: ExperimentSpec, path: Path) -> Repeat:
    """Run ``spec`` in lockstep, recording to ``path``; time the run phase and the whole call."""
    spec = dataclasses.replace(spec, lockstep=True, log_path=path)
    first: list[float] = []

    def progress(status: Status) -> None:
        if not first:  # (the first call is at t = 0: nodes up, connected, recording started)
            first.append(time.perf_counter())

    started = time.perf_counter()
    run_experiment(spec, namespace=NAMESPACE, progress=progress)
    ended = time.perf_counter()
    run_started = first[0] if first else started
    return Repeat(ended - run_started, ended - started, path, run_digest(path))


def offline_run(spec: ExperimentSpec, path: Path) -> float:
    """Wall time [s] of ``record_offline`` of the spec's plant, inputs, slider commands,
    duration and log rate (no ROS, no controller): the core and the recorder alone."""
    commands = [command for command in spec.schedule
                if command.for_slider and (command.name not in CONTROLS or command.name == RESET)]
    started = time.perf_counter()
    record_offline(path, spec.plant, spec.inputs, commands, spec.duration, spec.log_rate)
    return time.perf_counter() - started


def bench_scenario(scenario_path: Path, repeats: int, folder: Path) -> bool:
    """Measure one scenario (see the module) and print its figures; False on a digest mismatch."""
    scenario = load_scenario(scenario_path)
    spec = scenario.spec()
    name = scenario.name
    print(f"\n=== {scenario_path.relative_to(ROOT)}: {spec.duration:g} simulated s, "
          f"{'closed' if spec.controller else 'open'} loop, log_rate {spec.log_rate:g} Hz, "
          f"{len(spec.schedule)} scheduled commands, {len(spec.operator)} operator actions, "
          f"lockstep forced on (the file says {scenario.lockstep})")
    runs = [lockstep_run(spec, folder / f"{name}_{k}.mcap") for k in range(repeats)]
    factors = [spec.duration / run.run_wall for run in runs]
    totals = [spec.duration / run.total_wall for run in runs]
    offline = [offline_run(spec, folder / f"{name}_offline.mcap") for _ in range(repeats)]
    offline_factor = spec.duration / statistics.median(offline)
    factor = statistics.median(factors)
    print(f"run phase (t = 0 to return): factor {factor:.2f} median (min {min(factors):.2f}, "
          f"max {max(factors):.2f}) over {repeats} repeats; "
          f"wall {', '.join(f'{run.run_wall:.2f}' for run in runs)} s")
    print(f"end to end (start-up and discovery included): factor {statistics.median(totals):.2f} median; "
          f"wall {', '.join(f'{run.total_wall:.2f}' for run in runs)} s")
    print(f"same-run baseline, record_offline (core + recorder, no ROS, no controller): factor "
          f"{offline_factor:.1f} median; lockstep / offline = {factor / offline_factor:.3f}")
    for k, run in enumerate(runs):
        print(f"digest of repeat {k + 1}: {run.digest}")
    if len({run.digest for run in runs}) == 1:
        print(f"digests: identical ({repeats} repeats)")
        return True
    reference = recording_digest(runs[0].path)
    print("!" * 100)
    print(f"!!! DIGEST MISMATCH in {name}: the lockstep repeats did not record the same run")
    for k, run in enumerate(runs[1:], start=2):
        if run.digest == runs[0].digest:
            print(f"!!! repeat 1 vs {k}: identical")
            continue
        for line in differences(reference, recording_digest(run.path)):
            print(f"!!! repeat 1 vs {k}: {line}")
    print("!" * 100)
    return False


def main() -> int:
    """Bench every scenario; 1 if any scenario's repeats recorded different runs (timing never fails it)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=3, help="lockstep runs per scenario (3)")
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")
    print(f"bench/lockstep.py  (ROS_DOMAIN_ID {os.environ['ROS_DOMAIN_ID']}, localhost only, namespace {NAMESPACE})")
    print("Factor = simulated s / wall s, in lockstep (as fast as the CPU allows); the baseline is record_offline "
          "of the same plant, run in this process just after (no ROS, no controller, no accelerometer). "
          "Digests: run_digest of each repeat's recording (wall-clock figures left out). Figures only; "
          "a digest mismatch exits 1.")
    same = True
    limit_heap_arenas()  # (as friction-sim and the node executables do, before any thread starts)
    rclpy.init(args=[])
    try:
        with tempfile.TemporaryDirectory() as folder:
            for path in SCENARIOS:
                same = bench_scenario(path, args.repeats, Path(folder)) and same
    finally:
        rclpy.try_shutdown()
    if not same:
        print("\nFAILED: a scenario's lockstep repeats recorded different runs (see above)")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
