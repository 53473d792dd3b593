"""The controller node under a flood of drive_force commands, half of them NaN or inf.

The flood comes from the tests' one flooder (``test/ros_harness.py NAMESPACE
RATE SECONDS mixed last``) in its own process; bench/controller.py runs it
the same way.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time
import uuid
from pathlib import Path

from rclpy.parameter import Parameter
from std_msgs.msg import Float64

from friction_sim.ros.controller import ControllerNode
from friction_sim.ros.controller_commands import COMMAND_HOLD_OFF

from ros_harness import HARNESS, LAST, MARK, Probe, kill_if_running

# -- the tests ------------------------------------------------------------------------

FLOOD_RATE = 10_000
FLOOD_SECONDS = 3.0
TEST_DIR = Path(__file__).resolve().parents[1]


def start_flood(probe: Probe, controller: ControllerNode, rate: int, seconds: float) -> subprocess.Popen[str]:
    """This module as the flooder, in its own process; returns once the flood has begun.  It floods
    once the controller has taken its mark: then the controller's reader knows the flooder's writer."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(TEST_DIR), os.environ.get("PYTHONPATH")]))}
    flooder = subprocess.Popen([sys.executable, str(HARNESS), probe.namespace, str(rate), str(seconds), "mixed",
                                "last", "confirm"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
    assert flooder.stdin is not None and flooder.stdout is not None
    assert flooder.stdout.readline().strip() == "matched"
    assert probe.spin_until(lambda: controller.control.drive_force == MARK, 30.0), "the flooder's mark never came"
    flooder.stdin.write("go\n")
    flooder.stdin.flush()
    assert flooder.stdout.readline().strip() == "flooding"
    return flooder


def test_a_flood_of_half_invalid_commands_is_taken_in_batches(ros: None) -> None:
    """10,000 drive_force commands a second, half NaN or inf: the controller
    used to decide and publish once per message it could take (about 1,350
    excitation_amplitude messages a second, a core busy).  Now it takes them
    in batches, at most one per hold-off, judges each message and answers
    each batch once; every refusal is counted, and the last valid value is
    the one in force."""
    ns = f"/c{uuid.uuid4().hex[:8]}"
    controller = ControllerNode(namespace=ns, parameter_overrides=[
        Parameter("plant_node", value=""), Parameter("target_speed", value=3e-4)])
    probe = Probe(ns, controller, outputs={"excitation_amplitude": Float64})
    flooder = None
    try:
        assert probe.spin_until(lambda: controller.ready and bool(probe.received["excitation_amplitude"]), 20.0)
        published: list[float] = []  # the controller's answers from now on, as it publishes them
        controller.output_listeners.append(lambda output: published.append(output.amplitude))
        before = len(probe.received["excitation_amplitude"])
        flooder = start_flood(probe, controller, FLOOD_RATE, FLOOD_SECONDS)
        answers, batches, started = len(published), controller.runtime.command_batches, time.monotonic()
        assert probe.spin_until(lambda: flooder is not None and flooder.poll() is not None, FLOOD_SECONDS + 30.0)
        elapsed = time.monotonic() - started
        sent = int(flooder.communicate(timeout=10)[0].split()[-1])
        assert probe.spin_until(lambda: controller.control.drive_force == LAST, 30.0), "the last valid value holds"
        # Quiet again: no batch, and so no answer, is still to come; then every answer has arrived.
        assert probe.spin_until(lambda: not controller.polling, 30.0), "quiet again: commands wake the node at once"
        assert probe.spin_until(lambda: len(probe.received["excitation_amplitude"]) - before >= len(published), 10.0)
        assert sent == int(FLOOD_RATE * FLOOD_SECONDS) + 1  # the flood and the last valid command
        most = elapsed / COMMAND_HOLD_OFF + 10  # one batch per hold-off at most, plus the quiet-time wake-ups
        assert len(published) - answers <= most, "one answer per batch"
        assert controller.runtime.command_batches - batches <= most  # (before: the mark's; the target was a parameter)
        assert controller.runtime.rejected > 100 and controller.runtime.accepted > 100, "both kinds, all through"
        assert "drive_force" in controller.runtime.last_rejection
        assert any(word in controller.runtime.last_rejection for word in ("nan", "inf"))
        runtime = controller.runtime
        assert runtime.accepted + runtime.rejected >= runtime.command_batches, "every message was judged"
        assert all(math.isfinite(m.data) for m in probe.received["excitation_amplitude"])
    finally:
        if flooder is not None:
            kill_if_running(flooder)
        probe.close()
        controller.destroy_node()


def test_a_lone_command_is_taken_at_once_and_the_polling_stops(ros: None) -> None:
    ns = f"/c{uuid.uuid4().hex[:8]}"
    controller = ControllerNode(namespace=ns, parameter_overrides=[Parameter("plant_node", value="")])
    probe = Probe(ns, controller, outputs={"excitation_amplitude": Float64})
    try:
        assert probe.spin_until(lambda: controller.ready and bool(probe.received["excitation_amplitude"]), 20.0)
        assert probe.spin_until(lambda: all(probe.publishers[t].get_subscription_count() for t in
                                            ("drive_force", "target_speed")), 10.0)
        # The controller's readers match our writers a moment later: it says so itself (in this process).
        assert probe.spin_until(probe.readers_know_our_writers, 10.0)
        for value, batches in ((0.8, 1), (0.9, 2)):
            probe.send("drive_force", value)
            assert probe.spin_until(lambda v=value: controller.control.drive_force == v, 5.0)  # type: ignore[misc]
            assert controller.runtime.command_batches == batches
            assert controller.polling, "after a batch, the topics are polled for a hold-off"
            assert probe.spin_until(lambda: not controller.polling, 30.0), "and then no more"
        # Two topics in one batch: each command is judged in the order they came.
        probe.send("target_speed", -2e-4)  # against the drive force in force: refused
        probe.send("drive_force", -0.7)
        probe.send("target_speed", -3e-4)  # with the new drive force: taken
        taken = probe.spin_until(lambda: controller.control.target_speed == -3e-4, 30.0)
        assert taken, controller.runtime.last_rejection
        assert controller.runtime.rejected == 1 and "-0.0002" in controller.runtime.last_rejection
    finally:
        probe.close()
        controller.destroy_node()
