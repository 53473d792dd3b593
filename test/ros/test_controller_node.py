"""The controller node over real topics: its model from the plant node,
diagnostics, its console scripts, and its parameters.  (The law itself is
tested offline in test/core/control/test_control.py, the acceptance cases in
test/experiment/test_acceptance.py.)"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy

from friction_sim.core.control.speedlimit import speed_limit
from friction_sim.core.model.params import SliderParams
from friction_sim.ros.controller import ControllerNode
from friction_sim.ros.controller_lockstep import LOCKSTEP_READ
from friction_sim.ros.slider import SliderNode

from ros_harness import Probe, kill_if_running

ROOT = Path(__file__).resolve().parents[2]


def controller_status(probe: Probe) -> dict[str, str]:
    """The values of the newest ``controller`` status the probe received ({} before one)."""
    for msg in reversed(probe.received["diagnostics"]):
        for status in msg.status:
            if status.name == "controller":
                return {kv.key: kv.value for kv in status.values}
    return {}


# -- over real topics -------------------------------------------------------------


def test_controller_reads_the_plant_and_reports_diagnostics(ros: None) -> None:
    ns = f"/c{uuid.uuid4().hex[:8]}"
    slider = SliderNode(namespace=ns, parameter_overrides=[Parameter("mass", value=2.0)])
    controller = ControllerNode(namespace=ns)
    probe = Probe(ns, slider, controller, outputs={"diagnostics": DiagnosticArray, "pose": __import__(
        "geometry_msgs.msg", fromlist=["PoseStamped"]).PoseStamped})
    try:
        assert probe.spin_until(lambda: controller.ready, 10.0)
        assert controller.control.config.model == SliderParams(mass=2.0)
        assert controller.get_parameter("mass").value == 2.0
        probe.send("target_speed", -1e-4)  # wrong sign: rejected
        assert probe.spin_until(lambda: controller.runtime.rejected == 1, 15.0)
        probe.send("target_speed", float("nan"))
        assert probe.spin_until(lambda: controller.runtime.rejected == 2, 15.0)
        assert controller.control.target_speed == 0.0002

        assert probe.spin_until(lambda: controller_status(probe).get("commands_rejected") == "2", 10.0)
        values = controller_status(probe)
        for key in ("target_speed", "measured_mean_speed", "feedforward_ratio", "applied_ratio", "integral",
                    "saturated", "unreachable"):
            assert key in values
        assert "nan" in values["last_rejection"]

        assert probe.set_parameter(f"{ns}/controller", "target_speed", 3e-4)[0]
        assert controller.control.target_speed == 3e-4
        assert probe.set_parameter(f"{ns}/controller", "max_amplitude_ratio", 0.999)[0]
        successful, reason = probe.set_parameter(f"{ns}/controller", "target_speed", -3e-4)
        assert not successful and "target_speed" in reason
    finally:
        probe.close()
        controller.destroy_node()
        slider.destroy_node()


def test_the_controller_follows_its_plant_s_parameter_changes_and_names_the_plant(ros: None) -> None:
    """Issue 23, item 8: the README's ``ros2 param set /slider
    excitation_frequency 100.0`` (and a drive force, a mass set as parameters)
    reach the controller's model as they happen, through /parameter_events:
    its diagnostics say 100 Hz, the sample limit is the new plant's, and they
    name the plant node it inverts."""
    ns = f"/c{uuid.uuid4().hex[:8]}"
    slider = SliderNode(namespace=ns)
    controller = ControllerNode(namespace=ns, parameter_overrides=[Parameter("diagnostics_period", value=0.1)])
    probe = Probe(ns, slider, controller, outputs={"diagnostics": DiagnosticArray})
    try:
        assert probe.spin_until(lambda: controller.ready, 10.0)
        before = controller.control.sample_limit
        assert probe.set_parameter(f"{ns}/slider", "excitation_frequency", 100.0)[0]
        assert probe.spin_until(lambda: controller.control.frequency == 100.0, 10.0), "the model follows f"
        assert probe.set_parameter(f"{ns}/slider", "drive_force", 0.8)[0]
        assert probe.spin_until(lambda: controller.control.drive_force == 0.8, 10.0), "and Fd"
        assert probe.set_parameter(f"{ns}/slider", "mass", 2.0)[0]
        assert probe.spin_until(lambda: controller.control.config.model.mass == 2.0, 10.0), "and the model"
        # the old plant's limit holds until its windows have passed; then the new plant's is in force
        assert probe.spin_until(lambda: controller.control.sample_limit == speed_limit(0.8, SliderParams(mass=2.0),
                                                                                       100.0), 10.0)
        assert controller.control.sample_limit == pytest.approx(2 * 0.8 / (2.0 * 100.0)) != before
        assert controller.get_parameter("excitation_frequency").value == 100.0
        assert probe.spin_until(lambda: controller_status(probe).get("plant_changes_followed") == "3", 10.0)
        values = controller_status(probe)
        assert values["plant_node"] == f"{ns}/slider" and values["model_source"] == f"plant node {ns}/slider"
        assert values["excitation_frequency"] == "100.0" and "f = 100 Hz" in values["plant"], values
        assert "m = 2 kg" in values["plant"] and "Fd = 0.8 N" in values["plant"], values["plant"]
    finally:
        probe.close()
        controller.destroy_node()
        slider.destroy_node()


def test_controller_without_its_plant_says_so_and_uses_its_own_model(ros: None) -> None:
    ns = f"/c{uuid.uuid4().hex[:8]}"
    started = time.monotonic()
    controller = ControllerNode(namespace=ns, parameter_overrides=[Parameter("mu", value=0.2)])
    probe = Probe(ns, controller, outputs={"excitation_amplitude": __import__(
        "std_msgs.msg", fromlist=["Float64"]).Float64})
    try:
        assert probe.spin_until(lambda: controller.ready, 30.0)
        assert time.monotonic() - started >= 5.0, "it waited 5 s for the plant node"
        assert controller.runtime.model_source == "own parameters"
        assert controller.control.config.model.mu == 0.2
    finally:
        probe.close()
        controller.destroy_node()


@pytest.mark.parametrize("command", [["controller"], ["friction-sim", "feeder"]])
def test_console_scripts_run_and_stop_on_sigint(ros: None, command: list[str]) -> None:
    ns = f"/c{uuid.uuid4().hex[:8]}"
    exe = Path(sys.executable).parent / command[0]
    process = subprocess.Popen([str(exe), *command[1:], "--ros-args", "-r", f"__ns:={ns}"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ))
    from std_msgs.msg import Float64

    probe = Probe(ns, outputs={"excitation_amplitude": Float64, "diagnostics": DiagnosticArray})
    try:
        # The controller's status comes from a timer of its executor: the process is up and spinning
        # (with a plant, its answers to the plant's samples too), and a SIGINT now stops a running node.
        assert probe.spin_until(lambda: bool(controller_status(probe)), 30.0), "the controller never reported"
        if command[0] != "controller":
            assert probe.spin_until(lambda: bool(probe.received["excitation_amplitude"]), 20.0)
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=15)
        assert process.returncode == 0, err
        assert "Traceback" not in err
    finally:
        kill_if_running(process)
        probe.close()


def test_a_target_is_checked_against_the_drive_force_in_force(ros: None) -> None:
    """The drive force came by topic (the parameter still says 0.7): a positive
    target is refused by ros2 param set instead of killing the node."""
    ns = f"/c{uuid.uuid4().hex[:8]}"
    controller = ControllerNode(namespace=ns, parameter_overrides=[Parameter("plant_node", value="")])
    probe = Probe(ns, controller, outputs={"excitation_amplitude": __import__(
        "std_msgs.msg", fromlist=["Float64"]).Float64})
    try:
        probe.send("drive_force", -0.5)
        assert probe.spin_until(lambda: controller.control.drive_force == -0.5, 10.0)
        successful, reason = probe.set_parameter(f"{ns}/controller", "target_speed", 0.0001)
        assert not successful and "target_speed" in reason and "-0.5" in reason
        assert probe.set_parameter(f"{ns}/controller", "target_speed", -0.0001)[0]
        assert controller.control.target_speed == -0.0001
    finally:
        probe.close()
        controller.destroy_node()


def test_controller_reads_the_general_model_from_the_plant(ros: None) -> None:
    """Issue 11: the whole model comes from the plant node (the text parameter
    landing_friction too); on a tilted vibration a target needs no drive force
    in its direction (an initial one waits for the plant's model), and the law
    inverts the general mean speed."""
    ns = f"/c{uuid.uuid4().hex[:8]}"
    plant = {"mu": 0.5, "static_ratio": 1.5, "excitation_angle": 60.0, "excitation_phase": 10.0,
             "track_inclination": 5.0, "restitution": 0.3, "landing_friction": "none"}
    slider = SliderNode(namespace=ns, parameter_overrides=[Parameter(k, value=v) for k, v in plant.items()])
    # U* = 0.02 with no drive force: the node's own (Kostek) model refuses it, the plant's takes it
    controller = ControllerNode(namespace=ns, parameter_overrides=[Parameter("drive_force", value=0.0),
                                                                   Parameter("target_speed", value=2e-3)])
    probe = Probe(ns, slider, controller)
    try:
        assert controller.control.target_speed == 0.0, "waiting for the plant's model"
        assert probe.spin_until(lambda: controller.ready, 10.0)
        assert controller.control.config.model == SliderParams(**plant)
        assert controller.get_parameter("landing_friction").value == "none"
        assert controller.runtime.model_source == f"plant node {ns}/slider"
        assert controller.control.target_speed == 2e-3 and controller.runtime.rejected == 0
        assert probe.set_parameter(f"{ns}/controller", "target_speed", 3e-3)[0]
        out = controller.control.output
        assert not (out.unreachable or out.saturated or out.runaway) and 0.0 < out.applied_ratio < 0.95
        successful, reason = probe.set_parameter(f"{ns}/controller", "landing_friction", "sliding")
        assert not successful and "landing_friction" in reason and "impulsive, none" in reason
    finally:
        probe.close()
        controller.destroy_node()
        slider.destroy_node()


def test_a_plant_without_the_general_parameters_leaves_them_as_they_are(ros: None) -> None:
    """A slider from before issue 11 answers mass, mu, gravity and the window
    but not the new model parameters (NOT_SET): those keep the controller's values."""
    from types import SimpleNamespace

    from rcl_interfaces.msg import ParameterType, ParameterValue

    ns = f"/c{uuid.uuid4().hex[:8]}"
    controller = ControllerNode(namespace=ns, parameter_overrides=[Parameter("plant_node", value=""),
                                                                   Parameter("excitation_angle", value=45.0)])
    try:
        def double(value: float) -> ParameterValue:
            return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)

        # (and no actuator, exciter or drive level: the force actuator, the only one it had; Fd and f
        # as they are; nor lockstep, its delay and its accelerometer: it ran in real time)
        answer = [double(2.0), double(0.2), double(9.81), *[ParameterValue() for _ in range(10)],
                  ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=2), double(0.75), double(60.0),
                  ParameterValue(), *[ParameterValue() for _ in LOCKSTEP_READ]]
        controller.plant.adopt(SimpleNamespace(values=answer))  # the reply of an older plant
        assert controller.control.config.model == SliderParams(mass=2.0, mu=0.2, gravity=9.81, excitation_angle=45.0)
        assert controller.control.config.mean_window_periods == 2
        assert controller.control.drive_force == 0.75 and controller.control.frequency == 60.0
        assert controller.runtime.plant_actuator == "force" and controller.runtime.drive is None
        assert controller.lockstep is None
    finally:
        controller.destroy_node()


