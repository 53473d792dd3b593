"""The plants an experiment drives: its slider (and controller) nodes in this process, or already
running in a namespace and attached to.

:class:`InProcessPlant` brings the nodes up here; its slider records the run, and hands its period
means to the result through a sink.  :class:`AttachedPlant` configures running nodes through their
parameter services, follows simulation time on the slider's stamps and records what the topics
carry.  Both answer the driver's questions alike: the simulation time, the inputs in force,
whether every sample is answered, whether a ``~/step`` is under way.  (No rclpy here: the driver
node and its executor come from :mod:`friction_sim.experiment.runner`.)
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import Any

from friction_sim.core.model import spec as settings
from friction_sim.core.model.commands import (
    COMMANDS,
    PARAMETERS,
    SLIDER,
    Command,
    apply,
    consumed_by,
    unused_input,
)
from friction_sim.core.model.params import Inputs
from friction_sim.core.runtime.controller import WAITING_FOR_PLANT
from friction_sim.core.runtime.lockstep import to_ns
from friction_sim.errors import ExperimentError, ParameterError
from friction_sim.experiment.job import ExperimentResult, ExperimentSpec
from friction_sim.io.messages import (
    STATE_TOPICS,
    TOPIC_TYPES,
    command_from_message,
    message_class,
    ns_to_seconds,
    seconds_to_ns,
    stamp_ns,
)
from friction_sim.io.sinks import MessageRecord, PeriodRecord, Record
from friction_sim.io.stamped import STAMPED_COMMAND, STAMPED_TYPE
from friction_sim.ros.driving import check_results, get_parameters, overrides, set_parameters, spin_until


def _plant_values(spec: ExperimentSpec) -> dict[str, Any]:
    """The slider's parameters for the experiment: plant, initial inputs, real-time factor."""
    plant = {name: getattr(spec.plant, name) for name in settings.PLANT}
    inputs = {name: getattr(spec.inputs, name) for name in settings.INPUTS if name in settings.SLIDER_NODE}
    lockstep = {"lockstep": True, "lockstep_participants": "scheduler,controller" if spec.controller
                else "scheduler"} if spec.lockstep else {}
    return {**plant, **inputs, "real_time_factor": spec.real_time_factor, **lockstep, **spec.slider_parameters}


def _controller_values(spec: ExperimentSpec) -> dict[str, Any]:
    """The controller's parameters: the plant's initial drive force and frequency, then the scenario's."""
    lockstep: dict[str, Any] = {"lockstep": True, **{name: spec.slider_parameters[name] for name in (
        "actuation_delay", "accelerometer_rate") if name in spec.slider_parameters}}
    return {"excitation_frequency": spec.inputs.excitation_frequency, "drive_force": spec.inputs.drive_force,
            **(lockstep if spec.lockstep else {}), **spec.controller_parameters}


