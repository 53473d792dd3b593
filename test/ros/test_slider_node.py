"""The slider node over real topics (DDS on localhost, random domain: conftest)."""

from __future__ import annotations

import itertools
import math
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock as ClockMsg

from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.predict import predict
from friction_sim.core.model import spec
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.simulation import run_schedule
from friction_sim.ros.slider import SliderNode

from ros_harness import (
    HARNESS,
    MARK,
    Probe,
    diagnostics_values,
    kill_if_running,
    namespace,
    stamp_ns,
)

ROOT = Path(__file__).resolve().parents[2]



def test_topic_contract_names_types_and_namespace(rig) -> None:  # type: ignore[no-untyped-def]
    node, probe, _ = rig
    ns = node.get_namespace()
    published = dict(node.get_publisher_names_and_types_by_node("slider", ns))
    assert published[f"{ns}/pose"] == ["geometry_msgs/msg/PoseStamped"]
    assert published[f"{ns}/velocity"] == ["geometry_msgs/msg/TwistStamped"]
    assert published[f"{ns}/friction_force"] == ["geometry_msgs/msg/WrenchStamped"]
    assert published[f"{ns}/mean_velocity"] == ["geometry_msgs/msg/TwistStamped"]
    assert published[f"{ns}/diagnostics"] == ["diagnostic_msgs/msg/DiagnosticArray"]
    assert "/clock" not in published, "no /clock publisher while publish_clock is false"
    subscribed = dict(node.get_subscriber_names_and_types_by_node("slider", ns))
    for name in ("drive_force", "excitation_amplitude", "excitation_frequency"):
        assert subscribed[f"{ns}/{name}"] == ["std_msgs/msg/Float64"]
    assert subscribed[f"{ns}/external_wrench"] == ["geometry_msgs/msg/WrenchStamped"]

    assert probe.spin_until(
        lambda: len(probe.received["mean_velocity"]) >= 3 and probe.received["diagnostics"], 15.0)
    poses, frictions = probe.received["pose"], probe.received["friction_force"]
    assert {m.header.frame_id for m in poses + frictions} == {"slideway"}
    stamps = [stamp_ns(m) for m in poses]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)
    # Units: R in [m g - Pa, m g + Pa] N, |friction| <= mu R, mean speed in m/s.
    for msg in frictions:
        normal, friction = msg.wrench.force.z, msg.wrench.force.x
        assert 5.0 - 1e-12 <= normal <= 15.0 + 1e-12
        assert abs(friction) <= 0.1 * normal + 1e-12
    expected = predict(SliderParams(), Inputs()).mean_velocity
    later = probe.received["mean_velocity"][1:]
    assert later and all(m.twist.linear.x == pytest.approx(expected, rel=1e-9) for m in later)
    values = diagnostics_values(probe.received["diagnostics"][-1])
    for key in ("achieved_real_time_factor", "tick_rate", "late_ticks", "commands_accepted",
                "commands_rejected", "last_rejection", "drive_force", "excitation_amplitude",
                "excitation_frequency", "phi", "amplitude_ratio", "predicted_U",
                "predicted_mean_velocity", "stick_fraction", "throw_number", "flight_fraction",
                "flight_fraction_in_interval", "lift_offs", "landings", "lift_offs_in_interval",
                "landings_in_interval"):
        assert key in values
    assert float(values["phi"]) == pytest.approx(0.7)
    assert 0.0 < float(values["stick_fraction"]) < 1.0
    # The paper's case never leaves the track: z = vz = 0, no flight.
    assert all(m.pose.position.z == 0.0 for m in poses)
    assert all(m.twist.linear.z == 0.0 for m in probe.received["velocity"])
    assert (float(values["throw_number"]), float(values["flight_fraction"]), values["lift_offs"]) == (0.5, 0.0, "0")


