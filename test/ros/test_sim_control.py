"""The slider's simulation control over real ROS services (std_srvs/Trigger):
``~/pause``, ``~/resume``, ``~/step`` and ``~/reset``.

Pausing stops simulation time exactly (and /clock with it), resuming goes on
without a jump, stepping a paused slider N times gives the trajectory that
running gives (to 1e-12, against the exact core run offline), a reset starts
the motion from rest again, and every call is recorded, so ``replay
--verify`` reproduces a run with pauses, steps and resets."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMsg

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.commands import Outcome
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.experiment.verify import recorded_commands, verify
from friction_sim.io.reader import read_recording
from friction_sim.ros.slider import SliderNode

from ros_harness import OUTPUTS, CommandLog, Probe, diagnostics_values, namespace, stamp_ns


class Rig:
    """A slider (recording to ``path`` if given) and a probe that calls its services."""

    def __init__(self, path: Path | None = None, **parameters: Any) -> None:
        self.ns = namespace()
        if path is not None:
            parameters["log_path"] = str(path)
        self.node = SliderNode(namespace=self.ns, parameter_overrides=[
            Parameter(name, value=value) for name, value in parameters.items()])
        self.outcomes: list[Outcome] = []
        self.node.sinks.append(CommandLog(self.outcomes))
        self.probe = Probe(self.ns, self.node, outputs={**OUTPUTS, "/clock": ClockMsg})
        self.probe.wait_for_connection()

    def call(self, name: str) -> Any:
        return self.probe.control(name)

    def poses_after(self, first: int) -> list[Any]:
        return self.probe.received["pose"][first:]

    def close(self) -> None:
        self.probe.close()
        self.node.destroy_node()


@pytest.fixture
def rig(ros: None) -> Iterator[Rig]:
    made = Rig()
    yield made
    made.close()


def _t(rig: Rig) -> float:
    return float(rig.node.realtime.slider.t)


def test_pause_stops_time_exactly_and_resume_goes_on_without_a_jump(ros: None) -> None:
    rig = Rig(publish_clock=True)
    try:
        assert rig.probe.spin_until(lambda: _t(rig) >= 0.2, 10.0)  # it has run a while (its own time)
        answer = rig.call("pause")
        assert answer.success and answer.message.startswith("paused at t = ")
        t_pause = _t(rig)
        # What was on its way arrives: the last state and /clock published are those of the pause's
        # instant (the first tick after it publishes the state the pause advanced to); wait for them.
        pause_ns = round(t_pause * 1e9)
        assert rig.probe.spin_until(lambda: any(stamp_ns(m) == pause_ns for m in rig.probe.received["pose"][-5:])
                                    and any(m.clock.sec * 1_000_000_000 + m.clock.nanosec == pause_ns
                                            for m in rig.probe.received["/clock"][-5:]), 10.0)
        poses, clocks = len(rig.probe.received["pose"]), len(rig.probe.received["/clock"])
        # Paused for 500 of the node's own ticks (about 0.5 s at 1 kHz; counted, not timed): each of
        # them would have published a state and /clock had it not been paused.
        ticks = rig.node.topics.ticks_published  # the node's tick count
        assert rig.probe.spin_until(lambda: rig.node.topics.ticks_published >= ticks + 500, 30.0)
        assert rig.node.realtime.now(0) == t_pause == _t(rig), "simulation time moved while paused"
        assert rig.probe.spin_until(lambda: any(
            diagnostics_values(m).get("paused") == "True" for m in rig.probe.received["diagnostics"]), 3.0)
        assert rig.call("pause").success is False, "a second pause is refused (nothing to do)"
        assert rig.call("resume").success
        # The first state and /clock after resuming arrive; the topics are reliable and in order, so
        # whatever a paused tick had published would have come before them.
        assert rig.probe.spin_until(lambda: any(stamp_ns(m) > pause_ns for m in rig.probe.received["pose"][poses:])
                                    and any(m.clock.sec * 1_000_000_000 + m.clock.nanosec > pause_ns
                                            for m in rig.probe.received["/clock"][clocks:]), 10.0)
        after = [stamp_ns(m) for m in rig.probe.received["pose"][poses:]]
        assert min(after) > pause_ns, "states were published while paused"
        assert all(m.clock.sec * 1_000_000_000 + m.clock.nanosec > pause_ns
                   for m in rig.probe.received["/clock"][clocks:]), "/clock went on while paused"
        assert all(stamp_ns(m) <= pause_ns for m in rig.probe.received["pose"][:poses])
        # No jump: the first state after resuming is a tick or so past the pause, not the 0.5 s waited.
        assert (min(after) - t_pause * 1e9) / 1e9 < 0.05
        assert rig.call("resume").success is False
        names = [o.name for o in rig.outcomes]
        assert names == ["pause", "pause", "resume", "resume"]
        assert [o.accepted for o in rig.outcomes] == [True, False, True, False]
    finally:
        rig.close()


def test_step_while_running_is_refused_with_the_reason_and_counted(rig: Rig) -> None:
    answer = rig.call("step")
    assert not answer.success and "running" in answer.message and "pause" in answer.message
    assert rig.node.realtime.rejected == 1
    assert rig.outcomes[-1].name == "step" and not rig.outcomes[-1].accepted


def test_step_advances_by_step_periods_or_step_time_and_publishes_the_state(rig: Rig) -> None:
    assert rig.call("pause").success
    t0 = _t(rig)
    first = len(rig.probe.received["pose"])
    answer = rig.call("step")  # step_periods = 1 at 50 Hz: 20 ms
    assert answer.success and "stepped 0.02 s" in answer.message
    assert _t(rig) == pytest.approx(t0 + 0.02, abs=1e-9)
    assert rig.probe.spin_until(lambda: any(
        stamp_ns(m) == round(_t(rig) * 1e9) for m in rig.poses_after(first)), 3.0), "the stepped state was published"
    assert rig.probe.set_parameter("slider", "step_periods", 3) == (True, "")
    assert rig.call("step").success
    assert _t(rig) == pytest.approx(t0 + 0.08, abs=1e-9)
    assert rig.probe.set_parameter("slider", "step_time", 0.0123) == (True, "")
    assert rig.call("step").success
    assert _t(rig) == pytest.approx(t0 + 0.0923, abs=1e-9)
    assert rig.probe.set_parameter("slider", "step_time", -1.0)[0] is False
    assert rig.probe.set_parameter("slider", "step_periods", 0)[0] is False


def _offline(times: np.ndarray, params: SliderParams | None = None, inputs: Inputs | None = None) -> np.ndarray:
    """x, v at ``times`` from the exact core, run offline in one go."""
    trajectory = Slider(params, inputs).sample(times)
    return np.vstack([trajectory.x, trajectory.v])


def _recorded_states(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(times [s], [x, v]) of the recording's pose and velocity samples."""
    recording = read_recording(path)
    poses = recording.decoded("pose")
    velocities = dict(recording.decoded("velocity"))
    times = np.array([t for t, _ in poses]) / 1e9
    values = np.array([[m.pose.position.x for _, m in poses], [velocities[t].twist.linear.x for t, _ in poses]])
    return times, values


