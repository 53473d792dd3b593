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

from friction_sim.errors import FrictionSimError, ParameterError
from friction_sim.core.params import Inputs, SliderParams

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


def settling_periods(samples: Sequence[tuple[float, float]], start: float, target: float, frequency: float,
                     tolerance: float) -> float:
    """Whole excitation periods from ``start`` until the first sample after
    which every sample stays within ``tolerance`` (relative) of ``target``
    (for a target of 0: exactly 0); inf when that never happens."""
    settled_at = None
    for t, v in samples:
        inside = abs(v - target) <= tolerance * abs(target) if target else v == 0.0
        if inside and settled_at is None:
            settled_at = t
        elif not inside:
            settled_at = None
    return math.inf if settled_at is None else float(math.ceil((settled_at - start) * frequency - 1e-6))


def step_metrics(samples: Sequence[tuple[float, float]], t_step: float, t_end: float, before: float,
                 target: float, frequency: float, tolerance: float) -> StepMetrics:
    """Metrics of the mean-speed samples in (t_step, t_end] for a step from
    ``before`` to ``target`` (samples stamped with their period's end)."""
    window = [(t, v) for t, v in samples if t_step < t <= t_end]
    if not window:
        return StepMetrics(t_step, target, math.inf, math.nan, math.nan)
    settling = settling_periods(window, t_step, target, frequency, tolerance)
    step = target - before
    if abs(step) > 0.05 * abs(target):  # a step of the target: overshoot beyond it, per step size
        direction = 1.0 if step > 0 else -1.0
        overshoot = max(0.0, max(direction * (v - target) for _, v in window)) / abs(step)
    else:  # a disturbance at a constant target: the peak deviation, per target
        overshoot = max(abs(v - target) for _, v in window) / abs(target) if target else math.nan
    steady = abs(window[-1][1] - target) / abs(target) if target != 0 else abs(window[-1][1])
    return StepMetrics(t_step, target, settling, overshoot, steady)


