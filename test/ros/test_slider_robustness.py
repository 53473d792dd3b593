"""The slider node's promises at the edges, over real ROS (DDS on localhost,
random domain: conftest): a command the core fails on is refused and the node
goes on; a simulation that cannot go on stops the node with one line and exit
code 3, never a silent dead tick thread; atomic parameter sets take effect
whole; values rclpy refuses are warned about and counted; a second node with
the same name is reported; --help."""

from __future__ import annotations

import itertools
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped

from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.urelation import u_map
from friction_sim.core.model import spec
from friction_sim.errors import NodeFault
from friction_sim.ros.run import EXIT_FAULT

from helpers import POISON
from ros_harness import Probe, diagnostics_values, kill_if_running, namespace, stamp_ns

BIN = Path(sys.executable).parent


def level(msg: DiagnosticArray) -> int:
    return int.from_bytes(msg.status[0].level, "little") if isinstance(msg.status[0].level, bytes) \
        else int(msg.status[0].level)


def start_slider(ns: str, *ros_args: str, python: str | None = None) -> subprocess.Popen[str]:
    """The slider console script (or ``python -c`` code that ends in its main) in its own process."""
    command = [str(BIN / "slider")] if python is None else [sys.executable, "-c", python]
    return subprocess.Popen([*command, "--ros-args", "-r", f"__ns:={ns}", *ros_args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ))


def stop(process: subprocess.Popen[str]) -> tuple[int, str]:
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    _out, err = process.communicate(timeout=20)
    return process.returncode, err


# -- a command the core fails on -------------------------------------------------




@pytest.mark.usefixtures("failing_core")
def test_a_command_the_core_fails_on_is_refused_and_the_node_goes_on(rig) -> None:  # type: ignore[no-untyped-def]
    node, probe, outcomes = rig
    probe.send("drive_force", POISON)
    assert probe.spin_until(lambda: len(outcomes) >= 1, 15.0)
    (outcome,) = outcomes
    assert not outcome.accepted and "OverflowError" in outcome.reason and "drive_force" in outcome.reason
    assert node.realtime.slider.inputs.drive_force == 0.7
    poses = len(probe.received["pose"])
    assert probe.spin_until(lambda: len(probe.received["pose"]) > poses + 200, 10.0), "still ticking"
    # The next parameter set neither kills the node nor takes the value the core cannot take.
    successful, reason = probe.set_parameter(f"{node.get_namespace()}/slider", "drive_force", POISON)
    assert not successful and "OverflowError" in reason
    assert probe.set_parameter(f"{node.get_namespace()}/slider", "drive_force", 0.9) == (True, "")
    assert node.realtime.slider.inputs.drive_force == 0.9 and not node.fault
    assert probe.spin_until(lambda: any(
        "OverflowError" in diagnostics_values(m)["last_rejection"] and level(m) == 1
        for m in probe.received["diagnostics"]), 10.0), "diagnostics WARN with the reason"


def test_a_simulation_fault_stops_the_node_in_process_and_parameter_sets_still_answer(
        rig, monkeypatch: pytest.MonkeyPatch) -> None:  # type: ignore[no-untyped-def]
    node, probe, _ = rig
    real = Slider.advance_to

    def advance_to(self: Slider, t: float) -> Any:
        if self.inputs.drive_force == POISON:
            raise ValueError("math domain error")
        return real(self, t)

    monkeypatch.setattr(Slider, "advance_to", advance_to)
    probe.send("drive_force", POISON)
    with pytest.raises(NodeFault, match="math domain error"):
        probe.spin_until(lambda: False, 15.0)
    assert "math domain error" in node.fault and "t = " in node.fault
    # It stopped, and said so: the fault is signalled from the tick thread just before it
    # returns, so wait for that thread to end (the timeout only guards a hang)
    node._ticker.join(timeout=10.0)  # noqa: SLF001
    assert not node._ticker.is_alive()  # noqa: SLF001
    assert probe.spin_until(lambda: any(level(m) == 2 for m in probe.received["diagnostics"]), 5.0)
    errors = [m for m in probe.received["diagnostics"] if level(m) == 2]
    assert errors and "math domain error" in errors[-1].status[0].message
    successful, reason = probe.set_parameter(f"{node.get_namespace()}/slider", "drive_force", 0.9)
    assert not successful and "math domain error" in reason
    successful, reason = probe.set_parameter(f"{node.get_namespace()}/slider", "mass", math.nan)
    assert not successful and "mass" in reason and "nan" in reason  # rclpy's own answer


