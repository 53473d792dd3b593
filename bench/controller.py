"""Benchmark of the mean-speed controller.

* acceptance (issues 4, 11, 21): the acceptance cases in closed loop over real
  topics, slider and controller in this process, real time.  Prints settling
  time (excitation periods), overshoot and steady error per step, and draws
  target, measured mean speed and Pa (the drive level on a resonant plant)
  against time for every case into one PNG.  The cases on the resonant exciter
  (7-9) run twice: with the inner loop, and with today's law through the
  exciter's steady gain (``inner_loop: false``) for comparison.
* flood (issue 10): the ``controller`` console script in its own process,
  regulating (this process sends it mean_velocity samples at 50 Hz, as a
  slider at 50 Hz would); its CPU share (from /proc) over windows of a few
  seconds, regulating only ("idle") and then under a flood of 10,000
  drive_force commands per second, half of them NaN or inf, from a third process
  (test/ros/test_controller_flood.py): medians of both and their ratio, and
  how many excitation_amplitude messages it published per second.  A process
  that subscribes and never takes a message is measured alongside: what
  receiving the flood costs any node (DDS), the floor of the controller's.

Prints figures only; nothing passes or fails here.  On a shared machine the
CPU figures are noisy: compare the ratio, and rerun.

Run: make bench   (or .venv/bin/python bench/controller.py [--part flood] [--png out/controller.png])
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import random
import statistics
import subprocess
import sys
import time
import uuid
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(1, 100)))
os.environ.setdefault("MPLBACKEND", "Agg")

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistStamped
from rclpy.executors import SingleThreadedExecutor
from std_msgs.msg import Float64

from friction_sim.experiment.acceptance import Verdict, acceptance_scenarios, judge
from friction_sim.experiment.job import ExperimentSpec
from friction_sim.experiment.report import command_label
from friction_sim.experiment.runner import ExperimentResult, run_experiment
from friction_sim.experiment.scenario import Scenario

BIN = Path(sys.executable).parent
FLOODER = Path(__file__).resolve().parents[1] / "test" / "ros_harness.py"
CLK_TCK = os.sysconf("SC_CLK_TCK")
TARGET = 3e-4  # m/s


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process ``pid`` so far [s]."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


class Watcher:
    """The controller's plant, as far as the controller can tell: mean_velocity
    samples at the target speed, one per 20 ms (50 Hz) with real-time stamps.
    Counts its excitation_amplitude messages and keeps its last diagnostics."""

    def __init__(self, namespace: str) -> None:
        self.node = rclpy.create_node("bench_watcher", namespace=namespace)
        self.amplitudes = 0
        self.status: dict[str, str] = {}
        self.node.create_subscription(Float64, "excitation_amplitude", self._on_amplitude, 100)
        self.node.create_subscription(DiagnosticArray, "diagnostics", self._on_diagnostics, 10)
        self._samples = self.node.create_publisher(TwistStamped, "mean_velocity", 10)
        self._sample = TwistStamped()
        self._sample.twist.linear.x = TARGET
        self.node.create_timer(0.02, self._publish_sample)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)

    def _publish_sample(self) -> None:
        self._sample.header.stamp.sec, self._sample.header.stamp.nanosec = divmod(time.monotonic_ns(), 10**9)
        self._samples.publish(self._sample)

    def _on_amplitude(self, msg: Float64) -> None:
        self.amplitudes += 1

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name == "controller":
                self.status = {kv.key: kv.value for kv in status.values} | {"level": str(status.level[0])}

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.05)


#: A process that only subscribes to drive_force and never takes a message:
#: what receiving the flood costs any node (DDS), whatever it does with it.
BARE_SUBSCRIBER = """
import sys, time, rclpy
from std_msgs.msg import Float64
rclpy.init()
node = rclpy.create_node("bench_bare", namespace=sys.argv[1])
node.create_subscription(Float64, "drive_force", lambda msg: None, 10)
while True:
    time.sleep(1.0)
