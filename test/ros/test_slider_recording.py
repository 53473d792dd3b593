"""The slider node and its recorder, over real ROS: the simulation waits for a
writer that falls behind (no message dropped, no jump in simulation time), a
recording that fails is reported (log, diagnostics ERROR) while the run goes
on, and shutdown then says so in one line with exit code 4; topics are stored
in the node's namespace."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, WrenchStamped
from rclpy.parameter import Parameter

from friction_sim.ros.run import EXIT_RECORDING_FAILED
from friction_sim.ros.slider import SliderNode

from ros_harness import Probe, diagnostics_values, kill_if_running, namespace, stamp_ns

BIN = Path(sys.executable).parent
FILE_LIMIT = 400_000  # bytes: the recording hits it after a few simulated seconds


def level(msg: DiagnosticArray) -> int:
    value = msg.status[0].level
    return value[0] if isinstance(value, bytes) else int(value)


def test_the_simulation_waits_for_a_slow_recorder_without_a_jump_in_time(ros: None, tmp_path: Path) -> None:
    ns = namespace()
    node = SliderNode(namespace=ns, parameter_overrides=[Parameter("log_path", value=str(tmp_path / "run.mcap"))])
    recorder = node.recorder
    assert recorder is not None and recorder.namespace == ns
    recorder.queue.capacity = 300  # a small queue, and a writer slower than the simulation:
    write = recorder._writer.write  # noqa: SLF001

    def slow(batch: Any) -> None:
        time.sleep(0.6)  # a slow writer is what is tested
        write(batch)

    recorder._writer.write = slow  # noqa: SLF001
    probe = Probe(ns, node, outputs={"pose": PoseStamped, "diagnostics": DiagnosticArray})
    try:
        probe.wait_for_connection(topic="pose")
        start, waited = len(probe.received["pose"]), recorder.queue.wait_seconds
        reported = len(probe.received["diagnostics"])
        began = time.monotonic()
        # Until the node's own counts say it: the tick has waited more than 2 s for the writer, and
        # three reports have come since (the last two of them over windows held back).
        assert probe.spin_until(lambda: recorder.queue.wait_seconds - waited > 2.0
                                and len(probe.received["diagnostics"]) >= reported + 3, 60.0)
        wall = time.monotonic() - began
        waited = recorder.queue.wait_seconds - waited
        assert recorder.queue.waits > 0 and waited > 2.0, "the tick waited for the writer"
        stamps = [stamp_ns(m) for m in probe.received["pose"][start:]]
        simulated = (stamps[-1] - stamps[0]) / 1e9
        # Simulation time holds still while the tick waits: over the window it advances by the wall
        # time less the waits.  A stall of a loaded machine is a late tick, which simulation time
        # follows (it counts on both sides); jumping over the waits would make up all of them, so
        # the bound lies half the waits (> 1 s) away from either behaviour.
        assert simulated < wall - 0.5 * waited, (
            f"simulation time jumped over the waits: {simulated:.3f} s simulated in {wall:.3f} s of wall time "
            f"with {waited:.3f} s of waits")
        reports = [diagnostics_values(m) for m in probe.received["diagnostics"][1:]]
        assert reports and all(float(r["achieved_real_time_factor"]) < 0.8 for r in reports[-2:]), reports
        assert any(level(m) == 1 and "held the simulation back" in m.status[0].message
                   for m in probe.received["diagnostics"])
    finally:
        recorder._writer.write = write  # noqa: SLF001
        probe.close()
        node.destroy_node()
    stats = recorder.stats
    assert stats.error is None and stats.dropped == 0 and node.exit_code == 0
    assert {f"{ns}/pose", f"{ns}/velocity", f"{ns}/friction_force"} <= set(stats.per_topic)


def _limit_file_size() -> None:  # runs in the child before exec
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG instead of killing
    resource.setrlimit(resource.RLIMIT_FSIZE, (FILE_LIMIT, FILE_LIMIT))


def test_a_failed_recording_is_reported_the_run_goes_on_and_exit_code_is_4(ros: None, tmp_path: Path) -> None:
    ns = namespace()
    path = tmp_path / "run.mcap"
    process = subprocess.Popen(
        [str(BIN / "slider"), "--ros-args", "-r", f"__ns:={ns}", "-p", f"log_path:={path}",
         "-p", "real_time_factor:=10.0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ),
        preexec_fn=_limit_file_size)
    probe = Probe(ns, outputs={"pose": PoseStamped, "diagnostics": DiagnosticArray})
    try:
        probe.wait_for_connection(timeout=20.0)

        def failed() -> bool:
            return any(level(m) == 2 for m in probe.received["diagnostics"])

        assert probe.spin_until(failed, 60.0), "diagnostics report the failed recording"
        error = next(m for m in probe.received["diagnostics"] if level(m) == 2)
        assert "recording failed" in error.status[0].message and "File too large" in error.status[0].message
        assert diagnostics_values(error)["recording_error"] == error.status[0].message
        poses = len(probe.received["pose"])
        assert probe.spin_until(lambda: len(probe.received["pose"]) > poses + 500, 10.0), "the run goes on"
        process.send_signal(signal.SIGINT)
        _out, err = process.communicate(timeout=20)
    finally:
        kill_if_running(process)
        probe.close()
    assert process.returncode == EXIT_RECORDING_FAILED, err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if "recording failed" in line]
    assert len(lines) == 2, err  # once when it failed, once at shutdown with what the file holds
    assert "messages written" in lines[1] and "are readable" in lines[1]
    assert f"exit code {EXIT_RECORDING_FAILED}" in lines[1]
    assert 0 < path.stat().st_size <= FILE_LIMIT
    verify = subprocess.run([str(BIN / "friction-sim"), "replay", str(path), "--verify"], capture_output=True,
                            text=True, timeout=120)
    assert verify.returncode == 0 and "reproducible" in verify.stdout, verify.stdout + verify.stderr


@pytest.mark.parametrize("log_path", ["/dev/full", "{tmp}/no/such/folder/run.mcap", "{tmp}/"])
def test_a_recording_that_cannot_start_is_one_line_and_exit_code_2(ros: None, tmp_path: Path, log_path: str) -> None:
    value = log_path.format(tmp=tmp_path)
    done = subprocess.run([str(BIN / "slider"), "--ros-args", "-r", f"__ns:={namespace()}", "-p",
                           f"log_path:={value}"], capture_output=True, text=True, timeout=30)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().count("\n") == 0 and "log_path" in done.stderr and "Traceback" not in done.stderr


def test_recording_faster_than_the_machine_computes_keeps_the_node_answering(ros: None, tmp_path: Path) -> None:
    """real_time_factor 999 at log_rate 1 kHz asks for a million recorded states
    a second.  Each tick used to take all of them under the node's lock, so ticks
    grew to seconds and a parameter set waited 15 s and more; now the simulation
    falls behind real time instead (diagnostics say so), every parameter set is
    answered at once, and the file lost nothing and verifies."""
    ns, path = namespace(), tmp_path / "fast.mcap"
    node = subprocess.Popen([str(BIN / "slider"), "--ros-args", "-r", f"__ns:={ns}", "-p", "excitation_frequency:=10.0",
                             "-p", f"log_path:={path}"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    probe = Probe(ns, outputs={"diagnostics": DiagnosticArray})
    try:
        probe.wait_for_connection(timeout=20.0, topic="diagnostics")
        assert probe.set_parameter(f"{ns}/slider", "real_time_factor", 999.0)[0]
        # The node says it has fallen behind: the parameter sets below are asked of a node that cannot keep up.
        assert probe.spin_until(lambda: any("cannot keep up" in m.status[0].message
                                            for m in probe.received["diagnostics"]), 30.0)
        for value in (0.71, 0.72, 0.73):
            started = time.monotonic()
            assert probe.set_parameter(f"{ns}/slider", "drive_force", value) == (True, "")
            assert time.monotonic() - started < 2.0, "a parameter set is answered at once"
    finally:
        probe.close()
        node.send_signal(signal.SIGINT)
        _, said = node.communicate(timeout=60)
    assert node.returncode == 0, said
    done = subprocess.run([str(BIN / "friction-sim"), "replay", str(path), "--verify"], capture_output=True,
                          text=True, timeout=300, check=False)
    assert done.returncode == 0 and "reproducible" in done.stdout, done.stdout + done.stderr


def test_a_hopping_slider_publishes_its_flight_and_the_recording_verifies(ros: None, tmp_path: Path) -> None:
    """Pa = 15 N on the default 1 kg slider (throw number 1.5): the node takes it,
    publishes z > 0 with R = 0 while the slider is off the track, counts lift-offs
    and landings in diagnostics; a lifting external force (force.z > 0) makes the
    flights longer; the recording holds the lift_off and landing events, marks
    the convention, and replay --verify reproduces the flight."""
    ns, path = namespace(), tmp_path / "hop.mcap"
    process = subprocess.Popen(
        [str(BIN / "slider"), "--ros-args", "-r", f"__ns:={ns}", "-p", "excitation_amplitude:=15.0",
         "-p", f"log_path:={path}"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=dict(os.environ))
    probe = Probe(ns, outputs={"pose": PoseStamped, "friction_force": WrenchStamped, "diagnostics": DiagnosticArray})
    try:
        probe.wait_for_connection(timeout=20.0)
        assert probe.spin_until(lambda: len(probe.received["diagnostics"]) >= 2, 10.0)
        poses = probe.received["pose"][-600:]
        normal = {stamp_ns(m): m.wrench.force.z for m in probe.received["friction_force"]}
        flying = [m for m in poses if m.pose.position.z > 0.0]
        assert flying and min(m.pose.position.z for m in poses) >= 0.0, "z > 0 published while it hops"
        assert all(normal[stamp_ns(m)] == 0.0 for m in flying if stamp_ns(m) in normal), "R = 0 in flight"
        before = diagnostics_values(probe.received["diagnostics"][-1])
        assert int(before["lift_offs"]) > 10 and int(before["landings"]) > 10
        assert float(before["throw_number"]) == 1.5 and 0.0 < float(before["flight_fraction"]) < 1.0
        probe.send("external_wrench", (0.0, 3.0))  # lifts: the load is m g - Fz = 7 N < Pa
        count = len(probe.received["diagnostics"])
        assert probe.spin_until(lambda: len(probe.received["diagnostics"]) >= count + 2, 10.0)
        after = diagnostics_values(probe.received["diagnostics"][-1])
        assert float(after["external_force_z"]) == 3.0
        assert float(after["flight_fraction"]) > float(before["flight_fraction"]), "a lifting force: longer flights"
        process.send_signal(signal.SIGINT)
        _out, err = process.communicate(timeout=20)
    finally:
        kill_if_running(process)
        probe.close()
    assert process.returncode == 0, err
    from friction_sim.io.reader import read_recording

    recording = read_recording(path)
    assert recording.metadata["friction_sim"]["external_force_z_convention"] == "lifts"
    events = [msg for _, msg in recording.decoded("events")]
    landings = [{kv.key: float(kv.value) for kv in m.values if kv.key.startswith("v")} for m in events
                if m.name == "landing"]
    assert any(m.name == "lift_off" for m in events) and landings
    assert all(v["vz_before"] < 0.0 for v in landings)
    done = subprocess.run([str(BIN / "friction-sim"), "replay", str(path), "--verify"], capture_output=True,
                          text=True, timeout=300, check=False)
    assert done.returncode == 0 and "reproducible" in done.stdout, done.stdout + done.stderr
    assert "largest height difference" in done.stdout


def test_the_recording_names_its_node_keeps_what_was_sent_and_the_feeder_s_targets(ros: None, tmp_path: Path) -> None:
    """Issue 23, defects 1, 7 and 9, as ``ros2 param set`` and a controller
    make them: every parameter event names the slider's fully qualified name
    (``/<ns>/slider``, not ``/slider``); a refused integer 2 for ``mass`` is
    recorded as the 2 that was sent, not 2.0; and the targets and statuses
    seen on the namespace are in the file (the shipped layout plots them)."""
    from friction_sim.io.reader import read_recording

    ns, path = namespace(), tmp_path / "run.mcap"
    node = SliderNode(namespace=ns, parameter_overrides=[Parameter("log_path", value=str(path))])
    probe = Probe(ns, node, outputs={"pose": PoseStamped, "diagnostics": DiagnosticArray})
    try:
        probe.wait_for_connection(topic="pose")
        assert not probe.set_parameter("slider", "mass", 2)[0]  # rclpy refuses the type; the node records it
        assert probe.set_parameter("slider", "mu", 0.12)[0]  # physics: recorded as a parameters command
        assert probe.set_parameter("slider", "frame_id", "rail")[0]  # not physics: recorded as it is set
        assert probe.spin_until(lambda: probe.publishers["target_speed"].get_subscription_count() >= 1)
        # the slider's reader matches our writer too (as wait_for_connection waits for)
        assert probe.spin_until(probe.readers_know_our_writers, 10.0)
        probe.send("target_speed", 2.5e-4)
        seen = len(probe.received["diagnostics"])
        assert probe.spin_until(lambda: len(probe.received["diagnostics"]) >= seen + 2, 15.0)
    finally:
        probe.close()
        node.destroy_node()
    recording = read_recording(path)
    by_topic: dict[str, list[Any]] = {}
    for raw in recording.messages:
        by_topic.setdefault(raw.topic, []).append(recording.decode(raw))
    events = by_topic[f"{ns}/parameters"]
    assert len(events) >= 3 and {msg.node for msg in events} == {f"{ns}/slider"}, {msg.node for msg in events}
    refusals = [{kv.key: kv.value for kv in msg.values} for msg in by_topic[f"{ns}/rejected_commands"]]
    assert {"mass": "2"} in refusals, refusals
    assert [msg.data for msg in by_topic[f"{ns}/target_speed"]] == [2.5e-4]
    assert by_topic[f"{ns}/diagnostics"], "the statuses seen on the namespace are recorded"
