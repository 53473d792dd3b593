"""Steering experiments over real ROS topics: a schedule of commands played into
a slider (and optionally a controller) running in this process, or already
running elsewhere.

The nodes run exactly as they would under ``ros2 run``; a driver node
publishes each scheduled :class:`~friction_sim.core.model.commands.Command` on its
topic (as :func:`friction_sim.io.messages.command_message`) when the slider's
simulation time reaches it, and listens to what the nodes publish.  The
result holds the time series a report or a test needs
(:class:`~friction_sim.experiment.job.ExperimentResult`);
:mod:`friction_sim.experiment.metrics` turns them into settling time,
overshoot and steady error.  This is the one module of the package outside
``friction_sim.ros`` that imports rclpy (lazily, inside the functions); a
driver's ROS primitives (turning the executor, parameter services) are
:mod:`friction_sim.ros.driving`.
"""

from __future__ import annotations

import contextlib
import functools
import math
import time
import uuid
from collections.abc import Callable, Sequence
from typing import Any

from friction_sim.core.model import spec as settings
from friction_sim.core.model.commands import (
    COMMANDS,
    CONTROLLER,
    PARAMETERS,
    SLIDER,
    Command,
    Outcome,
    apply,
    consumed_by,
    unused_input,
)
from friction_sim.core.model.params import Inputs
from friction_sim.core.runtime.controller import WAITING_FOR_PLANT
from friction_sim.core.runtime.lockstep import to_ns
from friction_sim.errors import ExperimentError, ParameterError
from friction_sim.experiment.job import (
    SCENARIO_METADATA,
    ExperimentResult,
    ExperimentSpec,
    OperatorAction,
    Status,
    scenario_metadata,
)
from friction_sim.experiment.lockstep_run import (
    ScheduleParticipant,
    for_controller,
    for_slider,
    plant_sets,
    timeline,
)
from friction_sim.io.messages import (
    STATE_TOPICS,
    TOPIC_TYPES,
    command_from_message,
    command_message,
    message_class,
    ns_to_seconds,
    stamp_ns,
)
from friction_sim.io.stamped import STAMPED_COMMAND, STAMPED_TYPE
from friction_sim.ros.driving import get_parameters, overrides, set_parameters, spin_once, spin_until

Progress = Callable[[Status], None]
#: Wall time [s] a lockstep run waits for a slider whose time stands still on its way to a point
#: of the schedule (its own lockstep_timeout names a participant that does not answer before this).
LOCKSTEP_WAIT = 120.0


def run_experiment(spec: ExperimentSpec, *, namespace: str | None = None, attach: bool = False,
                   progress: Progress | None = None) -> ExperimentResult:
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
        scheduler = ScheduleParticipant(spec, driver, functools.partial(spin_until, executor), LOCKSTEP_WAIT,
                                        attached=attach) if spec.lockstep else None
        _wait_until_connected(executor, publishers, spec.controller, plant, scheduler)
        operator = _OperatorHands(driver, executor, publishers, spec.operator)
        if scheduler is not None:
            _play_lockstep(spec, plant, executor, scheduler, result, progress, operator)
        else:
            _play(spec, plant, executor, publishers, result, progress, operator)
    finally:
        if plant is not None:
            plant.close()
        driver.destroy_node()
        executor.shutdown(timeout_sec=0.0)
    return result


def run_standalone(spec: ExperimentSpec, *, namespace: str | None = None, attach: bool = False,
                   progress: Progress | None = None) -> ExperimentResult:
    """:func:`run_experiment` in a process that has not initialised rclpy (a
    command-line job): initialise it, run, and shut it down again."""
    import rclpy

    rclpy.init(args=[])
    try:
        return run_experiment(spec, namespace=namespace, attach=attach, progress=progress)
    finally:
        rclpy.try_shutdown()


def _play(spec: ExperimentSpec, plant: _InProcess | _Attached, executor: Any, publishers: dict[str, Any],
          result: ExperimentResult, progress: Progress | None, operator: _OperatorHands) -> None:
    """Publish each scheduled command when simulation time reaches it (and do
    what the operator does at its time)."""
    pending = sorted(spec.schedule, key=lambda c: c.t)
    start = plant.now()
    _start_recording(spec, plant.recorder, start)
    target = spec.initial_target
    last_progress = time.monotonic()
    while (now := plant.now() - start) < spec.duration:
        while pending and pending[0].t <= now:
            command = pending.pop(0)
            if command.name == PARAMETERS:  # a plant parameter (a load on the slideway): set, not published
                plant.set_parameters(dict(command.values))
            else:
                publishers[command.name].publish(command_message(command.at(now + start)))
            result.commands.append(command.at(now))
            if not plant.RECORDS_TARGETS:
                _record_unseen(plant.recorder, command.at(now + start))
            target = command.values.get("target_speed", target)
        operator.act(now, start)
        spin_once(executor, 0.0005)
        if progress is not None and time.monotonic() - last_progress > 0.25:
            progress(_status(spec, now, target, plant.inputs(), result))
            last_progress = time.monotonic()
    _shift(result, start)


