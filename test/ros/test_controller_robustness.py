"""The controller node against bad input and its own bugs (issue 10): samples
no plant could produce, parameter values rclpy refuses, an unexpected error in
a callback, a namesake in the graph; its diagnostics' stamps and --help."""

from __future__ import annotations

import math
import subprocess
import sys
import uuid
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import TwistStamped
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMsg
from std_msgs.msg import Float64

from friction_sim.core.control import reach
from friction_sim.ros.controller import ControllerNode

from ros_harness import Probe

OUTPUTS = {"excitation_amplitude": Float64, "diagnostics": DiagnosticArray}


def status_of(probe: Probe) -> DiagnosticStatus | None:
    """The controller's latest diagnostics status."""
    for msg in reversed(probe.received["diagnostics"]):
        for status in msg.status:
            if status.name == "controller":
                return status
    return None


def values_of(probe: Probe) -> dict[str, str]:
    status = status_of(probe)
    return {kv.key: kv.value for kv in status.values} if status is not None else {}


@pytest.fixture
def running(ros: None) -> Any:
    """A regulating controller without a plant node, and a probe spinning both."""
    ns = f"/c{uuid.uuid4().hex[:8]}"
    controller = ControllerNode(namespace=ns, parameter_overrides=[Parameter("plant_node", value="")])
    probe = Probe(ns, controller, outputs=OUTPUTS)
    assert probe.spin_until(lambda: controller.ready and bool(probe.received["excitation_amplitude"]), 20.0)
    assert probe.spin_until(lambda: probe.publishers["target_speed"].get_subscription_count() > 0, 10.0)
    assert probe.spin_until(probe.readers_know_our_writers, 10.0)  # the controller's readers know ours too
    yield ns, controller, probe
    probe.close()
    controller.destroy_node()


def test_impossible_samples_are_refused_counted_and_reported(running: Any) -> None:
    """-1e300 and 1e308 on mean_velocity used to reach the law (and make it NaN)."""
    _, controller, probe = running
    publisher = probe.node.create_publisher(TwistStamped, "mean_velocity", 10)
    assert probe.spin_until(lambda: publisher.get_subscription_count() > 0, 10.0)
    # and the controller's reader knows our writer (it says so itself: it is in this process)
    (reader,) = [sub for sub in controller.subscriptions if sub.topic_name == publisher.topic_name]
    assert probe.spin_until(lambda: reader.get_publisher_count() > 0, 10.0)
    amplitude = controller.control.output.amplitude
    for n, value in enumerate((-1e300, 1e308, math.nan, 2e-4)):
        msg = TwistStamped()
        msg.header.stamp.sec = 100 + n
        msg.twist.linear.x = value
        publisher.publish(msg)
    runtime = controller.runtime
    assert probe.spin_until(lambda: runtime.samples_rejected + runtime.samples_accepted == 4, 30.0)
    assert controller.runtime.samples_rejected == 3 and controller.runtime.samples_accepted == 1
    assert "mean_velocity" in controller.runtime.last_sample_rejection
    assert probe.spin_until(lambda: values_of(probe).get("samples_rejected") == "3", 5.0)
    values = values_of(probe)
    assert values["sample_limit"] == repr(controller.control.sample_limit) or float(values["sample_limit"]) > 0
    assert status_of(probe).level == DiagnosticStatus.WARN  # type: ignore[union-attr]
    assert controller.control.output.amplitude == amplitude, "nothing integrated from them"
    assert all(math.isfinite(m.data) for m in probe.received["excitation_amplitude"])


@pytest.mark.parametrize(("name", "value", "words"), [
    ("target_speed", math.nan, ("target_speed", "nan")),
    ("integral_gain", 5.0, ("integral_gain", "5.0")),
    ("mass", "heavy", ("mass", "'heavy'")),
])
def test_parameter_values_rclpy_refuses_are_counted(running: Any, name: str, value: Any,
                                                    words: tuple[str, ...]) -> None:
    """rclpy's descriptor checks refuse these before the node's callbacks:
    they were neither warned about nor counted."""
    ns, controller, probe = running
    successful, _ = probe.set_parameter(f"{ns}/controller", name, value)
    assert not successful
    assert controller.runtime.rejected == 1
    for word in words:
        assert word in controller.runtime.last_rejection
    assert probe.spin_until(lambda: values_of(probe).get("commands_rejected") == "1", 5.0)


