"""Issue 28, finding 7, over real ROS: pause, ``ros2 param set`` the actuator to
resonant, ``ros2 param set`` a new excitation frequency, resume; the node took
the two sets as two changes at the paused instant, and ``replay --verify``
replays exactly those two (merged into one, the transient of the switch
followed by the new frequency was lost: 1.293e-05 m, NOT reproducible)."""

from __future__ import annotations

from pathlib import Path

from rclpy.parameter import Parameter

from friction_sim.core.model.commands import PARAMETERS
from friction_sim.experiment.verify import recorded_commands, verify
from friction_sim.io.reader import read_recording
from friction_sim.ros.slider import SliderNode

from ros_harness import Probe, namespace


def test_two_parameter_sets_at_a_paused_instant_replay_verify(ros: None, tmp_path: Path) -> None:
    path = tmp_path / "switch.mcap"
    ns = namespace()
    node = SliderNode(namespace=ns, parameter_overrides=[Parameter("log_path", value=str(path))])
    probe = Probe(ns, node)
    try:
        probe.wait_for_connection()
        slider = node.realtime.slider
        assert probe.spin_until(lambda: slider.t > 0.2, 10.0)
        assert probe.control("pause").success
        t_pause = slider.t
        assert probe.set_parameter("slider", "actuator", "resonant") == (True, "")
        assert probe.set_parameter("slider", "excitation_frequency", 55.0) == (True, "")
        assert node.realtime.accepted == 2 and slider.t == t_pause, "two changes, at the paused instant"
        assert probe.control("resume").success
        assert probe.spin_until(lambda: slider.t > t_pause + 0.3, 10.0)
    finally:
        probe.close()
        node.destroy_node()
    recording = read_recording(path)
    sets = [(c.t, dict(c.values)) for c in recorded_commands(recording) if c.name == PARAMETERS]
    assert sets == [(t_pause, {"actuator": "resonant"}), (t_pause, {"excitation_frequency": 55.0})]
    result = verify(recording)
    assert result.passed, result.lines()
