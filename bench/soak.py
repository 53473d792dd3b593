"""Soak test of a long lockstep run: does the feeder keep its pace and its memory for a simulated hour?

The demo's feeder (config/demo.yaml's plant, slider and controller with the
demo's controller parameters, in this process on one executor) runs in
lockstep for ``--minutes`` simulated minutes (60), the controller regulating
throughout: its target starts at 0.1 mm/s and steps every simulated minute
(t = 60 k) through 0.3, 0.15, 0.1, 0.3, ... mm/s.  The slider records at
``--log-rate`` (100 Hz by default: at the node's default 1 kHz an hour's
recording is of the order of 1 GB, which measures the disk rather than the
run); the demo's accelerometer is left off for the same reason (the
force-actuated plant's controller does not read it).  It prints:

  * every simulated minute (the progress callback: the driver waits for the
    slider at each target step, and at the end): the minute, wall seconds
    since t = 0, the process's RSS (VmRSS) and its ratio to the RSS after the
    first minute (a leak grows it minute by minute);
  * at the end: the achieved factor (simulated s / wall s), the file's size,
    whether RSS stayed within +10 % of the first minute's value afterwards
    (its largest growth, and the mean growth per simulated minute), and
    ``friction-sim replay FILE --verify`` (exit code and last line): the
    recording re-simulates exactly;
  * then the same hour again into a second file, and whether the two
    recordings' ``recording_digest`` are identical (else the topics that
    differ): lockstep gives the same run every time (``--once`` skips it).

Timing never fails it: the exit code is 1 only when verify fails or the two
recordings differ.

Run: make bench   (or .venv/bin/python bench/soak.py [--minutes 60] [--log-rate 100] [--output DIR] [--once])
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(1, 100)))

import rclpy

from friction_sim.core.model.commands import Command
from friction_sim.experiment.job import ExperimentSpec, Status
from friction_sim.experiment.runner import run_experiment
from friction_sim.experiment.scenario import load_scenario
from friction_sim.io.digest import differences, recording_digest
from friction_sim.ros.heap import limit_heap_arenas

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "config" / "demo.yaml"
FRICTION_SIM = Path(sys.executable).parent / "friction-sim"
#: One namespace for both runs: the digests include the topic names.
NAMESPACE = "/bench_soak"
#: The targets [m/s] the controller cycles through, one per simulated minute.
TARGETS = (0.1e-3, 0.3e-3, 0.15e-3)
#: Allowed RSS growth after the first minute (printed, never failing).
RSS_GROWTH = 0.10


def rss_mb() -> float:
    """This process's resident set size [MB] (VmRSS of /proc/self/status)."""
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024 / 1e6
    return float("nan")


def soak_spec(minutes: int, log_rate: float, path: Path) -> ExperimentSpec:
    """The demo feeder in lockstep for ``minutes`` simulated minutes, the target stepping each minute."""
    demo = load_scenario(DEMO)
    schedule = [Command(60.0 * k, "target_speed", {"target_speed": TARGETS[k % len(TARGETS)]})
                for k in range(1, minutes)]
    return ExperimentSpec(
        duration=60.0 * minutes, schedule=schedule, plant=demo.params, inputs=demo.inputs, controller=True,
        controller_parameters={**(demo.controller or {}), "target_speed": TARGETS[0]}, log_path=path,
        log_rate=log_rate, name="soak", lockstep=True)


@dataclasses.dataclass
class Soak:
    """What one soak run measured: wall times [s] and RSS [MB] per simulated minute."""

    path: Path
    total_wall: float = 0.0
    run_wall: float = 0.0
    rss: list[float] = dataclasses.field(default_factory=list)  # after minute 1, 2, ...

    def growth(self) -> float:
        """Largest RSS after the first minute relative to the first minute's, minus 1 (0: none)."""
        return max((value / self.rss[0] - 1.0 for value in self.rss[1:]), default=0.0)

    def per_minute(self) -> float:
        """Mean RSS growth [MB] per simulated minute after the first (what an hour multiplies)."""
        return (self.rss[-1] - self.rss[0]) / (len(self.rss) - 1) if len(self.rss) > 1 else 0.0


def soak(spec: ExperimentSpec, *, verbose: bool) -> Soak:
    """Run ``spec`` in lockstep; print a line per simulated minute when ``verbose``."""
    assert spec.log_path is not None
    result = Soak(spec.log_path)
    zero: list[float] = []
    targets: list[float | None] = []  # the target in force from each progress call on (the step just made)

    def progress(status: Status) -> None:
        now = time.perf_counter()
        if not zero:  # t = 0: nodes up and connected, the recording started
            zero.append(now)
            targets.append(status.target)
            if verbose:
                print(f"  t = 0 after {now - started:.1f} s of start-up: RSS {rss_mb():.1f} MB", flush=True)
            return
        result.rss.append(rss_mb())
        if verbose:
            held = targets[-1] if targets[-1] is not None else float("nan")
            print(f"  minute {round(status.t / 60.0):3d}: wall {now - zero[0]:8.1f} s, RSS {result.rss[-1]:7.1f} MB "
                  f"({result.rss[-1] / result.rss[0] - 1.0:+6.1%} vs minute 1); mean speed "
                  f"{status.mean_speed * 1e3:.4f} mm/s, target over the minute {held * 1e3:.3f} mm/s", flush=True)
        targets.append(status.target)

    started = time.perf_counter()
    run_experiment(spec, namespace=NAMESPACE, progress=progress)
    ended = time.perf_counter()
    result.total_wall = ended - started
    result.run_wall = ended - (zero[0] if zero else started)
    return result


