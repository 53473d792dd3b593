"""``replay --verify`` on resonant recordings whose commands came several at
one instant (issue 28, finding 7): the node takes each command as a change of
its own, a ``ros2 param set`` of several parameters as one, and verify
replays exactly those changes in the same order, through the same function
(:func:`friction_sim.core.model.commands.take`).  Merged into one change, a
switch to the resonant actuator followed by a new frequency loses the
transient the node simulated (1.3e-05 m in the issue's run)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from friction_sim.cli.replay import run
from friction_sim.core.engine.single import Slider
from friction_sim.core.model.commands import COMMANDS, PARAMETERS, RESET, Command, Outcome, apply
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.errors import ParameterError
from friction_sim.experiment.offline import record_offline
from friction_sim.experiment.verify import recorded_commands, sample_times, verify
from friction_sim.io.reader import read_recording
from friction_sim.io.recorder import Recorder, plant_parameters, recording_metadata
from friction_sim.io.series import POSITION_XZ, VELOCITY_XZ, state_blocks
from friction_sim.io.sinks import CommandRecord, ParametersRecord, deliver_tick

from recording_helpers import replay_args

FORCE = SliderParams(natural_frequency=52.0, excitation_angle=45.0, restitution=0.3)
RESONANT = SliderParams(actuator="resonant", natural_frequency=52.0, excitation_angle=45.0, restitution=0.3)
INPUTS = Inputs(excitation_amplitude=3.0, drive_level=0.5)
LOG_RATE = 2000.0
TICK_NS = 1_000_000  # the node's tick at publish_rate 1000 Hz


class NodeRun:
    """What the slider node does with its :class:`RealtimeSlider` and its
    recorder, without ROS: ticks on a counter, the services' and parameter
    sets' calls in between, each outcome recorded as the node records it."""

    def __init__(self, path: Path, params: SliderParams, inputs: Inputs) -> None:
        self.rt = RealtimeSlider(params, inputs, wall_ns=0, publish_rate=1e9 / TICK_NS, log_rate=LOG_RATE)
        self.recorder = Recorder(path, recording_metadata(params, inputs, log_rate=LOG_RATE), block_when_full=True)
        self.recorder.write(ParametersRecord({**plant_parameters(params, inputs), "log_rate": LOG_RATE,
                                              "frame_id": "slideway"}, 0.0, False))
        self.wall_ns = 0

    def ticks(self, n: int) -> None:
        for _ in range(n):
            self.wall_ns += TICK_NS
            deliver_tick([self.recorder], self.rt.tick(self.wall_ns), "slideway")

    def call(self, name: str) -> None:
        """``~/pause``, ``~/resume`` or ``~/reset``."""
        act: Callable[[int], Outcome] = getattr(self.rt, name)
        self.record(act(self.wall_ns))

    def set(self, **values: Any) -> None:
        """One ``ros2 param set`` (several values: one atomic set)."""
        self.record(self.rt.configure(values, self.wall_ns))

    def send(self, *commands: Command) -> None:
        """Commands one tick takes from the topics."""
        for outcome in self.rt.commands(list(commands), self.wall_ns):
            self.record(outcome)

    def record(self, outcome: Outcome) -> None:
        assert outcome.accepted, outcome.reason
        self.recorder.write(CommandRecord(outcome, "slideway"))

    def close(self) -> None:
        self.recorder.finish()


def topic(name: str, value: float) -> Command:
    return Command(0.0, name, {name: value})


def at(t: float, name: str, value: float | str) -> Command:
    """A command on topic ``name`` at ``t``, or a parameter set of the plant field ``name``."""
    return Command(t, name, {name: value}) if name in COMMANDS else Command(t, PARAMETERS, {name: value})


