"""The figure of a recording (``friction-sim replay --plot``): position,
velocity, friction force and normal force R against time, commands marked;
a recording in which the slider leaves the track gets a fifth panel, its
height z above the track.

The file is streamed in two passes (the commands; the states, thinned to
the extremes of each run of samples, :func:`friction_sim.io.series.thinned_series`),
so a figure of a day-long recording takes as little memory as one of a minute."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from friction_sim.core.model.commands import PARAMETERS
from friction_sim.io.messages import (
    COMMAND_TOPICS,
    NS_PER_S,
    command_from_message,
    ns_to_seconds,
    parameter_event_values,
)
from friction_sim.io.reader import Recording
from friction_sim.io.series import FORCE, POSITION_XZ, VELOCITY, thinned_series

#: About how many points each trace of the figure keeps.
POINTS = 4000
REJECTED = "rejected_commands"

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
    """(t [s], label, accepted) of every command in the recording (refused
    ones too; every parameter change, not only the physics), in one pass."""
    names = {recording.topic_name(topic): topic for topic in (*COMMAND_TOPICS, REJECTED)}
    marks: list[tuple[float, str, bool]] = []
    initial_seen = False
    for raw in recording.iter_messages([*COMMAND_TOPICS, REJECTED]):
        topic, msg, t = names[raw.topic], recording.decode(raw), ns_to_seconds(raw.log_time)
        if topic == REJECTED:
            marks.append((t, f"refused {msg.name}", False))
        elif topic == PARAMETERS:
            new, changed = parameter_event_values(msg)
            if new and not initial_seen:
                initial_seen = True
                continue
            values = {**new, **changed}
            if values:
                marks.append((t, _label(PARAMETERS, values), True))
        else:
            command = command_from_message(topic, msg, t)
            if command.values:
                marks.append((t, _label(topic, dict(command.values)), True))
    return sorted(marks)


def plot(recording: Recording, points: int = POINTS) -> Figure:
    """Position, velocity, friction force and normal force R (and the height z,
    if the slider flies) against time, with every command marked (refused ones dotted red); each trace thinned
    to about ``points`` points.  matplotlib is imported here; the Figure is
    not registered with pyplot."""
    from matplotlib.figure import Figure

    series = thinned_series(recording, {"pose": POSITION_XZ, "velocity": VELOCITY, "friction_force": FORCE,
                                        "mean_velocity": VELOCITY}, points)
    (pose_ns, pose), (vel_ns, vel) = series["pose"], series["velocity"]
    (force_ns, force), (mean_ns, mean) = series["friction_force"], series["mean_velocity"]
    flies = bool(pose.size and (pose[:, 2] != 0.0).any())
    figure = Figure(figsize=(10, 11 if flies else 9), layout="constrained")
    axes = figure.subplots(5 if flies else 4, 1, sharex=True)
    axes[0].plot(pose_ns / NS_PER_S, pose[:, 0] * 1e3, lw=0.8)
    axes[0].set_ylabel("position x [mm]")
    axes[1].plot(vel_ns / NS_PER_S, vel[:, 0] * 1e3, lw=0.8, label="v")
    if mean_ns.size:
        axes[1].step(mean_ns / NS_PER_S, mean[:, 0] * 1e3, where="pre", lw=1.2, label="mean over window")
        axes[1].legend(loc="upper right", fontsize="small")
    axes[1].set_ylabel("velocity v [mm/s]")
    axes[2].plot(force_ns / NS_PER_S, force[:, 0], lw=0.8, color="tab:red")
    axes[2].set_ylabel("friction force [N]")
    axes[3].plot(force_ns / NS_PER_S, force[:, 2], lw=0.8, color="tab:green")
    axes[3].set_ylabel("normal force R [N]")
    if flies:
        axes[4].plot(pose_ns / NS_PER_S, pose[:, 2] * 1e6, lw=0.8, color="tab:purple")
        axes[4].set_ylabel("height z [µm]")
    axes[-1].set_xlabel("simulation time t [s]")
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
