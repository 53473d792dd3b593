"""Steering experiments over real ROS topics: a schedule of commands played into
a slider (and optionally a controller) running in this process, or already
running elsewhere.

The nodes run exactly as they would under ``ros2 run``; a driver node
publishes each scheduled :class:`~friction_sim.core.model.commands.Command` on its
topic (as :func:`friction_sim.io.messages.command_message`) when the slider's
simulation time reaches it (in lockstep: stamped, see
:mod:`friction_sim.experiment.lockstep_run`), and collects what the nodes
publish: from the topics when attached, from the slider's sinks when the nodes
run in this process (:mod:`friction_sim.experiment.plants`).  The result holds the time series a report or a test needs
(:class:`~friction_sim.experiment.job.ExperimentResult`);
:mod:`friction_sim.experiment.metrics` turns them into settling time,
overshoot and steady error.  This is the one module of the package outside
``friction_sim.ros`` that imports rclpy (lazily, inside the functions); a
driver's ROS primitives (turning the executor, parameter services) are
:mod:`friction_sim.ros.driving`.
"""

from __future__ import annotations

import functools
import math
import time
import uuid
from collections.abc import Callable, Sequence
from typing import Any

from friction_sim.core.engine import transient_kernel
from friction_sim.core.model.commands import (
    COMMANDS,
    CONTROLLER,
    PARAMETERS,
    SLIDER,
    Command,
    Outcome,
    consumed_by,
)
from friction_sim.core.model.params import Inputs
from friction_sim.core.physics.plant import slideway_amplitude
from friction_sim.core.runtime.lockstep import to_ns
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
from friction_sim.experiment.plants import AttachedPlant, InProcessPlant, collect_mean_velocity
from friction_sim.io.messages import (
    command_message,
    message_class,
)
from friction_sim.io.sinks import CommandRecord
from friction_sim.ros.driving import spin_once, spin_until
from friction_sim.ros.heap import run_heap

Progress = Callable[[Status], None]
#: Wall time [s] a lockstep run waits for a slider whose time stands still on its way to a point
#: of the schedule (its own lockstep_timeout names a participant that does not answer before this).
LOCKSTEP_WAIT = 120.0
#: Wall time [s] between the lockstep driver's looks at the slider's time.  Attached, the slider's
#: state messages wake it as they come; in this process the slider triggers a guard condition
#: when it stands at the driver's promise, so the looks in between only re-check the deadline
#: (each is a rebuild of the executor's wait set, ~0.5 ms of the GIL the slider computes with).
ATTACHED_POLL = 0.01
HELD_POLL = 0.1
#: Wall time [s] a lockstep run in this process waits, before it starts, for its resonant
#: slider's compiled transient step to load (:func:`~friction_sim.core.engine.transient_kernel.await_loading`):
#: a load from the cache takes ~0.5 s; a first compile, longer, is not waited for.
KERNEL_WAIT = 3.0


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
    plant: InProcessPlant | AttachedPlant | None = None
    try:
        publishers = _command_publishers(driver)
        if attach:
            collect_mean_velocity(driver, result)
        plant = AttachedPlant(spec, driver, executor) if attach else InProcessPlant(spec, ns, executor, result)
        # (a slider in this process wakes the executor when it stands where the driver waits for it)
        scheduler = ScheduleParticipant(spec, driver, functools.partial(
            spin_until, executor, poll=ATTACHED_POLL if attach else HELD_POLL), LOCKSTEP_WAIT,
            attached=attach) if spec.lockstep else None
        _wait_until_connected(executor, publishers, spec.controller, plant, scheduler)
        operator = _OperatorHands(driver, executor, publishers, spec.operator)
        if scheduler is not None and not attach:  # (the slider stands at its start until the first promise)
            transient_kernel.await_loading(KERNEL_WAIT)
        with run_heap():  # (the collector walks what the run makes, not the process's start-up)
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


def _play(spec: ExperimentSpec, plant: InProcessPlant | AttachedPlant, executor: Any, publishers: dict[str, Any],
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


def _play_lockstep(spec: ExperimentSpec, plant: InProcessPlant | AttachedPlant, executor: Any,
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
            plant.set_controller_parameters(controller)
            for command in commands:
                if not command.for_slider:
                    _record_unseen(plant.recorder, command.at(start + t_ns / 1e9))
        if calls:
            following = start_ns + (points[index + 1][0] if index + 1 < len(points) else t_ns)
            operator.call_in_lockstep(calls, plant, functools.partial(scheduler.promise, following))
        if progress is not None:
            progress(_status(spec, t_ns / 1e9, target, plant.inputs(), result))
    if isinstance(plant, AttachedPlant):
        scheduler.finish(plant)
    else:
        _collect_to_the_end(plant, executor, result)
    _shift(result, start)


def _collect_to_the_end(plant: InProcessPlant, executor: Any, result: ExperimentResult) -> None:
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
        recorder.write(CommandRecord(Outcome(command.at(round(command.t * 1e9) / 1e9)), ""))


def _status(spec: ExperimentSpec, now: float, target: float | None, inputs: Inputs,
            result: ExperimentResult) -> Status:
    """The status line's view at ``now``: the resonant plant by its drive level and the
    slideway's steady amplitude, the force actuator by its Pa."""
    speed = result.mean_velocity[-1][1] if result.mean_velocity else math.nan
    if spec.plant.resonant:
        slideway = slideway_amplitude(spec.plant, inputs)[0]
        return Status(now, spec.duration, target, speed, slideway, inputs.drive_force, inputs.excitation_frequency,
                      inputs.drive_level)
    return Status(now, spec.duration, target, speed, inputs.excitation_amplitude, inputs.drive_force,
                  inputs.excitation_frequency)


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


def _wait_until_connected(executor: Any, publishers: dict[str, Any], controller: bool,
                          plant: InProcessPlant | AttachedPlant, scheduler: ScheduleParticipant | None,
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
