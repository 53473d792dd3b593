"""--verify on real and tampered recordings."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from friction_sim.cli.replay import run
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.simulation import random_schedule
from friction_sim.experiment.offline import record_offline
from friction_sim.experiment.verify import verify
from friction_sim.io.reader import read_recording

from recording_helpers import replay_args, rewrite


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_verify_passes_on_recordings_of_random_schedules(tmp_path: Path, seed: int,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(seed)
    params = SliderParams(mass=float(rng.uniform(0.5, 2.0)), mu=float(rng.uniform(0.05, 0.3)))
    inputs = Inputs(drive_force=float(rng.uniform(-0.5, 0.5)) * params.mu * params.weight,
                    excitation_amplitude=float(rng.uniform(0.1, 0.8)) * params.weight)
    schedule = random_schedule(rng, 1.5, weight=params.weight, external=bool(seed % 2))
    path = tmp_path / "run.mcap"
    record_offline(path, params, inputs, schedule, duration=1.5, log_rate=float(rng.choice([1000.0, 2500.0, 300.0])))
    result = verify(read_recording(path))
    assert result.passed and result.samples > 400 and result.commands >= len(schedule)
    assert result.rel_dx <= 1e-9 and result.rel_dv <= 1e-9 and result.x_scale > 0.0
    assert run(replay_args(path, verify=True)) == 0
    out = capsys.readouterr().out
    assert "largest position difference" in out and "largest velocity difference" in out
    assert out.rstrip().endswith("reproducible (tolerance 1e-09 relative)")


def test_verify_fails_on_a_tampered_copy(real_recording: Path, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    recording = read_recording(real_recording)
    poses = recording.decoded("pose")
    worst_t, _worst = max(poses, key=lambda item: abs(item[1].pose.position.x))

    def nudge(topic: str, t: int, msg: Any) -> Any:
        if topic.lstrip("/") == "pose" and t == worst_t:
            msg.pose.position.x *= 1.0 + 1e-6
        return msg

    untouched = rewrite(real_recording, tmp_path / "copy.mcap")
    assert run(replay_args(untouched, verify=True)) == 0, "copying alone keeps it reproducible"
    tampered = rewrite(real_recording, tmp_path / "tampered.mcap", nudge)
    capsys.readouterr()
    assert run(replay_args(tampered, verify=True)) == 1
    out = capsys.readouterr().out
    assert "NOT reproducible" in out and f"at t = {worst_t / 1e9:.6f} s" in out
    result = verify(read_recording(tampered))
    assert result.rel_dx == pytest.approx(1e-6, rel=1e-3) and result.rel_dv == 0.0


def test_verify_fails_when_a_command_is_missing(real_recording: Path, tmp_path: Path) -> None:
    recording = read_recording(real_recording)
    x = {t: msg.pose.position.x for t, msg in recording.decoded("pose")}
    times = [raw.log_time for raw in recording.messages_on("drive_force")] + [recording.end_ns]

    def travel(k: int) -> float:  # motion between command k and the next, to the nearest samples
        start, end = (max(t for t in x if t <= when) for when in times[k:k + 2])
        return abs(x[end] - x[start])

    dropped = times[max(range(len(times) - 1), key=travel)]  # the command that mattered most
    copy = rewrite(real_recording, tmp_path / "lost.mcap",
                   lambda topic, t, msg: None if topic.lstrip("/") == "drive_force" and t == dropped else msg)
    result = verify(read_recording(copy))
    assert not result.passed and result.worst_dx_t >= dropped / 1e9
    assert run(replay_args(copy, verify=True)) == 1


def test_verify_re_simulates_the_resonant_actuator_and_its_drive_level(tmp_path: Path) -> None:
    """Issue 21: drive_level is a recorded command; replay --verify re-simulates
    the exciter's transients after each step (and the refused Pa commands stay refused)."""
    from friction_sim.core.model.commands import Command

    params = SliderParams(actuator="resonant", natural_frequency=52.0, excitation_angle=45.0, restitution=0.3)
    schedule = [Command(0.1, "drive_level", {"drive_level": 0.95}), Command(0.35, "excitation_amplitude",
                                                                           {"excitation_amplitude": 2.0}),
                Command(0.5, "excitation_frequency", {"excitation_frequency": 52.0}),
                Command(0.8, "drive_level", {"drive_level": 0.3})]
    path = tmp_path / "resonant.mcap"
    record_offline(path, params, Inputs(drive_level=0.5), schedule, duration=1.2, log_rate=2000.0)
    recording = read_recording(path)
    assert recording.count("drive_level") == 2 and recording.count("rejected_commands") == 1
    result = verify(recording)
    assert result.passed and result.commands >= 3 and result.samples > 2000
    assert result.rel_dx <= 1e-9 and result.rel_dv <= 1e-9