def test_published_trajectory_equals_the_exact_core_whatever_the_jitter(rig) -> None:  # type: ignore[no-untyped-def]
    node, probe, outcomes = rig
    rng = random.Random(3)
    start = len(probe.received["pose"])
    end = time.monotonic() + 1.5
    commands = [("drive_force", 0.85), ("excitation_amplitude", 7.0), ("excitation_frequency", 80.0),
                ("drive_force", -0.8), ("external_wrench", (0.05, 1.0)), ("excitation_amplitude", 2.0),
                ("drive_force", 0.95)]
    send_at = time.monotonic() + 0.1
    # Until every command is out (a loaded machine may run this loop late: the window is at
    # least 1.5 s of jitter, not a deadline for the commands), and for 1.5 s at least.
    while commands or time.monotonic() < end:
        if commands and time.monotonic() > send_at:
            probe.send(*commands.pop(0))
            send_at += 0.18
        probe.executor.spin_once(timeout_sec=0.001)
        if rng.random() < 0.01:
            with node._lock:  # noqa: SLF001 - hold the tick thread back: jitter, late ticks
                time.sleep(rng.choice([0.0005, 0.003, 0.012]))  # the jitter under test
    # The tick thread takes each command at its next tick; give a loaded machine time to get there.
    assert probe.spin_until(lambda: sum(o.accepted for o in outcomes) >= 7, 10.0)
    probe.spin_until(lambda: len(probe.received["pose"]) - start >= 1500, 10.0)
    accepted = [o for o in outcomes if o.accepted]
    assert len(accepted) == 7
    assert node.realtime.interval.stats.total_late_ticks > 0, "the jitter made some ticks late"

    velocities = {stamp_ns(m): m for m in probe.received["velocity"]}
    frictions = {stamp_ns(m): m for m in probe.received["friction_force"]}
    # A stalled subscriber may lose a message (depth 10): compare where all three arrived.
    poses = [m for m in probe.received["pose"][start:] if stamp_ns(m) in velocities and stamp_ns(m) in frictions]
    assert len(poses) > 500
    times = np.array([stamp_ns(m) for m in poses]) / 1e9
    first = times[0]
    reference = Slider(SliderParams(), Inputs())
    schedule = [o.command for o in outcomes if o.accepted]
    before = [c for c in schedule if c.t <= first]
    for command in before:
        reference.advance_to(command.t)
        reference.set_inputs(**command.changes)
    exact = run_schedule(reference, [c for c in schedule if c.t > first], times)
    x = np.array([m.pose.position.x for m in poses])
    v = np.array([velocities[stamp_ns(m)].twist.linear.x for m in poses])
    fx = np.array([frictions[stamp_ns(m)].wrench.force.x for m in poses])
    fz = np.array([frictions[stamp_ns(m)].wrench.force.z for m in poses])
    assert np.max(np.abs(x - exact.x)) <= 1e-9 * np.max(np.abs(exact.x))
    assert np.max(np.abs(v - exact.v)) <= 1e-9 * np.max(np.abs(exact.v))
    np.testing.assert_allclose(fz, exact.normal_force, rtol=1e-9)
    assert np.max(np.abs(fx - exact.friction_force)) <= 1e-9 * np.max(np.abs(exact.friction_force))
    assert np.ptp(x) > 1e-6 and np.count_nonzero(v) > 100, "the slider really moved"


BAD_INPUTS = [
    ("drive_force", math.nan, "nan"),
    ("drive_force", math.inf, "inf"),
    ("excitation_amplitude", -math.inf, "-inf"),
    ("excitation_amplitude", 2e6, "2000000.0"),  # above the weight is not refused (it hops); beyond the range is
    ("excitation_amplitude", -1.0, "-1.0"),
    ("excitation_frequency", 0.0, "0.0"),
    ("excitation_frequency", -50.0, "-50.0"),
    ("excitation_frequency", math.nan, "nan"),
    ("external_wrench", (0.0, -2e6), "-2000000.0"),
    ("external_wrench", (math.nan, 0.0), "nan"),
    ("external_wrench", (0.0, -math.inf), "-inf"),
    # finite but absurd: outside the documented ranges, refused by the core's one gate
    ("drive_force", 1e308, "1e+308"),
    ("excitation_frequency", 1e-300, "1e-300"),
    ("excitation_frequency", 25000.0, "25000.0"),
    ("external_wrench", (1e308, 0.0), "1e+308"),
]