@pytest.mark.parametrize("step_periods", [1, 7])
def test_stepping_n_times_gives_the_trajectory_running_gives(ros: None, tmp_path: Path, step_periods: int) -> None:
    """Pause at once, then step: every recorded state equals the exact core's
    state at its time, run offline without any stop, to 1e-12."""
    path = tmp_path / "stepped.mcap"
    rig = Rig(path, step_periods=step_periods)
    try:
        assert rig.call("pause").success
        t_pause = _t(rig)
        for _ in range(12):
            assert rig.call("step").success
        t_end = _t(rig)
    finally:
        rig.close()
    assert t_end == pytest.approx(t_pause + 12 * step_periods / 50.0, abs=1e-9)
    times, values = _recorded_states(path)
    assert times[-1] == pytest.approx(t_end, abs=1e-3) and len(times) > 12 * step_periods * 20 * 0.99
    exact = _offline(times)
    scale = np.max(np.abs(exact), axis=1)
    assert np.max(np.abs(values - exact), axis=1).max() <= 1e-12 * max(scale.max(), 1e-300)
    assert np.all(np.abs(values[0] - exact[0]) <= 1e-12 * scale[0])
    assert np.all(np.abs(values[1] - exact[1]) <= 1e-12 * scale[1])
    result = verify(read_recording(path))
    assert result.passed, result.lines()