FAULTY_SLIDER = f"""
import sys
from friction_sim.core.engine.single import Slider
real = Slider.advance_to
def advance_to(self, t):
    if self.inputs.drive_force == {POISON!r}:
        raise ValueError("math domain error")
    return real(self, t)
Slider.advance_to = advance_to
from friction_sim.ros.slider import main
sys.exit(main())
"""


def test_a_simulation_fault_ends_the_process_with_one_line_and_exit_code_3(ros: None) -> None:
    ns = namespace()
    process = start_slider(ns, python=FAULTY_SLIDER)
    probe = Probe(ns)
    try:
        probe.wait_for_connection(timeout=20.0)
        probe.send("drive_force", POISON)
        code = process.wait(timeout=20.0)
        _out, err = process.communicate(timeout=10)
        # the ERROR status it published before it ended, on its way here
        probe.spin_until(lambda: any(level(m) == 2 for m in probe.received["diagnostics"]), 10.0)
    finally:
        kill_if_running(process)
        probe.close()
    assert code == EXIT_FAULT, err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if "math domain error" in line]
    assert len(lines) == 1 and "ERROR" in lines[0] and f"exit code {EXIT_FAULT}" in lines[0], err
    errors = [m for m in probe.received["diagnostics"] if level(m) == 2]
    assert errors and "math domain error" in errors[-1].status[0].message, "diagnostics said so before the end"


# -- atomic parameter sets ---------------------------------------------------------


#: How long 600 states may take to come [s]: only a guard against a hang.  At 2500 Hz a hopping
#: slider's tick simulates many flights; on a machine that other work starves it publishes far
#: below its 1 kHz (one loaded suite: fewer than 600 in 10 s), and that is not what is tested.
STATES_GUARD = 120.0


def test_an_atomic_set_valid_together_is_applied_whole(ros: None) -> None:
    """{excitation_frequency: 2500, real_time_factor: 1} from a real-time factor of 10
    (each alone would break f x rtf <= 20000), {mass: 0.4, excitation_amplitude: 3}
    from the defaults: the simulation runs on the new values.  A set with one bad
    value (a landing_friction that is not a choice) is refused whole.  A set that
    takes the throw number above 1 ({mass: 0.2, excitation_amplitude: 3}: Pa > m g)
    is taken, and the slider hops: z > 0 and R = 0 are published.  The node's log
    says what the answers say."""
    ns = namespace()
    process = start_slider(ns, "-p", "real_time_factor:=10.0")
    probe = Probe(ns, outputs={"diagnostics": DiagnosticArray, "mean_velocity": TwistStamped,
                               "pose": PoseStamped, "friction_force": WrenchStamped})
    try:
        probe.wait_for_connection(timeout=20.0)
        slider = f"{ns}/slider"
        assert probe.set_parameters_atomically(slider, {"excitation_frequency": 2500.0,
                                                        "real_time_factor": 1.0}) == (True, "")
        settled = len(probe.received["diagnostics"])
        assert probe.spin_until(lambda: len(probe.received["diagnostics"]) >= settled + 2, 10.0)
        before, values = (diagnostics_values(d) for d in probe.received["diagnostics"][-2:])
        assert float(values["excitation_frequency"]) == 2500.0 and float(values["real_time_factor"]) == 1.0
        # over the 1 s interval: simulated time plus what a stall of the host let slip (max_catch_up)
        slipped = float(values["time_slipped"]) - float(before["time_slipped"])
        assert 0.8 < float(values["achieved_real_time_factor"]) + slipped < 1.2, (values, slipped)
        periods = probe.received["mean_velocity"][-200:]
        gaps = {round((stamp_ns(b) - stamp_ns(a)) / 1e3) for a, b in itertools.pairwise(periods)}
        assert 400 in gaps, f"periods of 0.4 ms in simulation time: {sorted(gaps)[:5]}"

        assert probe.set_parameters_atomically(slider, {"mass": 0.4, "excitation_amplitude": 3.0}) == (True, "")

        def normal_range() -> tuple[float, float]:
            """R = m g - Pa sin(theta) over the last 500 states, within [m g - Pa, m g + Pa]
            (tick jitter spreads the phases sampled)."""
            count = len(probe.received["friction_force"])
            assert probe.spin_until(lambda: len(probe.received["friction_force"]) > count + 600, STATES_GUARD)
            normal = [m.wrench.force.z for m in probe.received["friction_force"][-500:]]
            return min(normal), max(normal)

        # Within [1, 7] N and spread over more than 3 N: m g = 4 N and Pa = 3 N, both in force
        # (the mass alone gives [-1, 9] N: a hop; Pa alone gives [7, 13] N).
        low, high = normal_range()
        assert low >= 1.0 - 1e-9 and high <= 7.0 + 1e-9 and high - low > 3.0, (low, high)
        # Refused whole: one value is not one of its choices; nothing changes.
        successful, reason = probe.set_parameters_atomically(
            slider, {"mass": 0.3, "excitation_amplitude": 3.5, "landing_friction": "bouncy"})
        assert not successful and "landing_friction = 'bouncy'" in reason and "impulsive, none" in reason, reason
        low, high = normal_range()  # (over states that all came after the refusal)
        assert low >= 1.0 - 1e-9 and high <= 7.0 + 1e-9 and high - low > 3.0, (low, high)
        # Taken whole: Pa = 3 N > m g = 2 N, throw number 1.5: it hops.
        assert probe.set_parameters_atomically(slider, {"mass": 0.2, "excitation_amplitude": 3.0}) == (True, "")
        # (each topic's own 600 new messages: the two topics do not arrive in step)
        count, forces = len(probe.received["pose"]), len(probe.received["friction_force"])
        assert probe.spin_until(lambda: len(probe.received["pose"]) > count + 600
                                and len(probe.received["friction_force"]) > forces + 600, STATES_GUARD)
        heights = [m.pose.position.z for m in probe.received["pose"][-500:]]
        normal = {stamp_ns(m): m.wrench.force.z for m in probe.received["friction_force"][-500:]}
        flying = [m for m in probe.received["pose"][-500:] if m.pose.position.z > 0.0]
        assert min(heights) >= 0.0 and flying, "z > 0 is published while it hops"
        assert all(normal.get(stamp_ns(m), 0.0) == 0.0 for m in flying), "R = 0 in flight"
        assert min(normal.values()) >= 0.0 and max(normal.values()) <= 2.0 + 3.0 + 1e-9
    finally:
        code, err = stop(process)
        probe.close()
    assert code == 0, err
    accepted = [line for line in err.splitlines() if "parameters set:" in line]
    assert len(accepted) == 3, err
    assert "excitation_frequency = 2500.0" in accepted[0] and "real_time_factor = 1.0" in accepted[0]
    assert "mass = 0.4" in accepted[1] and "excitation_amplitude = 3.0" in accepted[1]
    assert "mass = 0.2" in accepted[2] and "excitation_amplitude = 3.0" in accepted[2]
    refused = [line for line in err.splitlines() if "WARN" in line and "rejected" in line]
    assert len(refused) == 1 and "landing_friction = 'bouncy'" in refused[0], err


