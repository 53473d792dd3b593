"""Benchmark of the mean-speed controller (issue 4): the five acceptance cases
in closed loop over real topics, slider and controller in this process, real
time.  Prints settling time (excitation periods), overshoot and steady error
per step, and draws target, measured mean speed and Pa against time for all
five cases into one PNG.  Prints figures only; nothing passes or fails here.

Run: make bench   (or .venv/bin/python bench/controller.py [--png out/controller.png])
"""

from __future__ import annotations

import argparse
import os
import random
import sys
from pathlib import Path

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(1, 100)))
os.environ.setdefault("MPLBACKEND", "Agg")

import rclpy

from friction_sim.experiment.acceptance import acceptance_scenarios, judge
from friction_sim.experiment.report import command_label
from friction_sim.experiment.runner import ExperimentResult, run_experiment
from friction_sim.experiment.scenario import Scenario


def draw(runs: list[tuple[Scenario, ExperimentResult]], path: Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9.0, 13.0), layout="constrained")
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


def main() -> int:
    parser = argparse.ArgumentParser(description="controller acceptance benchmark")
    parser.add_argument("--png", type=Path, default=Path("out/controller.png"))
    args = parser.parse_args()
    print(f"bench/controller.py  (ROS_DOMAIN_ID {os.environ['ROS_DOMAIN_ID']}, localhost only, real time)")
    rclpy.init()
    runs = []
    try:
        for case in acceptance_scenarios():
            result = run_experiment(case.spec())
            runs.append((case, result))
            print(f"{case.name}: {case.description}")
            for verdict in judge(case, result):
                e, m = verdict.expectation, verdict.metrics
                print(f"    change at {e.t:.1f} s, target {verdict.target * 1e3:.2f} mm/s: within {e.within:.0%} "
                      f"after {m.settling_periods} periods (limit {e.periods}); overshoot {m.overshoot:.1%}"
                      + (f" (limit {e.overshoot:.0%})" if e.overshoot < 1 else "")
                      + f"; steady error {m.steady_error:.1e}  [{'met' if verdict.met else 'MISSED'}]")
    finally:
        rclpy.try_shutdown()
    draw(runs, args.png)
    print(f"picture: {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
