"""Recordings of the general model: a hopping run's height, normal velocity,
contact force and flight events in the file and back (reader, verify, replay,
CSV), and the external_wrench convention marker: files written before it
(force.z > 0 pressed the slider on the track) still replay and verify."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from friction_sim.cli.replay import run
from friction_sim.core.model.commands import Command
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.errors import RecordingError
from friction_sim.experiment.offline import record_offline
from friction_sim.experiment.verify import initial_parameters, recorded_commands, verify
from friction_sim.io.reader import read_recording
from friction_sim.io.recorder import CONVENTION_KEY, FORMAT, METADATA_NAME
from friction_sim.io.series import FORCE, POSITION_XZ, VELOCITY_XZ, state_values

from recording_helpers import replay_args, rewrite

G, PA, F = 10.0, 15.0, 50.0  # the default 1 kg slider on a level track, thrown at Gamma = 1.5
OMEGA = 2.0 * math.pi * F
HOP_SCHEDULE = [
    Command(0.2, "external_wrench", {"external_force_x": 0.05, "external_force_z": 2.0}),  # lifts: higher hops
    Command(0.3, "parameters", {"restitution": 0.4, "landing_friction": "none"}),
    Command(0.4, "excitation_amplitude", {"excitation_amplitude": 4.0}),  # back on the track for good
]


@pytest.fixture(scope="module")
def hopping(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """0.5 s of a slider thrown off the track every period, then bouncing with
    restitution and no landing friction, then back in contact (log rate 2 kHz)."""
    path = tmp_path_factory.mktemp("hop") / "hop.mcap"
    record_offline(path, SliderParams(), Inputs(excitation_amplitude=PA), HOP_SCHEDULE, duration=0.5,
                   log_rate=2000.0)
    return path


def _events(path: Path) -> list[tuple[str, dict[str, str]]]:
    recording = read_recording(path)
    return [(msg.name, {kv.key: kv.value for kv in msg.values}) for _, msg in recording.decoded("events")]


def _states(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t [s], pose x y z, velocity x y z, force x y z) of every recorded state."""
    recording = read_recording(path)
    t, pose = state_values(recording, recording.messages_on("pose"), POSITION_XZ)
    _, velocity = state_values(recording, recording.messages_on("velocity"), VELOCITY_XZ)
    _, force = state_values(recording, recording.messages_on("friction_force"), FORCE)
    return t / 1e9, pose, velocity, force


def test_a_hopping_run_records_height_normal_velocity_contact_force_and_flight_events(hopping: Path) -> None:
    recording = read_recording(hopping)
    meta = recording.metadata[METADATA_NAME]
    assert meta[CONVENTION_KEY] == "lifts" and meta["format"] == FORMAT
    assert recording.external_force_z_convention == "lifts" and recording.external_force_z_sign == 1.0
    events = _events(hopping)
    kinds = [name for name, _ in events]
    assert {"lift_off", "landing"} <= set(kinds)
    first = next(values for name, values in events if name == "lift_off")
    # From rest at theta = 0 the contact force m g - Pa sin(theta) first reaches 0 at sin(theta) = 1/Gamma.
    assert float(first["t"]) == pytest.approx(math.asin(G / PA) / OMEGA, rel=1e-12)
    assert (first["before"], first["after"]) == ("forward", "flight")
    # It slipped before: mu R = Fd at sin(theta) = (1 - phi)/a = (1 - 0.7)/1.5 (point A of the paper).
    assert kinds[0] == "slip_start" and float(events[0][1]["t"]) == pytest.approx(math.asin(0.2) / OMEGA, rel=1e-12)
    landings = [values for name, values in events if name == "landing"]
    assert all(float(v["vz_before"]) < 0.0 for v in landings), "it lands moving down"
    plastic = [v for v in landings if float(v["t"]) < 0.3]
    assert plastic and all(float(v["vz_after"]) == 0.0 for v in plastic), "e = 0: plastic landings"
    bouncing = [v for v in landings if 0.3 < float(v["t"]) < 0.4]
    rebounds = [v for v in bouncing if float(v["vz_after"]) > 0.0]
    assert rebounds, "with e = 0.4 the slider bounces"
    for v in rebounds:  # normal restitution; no landing friction keeps the tangential speed
        assert float(v["vz_after"]) == pytest.approx(-0.4 * float(v["vz_before"]), rel=1e-12)
    for v in bouncing:
        assert float(v["v_after"]) == float(v["v_before"])
    assert not [name for name, values in events if name == "lift_off" and float(values["t"]) > 0.41]

    t, pose, velocity, force = _states(hopping)
    flying = pose[:, 2] > 0.0
    assert flying.any() and (pose[:, 2] >= 0.0).all() and not pose[:, 1].any() and not velocity[:, 1].any()
    assert (force[flying] == 0.0).all(), "no contact force, no friction in flight"
    assert (velocity[~flying & (t > 0.45), 2] == 0.0).all() and (force[t > 0.45, 2] > 0.0).all()