class InProcessPlant:
    """Slider (and controller) nodes in this process; the slider records."""

    #: The slider records what it sees on target_speed itself.
    RECORDS_TARGETS = True

    def __init__(self, spec: ExperimentSpec, ns: str, executor: Any, result: ExperimentResult) -> None:
        from friction_sim.ros.controller import ControllerNode
        from friction_sim.ros.run import wall_ns
        from friction_sim.ros.slider import SliderNode

        values = _plant_values(spec)
        if spec.log_path:
            values.update(log_path=str(spec.log_path), log_rate=spec.log_rate)
        self._wall_ns = wall_ns
        self.slider = SliderNode(namespace=ns, parameter_overrides=overrides(values))
        self.slider.sinks.append(_SampleSink(result))
        self.nodes: list[Any] = [self.slider]
        if spec.controller:
            try:
                controller = ControllerNode(namespace=ns, parameter_overrides=overrides(_controller_values(spec)))
            except BaseException:
                self.close()  # the slider's tick thread and recorder must not outlive the failure
                raise
            controller.output_listeners.append(lambda out: result.amplitude.append((self.now(), out.amplitude)))
            controller.drive_listeners.append(lambda drive: result.drive.append(
                (self.now(), drive.level, drive.frequency, drive.per_drive)))
            self.nodes.append(controller)
        self._own: Any = None
        if spec.lockstep and spec.controller:  # (its answers wait for no one else's callbacks)
            from friction_sim.ros.run import SpinThread

            self._own = SpinThread(self.nodes[-1])
        for node in self.nodes[:1] if self._own is not None else self.nodes:
            executor.add_node(node)
        self.recorder = self.slider.recorder

    def now(self) -> float:
        """The slider's simulation time [s]."""
        return float(self.slider.realtime.now(self._wall_ns()))

    def now_ns(self) -> int:
        return to_ns(self.now())

    def last_sample_ns(self) -> int:
        """The stamp [ns] of the last mean velocity the slider published (-1: none yet)."""
        with self.slider.lock:
            period = self.slider.realtime.period_means.last
        return to_ns(period.t) if period is not None else -1

    def answered(self) -> bool:
        """In lockstep: whether every sample the slider published has its answer."""
        gate = getattr(self.slider.realtime, "gate", None)
        return gate is None or not gate.awaited

    def standing(self) -> bool:
        """Whether no ~/step is under way (lockstep: the loop advances a step after the call)."""
        gate = getattr(self.slider.realtime, "gate", None)
        return gate is None or not gate.stepping

    def inputs(self) -> Inputs:
        """The slider's inputs in force."""
        inputs: Inputs = self.slider.realtime.slider.inputs
        return inputs

    def ready(self) -> bool:
        """Whether every node is ready (a controller has its plant's parameters)."""
        return all(getattr(node, "ready", True) for node in self.nodes)

    def set_parameters(self, values: dict[str, Any]) -> None:
        """Set the slider's parameters (as ``ros2 param set`` would); a refusal is an ExperimentError."""
        result = self.slider.set_parameters_atomically(overrides(values))
        if not result.successful:
            raise ExperimentError(f"the slider refused {values}: {result.reason}")

    def set_controller_parameters(self, values: dict[str, Any]) -> None:
        """Set the controller's parameters, one by one (as its parameter service does, on the node
        itself: a round trip through DDS, a few ms, held the slider at each scheduled target)."""
        check_results("controller", values, self.nodes[1].set_parameters(overrides(values)))

    def close(self) -> None:
        """Destroy the nodes (the slider finishes its recording)."""
        if self._own is not None:
            self._own.stop()
        for node in self.nodes:
            node.destroy_node()