def _play_lockstep(spec: ExperimentSpec, plant: _InProcess | _Attached, executor: Any,
                   scheduler: ScheduleParticipant, result: ExperimentResult, progress: Progress | None,
                   operator: _OperatorHands) -> None:
    """Send the schedule stamped, as the slider's scheduler participant (see
    :mod:`friction_sim.experiment.lockstep_run`): each time's commands at once,
    and at a time with a parameter set, a controller input or an operator's
    calls, wait until the slider stands there to do them."""
    start_ns = plant.now_ns()
    start = start_ns / 1e9
    _start_recording(spec, plant.recorder, start)
    target = spec.initial_target
    if progress is not None:
        progress(_status(spec, 0.0, target, plant.inputs(), result))
    points = timeline(spec)
    for index, (t_ns, commands, actions) in enumerate(points):
        sent = [command for command in commands if for_slider(command)] + \
            [action.send for action in actions if action.send is not None]
        scheduler.promise(start_ns + t_ns, [command.at(start + t_ns / 1e9) for command in sent])
        for command in commands:
            result.commands.append(command.at(t_ns / 1e9))
            target = command.values.get("target_speed", target)
        controller = for_controller(commands) if spec.controller else {}
        calls = [name for action in actions for name in action.calls]
        if not (controller or plant_sets(commands) or calls) and index < len(points) - 1:
            continue
        scheduler.reach(plant, start_ns + t_ns)
        for command in plant_sets(commands):
            plant.set_parameters(dict(command.values))
        if controller:
            set_parameters(scheduler.driver, executor, "controller", controller)
            for command in commands:
                if not command.for_slider:
                    _record_unseen(plant.recorder, command.at(start + t_ns / 1e9))
        if calls:
            following = start_ns + (points[index + 1][0] if index + 1 < len(points) else t_ns)
            operator.call_in_lockstep(calls, plant, functools.partial(scheduler.promise, following))
        if progress is not None:
            progress(_status(spec, t_ns / 1e9, target, plant.inputs(), result))
    if isinstance(plant, _Attached):
        scheduler.finish(plant)
    else:
        _collect_to_the_end(plant, executor, result)
    _shift(result, start)


def _collect_to_the_end(plant: _InProcess, executor: Any, result: ExperimentResult) -> None:
    """Wait until the driver has taken the last mean velocity the slider in this process
    published (the slider says which): the run may reach its end with samples still
    queued for the driver's subscription (one run kept 53 of 69)."""
    last_ns = plant.last_sample_ns()
    spin_until(executor, lambda: last_ns < 0 or (len(result.mean_velocity) > 0
                                                 and to_ns(result.mean_velocity[-1][0]) >= last_ns),
               LOCKSTEP_WAIT, f"the last mean velocity (t = {last_ns / 1e9:.9f} s) never reached the driver")


def _start_recording(spec: ExperimentSpec, recorder: Any, start: float) -> None:
    """Write the scenario metadata record and the initial target into the recording."""
    if recorder is None:
        return
    recorder.add_metadata(SCENARIO_METADATA, scenario_metadata(spec, round(start * 1e9)))
    if spec.initial_target is not None:
        _record_unseen(recorder, Command(start, "target_speed", {"target_speed": spec.initial_target}))


def _record_unseen(recorder: Any, command: Command) -> None:
    """Log a command the slider does not consume (a target for the controller)
    in a recording that does not see it: an attached run's, and the initial
    target (a controller parameter, not a message)."""
    if recorder is not None and not command.for_slider:
        recorder.on_command(Outcome(command.at(round(command.t * 1e9) / 1e9)), "")


def _status(spec: ExperimentSpec, now: float, target: float | None, inputs: Inputs,
            result: ExperimentResult) -> Status:
    """The status line's view at ``now``."""
    speed = result.mean_velocity[-1][1] if result.mean_velocity else math.nan
    return Status(now, spec.duration, target, speed, inputs.excitation_amplitude, inputs.drive_force,
                  inputs.excitation_frequency)


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