#: Plants whose every setting the controller takes differs from the controller's defaults (issue 28,
#: item 1); the resonant actuator's slideway moves along one line, so its excitation_phase is 0 and the
#: force actuator's plant differs there.
RUNNING_FEEDERS = {
    "resonant": {
        "mass": 1.3, "mu": 0.12, "gravity": 9.81, "static_ratio": 1.2, "excitation_angle": 80.0,
        "track_inclination": 2.0, "restitution": 0.1, "landing_friction": "none",
        "actuator": "resonant", "natural_frequency": 51.0, "damping_ratio": 0.05, "full_drive_acceleration": 12.0,
        "mean_window_periods": 2, "drive_force": 0.8, "excitation_frequency": 49.4, "drive_level": 0.6,
    },
    "force": {
        "mass": 1.3, "mu": 0.12, "gravity": 9.81, "static_ratio": 1.2, "excitation_angle": 80.0,
        "excitation_phase": 10.0, "track_inclination": 2.0, "restitution": 0.1, "landing_friction": "none",
        "mean_window_periods": 2, "drive_force": 0.8, "excitation_frequency": 100.0,
    },
}


@pytest.mark.parametrize("actuator", list(RUNNING_FEEDERS))
def test_the_controller_takes_its_whole_plant_at_start_up(ros: None, actuator: str) -> None:
    """Issue 28, item 1: a controller started with its defaults on a feeder that
    runs with other settings takes every one of them, the drive force, the
    frequency and the drive level among them, before it publishes anything, and
    its diagnostics name each value it took."""
    from friction_sim.core.model.spec import CONTROLLER_NODE

    feeder = RUNNING_FEEDERS[actuator]
    plant = {name: value for name, value in feeder.items() if name != "drive_level"}
    assert all(CONTROLLER_NODE[name].default != value for name, value in plant.items())
    ns = f"/c{uuid.uuid4().hex[:8]}"
    slider = SliderNode(namespace=ns, parameter_overrides=[Parameter(name, value=value)
                                                           for name, value in feeder.items()])
    controller = ControllerNode(namespace=ns, parameter_overrides=[Parameter("diagnostics_period", value=0.1)])
    probe = Probe(ns, slider, controller, outputs={"diagnostics": DiagnosticArray})
    try:
        assert probe.spin_until(lambda: controller.ready, 15.0)
        assert probe.spin_until(lambda: controller_status(probe).get("taken_from_plant", "") != "", 10.0)
        values = controller_status(probe)
    finally:
        probe.close()
        controller.destroy_node()
        slider.destroy_node()
    for name, value in plant.items():
        assert controller.get_parameter(name).value == value, name
    frequency = plant["excitation_frequency"]
    assert controller.control.drive_force == 0.8 and controller.control.frequency == frequency
    assert controller.control.config.model.mass == 1.3 and controller.control.config.mean_window_periods == 2
    drive = controller.runtime.drive
    if actuator == "resonant":
        assert drive is not None and drive.start_level == 0.6 and drive.loop.cycles == 2
        assert drive.model.natural_frequency == 51.0 and drive.model.full_drive_acceleration == 12.0
    else:
        assert drive is None
    taken = values["taken_from_plant"]
    for name, value in feeder.items():
        assert f"{name} {value:g}" in taken if isinstance(value, float) else f"{name} {value}" in taken, (name, taken)
    assert "Fd = 0.8 N" in values["plant"] and f"f = {frequency:g} Hz" in values["plant"], values["plant"]
    assert values["model_source"] == f"plant node {ns}/slider"


@pytest.mark.parametrize(("actuator", "reads"), [("force", False), ("resonant", True)])
def test_in_lockstep_the_controller_reads_the_accelerometer_only_for_its_inner_loop(
        ros: None, actuator: str, reads: bool) -> None:
    """A reader of the accelerometer as deep as a lockstep window makes each of the slider's
    thousand readings a second cost it several times more: the controller of a force-actuated
    plant has none; the resonant plant's inner loop reads them (transient local: from the start)."""
    ns = f"/c{uuid.uuid4().hex[:8]}"
    controller = ControllerNode(namespace=ns, parameter_overrides=[
        Parameter("plant_node", value=""), Parameter("lockstep", value=True), Parameter("actuator", value=actuator),
        Parameter("accelerometer_rate", value=1000.0 if reads else 0.0)])
    try:
        deadline = time.monotonic() + 30.0
        while controller.lockstep is None:  # it settles its model (its own: no plant node) on its timer
            assert time.monotonic() < deadline, "the controller never settled its model"
            rclpy.spin_once(controller, timeout_sec=0.05)
        assert (controller.accelerometer is not None) == reads
        if reads:
            assert controller.accelerometer.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
    finally:
        controller.destroy_node()
