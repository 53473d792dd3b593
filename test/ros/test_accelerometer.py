"""The resonant actuator on ROS (issue 21, item 2): the accelerometer, the
drive_level topic and the refusal of excitation_amplitude, over real DDS."""

from __future__ import annotations

import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.ros.slider import SliderNode

from ros_harness import Probe, diagnostics_values, namespace, stamp_ns

RATE = 1000.0
PLANT = SliderParams(actuator="resonant", natural_frequency=52.0, excitation_angle=60.0, track_inclination=3.0)


def _node(ns: str, **extra: object) -> SliderNode:
    values = {"accelerometer_rate": RATE, "actuator": "resonant", "natural_frequency": 52.0,
              "excitation_angle": 60.0, "track_inclination": 3.0, "diagnostics_period": 0.1, **extra}
    return SliderNode(namespace=ns, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()])


def test_the_accelerometer_reads_the_slideway_on_its_grid(ros: None) -> None:
    ns = namespace()
    node = _node(ns)
    probe = Probe(ns, node, outputs={"accelerometer": Imu, "pose": type(node._pose)})  # noqa: SLF001
    try:
        assert probe.spin_until(lambda: len(probe.received["accelerometer"]) >= 300, 30.0)
    finally:
        probe.close()
        node.destroy_node()
    samples = probe.received["accelerometer"][:300]
    stamps = np.array([stamp_ns(m) for m in samples])
    grid = np.rint(stamps * RATE / 1e9)
    assert np.all(np.diff(grid) == 1), "one sample per grid point k/rate, none skipped"
    assert np.all(np.abs(stamps - grid / RATE * 1e9) <= 1.0), "stamped at k/rate (to the nanosecond)"
    assert all(m.orientation_covariance[0] == -1.0 and m.angular_velocity_covariance[0] == -1.0 for m in samples)
    assert all(m.header.frame_id == "slideway" for m in samples)
    # the same plant offline: the slideway's acceleration less gravity, in the track frame
    slider = Slider(PLANT, Inputs())
    g, alpha = PLANT.gravity, math.radians(PLANT.track_inclination)
    for k, msg in zip(grid, samples):
        slider.advance_to(float(k) / RATE)
        along, normal = slider.slideway_acceleration()
        # (cutting time at other points changes nothing; the sum with g rounds once)
        scale = g + 10.0
        assert msg.linear_acceleration.x == pytest.approx(along + g * math.sin(alpha), abs=1e-12 * scale)
        assert msg.linear_acceleration.z == pytest.approx(normal + g * math.cos(alpha), abs=1e-12 * scale)
        assert msg.linear_acceleration.y == 0.0
    # it vibrates: along the line at 60 degrees, cot(60) times the normal part
    z = np.array([m.linear_acceleration.z for m in samples]) - g * math.cos(alpha)
    x = np.array([m.linear_acceleration.x for m in samples]) - g * math.sin(alpha)
    assert np.ptp(z) > 1.0 and x == pytest.approx(z / math.tan(math.radians(60.0)), abs=1e-12 * scale)


def test_drive_level_steers_and_excitation_amplitude_is_refused_naming_it(ros: None) -> None:
    ns = namespace()
    node = _node(ns, accelerometer_rate=0.0)
    probe = Probe(ns, node, outputs={"diagnostics": DiagnosticArray, "pose": type(node._pose)})  # noqa: SLF001
    try:
        probe.wait_for_connection()

        def latest() -> dict[str, str]:
            return diagnostics_values(probe.received["diagnostics"][-1]) if probe.received["diagnostics"] else {}

        probe.send("drive_level", 0.9)
        assert probe.spin_until(lambda: latest().get("drive_level") == "0.9", 15.0), latest()
        rejected = int(latest()["commands_rejected"])
        probe.send("excitation_amplitude", 3.0)
        assert probe.spin_until(lambda: int(latest().get("commands_rejected", "0")) > rejected, 15.0), latest()
        report = latest()
        assert "drive_level" in report["last_rejection"] and "excitation_amplitude" in report["last_rejection"]
        assert "\n" not in report["last_rejection"]
        assert report["excitation_amplitude"] == "5.0" and report["actuator"] == "resonant"
        assert float(report["exciter_lag_deg"]) == pytest.approx(27.0, abs=0.5)  # 50 Hz against 52 Hz, Q = 25
    finally:
        probe.close()
        node.destroy_node()