class AttachedPlant:
    """Nodes already running in the driver's namespace: configure them through
    their parameter services, follow simulation time on the slider's stamps,
    and record what the topics carry."""

    RECORDED = (*STATE_TOPICS, "mean_velocity", *(entry.name for entry in consumed_by(SLIDER)))
    #: Stamped topics whose messages are recorded once per stamp.
    RESENT = (*STATE_TOPICS, "mean_velocity")
    #: The targets this process publishes are recorded as it publishes them.
    RECORDS_TARGETS = False

    def __init__(self, spec: ExperimentSpec, driver: Any, executor: Any) -> None:
        self.driver, self.executor = driver, executor
        self._params, self._inputs = spec.plant, spec.inputs
        # The controller first: it follows its plant's parameter changes, and an active one answers
        # each with a Pa that would overwrite the scenario's amplitude on the slider; stood by
        # (an open-loop start), it publishes nothing.
        if spec.controller:
            # (with the plant's actuator and exciter data: a running controller follows its plant's model
            # on /parameter_events, but not the exciter's data sheet, which it reads only at start-up; so
            # first its start-up read must be over, or what it reads would overwrite what is set here)
            _wait_for_controller_model(driver, executor)
            exciter = {name: getattr(spec.plant, name) for name in ("actuator", *settings.EXCITER)}
            set_parameters(driver, executor, "controller", {name: value for name, value in {
                **exciter, **_controller_values(spec)}.items() if not settings.CONTROLLER_NODE[name].start_only})
        # (not the input the scenario's actuator does not use: the slider refuses a value of it it does not hold)
        unused = unused_input(spec.plant.actuator)
        set_parameters(driver, executor, "slider", {name: value for name, value in _plant_values(spec).items()
                                                    if not settings.SLIDER_NODE[name].start_only and name != unused})
        if spec.lockstep:
            _check_lockstep(driver, executor, spec)
        self.recorder = _attached_recorder(spec, driver.get_namespace())
        self._last_ns: dict[str, int] = {}
        #: Poses the slider sent again (lockstep: while it waits, every REPEAT s).
        self.resent = 0
        for topic in self.RECORDED:
            driver.create_subscription(message_class(TOPIC_TYPES[topic]), topic, self._keeper(topic), 100)
        if spec.lockstep:  # what this driver sends the slider stamped, recorded as the slider takes it
            driver.create_subscription(message_class(STAMPED_TYPE), STAMPED_COMMAND, self._keeper(STAMPED_COMMAND),
                                       100)

    def _keeper(self, topic: str) -> Callable[[Any], None]:
        """The callback of ``topic``: follow time and inputs, and record the message."""

        def keep(msg: Any) -> None:
            if topic in self.RESENT:  # (in lockstep a waiting slider sends its state and sample again)
                if stamp_ns(msg.header.stamp) <= self._last_ns.get(topic, -1):
                    self.resent += topic == "pose"
                    return
                self._last_ns[topic] = stamp_ns(msg.header.stamp)
            if topic in COMMANDS:
                self._follow(command_from_message(topic, msg, self.now()))
            if self.recorder is not None and (self._pose_ns >= 0 or topic not in COMMANDS):
                # commands are logged when seen (their stamps are the sender's), states at their stamps
                log_ns = self._pose_ns if topic in COMMANDS else stamp_ns(msg.header.stamp)
                self.recorder.write(MessageRecord(topic, msg, log_ns))

        return keep

    def _follow(self, command: Command) -> None:
        """Track the inputs in force (for the status line); a refused command changes nothing."""
        with contextlib.suppress(ParameterError):
            self._params, self._inputs = apply(command, self._params, self._inputs)

    @property
    def _pose_ns(self) -> int:
        """The newest pose stamp seen [ns] (-1: none yet)."""
        return self._last_ns.get("pose", -1)

    def now(self) -> float:
        """Simulation time [s]: the newest pose stamp seen."""
        return self._pose_ns / 1e9

    def now_ns(self) -> int:
        """The time [ns] every state topic has reached (they travel apart: the recording of a point
        the driver waits at holds all three)."""
        return min((self._last_ns.get(topic, -1) for topic in STATE_TOPICS), default=-1)

    def sample_ns(self) -> int:
        """The newest mean_velocity stamp recorded [ns] (-1: none yet)."""
        return self._last_ns.get("mean_velocity", -1)

    def standing(self) -> bool:
        """(a step in another process: its end is not known here; the stamps show it)"""
        return True

    def inputs(self) -> Inputs:
        """The inputs in force, as followed on the command topics."""
        return self._inputs

    def ready(self) -> bool:
        """Whether the slider has published its time yet (each of its state topics: in lockstep
        the recording then holds the state it waits in, whichever topic came first)."""
        return all(self._last_ns.get(topic, -1) >= 0 for topic in STATE_TOPICS)

    def set_parameters(self, values: dict[str, Any]) -> None:
        """Set the slider's parameters through its parameter service."""
        set_parameters(self.driver, self.executor, "slider", values)
        self._follow(Command(self.now(), PARAMETERS, values))

    def set_controller_parameters(self, values: dict[str, Any]) -> None:
        """Set the controller's parameters through its parameter service."""
        set_parameters(self.driver, self.executor, "controller", values)

    def close(self) -> None:
        """Finish this process's recording."""
        if self.recorder is not None:
            self.recorder.finish()


