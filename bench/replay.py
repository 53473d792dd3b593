"""Benchmark of ``friction-sim replay --publish``: how well the recorded timing holds.

A recording (2 s, states at 200 Hz, two drive-force changes) is published on
real topics, this process listening; each message's arrival is taken from the
middleware's receive stamp.  Printed: the arrival offsets' spread around their
median (50th, 90th percentile, largest), the drift between the second half and
the first, and the republisher's own largest lateness.  Repeated a few times;
medians over the repeats.  The test (test/ros/test_republisher.py) checks the
schedule exactly on a virtual clock; this measures what one machine achieves.

Prints figures only; nothing passes or fails here.

Run: make bench   (or .venv/bin/python bench/replay.py [--repeats 3])
"""

from __future__ import annotations

import argparse
import os
import random
import statistics
import tempfile
import threading
import time
import uuid
from pathlib import Path
from typing import Any

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(1, 100)))

import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor

from friction_sim.core.model.commands import Command
from friction_sim.experiment.offline import record_offline
from friction_sim.io.reader import Recording, read_recording
from friction_sim.ros.republisher import publish

TOPICS = ["pose", "velocity", "events", "drive_force"]


def one_replay(recording: Recording) -> dict[str, float]:
    """Publish ``recording`` once and return the timing figures [ms]."""
    namespace = f"/replay_{uuid.uuid4().hex[:8]}"
    listener = rclpy.create_node("listener", namespace=namespace)
    arrivals: list[float] = []
    for topic in TOPICS:
        listener.create_subscription(
            recording.message_type(topic), topic,
            lambda msg, info: arrivals.append(info["received_timestamp"] / 1e9), 1000)
    executor = SingleThreadedExecutor()
    executor.add_node(listener)
    outcome: dict[str, Any] = {}
    total = sum(len(recording.decoded(topic)) for topic in TOPICS)
    player = threading.Thread(target=lambda: outcome.update(result=publish(
        recording, topics=TOPICS, namespace=namespace, wait_for_subscribers=1, wait_timeout=10.0, delay=0.3)))
    player.start()
    deadline = time.monotonic() + 60.0
    while len(arrivals) < total and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.002)
    player.join(timeout=10.0)
    executor.shutdown(timeout_sec=0.0)
    listener.destroy_node()
    recorded = sorted(log / 1e9 for topic in TOPICS for log, _ in recording.decoded(topic))
    arrived = sorted(arrivals)
    offsets = np.array(arrived[:len(recorded)]) - np.array(recorded[:len(arrived)])
    errors = np.abs(offsets - np.median(offsets))
    half = len(offsets) // 2
    return {"p50": 1e3 * float(np.percentile(errors, 50)), "p90": 1e3 * float(np.percentile(errors, 90)),
            "max": 1e3 * float(errors.max()),
            "drift": 1e3 * float(np.median(offsets[half:]) - np.median(offsets[:half])),
            "late": 1e3 * outcome["result"].max_late, "lost": float(total - len(arrivals))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    rclpy.init()
    try:
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "replay.mcap"
            record_offline(path, schedule=[Command(0.6, "drive_force", {"drive_force": 0.9}),
                                           Command(1.3, "drive_force", {"drive_force": 0.6})],
                           duration=2.0, log_rate=200.0)
            recording = read_recording(path)
            runs = [one_replay(recording) for _ in range(args.repeats)]
    finally:
        rclpy.shutdown()
    print(f"replay --publish of a 2 s recording at 200 Hz, medians of {args.repeats} runs "
          "(arrival offset from the run's median offset):")
    for key, label in (("p50", "median error"), ("p90", "90th percentile error"), ("max", "largest error"),
                       ("drift", "drift, second half - first"), ("late", "republisher's largest lateness"),
                       ("lost", "messages not received")):
        unit = "" if key == "lost" else " ms"
        print(f"    {label:34s} {statistics.median(run[key] for run in runs):8.3f}{unit}")


if __name__ == "__main__":
    main()
