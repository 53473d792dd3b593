"""The resonant actuator on ROS (issue 21, item 2; issue 28): the accelerometer,
the drive_level topic, the diagnostics of what acts and the refusal of
excitation_amplitude, over real DDS."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.exciter import response
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
    # (the queue holds 10 s of readings: on a loaded machine this process may not run for
    # 0.1 s, and a queue of 100 then lost readings before the probe took them)
    probe = Probe(ns, node, outputs={"accelerometer": Imu, "pose": PoseStamped}, depth=10 * int(RATE))
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


def _waiter(probe: Probe) -> Callable[[Callable[[dict[str, str]], bool]], dict[str, str]]:
    """A function that spins until a diagnostics message satisfies ``condition``
    (waiting for the message itself) and returns its values."""
    def wait(condition: Callable[[dict[str, str]], bool]) -> dict[str, str]:
        found: list[dict[str, str]] = []

        def seen() -> bool:
            found[:] = [v for v in map(diagnostics_values, probe.received["diagnostics"]) if condition(v)][-1:]
            return bool(found)

        if not probe.spin_until(seen, 15.0):
            messages = probe.received["diagnostics"]
            raise AssertionError(f"no such diagnostics in 15 s; the last: "
                                 f"{diagnostics_values(messages[-1]) if messages else 'none'}")
        return found[0]
    return wait


def test_resonant_diagnostics_show_the_drive_level_its_steady_pa_and_the_envelope(ros: None) -> None:
    """Issue 28, item 4, over DDS: the slider's /diagnostics show what acts with
    the resonant actuator (u, the steady Pa m u A G(f/f_n) and the exciter's
    envelope now), and excitation_amplitude, which it ignores, marked unused."""
    ns = namespace()
    node = _node(ns, accelerometer_rate=0.0)
    probe = Probe(ns, node, outputs={"diagnostics": DiagnosticArray, "pose": PoseStamped})
    wait = _waiter(probe)
    gain = response(50.0, 52.0, PLANT.damping_ratio).gain
    try:
        probe.wait_for_connection()
        # steady from the start (no transient yet): the envelope is the steady Pa, far from the 5 N parameter
        report = wait(lambda values: "steady_excitation_amplitude" in values)
        steady = PLANT.mass * 0.5 * PLANT.full_drive_acceleration * gain
        assert report["actuator"] == "resonant" and report["drive_level"] == "0.5"
        assert float(report["steady_excitation_amplitude"]) == pytest.approx(steady, rel=1e-12)
        assert float(report["excitation_envelope"]) == pytest.approx(steady, rel=1e-12)
        assert report["excitation_amplitude"] == "5.0 (unused: actuator resonant)"
        probe.send("drive_level", 0.9)
        report = wait(lambda values: values.get("drive_level") == "0.9")
        steady = PLANT.mass * 0.9 * PLANT.full_drive_acceleration * gain
        assert float(report["steady_excitation_amplitude"]) == pytest.approx(steady, rel=1e-12)
        assert float(report["excitation_envelope"]) > steady * (1 + 1e-6), "the transient after the step shows"
        assert report["excitation_amplitude"] == "5.0 (unused: actuator resonant)"
    finally:
        probe.close()
        node.destroy_node()


def test_drive_level_steers_and_excitation_amplitude_is_refused_naming_it(ros: None) -> None:
    """Issue 28, finding 8: a Pa is refused by the resonant actuator on its topic
    whatever its value (the one held too), and as a parameter set to any other
    value than the one held, with the same one-line reason, counted as refused
    and never as accepted; a set that keeps the value held (a dump loaded back)
    is taken and changes nothing."""
    ns = namespace()
    node = _node(ns, accelerometer_rate=0.0)
    probe = Probe(ns, node, outputs={"diagnostics": DiagnosticArray, "pose": PoseStamped})
    wait = _waiter(probe)
    why = "excitation_amplitude = 5.0 rejected: is not used by actuator resonant: set drive_level (0 … 1) instead"
    try:
        probe.wait_for_connection()
        probe.send("drive_level", 0.9)
        report = wait(lambda values: values.get("drive_level") == "0.9")
        accepted, rejected = int(report["commands_accepted"]), int(report["commands_rejected"])
        probe.send("excitation_amplitude", 5.0)  # the value held
        report = wait(lambda values: int(values["commands_rejected"]) > rejected)
        assert report["last_rejection"] == why, report["last_rejection"]
        assert (int(report["commands_rejected"]), int(report["commands_accepted"])) == (rejected + 1, accepted)
        assert probe.set_parameter(node.get_fully_qualified_name(), "excitation_amplitude", 15.0) == \
            (False, why.replace("= 5.0", "= 15.0"))
        assert probe.set_parameter(node.get_fully_qualified_name(), "excitation_amplitude", 5.0) == (True, "")
        report = wait(lambda values: int(values["commands_rejected"]) >= rejected + 2
                      and int(values["commands_accepted"]) >= accepted + 1)
        assert (int(report["commands_rejected"]), int(report["commands_accepted"])) == (rejected + 2, accepted + 1)
        assert report["excitation_amplitude"] == "5.0 (unused: actuator resonant)" and report["drive_level"] == "0.9"
        assert node.get_parameter("excitation_amplitude").value == 5.0
        assert float(report["exciter_lag_deg"]) == pytest.approx(27.0, abs=0.5)  # 50 Hz against 52 Hz, Q = 25
    finally:
        probe.close()
        node.destroy_node()
