"""Pictures of the paper's figures.  Each function takes result objects and
returns a matplotlib Figure; matplotlib is imported only when one is drawn,
so the core and the nodes never pay for it.

* :func:`u_map_figure` is the paper's Fig. 3: U over (Fd/FfN, Pa/Q).
* :func:`trace_figure` is the paper's Fig. 2: forces with the impulse areas,
  acceleration, velocity and displacement, with the points A, B, C.
* :func:`report_figure` is an experiment report's picture: target and
  measured mean speed, Pa, Fd and f against time.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from friction_sim.core.events import EventKind
from friction_sim.core.simulation import SimulationResult
from friction_sim.core.urelation import UMap
from friction_sim.experiment.report import RunData, SegmentRow, inputs_at

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _pyplot_free_figure(**kwargs: object) -> Figure:
    """A Figure not registered with pyplot (no GUI backend, no global state)."""
    from matplotlib.figure import Figure

    return Figure(**kwargs)  # type: ignore[arg-type]


def u_map_figure(umap: UMap) -> Figure:
    """U as filled contours over phi = Fd/FfN (x) and a = Pa/Q (y), the
    no-motion region hatched and its boundary phi = 1 - a drawn."""
    fig = _pyplot_free_figure(figsize=(7.0, 5.6), layout="constrained")
    ax = fig.add_subplot()
    phi, a = np.meshgrid(umap.phi, umap.amplitude_ratio)
    u = np.where(np.isfinite(umap.u), umap.u, np.nan)
    shading = ax.pcolormesh(phi, a, u, shading="gouraud", cmap="viridis")
    steps = np.array([0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5])
    levels = steps[steps < np.nanmax(u)]
    lines = ax.contour(phi, a, u, levels=levels, colors="white", linewidths=0.7)
    ax.clabel(lines, fmt="%g", fontsize=7)
    boundary = np.linspace(0.0, 1.0, 200)
    ax.fill_between(boundary, 0.0, 1.0 - boundary, facecolor="none", hatch="//",
                    edgecolor="0.4", linewidth=0.0, label="no motion (U = 0)")
    ax.plot(boundary, 1.0 - boundary, color="red", linewidth=1.5, label="boundary Fd/FfN = 1 - Pa/Q")
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(0.0, 1.0)
    ax.set_xlabel("Fd / FfN  (phi = Fd / (mu m g))")
    ax.set_ylabel("Pa / Q  (a = Pa / (m g))")
    ax.set_title("Nondimensional mean speed U = V f / (g mu)")
    ax.legend(loc="lower left", fontsize=8)
    fig.colorbar(shading, ax=ax, label="U")
    return fig


def trace_figure(result: SimulationResult) -> Figure:
    """The paper's Fig. 2 from a sampled simulation (``sample_rate`` set)."""
    traj = result.trajectory
    if traj is None:
        raise ValueError("trace_figure needs a SimulationResult with a sampled trajectory")
    t_ms = traj.t * 1e3
    drive = result.inputs.tangential_force
    limit = result.params.mu * traj.normal_force
    friction_magnitude = np.abs(traj.friction_force)
    slipping = traj.mode != 0

    fig = _pyplot_free_figure(figsize=(8.0, 9.0), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True)
    ax = axes[0]
    ax.plot(t_ms, np.full_like(t_ms, drive), color="black", label="Fd")
    ax.plot(t_ms, limit, color="tab:blue", linestyle="--", label="mu R")
    ax.plot(t_ms, friction_magnitude, color="tab:red", label="|Ff| (friction force)")
    ax.fill_between(t_ms, drive, friction_magnitude, where=slipping & (drive >= friction_magnitude),
                    facecolor="none", hatch="///", edgecolor="tab:green", label="impulse accelerating")
    ax.fill_between(t_ms, drive, friction_magnitude, where=slipping & (drive < friction_magnitude),
                    facecolor="none", hatch="\\\\\\", edgecolor="tab:orange", label="impulse decelerating")
    ax.set_ylabel("force [N]")
    ax.legend(loc="upper right", fontsize=7, ncol=2)
    for axis, values, label in (
        (axes[1], traj.acceleration, "acceleration [m/s²]"),
        (axes[2], traj.v * 1e3, "velocity [mm/s]"),
        (axes[3], traj.x * 1e6, "displacement [µm]"),
    ):
        axis.plot(t_ms, values, color="black", linewidth=1.0)
        axis.set_ylabel(label)
        axis.grid(alpha=0.3)
    axes[-1].set_xlabel("time [ms]")
    _mark_points(axes, result)
    p, i = result.params, result.inputs
    fig.suptitle(
        f"Pa = {i.excitation_amplitude:g} N, Fd = {i.drive_force:g} N, f = {i.excitation_frequency:g} Hz, "
        f"mu = {p.mu:g}, g = {p.gravity:g} m/s², m = {p.mass:g} kg"
    )
    return fig


