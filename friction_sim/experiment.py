"""Steering experiments over real ROS topics: a schedule of commands played into
a slider (and optionally a controller) running in this process.

The nodes run exactly as they would under ``ros2 run``; a driver node
publishes each scheduled command on its topic when the slider's simulation
time reaches it, and listens to what the nodes publish.  The result holds
the time series a report or a test needs, and :func:`step_metrics` turns them
into settling time, overshoot and steady error per target step.
"""

from __future__ import annotations

import math
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

from friction_sim.errors import ParameterError
from friction_sim.params import Inputs, SliderParams

COMMAND_TOPICS = ("drive_force", "excitation_amplitude", "excitation_frequency", "target_speed", "external_wrench")


@dataclass(frozen=True)
class ScheduledCommand:
    """Publish ``value`` on ``topic`` at simulation time ``t`` [s].  For
    ``external_wrench`` the value is (force.x, force.z) in N."""

    t: float
    topic: str
    value: float | tuple[float, float]

    def __post_init__(self) -> None:
        if self.topic not in COMMAND_TOPICS:
            raise ParameterError("topic", self.topic, f"must be one of {', '.join(COMMAND_TOPICS)}")
        if not (isinstance(self.t, (int, float)) and math.isfinite(self.t) and self.t >= 0.0):
            raise ParameterError("t", self.t, "must be a finite time >= 0 s")


@dataclass(frozen=True)
class ExperimentSpec:
    """Everything an experiment needs (see :func:`run_experiment`)."""

    duration: float
    schedule: Sequence[ScheduledCommand] = ()
    plant: SliderParams = SliderParams()
    inputs: Inputs = Inputs()
    controller: bool = False
    controller_parameters: dict[str, Any] = field(default_factory=dict)
    slider_parameters: dict[str, Any] = field(default_factory=dict)
    real_time_factor: float = 1.0
    log_path: Path | None = None  # record the run (the slider's recording) to this MCAP file
    log_rate: float = 1000.0
    notes: dict[str, str] = field(default_factory=dict)  # written as the recording's scenario metadata


@dataclass(frozen=True)
class Status:
    """A live view of a running experiment (for the status line)."""

    t: float
    duration: float
    target: float | None
    mean_speed: float
    amplitude: float
    drive_force: float
    frequency: float

    def line(self) -> str:
        target = "open loop" if self.target is None else f"{self.target * 1e3:.3f} mm/s"
        return (f"t {self.t:6.2f}/{self.duration:g} s | target {target:>12} | mean speed "
                f"{self.mean_speed * 1e3:8.4f} mm/s | Pa {self.amplitude:6.3f} N | Fd {self.drive_force:6.3f} N "
                f"| f {self.frequency:g} Hz")


@dataclass
class ExperimentResult:
    """Time series of one run (simulation time in s; speeds in m/s, forces in N)."""

    mean_velocity: list[tuple[float, float]] = field(default_factory=list)
    amplitude: list[tuple[float, float]] = field(default_factory=list)  # controller output, at the sample time
    commands: list[tuple[float, str, Any]] = field(default_factory=list)  # as published by the driver
    duration: float = 0.0


@dataclass(frozen=True)
class StepMetrics:
    """How a regulated mean speed answered one step of the target.

    settling_periods: whole excitation periods from the step until the first
        sample after which every sample stays within the tolerance (inf: never).
    overshoot: largest excursion beyond the target, as a fraction of the step;
        for a disturbance at a constant target, the peak deviation as a
        fraction of the target.
    steady_error: relative error of the last sample before the next step.
    """

    t: float
    target: float
    settling_periods: float
    overshoot: float
    steady_error: float


def step_metrics(samples: Sequence[tuple[float, float]], t_step: float, t_end: float, before: float,
                 target: float, frequency: float, tolerance: float) -> StepMetrics:
    """Metrics of the mean-speed samples in (t_step, t_end] for a step from
    ``before`` to ``target`` (samples stamped with their period's end)."""
    window = [(t, v) for t, v in samples if t_step < t <= t_end]
    if not window:
        return StepMetrics(t_step, target, math.inf, math.nan, math.nan)
    settled_from = None
    for t, v in window:
        inside = abs(v - target) <= tolerance * abs(target)
        if inside and settled_from is None:
            settled_from = t
        elif not inside:
            settled_from = None
    settling = math.inf if settled_from is None else math.ceil((settled_from - t_step) * frequency - 1e-6)
    step = target - before
    if abs(step) > 0.05 * abs(target):  # a step of the target: overshoot beyond it, per step size
        direction = 1.0 if step > 0 else -1.0
        overshoot = max(0.0, max(direction * (v - target) for _, v in window)) / abs(step)
    else:  # a disturbance at a constant target: the peak deviation, per target
        overshoot = max(abs(v - target) for _, v in window) / abs(target) if target else math.nan
    steady = abs(window[-1][1] - target) / abs(target) if target != 0 else abs(window[-1][1])
    return StepMetrics(t_step, target, settling, overshoot, steady)