def test_reset_starts_again_from_rest_and_replay_verify_reproduces_it(ros: None, tmp_path: Path) -> None:
    """A run with a pause, steps, a command while paused, a reset and a resume:
    the recording holds every call on sim_control, the motion after the reset
    is the motion from the start shifted in time, and verify reproduces it."""
    path = tmp_path / "reset.mcap"
    rig = Rig(path)
    try:
        assert rig.probe.spin_until(lambda: _t(rig) >= 0.3, 10.0)  # it has run a while (its own time)
        assert rig.call("pause").success
        assert rig.call("step").success
        rig.probe.send("excitation_amplitude", 4.0)
        assert rig.probe.spin_until(lambda: rig.node.realtime.slider.inputs.excitation_amplitude == 4.0, 3.0)
        assert rig.call("step").success
        answer = rig.call("reset")
        assert answer.success and "x = 0 m" in answer.message
        t_reset = _t(rig)
        state = rig.node.realtime.slider.state()
        assert (state.x, state.v) == (0.0, 0.0)
        assert rig.call("resume").success
        assert rig.probe.spin_until(lambda: _t(rig) >= t_reset + 0.4, 10.0)  # a motion after the reset to compare
    finally:
        rig.close()
    recording = read_recording(path)
    controls = [(m.name, t) for t, m in recording.decoded("sim_control")]
    assert [name for name, _ in controls] == ["pause", "step", "step", "reset", "resume"]
    assert controls[3][1] == round(t_reset * 1e9)
    commands = recorded_commands(recording)
    assert [c.name for c in commands if c.name in ("reset", "excitation_amplitude")] == \
        ["excitation_amplitude", "reset"]
    result = verify(recording)
    assert result.passed, result.lines()
    times, values = _recorded_states(path)
    after = times > t_reset
    exact = _offline(times[after] - t_reset, inputs=Inputs(excitation_amplitude=4.0))
    assert np.max(np.abs(values[0, after] - exact[0])) <= 1e-12 * np.max(np.abs(exact[0]))
    assert values[0, times == t_reset].size == 0 or values[0, times == t_reset][0] != 0.0, \
        "a sample at the reset instant is the state before it"


def test_reset_while_running_keeps_the_parameters_in_force(rig: Rig) -> None:
    assert rig.probe.set_parameter("slider", "excitation_amplitude", 6.0) == (True, "")
    assert rig.probe.spin_until(lambda: rig.node.realtime.slider.state().x > 0.0, 10.0)
    assert rig.call("reset").success
    slider = rig.node.realtime.slider
    assert slider.inputs.excitation_amplitude == 6.0
    assert slider.state().x < 1e-4
    t_reset = slider.t
    assert rig.probe.spin_until(lambda: slider.t > t_reset, 10.0), "it runs on after the reset"
    assert rig.node.realtime.paused is False


CALLS = st.one_of(st.sampled_from(["pause", "resume", "step", "reset", "wait"]),
                  st.tuples(st.just("step_periods"), st.integers(1, 12)),
                  st.tuples(st.just("step_time"), st.sampled_from([0.0, 1e-9, 0.0123, 0.1])))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(calls=st.lists(CALLS, min_size=1, max_size=10))
def test_any_sequence_of_calls_keeps_time_exact_and_the_recording_verifies(
        ros: None, tmp_path_factory: pytest.TempPathFactory, calls: list[Any]) -> None:
    """Over real ROS: whatever the order of pause, resume, step, reset and
    step-size changes, a call succeeds exactly when it can, simulation time
    never goes back and moves while paused only by the steps, every accepted
    call is on sim_control in order, and replay --verify reproduces the run."""
    path = tmp_path_factory.mktemp("calls") / "run.mcap"
    rig = Rig(path)
    accepted: list[str] = []
    try:
        paused, periods, step_time = False, 1, 0.0
        for call in calls:
            before = _t(rig)
            if isinstance(call, tuple):
                name, value = call
                assert rig.probe.set_parameter("slider", name, value) == (True, "")
                periods, step_time = (value, step_time) if name == "step_periods" else (periods, value)
                continue
            if call == "wait":  # 50 of the node's ticks (counted, not timed): paused, none moves time
                ticks = rig.node.topics.ticks_published  # the node's tick count
                assert rig.probe.spin_until(lambda n=ticks: rig.node.topics.ticks_published >= n + 50, 10.0)
                assert (_t(rig) == before) if paused else True
                continue
            was_paused = paused
            answer = rig.call(call)
            expected = {"pause": not paused, "resume": paused, "step": paused, "reset": True}[call]
            assert answer.success == expected, (call, answer.message)
            if answer.success:
                accepted.append(call)
                paused = {"pause": True, "resume": False}.get(call, paused)
            after = _t(rig)
            assert after >= before
            if call == "step" and answer.success:
                length = step_time if step_time > 0.0 else periods / 50.0
                assert after - before == pytest.approx(length, abs=1e-9)
            elif was_paused and paused:  # a pause itself advances to the instant it stops
                assert after == before
    finally:
        rig.close()
    recording = read_recording(path)
    assert [m.name for _, m in recording.decoded("sim_control")] == accepted
    result = verify(recording)
    assert result.passed, result.lines()
