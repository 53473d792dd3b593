"""record_offline: the states it records are the exact core's, on the grid."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from friction_sim.core.engine.single import Slider
from friction_sim.core.runtime.simulation import random_schedule, run_schedule
from friction_sim.experiment.offline import record_offline
from friction_sim.io import messages as M
from friction_sim.io.reader import read_recording


def test_state_log_matches_a_vectorised_sample_of_the_same_run(tmp_path: Path) -> None:
    schedule = random_schedule(np.random.default_rng(3), 0.6)
    path = tmp_path / "run.mcap"
    record_offline(path, schedule=schedule, duration=0.6, log_rate=1000.0)
    recording = read_recording(path)

    grid = np.arange(601) / 1000.0
    # Commands take effect at whole-nanosecond simulation times, as in the node.
    on_ns = [c.at(M.ns_to_seconds(M.seconds_to_ns(c.t))) for c in schedule]
    reference = run_schedule(Slider(), on_ns, grid)
    x = np.array([m.pose.position.x for _, m in recording.decoded("pose")])
    v = np.array([m.twist.linear.x for _, m in recording.decoded("velocity")])
    assert np.max(np.abs(x - reference.x)) <= 1e-12 * np.max(np.abs(reference.x))
    assert np.max(np.abs(v - reference.v)) <= 1e-12 * np.max(np.abs(reference.v))
    means = recording.decoded("mean_velocity")
    assert len(means) > 10 and all(M.stamp_ns(m.header.stamp) == t for t, m in means)