def test_every_kind_of_bad_input_is_rejected_and_publishing_goes_on(rig) -> None:  # type: ignore[no-untyped-def]
    node, probe, outcomes = rig
    before_inputs = node.realtime.slider.inputs
    for topic, value, text in BAD_INPUTS:
        count = len(outcomes)
        probe.send(topic, value)
        assert probe.spin_until(lambda count=count: len(outcomes) > count, 15.0), topic
        outcome = outcomes[-1]
        assert not outcome.accepted
        assert outcome.name == topic
        assert text in outcome.reason, outcome.reason
        assert "rejected" in outcome.reason
        assert node.realtime.slider.inputs == before_inputs, "the last valid value stays in force"
    assert node.realtime.rejected == len(BAD_INPUTS)
    poses = len(probe.received["pose"])
    probe.send("drive_force", 0.8)
    assert probe.spin_until(lambda: len(probe.received["pose"]) > poses + 100, 10.0), "still publishing"
    # (How fast it publishes is the machine's speed, not behaviour: bench/node.py measures the
    # tick rate; a loaded CI machine once gave a median interval of 1.29 ms here.)
    stamps = [stamp_ns(m) for m in probe.received["pose"][poses + 1:]]
    assert all(b > a for a, b in itertools.pairwise(stamps)), "simulation time goes on, state after state"
    assert probe.spin_until(lambda: node.realtime.slider.inputs.drive_force == 0.8, 15.0)
    assert probe.spin_until(lambda: any(
        diagnostics_values(m)["commands_rejected"] == str(len(BAD_INPUTS)) for m in probe.received["diagnostics"]
    ), 10.0)