# -- values rclpy refuses, names, start-up ---------------------------------------------


REFUSED_BY_RCLPY = [  # name, value, what the warning names
    ("mass", math.nan, "mass = nan"),
    ("mass", 1e9, "mass = 1000000000.0"),
    ("excitation_frequency", -math.inf, "excitation_frequency = -inf"),
    ("mass", 2, "write 2.0"),
    ("drive_force", "strong", "drive_force = 'strong'"),
    ("mean_window_periods", 0, "mean_window_periods = 0"),
    ("log_path", "/tmp/x.mcap", "read-only"),
    ("no_such_parameter", 1.0, "no such parameter"),
]


def test_values_rclpy_refuses_are_warned_and_counted_and_a_namesake_is_reported(ros: None) -> None:
    ns = namespace()
    process = start_slider(ns)
    probe = Probe(ns, outputs={"diagnostics": DiagnosticArray, "pose": PoseStamped})
    namesake = None
    try:
        probe.wait_for_connection(timeout=20.0)
        for name, value, _ in REFUSED_BY_RCLPY:
            successful, _reason = probe.set_parameter(f"{ns}/slider", name, value)
            assert not successful, (name, value)
        refused = len(REFUSED_BY_RCLPY)

        def counted() -> bool:
            diags = probe.received["diagnostics"]
            return bool(diags) and diagnostics_values(diags[-1])["commands_rejected"] == str(refused)

        assert probe.spin_until(counted, 10.0), "every refusal is counted in diagnostics"
        assert "no such parameter" in diagnostics_values(probe.received["diagnostics"][-1])["last_rejection"]
        # A second node under the same fully qualified name: the slider says so.
        namesake = rclpy.create_node("slider", namespace=ns)
        probe.executor.add_node(namesake)
        assert probe.spin_until(lambda: any(
            "another node named" in m.status[0].message and level(m) >= DiagnosticStatus.WARN[0]
            for m in probe.received["diagnostics"][-2:]), 10.0)
    finally:
        code, err = stop(process)
        if namesake is not None:
            namesake.destroy_node()
        probe.close()
    assert code == 0, err
    warnings = [line for line in err.splitlines() if "WARN" in line]
    for name, _value, text in REFUSED_BY_RCLPY:
        assert any(name in line and text in line for line in warnings), (name, text, err)
    assert any(f"another node named {ns}/slider" in line for line in warnings), err