"""


def windows(watcher: Watcher, pids: dict[str, int], count: int, seconds: float) -> dict[str, list[float]]:
    """CPU share of each process and the controller's amplitude messages per
    second (key ``amplitudes``) over ``count`` windows."""
    figures: dict[str, list[float]] = {name: [] for name in [*pids, "amplitudes"]}
    for _ in range(count):
        cpu = {name: cpu_seconds(pid) for name, pid in pids.items()}
        sent, start = watcher.amplitudes, time.monotonic()
        watcher.spin_for(seconds)
        elapsed = time.monotonic() - start
        for name, pid in pids.items():
            figures[name].append((cpu_seconds(pid) - cpu[name]) / elapsed)
        figures["amplitudes"].append((watcher.amplitudes - sent) / elapsed)
    return figures


def flood_bench(rate: int, count: int, seconds: float) -> None:
    ns = f"/bench_{uuid.uuid4().hex[:8]}"
    node = subprocess.Popen([str(BIN / "controller"), "--ros-args", "-r", f"__ns:={ns}", "-p", "plant_node:=''",
                             "-p", f"target_speed:={TARGET}"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True)
    bare = subprocess.Popen([sys.executable, "-c", BARE_SUBSCRIBER, ns])
    watcher = Watcher(ns)
    flooder = None
    pids = {"controller": node.pid, "bare subscriber": bare.pid}
    try:
        deadline = time.monotonic() + 20.0
        while watcher.amplitudes == 0 and time.monotonic() < deadline:
            watcher.spin_for(0.1)
        watcher.spin_for(1.0)
        idle = windows(watcher, pids, count, seconds)
        flooder = subprocess.Popen([sys.executable, str(FLOODER), ns, str(rate), str(count * seconds + 1.5), "mixed",
                                    "last"], stdout=subprocess.PIPE, text=True)
        assert flooder.stdout is not None
        flooder.stdout.readline()  # "flooding"
        watcher.spin_for(1.0)
        flooded = windows(watcher, pids, count, seconds)
        sent = int(flooder.communicate(timeout=60)[0].split()[-1])
        watcher.spin_for(2.5)  # the next diagnostics
    finally:
        for process in (flooder, bare):
            if process is not None and process.poll() is None:
                process.kill()
                process.communicate()
        node.terminate()
        node.communicate(timeout=15)
        watcher.executor.shutdown(timeout_sec=0.0)
        watcher.node.destroy_node()
    print(f"flood: {count} windows of {seconds:g} s each, idle (regulating on 50 samples/s) then also under "
          f"{rate} drive_force/s (half NaN/inf; {sent} sent)")
    for name in pids:
        idle_cpu, flood_cpu = statistics.median(idle[name]), statistics.median(flooded[name])
        ratio = f"{flood_cpu / idle_cpu:.1f}" if idle_cpu > 0 else "n/a (idle below the 10 ms resolution of /proc)"
        print(f"    {name} CPU share, median (min-max): idle {idle_cpu:.1%} ({min(idle[name]):.1%}-"
              f"{max(idle[name]):.1%}), flood {flood_cpu:.1%} ({min(flooded[name]):.1%}-{max(flooded[name]):.1%}); "
              f"ratio flood/idle {ratio}")
    print(f"    controller excitation_amplitude messages/s, median: idle {statistics.median(idle['amplitudes']):.0f}, "
          f"flood {statistics.median(flooded['amplitudes']):.0f}")
    keys = ("commands_accepted", "commands_rejected", "command_batches", "last_rejection", "drive_force")
    print("    controller diagnostics after the flood: "
          + ", ".join(f"{k} {watcher.status[k]}" for k in keys if k in watcher.status))
    print("    (the bare subscriber never takes a message: its share is what receiving the flood costs any node)")


def draw(runs: list[tuple[Scenario, ExperimentResult]], path: Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.0, 2.2 * len(runs)), layout="constrained")
    axes = fig.subplots(len(runs), 1)
    for ax, (case, result) in zip(axes, runs):
        t = [s for s, _ in result.mean_velocity]
        ax.plot(t, [v * 1e3 for _, v in result.mean_velocity], ".-", markersize=3, linewidth=0.8,
                label="measured mean speed")
        steps = [(0.0, case.initial_target or 0.0)] + [(c.t, c.values["target_speed"]) for c in result.commands
                                                       if c.name == "target_speed"]
        xs, ys = [], []
        for (t0, v0), (t1, _) in zip(steps, steps[1:] + [(case.duration, None)]):
            xs += [t0, t1]
            ys += [v0 * 1e3, v0 * 1e3]
        ax.plot(xs, ys, "k--", linewidth=1.0, label="target")
        ax.set_ylim(0.0, max(0.5, 1.3 * max((v * 1e3 for _, v in result.mean_velocity), default=0.5)))
        if "unreachable" in case.name:
            ax.set_ylim(0.0, 3.0)
        ax.set_ylabel("mean speed [mm/s]")
        ax.set_title(case.description, fontsize=10)
        right = ax.twinx()
        if result.drive:
            right.step([s for s, *_ in result.drive], [level for _, level, *_ in result.drive], where="post",
                       color="tab:red", linewidth=0.9, label="drive level")
            right.set_ylabel("drive level", color="tab:red")
            right.set_ylim(0.0, 1.0)
        else:
            if result.amplitude:
                right.step([s for s, _ in result.amplitude], [a for _, a in result.amplitude], where="post",
                           color="tab:red", linewidth=0.9, label="Pa")
            right.set_ylabel("Pa [N]", color="tab:red")
            right.set_ylim(0.0, 10.0)
        for command in result.commands:
            if command.name != "target_speed":
                ax.axvline(command.t, color="0.6", linewidth=0.8)
                ax.annotate(command_label(command), (command.t, ax.get_ylim()[1] * 0.9), fontsize=8,
                            xytext=(3, 0), textcoords="offset points")
        ax.legend(loc="upper left", fontsize=8)
    axes[-1].set_xlabel("simulation time [s]")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def variants(case: Scenario) -> list[tuple[str, ExperimentSpec]]:
    """The runs of a case: as shipped, and on a resonant plant also today's law
    through the steady gain (the inner loop off)."""
    spec = case.spec()
    if not case.params.resonant:
        return [("", spec)]
    today = dataclasses.replace(spec, controller_parameters={**spec.controller_parameters, "inner_loop": False,
                                                             "track_resonance": False})
    return [(" (inner loop)", spec), (" (today's law, drive through the steady gain)", today)]


def verdict_line(verdict: Verdict) -> str:
    """One judged expectation, in a line."""
    e, m = verdict.expectation, verdict.metrics
    if e.quantity == "amplitude_per_drive":
        what = f"amplitude per unit drive back to {verdict.target:.2f} m/s^2"
    else:
        what = f"target {verdict.target * 1e3:.2f} mm/s"
    return (f"    change at {e.t:.1f} s, {what}: within {e.within:.0%} after {m.settling_periods} periods "
            f"(limit {e.periods}); overshoot {m.overshoot:.1%}" + (f" (limit {e.overshoot:.0%})" if e.overshoot < 1
                                                                  else "")
            + f"; steady error {m.steady_error:.1e}  [{'met' if verdict.met else 'MISSED'}]")


def main() -> int:
    parser = argparse.ArgumentParser(description="controller benchmark: acceptance cases and a command flood")
    parser.add_argument("--png", type=Path, default=Path("out/controller.png"))
    parser.add_argument("--part", choices=("all", "acceptance", "flood"), default="all")
    parser.add_argument("--flood-rate", type=int, default=10_000, help="commands per second")
    parser.add_argument("--windows", type=int, default=5, help="measurement windows, idle and flooded each")
    parser.add_argument("--window", type=float, default=2.0, help="seconds per window")
    args = parser.parse_args()
    print(f"bench/controller.py  (ROS_DOMAIN_ID {os.environ['ROS_DOMAIN_ID']}, localhost only, real time)")
    rclpy.init()
    runs = []
    try:
        if args.part in ("all", "flood"):
            flood_bench(args.flood_rate, args.windows, args.window)
        for case in acceptance_scenarios() if args.part in ("all", "acceptance") else ():
            for variant, spec in variants(case):
                result = run_experiment(spec)
                runs.append((dataclasses.replace(case, description=case.description + variant), result))
                print(f"{case.name}{variant}: {case.description}")
                for verdict in judge(case, result):
                    print(verdict_line(verdict))
    finally:
        rclpy.try_shutdown()
    if runs:
        draw(runs, args.png)
        print(f"picture: {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