class Recorder:
    """A logger that keeps what it is asked to log and passes it on."""

    def __init__(self, logger: Any) -> None:
        self._logger = logger
        self.errors: list[str] = []

    def error(self, text: str) -> None:
        self.errors.append(text)
        self._logger.error(text)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._logger, name)


def test_an_unexpected_error_is_reported_once_and_the_node_goes_on(running: Any,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """A bug in the law (here: the inverse relation raising) used to end the
    executor's spin: the node died with a traceback (or, in a process of
    several nodes, stopped answering).  Now the input is refused, the law's
    state stays, the error is logged once and diagnostics say ERROR."""
    ns, controller, probe = running
    logger = Recorder(controller.get_logger())
    monkeypatch.setattr(controller, "get_logger", lambda: logger)

    def broken(u: float, phi: float, top: float) -> float:
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(reach, "inverse", broken)
    target = controller.control.target_speed
    for n, value in enumerate((3e-4, 3.5e-4)):
        probe.send("target_speed", value)
        assert probe.spin_until(lambda n=n: controller.runtime.internal_errors == n + 1, 10.0)  # type: ignore[misc]
    assert controller.control.target_speed == target, "refused: the state is as before"
    assert len(logger.errors) == 1 and "ZeroDivisionError" in logger.errors[0]
    successful, reason = probe.set_parameter(f"{ns}/controller", "target_speed", 4e-4)
    assert not successful and "internal error" in reason and "ZeroDivisionError" in reason
    assert controller.get_parameter("target_speed").value != 4e-4
    assert probe.spin_until(lambda: (status := status_of(probe)) is not None
                            and status.level == DiagnosticStatus.ERROR, 5.0)
    assert "ZeroDivisionError" in status_of(probe).message  # type: ignore[union-attr]
    monkeypatch.undo()
    probe.send("target_speed", 3e-4)
    assert probe.spin_until(lambda: controller.control.target_speed == 3e-4, 10.0), "and it goes on"


def test_a_namesake_in_the_graph_is_reported(running: Any) -> None:
    ns, _, probe = running
    twin = ControllerNode(namespace=ns, parameter_overrides=[Parameter("plant_node", value="")])
    probe.executor.add_node(twin)
    try:
        assert probe.spin_until(lambda: "named" in (getattr(status_of(probe), "message", "")), 10.0)
        assert f"{ns}/controller" in status_of(probe).message  # type: ignore[union-attr]
    finally:
        probe.executor.remove_node(twin)
        twin.destroy_node()


def test_diagnostics_are_stamped_by_the_node_clock_like_the_slider(ros: None) -> None:
    """Both nodes stamp diagnostics with the node's clock: /clock under use_sim_time."""
    ns = f"/c{uuid.uuid4().hex[:8]}"
    controller = ControllerNode(namespace=ns, parameter_overrides=[
        Parameter("plant_node", value=""), Parameter("use_sim_time", value=True)])
    probe = Probe(ns, controller, outputs=OUTPUTS)
    clock = probe.node.create_publisher(ClockMsg, "/clock", 10)
    try:
        def sim_stamped() -> bool:
            msg = ClockMsg()
            msg.clock.sec = 1234
            clock.publish(msg)
            return any(m.header.stamp.sec == 1234 for m in probe.received["diagnostics"])

        assert probe.spin_until(sim_stamped, 15.0)
    finally:
        probe.close()
        controller.destroy_node()


def test_help_describes_the_node_without_starting_it() -> None:
    exe = Path(sys.executable).parent / "controller"
    done = subprocess.run([str(exe), "--help"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    for word in ("target_speed", "max_amplitude_ratio", "mean_velocity", "excitation_amplitude", "exit codes"):
        assert word in done.stdout
