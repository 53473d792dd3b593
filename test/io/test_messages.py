"""The messages a run is published and recorded as: states, commands,
rejections, events and parameters (no rclpy: the message packages only)."""

from __future__ import annotations

import pytest

from friction_sim.core.model.commands import Command, Outcome
from friction_sim.core.model.events import Event, EventKind, Mode, SliderState
from friction_sim.io import messages as M

STATE = SliderState(t=1.2345678901, x=1.5e-4, v=-2.5e-3, acceleration=0.3, friction_force=-0.95,
                    normal_force=9.5, phase=1.0, mode=Mode.BACKWARD)
FLOAT_COMMANDS = ("drive_force", "excitation_amplitude", "excitation_frequency", "target_speed")


def test_state_messages_carry_x_v_friction_and_normal_force() -> None:
    pose, twist, wrench = M.state_messages(STATE, "rail")
    assert pose.pose.position.x == STATE.x and pose.pose.orientation.w == 1.0
    assert twist.twist.linear.x == STATE.v
    assert (wrench.wrench.force.x, wrench.wrench.force.z) == (STATE.friction_force, STATE.normal_force)
    for msg in (pose, twist, wrench):
        assert msg.header.frame_id == "rail"
        assert M.stamp_ns(msg.header.stamp) == 1_234_567_890


def test_state_messages_carry_the_height_its_rate_and_no_contact_force_in_flight() -> None:
    flying = SliderState(t=0.5, x=2e-3, v=0.04, acceleration=0.7, friction_force=0.0, normal_force=0.0,
                         phase=2.0, mode=Mode.FLIGHT, z=3.25e-4, vz=-0.0125)
    pose, twist, wrench = M.state_messages(flying)
    assert (pose.pose.position.x, pose.pose.position.y, pose.pose.position.z) == (2e-3, 0.0, 3.25e-4)
    assert (twist.twist.linear.x, twist.twist.linear.y, twist.twist.linear.z) == (0.04, 0.0, -0.0125)
    assert (wrench.wrench.force.x, wrench.wrench.force.z) == (0.0, 0.0)
    on_track = M.state_messages(STATE)  # z = vz = 0 in contact: the paper's messages, unchanged
    assert (on_track[0].pose.position.z, on_track[1].twist.linear.z) == (0.0, 0.0)


def test_flight_events_carry_the_velocities_before_and_after() -> None:
    landing = M.event_message(Event(0.031, EventKind.LANDING, 4e-4, 3.9, Mode.FLIGHT, Mode.STUCK,
                                    v_before=0.021, v_after=0.0, vz_before=-0.08, vz_after=0.0))
    assert (landing.name, landing.message) == ("landing", "flight -> stuck")
    values = {kv.key: kv.value for kv in landing.values}
    assert list(values) == ["t", "x", "phase", "before", "after", "v_before", "v_after", "vz_before", "vz_after"]
    assert (float(values["v_before"]), float(values["vz_before"])) == (0.021, -0.08)
    assert (float(values["v_after"]), float(values["vz_after"])) == (0.0, 0.0)
    lift_off = M.event_message(Event(0.0023, EventKind.LIFT_OFF, 1e-5, 0.7297, Mode.FORWARD, Mode.FLIGHT,
                                     v_before=0.01, v_after=0.01))
    assert (lift_off.name, lift_off.message) == ("lift_off", "forward -> flight")
    assert {kv.key: kv.value for kv in lift_off.values}["v_after"] == "0.01"
    stick = M.event_message(Event(0.01, EventKind.STICK, 1e-5, 3.0, Mode.FORWARD, Mode.STUCK))
    assert [kv.key for kv in stick.values] == ["t", "x", "phase", "before", "after"]  # as before flight existed


def test_time_helpers_round_trip_whole_nanoseconds() -> None:
    for ns in (0, 1, 999_999_999, 1_000_000_000, 3_600_123_456_789, -1, -1_500_000_000):
        stamp = M.time_msg(ns)
        assert 0 <= stamp.nanosec < 1_000_000_000
        assert M.stamp_ns(stamp) == ns
        assert M.seconds_to_ns(M.ns_to_seconds(ns)) == ns