def test_the_first_flight_is_the_analytic_one(hopping: Path) -> None:
    """Independent of the core: from lift-off at t0 with z = vz = 0, m z'' = -(m g - Pa sin(w t)),
    so vz = -g s + (Pa/(m w)) (cos w t0 - cos w t) and
    z = -g s^2/2 + (Pa/(m w)) (s cos w t0 - (sin w t - sin w t0)/w), s = t - t0."""
    events = _events(hopping)
    t0 = float(next(v for name, v in events if name == "lift_off")["t"])
    t1 = float(next(v for name, v in events if name == "landing")["t"])
    t, pose, velocity, _ = _states(hopping)
    inside = (t > t0) & (t < t1)
    assert inside.sum() > 10
    s = t[inside] - t0
    vz = -G * s + PA / OMEGA * (math.cos(OMEGA * t0) - np.cos(OMEGA * t[inside]))
    z = -G * s**2 / 2 + PA / OMEGA * (s * math.cos(OMEGA * t0) - (np.sin(OMEGA * t[inside]) - math.sin(OMEGA * t0))
                                      / OMEGA)
    np.testing.assert_allclose(pose[inside, 2], z, rtol=0, atol=1e-9 * np.max(np.abs(z)))
    np.testing.assert_allclose(velocity[inside, 2], vz, rtol=0, atol=1e-9 * np.max(np.abs(vz)))


def test_verify_reproduces_a_hopping_run_and_catches_a_wrong_height(hopping: Path, tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    result = verify(read_recording(hopping))
    assert result.passed and result.commands == len(HOP_SCHEDULE)
    assert result.z_scale > 1e-5 and result.vz_scale > 1e-3, "the heights were compared"
    assert max(result.rel_dx, result.rel_dv, result.rel_dz, result.rel_dvz) <= 1e-9
    assert run(replay_args(hopping, verify=True)) == 0
    out = capsys.readouterr().out
    assert "largest height difference" in out and "largest normal velocity difference" in out
    assert out.rstrip().endswith("reproducible (tolerance 1e-09 relative)")

    highest = max(read_recording(hopping).decoded("pose"), key=lambda item: item[1].pose.position.z)[0]

    def nudge(topic: str, t: int, msg: Any) -> Any:
        if topic.lstrip("/") == "pose" and t == highest:
            msg.pose.position.z *= 1.0 + 1e-6
        return msg

    tampered = verify(read_recording(rewrite(hopping, tmp_path / "tampered.mcap", nudge)))
    assert not tampered.passed and tampered.rel_dz == pytest.approx(1e-6, rel=1e-3)
    assert tampered.rel_dx == tampered.rel_dv == 0.0 and tampered.worst_dz_t == highest / 1e9


def test_a_hopping_runs_csv_has_the_height(hopping: Path, tmp_path: Path) -> None:
    assert run(replay_args(hopping, csv=tmp_path / "csv", topics=["pose", "events"])) == 0
    with (tmp_path / "csv" / "pose.csv").open() as stream:
        rows = list(csv.DictReader(stream))
    assert max(float(row["pose.position.z"]) for row in rows) > 0.0


# -- the external_wrench convention -------------------------------------------------


def _as_written_before_the_marker(source: Path, target: Path) -> Path:
    """``source`` as the old code wrote the same run: force.z of external_wrench and
    every external_force_z value with the old sign (> 0 loads), and no marker."""
    def old_sign(topic: str, t: int, msg: Any) -> Any:
        name = topic.lstrip("/")
        if name == "external_wrench":
            msg.wrench.force.z = -msg.wrench.force.z
        elif name == "parameters":
            for parameter in (*msg.new_parameters, *msg.changed_parameters):
                if parameter.name == "external_force_z":
                    parameter.value.double_value = -parameter.value.double_value
        return msg

    def old_metadata(data: dict[str, str]) -> dict[str, str]:
        data.pop(CONVENTION_KEY)
        data["format"] = "friction_sim-recording/1"
        data["external_force_z"] = repr(-float(data["external_force_z"]))
        return data

    return rewrite(source, target, old_sign, metadata=old_metadata, external_force_z_convention=None)


@pytest.fixture(scope="module")
def pressed(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Command]]:
    """A run of the paper's model whose external force presses the slider on the
    track (Fz < 0 today) and later unloads it: (recording, schedule)."""
    path = tmp_path_factory.mktemp("pressed") / "today.mcap"
    schedule = [Command(0.15, "external_wrench", {"external_force_x": 0.02, "external_force_z": -3.0}),
                Command(0.3, "parameters", {"external_force_z": 2.5}),
                Command(0.45, "excitation_amplitude", {"excitation_amplitude": 6.0})]
    record_offline(path, SliderParams(), Inputs(external_force_z=-1.5), schedule, duration=0.6)
    return path, schedule