def _mark_points(axes: np.ndarray, result: SimulationResult) -> None:
    """Mark A (slip starts), B (peak velocity: Ft = mu R again, at the mirror
    phase pi - theta_A) and C (stick) on the velocity axis."""
    traj = result.trajectory
    assert traj is not None
    omega = 2.0 * math.pi * result.inputs.excitation_frequency
    end = traj.t[-1]
    points: list[tuple[str, float]] = []
    for event in result.events:
        if event.t > end:
            break
        if event.kind is EventKind.SLIP_START:
            points.append(("A", event.t))
            theta_a = math.asin(math.sin(event.phase))
            t_b = event.t + (math.pi - 2.0 * theta_a) / omega
            if t_b <= end:
                points.append(("B", t_b))
        elif event.kind is EventKind.STICK:
            points.append(("C", event.t))
    speed_axis = axes[2]
    for label, t in points:
        v = float(np.interp(t, traj.t, traj.v)) * 1e3
        speed_axis.plot(t * 1e3, v, "o", color="tab:purple", markersize=5)
        speed_axis.annotate(label, (t * 1e3, v), textcoords="offset points", xytext=(4, 6), fontsize=9)
        for axis in axes:
            axis.axvline(t * 1e3, color="0.75", linewidth=0.6, zorder=0)


def report_figure(data: RunData, rows: Sequence[SegmentRow]) -> Figure:
    """Target and measured mean speed, Pa, Fd and f against time, the
    segments' starts marked."""
    fig = _pyplot_free_figure(figsize=(10.0, 9.0), layout="constrained")
    ax_v, ax_pa, ax_fd, ax_f = fig.subplots(4, 1, sharex=True)
    _speed_panel(ax_v, data, rows)
    times = [0.0] + [c.t for c in data.commands] + [data.duration]
    states = [data.inputs] + [inputs_at(data, c.t) for c in data.commands]
    for axis, name, label in ((ax_pa, "excitation_amplitude", "Pa [N]"), (ax_fd, "drive_force", "Fd [N]"),
                              (ax_f, "excitation_frequency", "f [Hz]")):
        axis.step(times, [getattr(s, name) for s in states] + [getattr(states[-1], name)], where="post")
        axis.set_ylabel(label)
    for r in rows[1:]:
        for axis in (ax_v, ax_pa, ax_fd, ax_f):
            axis.axvline(r.start, color="0.8", linewidth=0.7, zorder=0)
    ax_f.set_xlabel("simulation time [s]")
    fig.suptitle(data.name)
    return fig


def _speed_panel(ax: Any, data: RunData, rows: Sequence[SegmentRow]) -> None:
    """Measured mean speed, with each segment's target (closed loop) or prediction (open loop)."""
    ax.plot([t for t, _ in data.mean_velocity], [v * 1e3 for _, v in data.mean_velocity], ".-",
            markersize=2, linewidth=0.7, label="measured mean speed")
    for r in rows:
        ax.plot([r.start, r.end], [r.target * 1e3] * 2, "k--" if r.mode == "closed loop" else "g:", linewidth=1.2)
    ax.plot([], [], "k--", label="target (closed loop)")
    ax.plot([], [], "g:", label="U-relation prediction (open loop)")
    ax.set_ylabel("mean speed [mm/s]")
    ax.legend(loc="upper left", fontsize=8)