def test_command_messages_per_topic() -> None:
    for topic in FLOAT_COMMANDS:
        msg = M.command_message(Command(0.5, topic, {topic: 0.25}))
        assert type(msg).__name__ == "Float64" and msg.data == 0.25
    wrench = M.command_message(Command(0.5, "external_wrench", {"external_force_x": 0.1, "external_force_z": -2.0}))
    assert (wrench.wrench.force.x, wrench.wrench.force.z) == (0.1, -2.0)
    assert M.stamp_ns(wrench.header.stamp) == 500_000_000
    change = M.command_message(Command(0.5, "parameters", {"mass": 2.0, "mu": 0.2}))
    assert M.parameter_event_values(change) == ({}, {"mass": 2.0, "mu": 0.2})
    text = M.command_message(Command(0.5, "parameters", {"landing_friction": "none", "restitution": 0.5}))
    assert M.parameter_event_values(text) == ({}, {"landing_friction": "none", "restitution": 0.5})
    back = M.command_from_message("parameters", text, 0.5)
    assert back == Command(0.5, "parameters", {"landing_friction": "none", "restitution": 0.5})
    with pytest.raises(ValueError, match="command = 'warp_drive' rejected: must be one of"):
        M.command_message(Command(0.5, "warp_drive", {"x": 1.0}))


def test_rejection_and_event_messages_are_readable_diagnostics() -> None:
    refused = M.rejection_message(Outcome(Command(0.5, "excitation_amplitude", {"excitation_amplitude": 12.5}),
                                          "excitation_amplitude = 12.5 rejected: must be < 10"))
    assert refused.level == M.DiagnosticStatus.WARN
    assert refused.name == "excitation_amplitude"
    assert refused.message == "excitation_amplitude = 12.5 rejected: must be < 10"
    assert [(kv.key, kv.value) for kv in refused.values] == [("excitation_amplitude", "12.5")]
    event = M.event_message(Event(0.0123, EventKind.SLIP_START, 1e-5, 0.7, Mode.STUCK, Mode.FORWARD))
    assert (event.level, event.name, event.message) == (M.DiagnosticStatus.OK, "slip_start", "stuck -> forward")
    values = {kv.key: kv.value for kv in event.values}
    assert float(values["t"]) == 0.0123 and float(values["x"]) == 1e-5 and float(values["phase"]) == 0.7
    assert (values["before"], values["after"]) == ("stuck", "forward")


def test_parameter_values_keep_their_types() -> None:
    values = {"mass": 1.5, "window": 3, "clock": True, "frame_id": "rail", "gains": [1.0, 2.5],
              "counts": [1, 2], "names": ["a", "b"], "flags": [True, False], "blob": b"\x01\x02"}
    msg = M.parameters_message(values, 2.0)
    new, changed = M.parameter_event_values(msg)
    assert new == values and changed == {}
    assert {p.name: p.value.type for p in msg.new_parameters} == {
        "mass": 3, "window": 2, "clock": 1, "frame_id": 4, "gains": 8, "counts": 7, "names": 9, "flags": 6,
        "blob": 5}
    assert M.stamp_ns(msg.stamp) == 2_000_000_000 and msg.node == "/slider"


@pytest.mark.parametrize("frames", [("slideway",), ("slideway", "a_much_longer_frame_name")])
def test_serialized_imu_readings_give_their_stamps_and_normal_accelerations(frames: tuple[str, ...]) -> None:
    """What the lockstep controller takes from the accelerometer topic, serialized: each message's
    stamp and linear_acceleration.z, in order, read at numpy speed when the messages share a layout
    and decoded one by one when they do not (frame names of two lengths)."""
    import numpy as np

    from friction_sim.core.model.records import Acceleration
    from friction_sim.io.cdr import serialize
    from friction_sim.io.series import imu_normals

    rng = np.random.default_rng(3)
    samples = [Acceleration(1.5 + k / 1000, *rng.normal(0.0, 20.0, 3)) for k in range(30)]
    datas = [serialize(M.imu_message(sample, frames[k % len(frames)], 0.1)) for k, sample in enumerate(samples)]
    assert imu_normals(datas) == [(M.seconds_to_ns(sample.t), sample.z) for sample in samples]
    assert imu_normals([]) == []