def run_experiment(spec: ExperimentSpec, *, namespace: str | None = None, attach: bool = False,
                   progress: Callable[[Status], None] | None = None) -> ExperimentResult:
    """Play the schedule over real topics in simulation time and collect what
    the nodes publish.  rclpy must be initialised.

    By default the slider (and controller) are brought up in this process, in
    ``namespace`` (a fresh one when None), and the slider records the run.
    With ``attach`` they are already running in ``namespace``: the scenario's
    plant and controller settings are applied through their parameter
    services, simulation time is read from the slider's stamps, and this
    process records what it sees on the topics.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    ns = namespace or f"/experiment_{uuid.uuid4().hex[:8]}"
    executor = SingleThreadedExecutor()
    result = ExperimentResult(duration=spec.duration)
    driver = rclpy.create_node("experiment_driver", namespace=ns)
    executor.add_node(driver)
    plant: _InProcess | _Attached | None = None
    try:
        publishers = _command_publishers(driver)
        _collect_mean_velocity(driver, result)
        plant = _Attached(spec, driver, executor) if attach else _InProcess(spec, ns, executor, result)
        _wait_until_connected(executor, publishers, spec.controller, plant)
        _play(spec, plant, executor, publishers, result, progress)
    finally:
        if plant is not None:
            plant.close()
        driver.destroy_node()
        executor.shutdown(timeout_sec=0.0)
    return result


def _play(spec: ExperimentSpec, plant: _InProcess | _Attached, executor: Any, publishers: dict[str, Any],
          result: ExperimentResult, progress: Callable[[Status], None] | None) -> None:
    """Publish each scheduled command when simulation time reaches it."""
    pending = sorted(spec.schedule, key=lambda c: c.t)
    start_sim = plant.now()
    recorder = plant.recorder
    if recorder is not None:
        recorder.add_metadata(SCENARIO_METADATA, {**spec.notes, "start_ns": round(start_sim * 1e9)})
        if spec.controller and "target_speed" in spec.controller_parameters:
            _record_target(recorder, start_sim, float(spec.controller_parameters["target_speed"]))
    last_progress = time.monotonic()
    target = spec.controller_parameters.get("target_speed") if spec.controller else None
    while (now := plant.now() - start_sim) < spec.duration:
        while pending and pending[0].t <= now:
            command = pending.pop(0)
            _publish(publishers[command.topic], command)
            result.commands.append((now, command.topic, command.value))
            if command.topic == "target_speed" and recorder is not None:
                _record_target(recorder, now + start_sim, float(command.value))  # type: ignore[arg-type]
            target = command.value if command.topic == "target_speed" else target
        executor.spin_once(timeout_sec=0.0005)
        if progress is not None and time.monotonic() - last_progress > 0.25:
            inputs = plant.inputs()
            progress(Status(now, spec.duration, target,  # type: ignore[arg-type]
                            result.mean_velocity[-1][1] if result.mean_velocity else math.nan,
                            inputs.excitation_amplitude, inputs.drive_force, inputs.excitation_frequency))
            last_progress = time.monotonic()
    _shift(result, start_sim)


def _plant_values(spec: ExperimentSpec) -> dict[str, Any]:
    return {
        "mass": spec.plant.mass, "mu": spec.plant.mu, "gravity": spec.plant.gravity,
        "drive_force": spec.inputs.drive_force, "excitation_amplitude": spec.inputs.excitation_amplitude,
        "excitation_frequency": spec.inputs.excitation_frequency, "real_time_factor": spec.real_time_factor,
        **spec.slider_parameters,
    }


def _controller_values(spec: ExperimentSpec) -> dict[str, Any]:
    return {"excitation_frequency": spec.inputs.excitation_frequency, "drive_force": spec.inputs.drive_force,
            **spec.controller_parameters}


class _InProcess:
    """Slider (and controller) nodes in this process; the slider records."""

    def __init__(self, spec: ExperimentSpec, ns: str, executor: Any, result: ExperimentResult) -> None:
        from rclpy.parameter import Parameter

        from friction_sim.ros.common import wall_ns
        from friction_sim.ros.controller import ControllerNode
        from friction_sim.ros.slider import SliderNode

        values = _plant_values(spec)
        if spec.log_path:
            values.update(log_path=str(spec.log_path), log_rate=spec.log_rate)
        self._wall_ns = wall_ns
        self.slider = SliderNode(namespace=ns, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()])
        self.nodes: list[Any] = [self.slider]
        if spec.controller:
            try:
                controller = ControllerNode(namespace=ns, parameter_overrides=[
                    Parameter(k, value=v) for k, v in _controller_values(spec).items()])
            except BaseException:
                self.close()  # the slider's tick thread and recorder must not outlive the failure
                raise
            controller.output_listeners.append(lambda out: result.amplitude.append((self.now(), out.amplitude)))
            self.nodes.append(controller)
        for node in self.nodes:
            executor.add_node(node)
        self.recorder = self.slider.recorder

    def now(self) -> float:
        return self.slider.realtime.clock.now(self._wall_ns())

    def inputs(self) -> Inputs:
        return self.slider.realtime.slider.inputs

    def ready(self) -> bool:
        return all(getattr(node, "ready", True) for node in self.nodes)

    def close(self) -> None:
        for node in self.nodes:
            node.destroy_node()


class _Attached:
    """Nodes already running in the driver's namespace: configure them through
    their parameter services, follow simulation time on the slider's stamps,
    and record what the topics carry."""

    RECORDED = ("pose", "velocity", "friction_force", "mean_velocity", "drive_force", "excitation_amplitude",
                "excitation_frequency", "external_wrench")

    def __init__(self, spec: ExperimentSpec, driver: Any, executor: Any) -> None:
        self.driver = driver
        self._stamp_ns = -1
        self._inputs = spec.inputs
        self._set_parameters(executor, "slider", {k: v for k, v in _plant_values(spec).items()})
        if spec.controller:
            self._set_parameters(executor, "controller", _controller_values(spec))
        self.recorder = None
        if spec.log_path:
            from friction_sim.io.recording import Recorder

            values = _plant_values(spec)
            self.recorder = Recorder(spec.log_path, metadata={**values, "recorded_by": "experiment --attach"})
        self._subscribe()

    def _set_parameters(self, executor: Any, node: str, values: dict[str, Any]) -> None:
        from rclpy.parameter import Parameter
        from rclpy.parameter_client import AsyncParameterClient

        client = AsyncParameterClient(self.driver, node)
        deadline = time.monotonic() + 10.0
        while not client.services_are_ready():
            if time.monotonic() > deadline:
                raise ExperimentError(f"no node '{node}' answers in {self.driver.get_namespace()} "
                                      "(start it first, e.g. friction-sim feeder --ros-args -r __ns:=...)")
            executor.spin_once(timeout_sec=0.05)
        future = client.set_parameters([Parameter(k, value=v) for k, v in values.items()])
        while not future.done():
            executor.spin_once(timeout_sec=0.05)
        for (name, _), result in zip(values.items(), future.result().results):
            if not result.successful:
                raise ExperimentError(f"{node} refused {name}: {result.reason}")

    def _subscribe(self) -> None:
        from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
        from std_msgs.msg import Float64

        kinds = {"pose": PoseStamped, "velocity": TwistStamped, "friction_force": WrenchStamped,
                 "mean_velocity": TwistStamped, "external_wrench": WrenchStamped}
        for topic in self.RECORDED:
            self.driver.create_subscription(kinds.get(topic, Float64), topic, self._keeper(topic), 100)

    def _keeper(self, topic: str) -> Callable[[Any], None]:
        from friction_sim.io.messages import stamp_ns

        def keep(msg: Any) -> None:
            header = getattr(msg, "header", None)
            if topic == "pose":
                self._stamp_ns = max(self._stamp_ns, stamp_ns(header.stamp))
            if topic in ("drive_force", "excitation_amplitude", "excitation_frequency"):
                self._inputs = self._inputs.replace(**{topic: msg.data})
            if self.recorder is not None and self._stamp_ns >= 0:
                stamped = header is not None and topic != "external_wrench"
                log_ns = stamp_ns(header.stamp) if stamped else self._stamp_ns
                self.recorder.write(topic, msg, log_ns)
        return keep

    def now(self) -> float:
        return self._stamp_ns / 1e9

    def inputs(self) -> Inputs:
        return self._inputs

    def ready(self) -> bool:
        return self._stamp_ns >= 0

    def close(self) -> None:
        if self.recorder is not None:
            self.recorder.finish()


class ExperimentError(FrictionSimError):
    """An experiment cannot start (its nodes do not answer or refuse settings)."""


def _command_publishers(driver: Any) -> dict[str, Any]:
    from geometry_msgs.msg import WrenchStamped
    from std_msgs.msg import Float64

    return {topic: driver.create_publisher(WrenchStamped if topic == "external_wrench" else Float64, topic, 10)
            for topic in COMMAND_TOPICS}


def _collect_mean_velocity(driver: Any, result: ExperimentResult) -> None:
    from geometry_msgs.msg import TwistStamped

    from friction_sim.io.messages import ns_to_seconds, stamp_ns

    driver.create_subscription(
        TwistStamped, "mean_velocity",
        lambda m: result.mean_velocity.append((ns_to_seconds(stamp_ns(m.header.stamp)),
                                               m.twist.linear.x)), 100)


SCENARIO_METADATA = "friction_sim_scenario"


def _record_target(recorder: Any, t: float, value: float) -> None:
    """Log a target the driver gave the controller (the slider never sees it)."""
    from friction_sim.core.realtime import CommandOutcome

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


def _wait_until_connected(executor: Any, publishers: dict[str, Any], controller: bool, plant: Any,
                          timeout: float = 10.0) -> None:
    """Spin until discovery has matched the driver's publishers and the nodes
    are ready (a controller has its plant's parameters; an attached slider
    has published its time)."""
    deadline = time.monotonic() + timeout
    needed = {"drive_force", "excitation_amplitude", "excitation_frequency", "external_wrench"}
    if controller:
        needed.add("target_speed")
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.01)
        if all(publishers[t].get_subscription_count() >= 1 for t in needed) and plant.ready():
            return
    raise ExperimentError(f"the experiment's nodes did not connect within {timeout:g} s")


def _shift(result: ExperimentResult, start: float) -> None:
    """Express every time relative to the experiment's start."""
    result.mean_velocity = [(t - start, v) for t, v in result.mean_velocity if t >= start]
    result.amplitude = [(t - start, a) for t, a in result.amplitude if t >= start]
