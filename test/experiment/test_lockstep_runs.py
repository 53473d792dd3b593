"""Lockstep over real topics: the same scenario gives the same recording, message by message.

Two recordings of a lockstep run may differ only in what the wall clock says
(:func:`friction_sim.io.digest.recording_digest` leaves exactly that out), so
each test compares whole digests: every state sample, event, period mean,
command, accelerometer reading and diagnostics message, with their stamps.
"""

from __future__ import annotations

import dataclasses
import threading
import time
import uuid
from pathlib import Path

import pytest

from friction_sim.core.runtime.lockstep import CONTROLLER
from friction_sim.experiment import runner
from friction_sim.experiment.scenario import load_scenario
from friction_sim.experiment.verify import verify
from friction_sim.io.digest import differences, recording_digest
from friction_sim.io.reader import read_recording

from helpers import hold_the_interpreter

ROOT = Path(__file__).resolve().parents[2]


def _run(path: str, out: Path, namespace: str, **changes: object) -> dict[str, str]:
    scenario = load_scenario(ROOT / path)
    spec = dataclasses.replace(scenario.spec(), log_path=out, lockstep=True)
    if changes:
        spec = dataclasses.replace(spec, slider_parameters={**spec.slider_parameters, **changes})
    runner.run_experiment(spec, namespace=namespace)
    return recording_digest(out)


def test_acceptance_7_with_noise_gives_the_same_recording_with_and_without_a_stall(
        ros: None, tmp_path: Path) -> None:
    """Resonant plant, inner loop on the accelerometer with seeded noise: two runs, the
    second with the whole process stalled for 0.4 s of wall time in the middle of the
    first target step, give recordings identical in every message and stamp."""
    namespace = f"/lockstep_{uuid.uuid4().hex[:8]}"
    first = _run("config/acceptance_7_resonant_steps.yaml", tmp_path / "a.mcap", namespace,
                 accelerometer_noise=0.05, accelerometer_seed=7)
    stalled: list[bool] = []
    publish = runner.ScheduleParticipant.promise

    def promise(self, t_ns, commands=()):  # type: ignore[no-untyped-def]
        if commands == [] and t_ns >= 1_000_000_000 and not stalled:  # the first target step's point
            threading.Timer(0.01, lambda: (hold_the_interpreter(0.4), stalled.append(True))).start()
        publish(self, t_ns, commands)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(runner.ScheduleParticipant, "promise", promise)
        second = _run("config/acceptance_7_resonant_steps.yaml", tmp_path / "b.mcap", namespace,
                      accelerometer_noise=0.05, accelerometer_seed=7)
    assert stalled, "the stall was injected"
    assert differences(first, second) == []
    result = verify(read_recording(tmp_path / "b.mcap"))  # replay --verify, as of any recording
    assert result.passed and result.samples == 3001, result.lines()
    assert int(first[f"{namespace}/mean_velocity"].split(":")[0]) == 149  # every period's mean but the first
    assert int(first[f"{namespace}/accelerometer"].split(":")[0]) == 3001


def test_the_demo_gives_the_same_recording_twice(ros: None, tmp_path: Path) -> None:
    """The demo: open-loop steps, a lift, closed loop with target, drive-force and
    frequency steps, a refused command, pause, two steps and a resume.  The driver sends
    the promises of the open-loop steps back to back; in the second run each of its
    promises after the first comes 0.1 s of wall time late (the slider then waits at the
    one before), so the slider's diagnostics are made with other promises come: the same
    recording all the same (each report counts the messages stamped by its time)."""
    namespace = f"/lockstep_{uuid.uuid4().hex[:8]}"
    first = _run("config/demo.yaml", tmp_path / "a.mcap", namespace)
    publish, sent = runner.ScheduleParticipant.promise, []

    def late(self, t_ns, commands=()):  # type: ignore[no-untyped-def]
        if sent:
            time.sleep(0.1)  # the delay under test: the scheduler's message comes late
        sent.append(t_ns)
        publish(self, t_ns, commands)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(runner.ScheduleParticipant, "promise", late)
        second = _run("config/demo.yaml", tmp_path / "b.mcap", namespace)
    assert len(sent) > 6
    assert differences(first, second) == []
    assert f"{namespace}/sim_control" in first and f"{namespace}/rejected_commands" in first