def test_a_file_written_before_the_marker_is_read_in_todays_convention(
        pressed: tuple[Path, list[Command]], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    today, schedule = pressed
    old = _as_written_before_the_marker(today, tmp_path / "old.mcap")
    recording = read_recording(old)
    assert CONVENTION_KEY not in recording.metadata[METADATA_NAME]
    assert recording.external_force_z_convention == "loads" and recording.external_force_z_sign == -1.0
    # As stored: the old sign.
    (_, wrench), = recording.decoded("external_wrench")
    assert wrench.wrench.force.z == 3.0
    # As read: today's.
    assert initial_parameters(recording)["external_force_z"] == -1.5
    assert [(c.t, c.name, dict(c.values)) for c in recorded_commands(recording)] == \
        [(c.t, c.name, dict(c.values)) for c in schedule]
    assert any("loads the contact (the old convention)" in line for line in recording.info_lines())

    result = verify(recording)
    assert result.passed and result.convention == "loads" and result.x_scale > 0.0
    assert result.rel_dx == result.rel_dv == 0.0, "the same run, to the last bit"
    assert run(replay_args(old, verify=True)) == 0
    out = capsys.readouterr().out
    assert "old file" in out and out.rstrip().endswith("reproducible (tolerance 1e-09 relative)")


def test_the_marker_matters_an_old_file_read_as_new_does_not_verify(pressed: tuple[Path, list[Command]],
                                                                     tmp_path: Path) -> None:
    today, _ = pressed
    old = _as_written_before_the_marker(today, tmp_path / "old.mcap")
    mislabelled = rewrite(old, tmp_path / "mislabelled.mcap")  # the copy gets today's marker
    assert read_recording(mislabelled).external_force_z_convention == "lifts"
    result = verify(read_recording(mislabelled))
    assert not result.passed and result.rel_dx > 1e-3


def test_an_unknown_convention_is_one_line(pressed: tuple[Path, list[Command]], tmp_path: Path) -> None:
    today, _ = pressed
    odd = rewrite(today, tmp_path / "odd.mcap", metadata=lambda data: {**data, CONVENTION_KEY: "sideways"})
    with pytest.raises(RecordingError) as excinfo:
        verify(read_recording(odd))
    message = str(excinfo.value)
    assert "external_force_z_convention = 'sideways'" in message and "lifts, loads" in message
    assert "\n" not in message
    assert run(replay_args(odd)) == 0  # describing it still works