class _InProcess:
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
            period = self.slider.realtime.last_period
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

    def close(self) -> None:
        """Destroy the nodes (the slider finishes its recording)."""
        if self._own is not None:
            self._own.stop()
        for node in self.nodes:
            node.destroy_node()


class _Attached:
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
                self.recorder.write(topic, msg, log_ns)

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


class _OperatorHands:
    """Does the scenario's operator actions when simulation time reaches them:
    publishes a command as it is, or calls the slider's control services in
    order, each waited for (its answer, refused or not, is the slider's to record)."""

    CALL_TIMEOUT = 10.0

    def __init__(self, driver: Any, executor: Any, publishers: dict[str, Any],
                 actions: Sequence[OperatorAction]) -> None:
        from std_srvs.srv import Trigger

        self._executor, self._publishers = executor, publishers
        self._pending = sorted(actions, key=lambda action: action.t)
        names = {name for action in actions for name in action.calls}
        self._clients = {name: driver.create_client(Trigger, f"slider/{name}") for name in sorted(names)}
        self._request = Trigger.Request

    def call_in_lockstep(self, calls: Sequence[str], plant: Any, release: Callable[[], None]) -> None:
        """The calls of one time in order, the slider standing there (lockstep): once a
        pause holds it, ``release`` lets the scheduler's promise move on, so the steps
        that follow can move it (each waited for)."""
        for name in calls:
            self._call(name)
            if name == "pause":
                release()
            if name == "step":
                spin_until(self._executor, plant.standing, self.CALL_TIMEOUT,
                           f"the slider's ~/step did not end within {self.CALL_TIMEOUT:g} s")

    def act(self, now: float, start: float) -> None:
        while self._pending and self._pending[0].t <= now:
            action = self._pending.pop(0)
            if action.send is not None:
                self._publishers[action.send.name].publish(command_message(action.send.at(now + start)))
            for name in action.calls:
                self._call(name)

    def _call(self, name: str) -> None:
        client = self._clients[name]
        spin_until(self._executor, client.service_is_ready, self.CALL_TIMEOUT,
                   f"the slider's ~/{name} service did not answer within {self.CALL_TIMEOUT:g} s")
        spin_until(self._executor, client.call_async(self._request()).done, self.CALL_TIMEOUT,
                   f"the slider's ~/{name} call got no answer within {self.CALL_TIMEOUT:g} s")


def _command_publishers(driver: Any) -> dict[str, Any]:
    """One publisher per command topic of the table."""
    return {name: driver.create_publisher(message_class(entry.message_type), name, 10)
            for name, entry in COMMANDS.items()}


def _collect_mean_velocity(driver: Any, result: ExperimentResult) -> None:
    """Append every mean-velocity sample (stamp [s], speed) to ``result``."""

    def collect(msg: Any) -> None:
        t = ns_to_seconds(stamp_ns(msg.header.stamp))
        if not result.mean_velocity or t > result.mean_velocity[-1][0]:  # (lockstep: a sample sent again)
            result.mean_velocity.append((t, msg.twist.linear.x))

    driver.create_subscription(message_class(TOPIC_TYPES["mean_velocity"]), "mean_velocity", collect, 100)


def _wait_until_connected(executor: Any, publishers: dict[str, Any], controller: bool,
                          plant: _InProcess | _Attached, scheduler: ScheduleParticipant | None,
                          timeout: float = 10.0) -> None:
    """Spin until discovery has matched the driver's publishers and the nodes
    are ready (a controller has its plant's parameters; an attached slider
    has published its time)."""
    nodes = (SLIDER, CONTROLLER) if controller else (SLIDER,)
    needed = {entry.name for node in nodes for entry in consumed_by(node)}
    spin_until(executor, lambda: all(publishers[name].get_subscription_count() >= 1 for name in needed)
               and plant.ready() and (scheduler is None or scheduler.connected()), timeout,
               f"the experiment's nodes did not connect within {timeout:g} s")


def _shift(result: ExperimentResult, start: float) -> None:
    """Express every time relative to the experiment's start (the samples before it dropped)."""
    result.mean_velocity = result.mean_velocity.since(start)
    result.amplitude = result.amplitude.since(start)
    result.drive = result.drive.since(start)


__all__ = ["ExperimentResult", "ExperimentSpec", "Status", "run_experiment", "run_standalone"]