def run_experiment(spec: ExperimentSpec, *, namespace: str | None = None,
                   progress: Callable[[Status], None] | None = None) -> ExperimentResult:
    """Bring up the nodes in this process, play the schedule over real topics in
    simulation time, and collect what they publish.  rclpy must be initialised."""
    import rclpy
    from geometry_msgs.msg import TwistStamped, WrenchStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from std_msgs.msg import Float64

    from friction_sim.nodes.common import wall_ns
    from friction_sim.nodes.controller import ControllerNode
    from friction_sim.nodes.slider import SliderNode

    ns = namespace or f"/experiment_{uuid.uuid4().hex[:8]}"
    plant_values = {
        "mass": spec.plant.mass, "mu": spec.plant.mu, "gravity": spec.plant.gravity,
        "drive_force": spec.inputs.drive_force, "excitation_amplitude": spec.inputs.excitation_amplitude,
        "excitation_frequency": spec.inputs.excitation_frequency, "real_time_factor": spec.real_time_factor,
        **({"log_path": str(spec.log_path), "log_rate": spec.log_rate} if spec.log_path else {}),
        **spec.slider_parameters,
    }
    nodes: list[Any] = []
    executor = SingleThreadedExecutor()
    result = ExperimentResult(duration=spec.duration)
    try:
        driver = rclpy.create_node("experiment_driver", namespace=ns)
        nodes.append(driver)
        publishers = {topic: driver.create_publisher(WrenchStamped if topic == "external_wrench" else Float64,
                                                     topic, 10) for topic in COMMAND_TOPICS}
        driver.create_subscription(
            TwistStamped, "mean_velocity",
            lambda m: result.mean_velocity.append((m.header.stamp.sec + m.header.stamp.nanosec * 1e-9,
                                                   m.twist.linear.x)), 100)
        slider = SliderNode(namespace=ns, parameter_overrides=[Parameter(k, value=v) for k, v in plant_values.items()])
        nodes.append(slider)
        if spec.controller:
            controller = ControllerNode(namespace=ns, parameter_overrides=[
                Parameter(k, value=v) for k, v in {"excitation_frequency": spec.inputs.excitation_frequency,
                                                   "drive_force": spec.inputs.drive_force,
                                                   **spec.controller_parameters}.items()])
            controller.output_listeners.append(
                lambda out: result.amplitude.append((slider.realtime.clock.now(wall_ns()), out.amplitude)))
            nodes.append(controller)
        for node in nodes:
            executor.add_node(node)
        _wait_until_connected(executor, publishers, spec.controller)
        pending = sorted(spec.schedule, key=lambda c: c.t)
        start_sim = slider.realtime.clock.now(wall_ns())
        recorder = slider.recorder
        if recorder is not None:
            recorder.add_metadata(SCENARIO_METADATA, {**spec.notes, "start_ns": round(start_sim * 1e9)})
            if spec.controller and "target_speed" in spec.controller_parameters:
                _record_target(recorder, start_sim, float(spec.controller_parameters["target_speed"]))
        last_progress = time.monotonic()
        target = spec.controller_parameters.get("target_speed") if spec.controller else None
        while (now := slider.realtime.clock.now(wall_ns()) - start_sim) < spec.duration:
            while pending and pending[0].t <= now:
                command = pending.pop(0)
                _publish(publishers[command.topic], command)
                result.commands.append((now, command.topic, command.value))
                if command.topic == "target_speed" and recorder is not None:
                    _record_target(recorder, now + start_sim, float(command.value))  # type: ignore[arg-type]
                target = command.value if command.topic == "target_speed" else target
            executor.spin_once(timeout_sec=0.0005)
            if progress is not None and time.monotonic() - last_progress > 0.25:
                inputs = slider.realtime.slider.inputs
                progress(Status(now, spec.duration, target,  # type: ignore[arg-type]
                                result.mean_velocity[-1][1] if result.mean_velocity else math.nan,
                                inputs.excitation_amplitude, inputs.drive_force, inputs.excitation_frequency))
                last_progress = time.monotonic()
        _shift(result, start_sim)
    finally:
        for node in nodes:
            node.destroy_node()
        executor.shutdown(timeout_sec=0.0)
    return result


SCENARIO_METADATA = "friction_sim_scenario"


def _record_target(recorder: Any, t: float, value: float) -> None:
    """Log a target the driver gave the controller (the slider never sees it)."""
    from friction_sim.realtime import CommandOutcome

    recorder.record_command(CommandOutcome(round(t * 1e9) / 1e9, "target_speed", {"target_speed": value}, True))


def _publish(publisher: Any, command: ScheduledCommand) -> None:
    from geometry_msgs.msg import WrenchStamped
    from std_msgs.msg import Float64

    if command.topic == "external_wrench":
        msg = WrenchStamped()
        msg.wrench.force.x, msg.wrench.force.z = command.value  # type: ignore[misc]
        publisher.publish(msg)
    else:
        publisher.publish(Float64(data=float(command.value)))  # type: ignore[arg-type]


def _wait_until_connected(executor: Any, publishers: dict[str, Any], controller: bool, timeout: float = 10.0) -> None:
    """Spin until discovery has matched the driver's publishers (and, with a
    controller, until it has its plant's parameters)."""
    deadline = time.monotonic() + timeout
    needed = {"drive_force", "excitation_amplitude", "excitation_frequency", "external_wrench"}
    if controller:
        needed.add("target_speed")
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.01)
        if all(publishers[t].get_subscription_count() >= 1 for t in needed):
            nodes = executor.get_nodes()
            if all(getattr(n, "ready", True) for n in nodes):
                return
    raise RuntimeError("the experiment's nodes did not connect within 10 s")


def _shift(result: ExperimentResult, start: float) -> None:
    """Express every time relative to the experiment's start."""
    result.mean_velocity = [(t - start, v) for t, v in result.mean_velocity if t >= start]
    result.amplitude = [(t - start, a) for t, a in result.amplitude if t >= start]