def _check_lockstep(driver: Any, executor: Any, spec: ExperimentSpec) -> None:
    """A lockstep run attaches to a slider started in lockstep with this driver (and the
    controller) among its participants: those are start-up parameters."""
    values = get_parameters(driver, executor, "slider", ["lockstep", "lockstep_participants"])
    lockstep, who = values[0].bool_value, values[1].string_value
    wanted = "scheduler,controller" if spec.controller else "scheduler"
    if not lockstep or set(who.replace(" ", "").split(",")) != set(wanted.split(",")):
        pace = f"in lockstep with {who!r}" if lockstep else "in real time"
        raise ExperimentError(
            f"the slider in {driver.get_namespace()} runs {pace}: a lockstep run needs it started with lockstep "
            f"true and lockstep_participants '{wanted}' "
            f"(friction-sim feeder --ros-args -p lockstep:=true -p lockstep_participants:={wanted}), or run it "
            "with --real-time")


def _attached_recorder(spec: ExperimentSpec, namespace: str) -> Any:
    """The recorder of an attached run (None: not recording); topics are stored
    fully qualified, in the namespace of the nodes it follows."""
    if not spec.log_path:
        return None
    from friction_sim.io.recorder import Recorder

    return Recorder(spec.log_path, metadata={**_plant_values(spec), "recorded_by": "experiment --attach"},
                    namespace=namespace)


def _wait_for_controller_model(driver: Any, executor: Any) -> None:
    """Wait until the namespace's controller has taken its plant's model at
    start-up (its diagnostics no longer say it waits for it: it reads the
    plant within 5 s or gives up and says so), so parameters set on it now are
    not overwritten by that read."""
    from diagnostic_msgs.msg import DiagnosticArray

    settled: list[bool] = []

    def on_diagnostics(msg: Any) -> None:
        if any(status.name == "controller" and WAITING_FOR_PLANT not in status.message for status in msg.status):
            settled.append(True)

    subscription = driver.create_subscription(DiagnosticArray, "diagnostics", on_diagnostics, 10)
    try:
        spin_until(executor, lambda: bool(settled), 30.0,
                   f"the controller in {driver.get_namespace()} reports no settled model on diagnostics "
                   "within 30 s (is it running, with its diagnostics_period under 25 s?)")
    finally:
        driver.destroy_subscription(subscription)


def collect_mean_velocity(driver: Any, result: ExperimentResult) -> None:
    """Append every mean-velocity sample (stamp [s], speed) an attached slider publishes to ``result``."""

    def collect(msg: Any) -> None:
        _keep_sample(result, stamp_ns(msg.header.stamp), msg.twist.linear.x)

    driver.create_subscription(message_class(TOPIC_TYPES["mean_velocity"]), "mean_velocity", collect, 100)


def _keep_sample(result: ExperimentResult, t_ns: int, speed: float) -> None:
    """Append a mean-velocity sample stamped ``t_ns`` to ``result`` (lockstep: once, though sent again)."""
    t = ns_to_seconds(t_ns)
    if not result.mean_velocity or t > result.mean_velocity[-1][0]:
        result.mean_velocity.append((t, speed))


class _SampleSink:
    """A sink of the slider in this process that hands its period means to the result as it
    publishes them: the same samples, at the same stamps, as the topic carries, without a
    subscription whose every sample wakes the driver's executor (a wait-set rebuild over
    every entity of the slider node, 50 times a simulated second)."""

    def __init__(self, result: ExperimentResult) -> None:
        self._result = result

    def write(self, record: Record) -> bool:
        """Keep a period's mean; the rest is not the result's (the schedule's commands come from the driver)."""
        if isinstance(record, PeriodRecord):
            _keep_sample(self._result, seconds_to_ns(record.period.t), record.period.mean_velocity)
        return True

    def close(self) -> None:
        """(nothing to finish)"""


__all__ = ["AttachedPlant", "InProcessPlant", "collect_mean_velocity"]
