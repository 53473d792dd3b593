"""The figure of a recording (``friction-sim replay --plot``): position,
velocity, friction force and normal force R against time, commands marked."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from friction_sim.core.commands import PARAMETERS
from friction_sim.io.messages import NS_PER_S, ns_to_seconds, parameter_event_values
from friction_sim.io.reader import Recording
from friction_sim.io.series import state_series
from friction_sim.io.verify import recorded_commands

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _label(name: str, values: dict[str, float]) -> str:
    """How a command reads on the figure: ``drive_force = 0.5``,
    ``external force = (fx, fz)``, ``mass = 1.3, mu = 0.1``."""
    if name == "external_wrench":
        return f"external force = ({values['external_force_x']:g}, {values['external_force_z']:g})"
    if name == PARAMETERS:
        return ", ".join(f"{k} = {v}" for k, v in values.items())
    return f"{name} = {values[name]:g}"


def command_marks(recording: Recording) -> list[tuple[float, str, bool]]:
    """(t [s], label, accepted) of every command in the recording (refused ones too)."""
    marks = [(command.t, _label(command.name, dict(command.values)), True)
             for command in recorded_commands(recording) if command.name != PARAMETERS]
    initial_seen = False
    for t_ns, msg in recording.decoded(PARAMETERS):  # every parameter change, not only the physics
        new, changed = parameter_event_values(msg)
        if new and not initial_seen:
            initial_seen = True
            continue
        values = {**new, **changed}
        if values:
            marks.append((ns_to_seconds(t_ns), _label(PARAMETERS, values), True))
    for t_ns, msg in recording.decoded("rejected_commands"):
        marks.append((ns_to_seconds(t_ns), f"refused {msg.name}", False))
    return sorted(marks)


def plot(recording: Recording) -> Figure:
    """Position, velocity, friction force and normal force R against time,
    with every command marked (refused ones dotted red).  matplotlib is
    imported here; the Figure is not registered with pyplot."""
    from matplotlib.figure import Figure

    pose_ns, pose = state_series(recording, "pose", lambda m: (m.pose.position.x,), 1)
    vel_ns, vel = state_series(recording, "velocity", lambda m: (m.twist.linear.x,), 1)
    force_ns, force = state_series(recording, "friction_force",
                                   lambda m: (m.wrench.force.x, m.wrench.force.y, m.wrench.force.z), 3)
    figure = Figure(figsize=(10, 9), layout="constrained")
    axes = figure.subplots(4, 1, sharex=True)
    axes[0].plot(pose_ns / NS_PER_S, pose[:, 0] * 1e3, lw=0.8)
    axes[0].set_ylabel("position x [mm]")
    axes[1].plot(vel_ns / NS_PER_S, vel[:, 0] * 1e3, lw=0.8, label="v")
    mean = recording.decoded("mean_velocity")
    if mean:
        axes[1].step([ns_to_seconds(t) for t, _ in mean], [m.twist.linear.x * 1e3 for _, m in mean],
                     where="pre", lw=1.2, label="mean over window")
        axes[1].legend(loc="upper right", fontsize="small")
    axes[1].set_ylabel("velocity v [mm/s]")
    axes[2].plot(force_ns / NS_PER_S, force[:, 0], lw=0.8, color="tab:red")
    axes[2].set_ylabel("friction force [N]")
    axes[3].plot(force_ns / NS_PER_S, force[:, 2], lw=0.8, color="tab:green")
    axes[3].set_ylabel("normal force R [N]")
    axes[3].set_xlabel("simulation time t [s]")
    marks = command_marks(recording)
    _mark(axes, marks)
    figure.suptitle(f"{recording.path.name}: {len(marks)} commands")
    return figure


def _mark(axes: Any, marks: list[tuple[float, str, bool]]) -> None:
    """A vertical line per command on every axis; the first 40 labelled on the top one."""
    for number, (t, label, accepted) in enumerate(marks):
        for ax in axes:
            ax.axvline(t, color="0.35" if accepted else "tab:red", ls="--" if accepted else ":", lw=0.8)
        if number < 40:
            axes[0].annotate(label, (t, 1.0), xycoords=("data", "axes fraction"), rotation=90, va="top",
                             ha="right", fontsize=6, color="0.25" if accepted else "tab:red")
    for ax in axes:
        ax.grid(True, lw=0.3)


__all__ = ["command_marks", "plot"]
