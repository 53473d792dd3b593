"""Stamped commands on sensor_msgs/JointState: what lockstep's participants send.

A stamped message must carry its stamp and values exactly (a closed loop in
lockstep is compared bit for bit), group the fields of one command topic into
one command, and refuse, naming the field and the value, what no slider
command can be (no rclpy: the message packages only).
"""

from __future__ import annotations

import pytest

from friction_sim.core.model.commands import Command
from friction_sim.errors import ParameterError
from friction_sim.io.stamped import CONTROL_ANSWER, STAMPED_COMMAND, stamped_commands, stamped_message

STAMP = 1_234_567_890_123  # 1234.567890123 s


def test_a_mapping_goes_out_and_comes_back_exactly() -> None:
    values = {"drive_level": 0.1 + 0.2, "excitation_frequency": 51.5, "drive_force": -0.7}
    msg = stamped_message(STAMP, values)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1234, 567_890_123)
    assert list(msg.name) == list(values) and list(msg.position) == list(values.values())
    assert stamped_commands(CONTROL_ANSWER, msg, 0.25) == (STAMP, [
        Command(0.25, "drive_level", {"drive_level": 0.1 + 0.2}),
        Command(0.25, "excitation_frequency", {"excitation_frequency": 51.5}),
        Command(0.25, "drive_force", {"drive_force": -0.7}),
    ])


def test_commands_go_out_and_come_back_at_the_time_they_are_taken() -> None:
    """Commands (an external wrench among them) come back as the same commands, at the
    simulation time they are taken, not the one they were built with."""
    commands = [Command(0.1, "excitation_amplitude", {"excitation_amplitude": 4.003030119775977}),
                Command(0.1, "external_wrench", {"external_force_x": 1.5, "external_force_z": -2.0}),
                Command(0.1, "drive_force", {"drive_force": 0.0})]
    stamp, back = stamped_commands(STAMPED_COMMAND, stamped_message(20_000_000, commands), 0.3)
    assert stamp == 20_000_000
    assert back == [command.at(0.3) for command in commands]


def test_no_names_is_an_answer_that_changes_nothing() -> None:
    msg = stamped_message(0)
    assert list(msg.name) == [] and list(msg.position) == []
    assert stamped_commands(CONTROL_ANSWER, msg, 0.0) == (0, [])
    assert stamped_commands(STAMPED_COMMAND, stamped_message(STAMP, []), 1.0) == (STAMP, [])


def test_the_external_forces_make_one_external_wrench_in_the_order_of_their_first_field() -> None:
    msg = stamped_message(STAMP, {"external_force_x": 0.5, "drive_level": 0.6, "external_force_z": -3.0})
    assert stamped_commands(STAMPED_COMMAND, msg, 2.0)[1] == [
        Command(2.0, "external_wrench", {"external_force_x": 0.5, "external_force_z": -3.0}),
        Command(2.0, "drive_level", {"drive_level": 0.6}),
    ]
    only_z = stamped_message(STAMP, {"external_force_z": 1.0})
    assert stamped_commands(STAMPED_COMMAND, only_z, 2.0)[1] == [
        Command(2.0, "external_wrench", {"external_force_z": 1.0})]


@pytest.mark.parametrize("name", ["bogus", "target_speed", "mass", "external_wrench", ""])
def test_a_name_that_is_no_slider_command_field_is_refused(name: str) -> None:
    """Unknown names, the controller's own target speed, a plant parameter and a
    topic (not a field) are refused, naming the topic's field and the name."""
    msg = stamped_message(STAMP, {"drive_level": 0.5, name: 1.0})
    with pytest.raises(ParameterError) as error:
        stamped_commands(CONTROL_ANSWER, msg, 0.0)
    assert (error.value.field, error.value.value) == ("control_answer.name", name)
    assert str(error.value).startswith(f"control_answer.name = {name!r} rejected: must be a slider command field:")
    assert "excitation_amplitude" in error.value.limit and "external_force_z" in error.value.limit


@pytest.mark.parametrize("names", [["drive_level", "drive_force"], []])
def test_names_and_values_of_different_lengths_are_refused(names: list[str]) -> None:
    msg = stamped_message(STAMP, {"excitation_amplitude": 3.0})
    msg.name = names
    with pytest.raises(ParameterError) as error:
        stamped_commands(STAMPED_COMMAND, msg, 0.0)
    assert (error.value.field, error.value.value) == ("stamped_command.position", 1)
    assert error.value.limit == f"must have one value per name ({len(names)})"


@pytest.mark.parametrize("name", ["drive_level", "external_force_x"])
def test_a_field_twice_is_refused(name: str) -> None:
    msg = stamped_message(STAMP, {name: 1.0, "external_force_z": 2.0})
    msg.name = [name, "external_force_z", name]
    msg.position = [1.0, 2.0, 1.0]
    with pytest.raises(ParameterError) as error:
        stamped_commands(STAMPED_COMMAND, msg, 0.0)
    assert (error.value.field, error.value.value, error.value.limit) == (
        "stamped_command.name", name, "must appear once per message")