def test_the_refusal_that_blames_the_load_names_the_parameter_that_was_set(ros: None) -> None:
    for args, blamed in ((["-p", "real_time_factor:=1000.0"], "real_time_factor = 1000.0"),
                         (["-p", "excitation_frequency:=500.0", "-p", "real_time_factor:=100.0"],
                          "real_time_factor = 100.0"),
                         (["-p", "excitation_frequency:=20000.0", "-p", "real_time_factor:=1.0"], None)):
        ns = namespace()
        process = start_slider(ns, *args)
        if blamed is None:  # allowed: it runs (the refusals come before a node publishes anything)
            probe = Probe(ns, outputs={"pose": PoseStamped})
            try:
                running = probe.spin_until(lambda p=probe, n=process: bool(p.received["pose"]) or n.poll() is not None,
                                           30.0)
            finally:
                probe.close()
            assert running and process.poll() is None, process.poll()
            code, err = stop(process)
            assert code == 0, err
            continue
        _out, err = process.communicate(timeout=20)
        assert process.returncode == 2
        assert err.strip().splitlines() == [err.strip()] and blamed in err and "Traceback" not in err, err


@pytest.mark.parametrize("script", ["slider", "controller"])
def test_help_prints_usage_and_exits_0_without_starting_a_node(script: str) -> None:
    done = subprocess.run([str(BIN / script), "--help"], capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"usage: {script}") and not done.stderr
    if script == "slider":
        for setting in spec.SLIDER_NODE.values():
            assert f"  {setting.name} = " in done.stdout
        for topic in ("drive_force", "external_wrench", "pose", "friction_force", "mean_velocity", "/clock"):
            assert f"  {topic} (" in done.stdout
        words = " ".join(done.stdout.split())  # as wrapped to the terminal width
        assert "excitation_frequency = 50.0 Hz" in words and "0.001 … 20000" in words
        assert "[impulsive | none]" in words, "plain text, not the README's markdown escape"
    words = " ".join(done.stdout.split())
    assert "\\" not in done.stdout, "no markdown escapes in plain text"
    codes = words[words.index("exit codes:"):]
    # Each node lists its own codes: 4 (a failed recording) is the slider's alone.
    assert "0 stopped by Ctrl-C" in codes and "2 bad argument" in codes and "3 " in codes
    assert ("4 ran to the end but its recording failed" in codes) == (script == "slider"), codes
    wrong = subprocess.run([str(BIN / script), "--frobnicate"], capture_output=True, text=True, timeout=30)
    assert wrong.returncode == 2 and "--frobnicate" in wrong.stderr and "Traceback" not in wrong.stderr


# -- diagnostics -----------------------------------------------------------------------


def test_diagnostics_give_the_groups_the_prediction_uses_stamped_by_the_node_clock(rig) -> None:  # type: ignore[no-untyped-def]
    node, probe, outcomes = rig
    probe.send("external_wrench", (0.05, 1.0))  # force.z > 0 lifts: the load is m g - Fz = 9 N
    assert probe.spin_until(lambda: any(o.accepted for o in outcomes), 15.0)
    start = len(probe.received["diagnostics"])
    assert probe.spin_until(lambda: len(probe.received["diagnostics"]) > start, 5.0)
    msg = probe.received["diagnostics"][-1]
    values = diagnostics_values(msg)
    phi, ratio = (0.7 + 0.05) / (0.1 * 9.0), 5.0 / 9.0
    assert float(values["throw_number"]) == 0.5  # Pa/(m g cos(alpha)), without the external force
    assert float(values["flight_fraction"]) == 0.0 and values["lift_offs"] == values["landings"] == "0"
    assert float(values["phi"]) == pytest.approx(phi, rel=1e-15)
    assert float(values["amplitude_ratio"]) == pytest.approx(ratio, rel=1e-15)
    assert float(values["predicted_U"]) == pytest.approx(u_map(phi, ratio), rel=1e-12)
    # Header stamp: the node's clock (ROS time = system time without use_sim_time), not simulation time.
    assert abs(stamp_ns(msg) / 1e9 - time.time()) < 5.0
    assert stamp_ns(msg) != round(float(values["sim_time"]) * 1e9)
    assert node.get_clock().clock_type.name == "ROS_TIME"