def test_two_parameter_sets_at_a_paused_instant_verify(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The issue: pause, set actuator resonant, set excitation_frequency 55, resume."""
    path = tmp_path / "switch.mcap"
    node = NodeRun(path, FORCE, INPUTS)
    node.ticks(300)
    node.call("pause")
    node.ticks(20)  # wall time passes while paused
    node.set(actuator="resonant")
    node.ticks(3)
    node.set(excitation_frequency=55.0)
    node.ticks(3)
    node.call("resume")
    node.ticks(500)
    node.close()
    recording = read_recording(path)
    assert [c.name for c in recorded_commands(recording)] == [PARAMETERS, PARAMETERS]
    result = verify(recording)
    assert result.passed, result.lines()
    assert run(replay_args(path, verify=True)) == 0
    assert capsys.readouterr().out.rstrip().endswith("reproducible (tolerance 1e-09 relative)")


def test_bursts_in_ticks_and_sets_at_paused_instants_verify(tmp_path: Path) -> None:
    """Tick batches, separate ticks and atomic and separate sets at paused
    instants, in orders where merging them would differ, with drive and
    frequency steps, switches both ways and a reset in between."""
    path = tmp_path / "bursts.mcap"
    node = NodeRun(path, FORCE, INPUTS)
    node.ticks(150)
    node.send(topic("drive_force", 0.3))
    node.ticks(100)
    node.call("pause")
    node.set(actuator="resonant")  # a switch, then two ticks' commands: three changes at one instant
    node.ticks(2)
    node.send(topic("drive_level", 0.9), topic("excitation_frequency", 54.0))
    node.ticks(2)
    node.send(topic("excitation_frequency", 50.0))
    node.call("resume")
    node.ticks(200)
    node.send(topic("excitation_frequency", 53.0), topic("drive_level", 0.6))
    node.ticks(150)
    node.call("pause")
    node.set(actuator="force", excitation_amplitude=4.0)  # one atomic set is one change
    node.send(topic("drive_force", -0.2))
    node.set(actuator="resonant")
    node.set(natural_frequency=55.0, damping_ratio=0.03)
    node.call("resume")
    node.ticks(150)
    node.call("pause")
    node.call("reset")
    node.set(actuator="force")
    node.set(actuator="resonant")
    node.send(topic("drive_level", 0.8))
    node.call("resume")
    node.ticks(250)
    node.close()
    recording = read_recording(path)
    assert len(recorded_commands(recording)) == 15
    result = verify(recording)
    assert result.passed, result.lines()
    assert result.samples > 2000


# A resonant run recorded offline: drive and frequency steps, actuator switches both ways and
# bursts at one instant (a parameter set is a set of the node's parameter service), and a reset.
SCHEDULE = [
    at(0.0, "drive_level", 0.9),
    at(0.1, "drive_force", 0.4),
    at(0.2, "excitation_frequency", 55.0),
    at(0.3, "actuator", "force"), at(0.3, "excitation_amplitude", 4.0),
    at(0.4, "actuator", "resonant"), at(0.4, "excitation_frequency", 50.0), at(0.4, "drive_level", 0.4),
    at(0.55, "drive_force", -0.3), at(0.55, "drive_level", 1.0), Command(0.62, RESET),
    at(0.7, "actuator", "force"), at(0.7, "actuator", "resonant"), at(0.7, "natural_frequency", 54.0),
    at(0.85, "excitation_frequency", 53.0),
]


def one_change_each(params: SliderParams, inputs: Inputs, schedule: Sequence[Command],
                    times: np.ndarray) -> np.ndarray:
    """x at ``times`` from the plain core, each command a set_plant of its own at its time
    (a sample at a command's time is the state before it, as the node logs it)."""
    slider = Slider(params, inputs, event_log_size=0)
    x = np.empty(times.size)
    commands = sorted(schedule, key=lambda command: command.t)
    k = 0
    for i, t in enumerate(times):
        while k < len(commands) and commands[k].t < t:
            slider.advance_to(commands[k].t)
            if commands[k].name == RESET:
                slider.restart()
            else:
                slider.set_plant(*apply(commands[k], slider.params, slider.inputs))
            k += 1
        slider.advance_to(t)
        x[i] = slider.state().x
    return x


def test_a_resonant_run_with_steps_switches_and_bursts_recorded_offline_verifies(tmp_path: Path) -> None:
    path = tmp_path / "offline.mcap"
    record_offline(path, RESONANT, INPUTS, SCHEDULE, duration=1.0, log_rate=LOG_RATE)
    recording = read_recording(path)
    assert len(recorded_commands(recording)) == len(SCHEDULE) and recording.count("rejected_commands") == 0
    result = verify(recording)
    assert result.passed, result.lines()
    blocks = [block["pose"] for block in state_blocks(recording, {"pose": POSITION_XZ, "velocity": VELOCITY_XZ})]
    pose_ns, x = np.concatenate([ns for ns, _ in blocks]), np.concatenate([pose[:, 0] for _, pose in blocks])
    exact = one_change_each(RESONANT, INPUTS, SCHEDULE, sample_times(pose_ns, LOG_RATE))
    assert pose_ns.size == 2001 and np.max(np.abs(x - exact)) <= 1e-12 * np.max(np.abs(exact)), \
        "the node takes each command of a burst as a change of its own"


@pytest.mark.parametrize("control", ["pause", "resume", "step"])
def test_record_offline_refuses_what_needs_a_clock(tmp_path: Path, control: str) -> None:
    with pytest.raises(ParameterError, match="no clock"):
        record_offline(tmp_path / "run.mcap", schedule=[Command(0.1, control)], duration=0.2)
