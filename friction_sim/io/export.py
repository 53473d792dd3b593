"""Writing results to CSV files (the only file output of the offline jobs)."""

from __future__ import annotations

import csv
from pathlib import Path

from friction_sim.core.slider import Event, Trajectory
from friction_sim.core.urelation import UMap

TRAJECTORY_COLUMNS = (
    "t", "kind", "x", "v", "acceleration", "friction_force", "normal_force", "phase", "mode",
)


def write_umap_csv(umap: UMap, path: Path) -> Path:
    """One row per grid point: phi, amplitude_ratio, U (full precision)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(("phi", "amplitude_ratio", "U"))
        for i, ratio in enumerate(umap.amplitude_ratio):
            for j, phi in enumerate(umap.phi):
                writer.writerow((repr(float(phi)), repr(float(ratio)), repr(float(umap.u[i, j]))))
    return path


def write_trajectory_csv(trajectory: Trajectory, events: list[Event], path: Path) -> Path:
    """The uniform samples (kind ``sample``) and the events (kind = the event's
    kind, state just after it; v = 0 at every event), merged in time order."""
    path.parent.mkdir(parents=True, exist_ok=True)
    rows: list[tuple[float, int, tuple[str, ...]]] = []
    for k in range(trajectory.t.size):
        rows.append((float(trajectory.t[k]), 1, (
            repr(float(trajectory.t[k])), "sample", repr(float(trajectory.x[k])),
            repr(float(trajectory.v[k])), repr(float(trajectory.acceleration[k])),
            repr(float(trajectory.friction_force[k])), repr(float(trajectory.normal_force[k])),
            repr(float(trajectory.phase[k])), str(int(trajectory.mode[k])),
        )))
    for event in events:
        rows.append((event.t, 0, (
            repr(event.t), event.kind.value, repr(event.x), "0.0", "", "", "",
            repr(event.phase), str(int(event.after)),
        )))
    rows.sort(key=lambda row: (row[0], row[1]))
    with path.open("w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(TRAJECTORY_COLUMNS)
        writer.writerows(row[2] for row in rows)
    return path