def verify(path: Path) -> tuple[int, str]:
    """``friction-sim replay PATH --verify`` in a child process: its exit code and last output line."""
    done = subprocess.run([str(FRICTION_SIM), "replay", str(path), "--verify"], capture_output=True, text=True,
                          check=False)
    lines = (done.stdout.strip() or done.stderr.strip()).splitlines()
    return done.returncode, lines[-1] if lines else "(no output)"


def report(result: Soak, duration: float, log_rate: float) -> None:
    """The end-of-run figures: factor, file size, RSS growth."""
    size = result.path.stat().st_size / 1e6
    print(f"factor {duration / result.run_wall:.2f} (simulated {duration:g} s in {result.run_wall:.1f} s of wall "
          f"time from t = 0; {duration / result.total_wall:.2f} end to end, start-up included)")
    print(f"file {result.path.name}: {size:.1f} MB at log_rate {log_rate:g} Hz ({size / (duration / 60):.2f} MB per "
          f"simulated minute; an hour at 1 kHz: at most ~{size * 1000 / log_rate * 3600 / duration:.0f} MB, this "
          "file scaled, though only its states grow with the rate)")
    if len(result.rss) < 2:
        print(f"RSS: {len(result.rss)} minute(s) seen, nothing to compare after the first")
        return
    growth = result.growth()
    verdict = "within" if growth <= RSS_GROWTH else "NOT within"
    print(f"RSS after the first minute: {verdict} +{RSS_GROWTH:.0%} of minute 1's {result.rss[0]:.1f} MB "
          f"(largest growth {growth:+.1%}, final {result.rss[-1]:.1f} MB; {result.per_minute():+.2f} MB per simulated "
          "minute after the first)")


def main() -> int:
    """Soak once (and again to compare); 1 if verify fails or the two recordings differ."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--minutes", type=int, default=60, help="simulated minutes (60)")
    parser.add_argument("--log-rate", type=float, default=100.0,
                        help="state samples recorded per simulated second (100: an hour at 1 kHz is ~1 GB)")
    parser.add_argument("--output", type=Path, metavar="DIR", help="keep the recordings in DIR (default: a temp dir)")
    parser.add_argument("--once", action="store_true", help="skip the second run and the digest comparison")
    args = parser.parse_args()
    if args.minutes < 1 or args.log_rate <= 0:
        parser.error("--minutes must be >= 1 and --log-rate > 0")
    duration = 60.0 * args.minutes
    print(f"bench/soak.py  (ROS_DOMAIN_ID {os.environ['ROS_DOMAIN_ID']}, localhost only, namespace {NAMESPACE})")
    print(f"The demo feeder in lockstep for {args.minutes} simulated minute(s), the target stepping every minute "
          f"through {', '.join(f'{t * 1e3:g}' for t in TARGETS)} mm/s; recording at {args.log_rate:g} Hz "
          "(at the default 1 kHz an hour's file is ~10x larger, of the order of 1 GB: the disk, not the run, "
          "would be measured). Figures only; "
          "exit 1 only if verify fails or the two runs' recordings differ.")
    ok = True
    limit_heap_arenas()  # (as friction-sim and the node executables do, before any thread starts)
    rclpy.init(args=[])
    try:
        with tempfile.TemporaryDirectory() as temporary:
            folder = args.output if args.output is not None else Path(temporary)
            folder.mkdir(parents=True, exist_ok=True)
            print("\n=== run 1")
            first = soak(soak_spec(args.minutes, args.log_rate, folder / "soak_1.mcap"), verbose=True)
            report(first, duration, args.log_rate)
            code, line = verify(first.path)
            print(f"replay --verify: exit {code}: {line}")
            if code != 0:
                print(f"!!! VERIFY FAILED for {first.path}")
                ok = False
            if not args.once:
                print("\n=== run 2 (the same run again, into a second file)")
                second = soak(soak_spec(args.minutes, args.log_rate, folder / "soak_2.mcap"), verbose=False)
                report(second, duration, args.log_rate)
                if first.rss and second.rss:
                    print(f"RSS over both runs: run 2 ended at {second.rss[-1]:.1f} MB, "
                          f"{second.rss[-1] / first.rss[0] - 1.0:+.1%} vs run 1's minute 1 ({first.rss[0]:.1f} MB)")
                found = differences(recording_digest(first.path), recording_digest(second.path))
                if found:
                    print("!!! RECORDING DIGESTS DIFFER between run 1 and run 2:")
                    for entry in found:
                        print(f"!!!   {entry}")
                    ok = False
                else:
                    print("recording digests of run 1 and run 2: identical")
    finally:
        rclpy.try_shutdown()
    print("\nOK" if ok else "\nFAILED (see !!! above)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