def test_attached_to_a_feeder_in_lockstep_the_recording_is_the_same_twice(ros: None, tmp_path: Path) -> None:
    """``experiment --attach`` in lockstep: two fresh feeders (another process each,
    started in lockstep with this driver and the controller as participants), the
    same scenario, recordings made by this process from the topics: identical."""
    import subprocess
    import sys

    scenario = load_scenario(ROOT / "config" / "acceptance_1_matched.yaml")
    digests = []
    namespace = f"/lockstep_{uuid.uuid4().hex[:8]}"  # (the same both times: the file's metadata names it)
    for run in ("a", "b"):
        feeder = subprocess.Popen(
            [str(Path(sys.executable).parent / "friction-sim"), "feeder", "--ros-args", "-r", f"__ns:={namespace}",
             "-p", "lockstep:=true", "-p", "lockstep_participants:=scheduler,controller"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            result = runner.run_experiment(dataclasses.replace(scenario.spec(), log_path=tmp_path / f"{run}.mcap"),
                                           namespace=namespace, attach=True)
        finally:
            feeder.send_signal(2)
            _, err = feeder.communicate(timeout=20)
        assert feeder.returncode == 0, err
        digests.append(recording_digest(tmp_path / f"{run}.mcap"))
        assert result.mean_velocity[-1][1] == pytest.approx(0.00015, rel=0.01)  # the last target, reached
    assert differences(*digests) == []
    assert int(digests[0][f"{namespace}/mean_velocity"].split(":")[0]) == 89  # every period's mean but the first


def test_a_participant_is_waited_for_until_it_joins_and_named_when_it_goes_silent(ros: None) -> None:
    """A slider in lockstep with a controller participant: before the controller
    joins, the slider waits at its first sample and says so (counted) once per
    lockstep_timeout; a controller that joins late is waited for and regulates;
    once it has answered and goes silent, the slider names it after
    lockstep_timeout (counted from when it began to wait for that answer) and
    stops (a fault), never running past the unanswered sample."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from friction_sim.ros.controller import ControllerNode
    from friction_sim.ros.run import NodeFault
    from friction_sim.ros.slider import SliderNode

    namespace = f"/lockstep_{uuid.uuid4().hex[:8]}"
    slider = SliderNode(namespace=namespace, parameter_overrides=[
        Parameter("lockstep", value=True), Parameter("lockstep_participants", value=CONTROLLER),
        Parameter("lockstep_timeout", value=0.5)])
    gate = slider.realtime.gate
    executor = SingleThreadedExecutor()
    executor.add_node(slider)
    controller = None
    try:
        deadline = time.monotonic() + 20.0
        while gate.join_waits < 2 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert gate.join_waits >= 2 and not slider.fault  # waited, said so, and goes on waiting
        assert slider.realtime.t_ns == 20_000_000  # at its first sample, not past it
        controller = ControllerNode(namespace=namespace, parameter_overrides=[Parameter("target_speed", value=1e-4)])
        executor.add_node(controller)
        while gate.answers < 50 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.01)
        assert gate.answers >= 50 and not slider.fault
        executor.remove_node(controller)
        controller.destroy_node()
        controller = None
        while not slider.fault and time.monotonic() < deadline:
            try:
                executor.spin_once(timeout_sec=0.05)
            except NodeFault:  # the slider ends the executor that spins it (run_node exits with code 3)
                break
        assert "lockstep: waited 0.5 s (lockstep_timeout) for the controller: no answer on control_answer to " \
            "the mean_velocity sample of t = " in slider.fault
        assert slider.realtime.t_ns == gate.awaited[0]  # it never ran past the unanswered sample
    finally:
        if controller is not None:
            controller.destroy_node()
        slider.destroy_node()


def test_step_moves_a_paused_lockstep_slider_by_exactly_its_length(ros: None) -> None:
    """``~/step`` keeps working in lockstep: paused, each call lets the slider go on by step_periods periods."""
    from rclpy.parameter import Parameter
    from std_srvs.srv import Trigger

    from friction_sim.ros.slider import SliderNode

    slider = SliderNode(namespace=f"/lockstep_{uuid.uuid4().hex[:8]}", parameter_overrides=[
        Parameter("lockstep", value=True), Parameter("lockstep_participants", value="")])

    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    caller = rclpy.create_node("caller", namespace=slider.get_namespace())
    executor = SingleThreadedExecutor()
    executor.add_node(slider)
    executor.add_node(caller)
    clients = {name: caller.create_client(Trigger, f"slider/{name}") for name in ("pause", "step")}

    def call(name: str) -> Trigger.Response:  # as ros2 service call does
        assert clients[name].wait_for_service(timeout_sec=10.0)
        future = clients[name].call_async(Trigger.Request())
        executor.spin_until_future_complete(future, timeout_sec=10.0)
        response: Trigger.Response = future.result()
        return response

    try:
        wall = time.monotonic()
        while slider.realtime.slider.t < 0.1 and time.monotonic() - wall < 10.0:  # nobody to wait for: it runs
            time.sleep(0.001)  # poll interval: waiting for t to pass 0.1
        assert call("pause").success
        t0 = slider.realtime.slider.t
        assert call("step").success
        assert call("step").success  # a second call extends the first
        deadline = time.monotonic() + 10.0
        while slider.realtime.gate.stepping and time.monotonic() < deadline:
            time.sleep(0.001)  # poll interval: waiting for the step to end
        assert slider.realtime.t_ns == round(t0 * 1e9) + 40_000_000
        assert slider.realtime.paused
    finally:
        caller.destroy_node()
        slider.destroy_node()