def test_parameters_via_the_parameter_services(rig) -> None:  # type: ignore[no-untyped-def]
    node, probe, _ = rig
    def set_(name: str, value: object) -> tuple[bool, str]:
        return probe.set_parameter(f"{node.get_namespace()}/slider", name, value)

    assert set_("drive_force", 0.8) == (True, "")
    assert node.realtime.slider.inputs.drive_force == 0.8
    # The general model's parameters: a string with choices, refused through the set-parameters
    # path with the field, the value and the choices; ranges refused by the descriptors.
    ok, reason = set_("landing_friction", "sticky")
    assert not ok and reason == "landing_friction = 'sticky' rejected: must be one of impulsive, none", reason
    assert node.realtime.slider.params.landing_friction == "impulsive"
    assert node.get_parameter("landing_friction").value == "impulsive"
    for name, value in (("restitution", 1.0), ("excitation_angle", 0.0), ("static_ratio", 0.5),
                        ("track_inclination", 90.0), ("excitation_phase", -200.0)):
        ok, reason = set_(name, value)  # rclpy's own reason (the node's warning says it in the spec's words)
        assert not ok and name in reason, (name, reason)
    assert node.realtime.slider.params == SliderParams()
    assert set_("landing_friction", "none") == (True, "")
    assert set_("restitution", 0.5) == (True, "")
    assert set_("excitation_angle", 30.0) == (True, "")
    assert node.realtime.slider.params == SliderParams(landing_friction="none", restitution=0.5,
                                                       excitation_angle=30.0)
    for name in ("landing_friction", "restitution", "excitation_angle"):
        assert set_(name, spec.SLIDER_NODE[name].default) == (True, "")
    # An amplitude above the weight, or a plant too light for the one in force: no longer refused.
    assert set_("excitation_amplitude", 12.0) == (True, "")
    assert node.realtime.slider.inputs.excitation_amplitude == 12.0
    assert set_("excitation_amplitude", 5.0) == (True, "")
    assert set_("mass", 0.4) == (True, "")
    assert node.realtime.slider.params.mass == 0.4
    assert set_("mass", 1.0) == (True, "")
    ok, reason = set_("excitation_frequency", math.nan)
    assert not ok and "excitation_frequency" in reason
    ok, reason = set_("mu", -0.1)
    assert not ok and "mu" in reason
    assert set_("mass", 2.0) == (True, "")
    assert node.realtime.slider.params == SliderParams(mass=2.0)
    assert set_("excitation_frequency", 100.0) == (True, "")
    assert node.realtime.slider.inputs.excitation_frequency == 100.0
    assert set_("mean_window_periods", 4) == (True, "")
    assert node.realtime.period_means.window_periods == 4
    assert set_("publish_rate", 200.0) == (True, "")
    set_ns = round(node.realtime.slider.t * 1e9)  # the set was answered: later ticks run at the new rate

    def since_set() -> list[Any]:
        return [m for m in probe.received["pose"] if stamp_ns(m) > set_ns]

    # The rate took effect: the node ticks on absolute deadlines 5 ms apart, so the poses stamped
    # after the set come 5 ms apart in simulated time, save the intervals a late tick and the one
    # that catches up with its deadline share, and what a stall of this busy process let slip (at the
    # old 1 kHz they would come 1 ms apart).  The median interval is the rate; the span of 200 poses
    # is not (a loaded CI machine gave 987 ms, and 985.9 ms on Jazzy, for 995).  How regular the
    # intervals are is the machine's pace, which this test does not judge: bench/node.py does.
    assert node.realtime.publish_rate == 200.0
    assert probe.spin_until(lambda: len(since_set()) >= 200, 20.0)
    stamps = [stamp_ns(m) for m in since_set()[:200]]
    intervals = sorted(later - earlier for earlier, later in itertools.pairwise(stamps))
    assert intervals[len(intervals) // 2] == pytest.approx(5_000_000, abs=500_000), intervals
    assert set_("real_time_factor", 3.0) == (True, "")
    rt = node.realtime
    sim_before, slipped, wall = rt.slider.t, rt.pace.time_slipped, time.monotonic()  # after the set's round trip
    probe.spin_for(1.0)
    # simulated time plus what stalls of this busy test process let slip (max_catch_up) runs at 3x the wall clock
    ratio = (rt.slider.t - sim_before + rt.pace.time_slipped - slipped) / (time.monotonic() - wall)
    assert 2.5 < ratio < 3.5


def test_clock_is_published_when_asked_and_advertised_only_then(ros: None) -> None:
    ns = namespace()
    node = SliderNode(namespace=ns, parameter_overrides=[Parameter("publish_clock", value=True)])
    probe = Probe(ns, node, outputs={"/clock": ClockMsg, "pose": PoseStamped})

    def clock_publishers() -> list[str]:
        return [kind for topic, kinds in node.get_publisher_names_and_types_by_node("slider", ns)
                for kind in kinds if topic == "/clock"]

    try:
        assert probe.spin_until(lambda: len(probe.received["/clock"]) > 50, 15.0)
        clocks = [m.clock.sec * 10**9 + m.clock.nanosec for m in probe.received["/clock"]]
        assert clocks == sorted(clocks)
        assert clock_publishers() == ["rosgraph_msgs/msg/Clock"]
        # publish_clock can change at run time: the publisher goes, and comes back.
        assert probe.set_parameter(f"{ns}/slider", "publish_clock", False) == (True, "")
        off_ns = round(node.realtime.slider.t * 1e9)  # the answer came: nothing later is published
        assert probe.spin_until(lambda: not clock_publishers(), 10.0)
        count = len(probe.received["/clock"])
        on_ns = round(node.realtime.slider.t * 1e9)  # before the set: every later /clock is stamped after it
        assert probe.set_parameter(f"{ns}/slider", "publish_clock", True) == (True, "")
        assert probe.spin_until(lambda: len(probe.received["/clock"]) > count + 50, 15.0)
        # Whatever came, however late: nothing is stamped between the answer that turned it off and the set
        # that turned it on again.
        clocks = [m.clock.sec * 10**9 + m.clock.nanosec for m in probe.received["/clock"]]
        assert not [c for c in clocks if off_ns < c < on_ns], "/clock was published while off"
    finally:
        probe.close()
        node.destroy_node()


@pytest.mark.parametrize("max_catch_up", [spec.MAX_CATCH_UP.default, 10.0])
def test_a_stalled_timer_does_not_change_the_physics(rig, max_catch_up: float) -> None:  # type: ignore[no-untyped-def]
    """A tick thread stalled for 0.25 s: with the default max_catch_up (0.02 s)
    the late tick simulates 0.02 s of it and the rest slips, counted; with 10 s
    it simulates the whole stall at once.  Either way the motion is exact and
    simulation time follows the wall clock again, lagging by the slip."""
    node, probe, _ = rig
    assert node.set_parameters([Parameter("max_catch_up", value=max_catch_up)])[0].successful
    set_ns = round(node.realtime.slider.t * 1e9)
    assert probe.spin_until(lambda: any(stamp_ns(m) > set_ns for m in probe.received["pose"][-3:]), 10.0), \
        "the node ticks on with the new max_catch_up"
    clock, rt = node.realtime.clock, node.realtime
    with node._lock:  # noqa: SLF001 - stall the tick thread: ticks are missed
        before_ns = round(rt.slider.t * 1e9)  # the last tick before the stall
        wall1, slipped1, stalls1 = time.monotonic_ns(), rt.pace.time_slipped, rt.pace.stalls
        lag1 = wall1 - clock.now_ns(wall1)
        time.sleep(0.25)  # the stall under test (time itself is what is tested)

    def after() -> list[int]:
        return [stamp for stamp in map(stamp_ns, probe.received["pose"]) if stamp > before_ns + 1000]

    assert probe.spin_until(lambda: len(after()) >= 5, 10.0)
    gaps = np.diff([before_ns, *after()[:5]]) / 1e9
    if max_catch_up > 0.25:
        assert gaps.max() > 0.2, "simulation time followed the wall clock over the stall"
    else:
        assert gaps.max() <= max_catch_up + 1e-9, "the late tick simulated at most max_catch_up of the stall"
        assert rt.pace.stalls > stalls1 and rt.pace.time_slipped - slipped1 > 0.2
    # Simulation time follows the wall clock again, behind by what slipped, to well under a millisecond.
    wall2 = time.monotonic_ns()
    lag2 = wall2 - clock.now_ns(wall2)
    assert abs((lag2 - lag1) - (rt.pace.time_slipped - slipped1) * 1e9) < 1_000_000
    exact = Slider(SliderParams(), Inputs())
    last = probe.received["pose"][-1]
    exact.advance_to(stamp_ns(last) / 1e9)
    assert last.pose.position.x == pytest.approx(exact.state().x, rel=1e-12)


SCRIPT = Path(sys.executable).parent / "slider"


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_slider_console_script_runs_takes_commands_and_stops_cleanly(ros: None, signum: int) -> None:
    assert SCRIPT.exists()
    ns = namespace()
    process = subprocess.Popen(
        [str(SCRIPT), "--ros-args", "-r", f"__ns:={ns}", "--params-file", str(ROOT / "config" / "slider.yaml"),
         "-p", "publish_rate:=200.0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ),
    )
    probe = Probe(ns)
    try:
        probe.wait_for_connection(timeout=20.0)
        probe.send("drive_force", 0.9)
        probe.send("excitation_amplitude", float("nan"))

        def reflected() -> bool:
            diags = probe.received["diagnostics"]
            return bool(diags) and diagnostics_values(diags[-1])["drive_force"] == "0.9" and \
                diagnostics_values(diags[-1])["commands_rejected"] == "1"

        assert probe.spin_until(reflected, 10.0), "the command reached the node and was reported"
        velocities = [m.twist.linear.x for m in probe.received["velocity"][-100:]]
        assert max(velocities) > 0.0
        process.send_signal(signum)
        _out, err = process.communicate(timeout=15)
        assert process.returncode == 0, err
        assert "Traceback" not in err
        assert "excitation_amplitude" in err and "nan" in err, "the rejection was logged"
    finally:
        kill_if_running(process)
        probe.close()


def rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise AssertionError("no VmRSS")


@pytest.mark.parametrize("kind", ["valid", "invalid"])
def test_a_flood_of_commands_does_not_stall_publishing(ros: None, kind: str) -> None:
    """10,000 commands/s for 4 s from another process into the slider process,
    valid ones or invalid ones (half NaN or inf, half out of range): it keeps
    ticking (its own diagnostics say so; bench/node.py measures at what
    rate), keeps handling commands, warns about the refused ones about once a second, and
    its memory does not grow."""
    ns = namespace()
    node = subprocess.Popen([str(SCRIPT), "--ros-args", "-r", f"__ns:={ns}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    probe = Probe(ns, outputs={"diagnostics": DiagnosticArray})
    try:
        probe.wait_for_connection(timeout=20.0, topic="diagnostics")
        flooder = subprocess.Popen([sys.executable, str(HARNESS), ns, "10000", "4.0", kind, "confirm"],
                                   stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        assert flooder.stdin is not None and flooder.stdout is not None
        assert flooder.stdout.readline().strip() == "matched"
        # The flood begins once the node reports the flooder's mark taken: its reader knows the
        # flooder's writer.  That report is the baseline (and the node a second or more into its run).
        assert probe.spin_until(lambda: diagnostics_values(probe.received["diagnostics"][-1])["drive_force"]
                                == str(MARK), 20.0), "the flooder's mark never came"
        rss_before = rss_kib(node.pid)
        start = len(probe.received["diagnostics"]) - 1
        flooder.stdin.write("go\n")
        flooder.stdin.flush()
        probe.spin_until(lambda: flooder.poll() is not None, 30.0)
        ended_ns = time.time_ns()  # the node's diagnostics are stamped by its (system) clock
        sent = int(flooder.communicate(timeout=10)[0].split()[-1])
        # (the flooder waited for the node to acknowledge every command): a report from after the flood
        assert probe.spin_until(lambda: stamp_ns(probe.received["diagnostics"][-1]) > ended_ns, 10.0)
        reports = [diagnostics_values(m) for m in probe.received["diagnostics"][start:]]
        rates = [float(r["tick_rate"]) for r in reports]
        counter = "commands_accepted" if kind == "valid" else "commands_rejected"
        handled = int(reports[-1][counter]) - int(reports[0][counter])
        # Behaviour, not the speed of this machine: the tick rate under a flood (the
        # 80 % target) is measured by bench/node.py.  Here: the flood was a flood, and
        # in every diagnostics window the node ticked (it never stalled) and in each
        # second the flood lasted it took commands (counted by the node itself).
        windows_with_commands = sum(int(now[counter]) > int(before[counter])
                                    for before, now in itertools.pairwise(reports))
        assert sent == 40_000, sent
        assert len(rates) >= 4 and min(rates) > 0.0, rates
        assert windows_with_commands >= 3, "commands were handled all through the flood"
        assert handled > 0
        assert rss_kib(node.pid) - rss_before < 20_000, "the node's memory did not grow"
    finally:
        node.send_signal(signal.SIGINT)
        _out, err = node.communicate(timeout=15)
        probe.close()
    assert node.returncode == 0
    warnings = [line for line in err.splitlines() if "rejected" in line]
    if kind == "invalid":
        assert 3 <= len(warnings) <= 8, "about one warning a second, each standing for the ones not shown"
        assert any("more refused in the last 1 s, not shown" in line for line in warnings)
    else:
        assert not warnings


def test_parameters_are_checked_against_the_inputs_in_force(rig) -> None:  # type: ignore[no-untyped-def]
    """A topic command changed the frequency since the parameters were set: a
    real-time factor the loop cannot follow at that frequency (f x rtf > 20000)
    is refused, though it was fine at the frequency the parameter still says;
    nothing changes.  (A mass that the amplitude in force lifts off is no
    longer refused: the slider hops.)"""
    node, probe, _outcomes = rig
    probe.send("excitation_frequency", 5000.0)
    assert probe.spin_until(lambda: node.realtime.slider.inputs.excitation_frequency == 5000.0, 15.0)
    successful, reason = probe.set_parameter(f"{node.get_namespace()}/slider", "real_time_factor", 5.0)
    assert not successful and "real_time_factor = 5.0" in reason and "5000" in reason, reason
    assert node.get_parameter("real_time_factor").value == 1.0
    assert node.realtime.clock.rate == 1.0
    probe.send("excitation_amplitude", 9.0)
    assert probe.spin_until(lambda: node.realtime.slider.inputs.excitation_amplitude == 9.0, 15.0)
    assert probe.set_parameter(f"{node.get_namespace()}/slider", "mass", 0.6) == (True, "")
    assert node.realtime.slider.params.mass == 0.6


def test_a_frequency_the_real_time_loop_cannot_follow_is_refused(rig) -> None:  # type: ignore[no-untyped-def]
    node, probe, outcomes = rig
    count = len(outcomes)
    probe.send("excitation_frequency", 1e7)
    assert probe.spin_until(lambda: len(outcomes) > count, 15.0)
    assert not outcomes[-1].accepted
    reason = outcomes[-1].reason
    assert "excitation_frequency" in reason and "10000000.0" in reason and "20000" in reason
    assert node.realtime.slider.inputs.excitation_frequency == 50.0
    poses = len(probe.received["pose"])
    # It goes on publishing (how fast is the machine's speed: bench/node.py; a loaded CI
    # machine once fell short of 100 poses in 0.3 s of wall time here).
    assert probe.spin_until(lambda: len(probe.received["pose"]) > poses + 100, 10.0), "still publishing"
