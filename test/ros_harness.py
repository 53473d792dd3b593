"""Test helpers for nodes: a probe node that records what a node publishes and
sends it commands, all spun in the test's own thread (no launch_testing)."""

from __future__ import annotations

import math
import subprocess
import sys
import time
import uuid
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
from rclpy.duration import Duration
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from std_msgs.msg import Float64

from friction_sim.io.sinks import CommandRecord, Record

OUTPUTS = {
    "pose": PoseStamped,
    "velocity": TwistStamped,
    "friction_force": WrenchStamped,
    "mean_velocity": TwistStamped,
    "diagnostics": DiagnosticArray,
}
INPUTS = {
    "drive_force": Float64,
    "excitation_amplitude": Float64,
    "excitation_frequency": Float64,
    "drive_level": Float64,
    "external_wrench": WrenchStamped,
    "target_speed": Float64,
}


class CommandLog:
    """A sink that keeps the commands as the node handled them (the rest it ignores)."""

    def __init__(self, outcomes: list[Any]) -> None:
        self.outcomes = outcomes

    def write(self, record: Record) -> bool:
        if isinstance(record, CommandRecord):
            self.outcomes.append(record.outcome)
        return True

    def close(self) -> None: ...


def namespace() -> str:
    """A fresh namespace per test: nodes of different tests never meet."""
    return f"/t{uuid.uuid4().hex[:8]}"


def diagnostics_values(msg: Any) -> dict[str, str]:
    """key -> value of the one status of a DiagnosticArray."""
    (status,) = msg.status
    return {kv.key: kv.value for kv in status.values}


def stamp_ns(msg: Any) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


class Probe:
    """Subscribes to every output of a slider in ``namespace`` and publishes
    to every input; spins the given nodes together with itself."""

    def __init__(self, namespace: str, *nodes: Node, outputs: dict[str, type] | None = None,
                 depth: int = 100) -> None:
        """``depth``: each subscription's queue.  A message that finds it full pushes out the
        oldest one not yet taken: a test that counts every message of a fast topic needs a
        queue that holds what comes while the machine does not run this process.  A test that
        looks at the last N messages after M > N more came relies on the default: at most
        ``depth`` of them can be older ones still queued."""
        self.node = rclpy.create_node("probe", namespace=namespace)
        self.namespace = namespace
        self._services: dict[str, Any] = {}
        self.received: dict[str, list[Any]] = defaultdict(list)
        for topic, kind in (outputs or OUTPUTS).items():
            self.node.create_subscription(kind, topic, self._keeper(topic), depth)
        self.publishers = {topic: self.node.create_publisher(kind, topic, 10) for topic, kind in INPUTS.items()}
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self._clients: dict[str, AsyncParameterClient] = {}
        self._nodes = nodes
        for node in nodes:
            self.executor.add_node(node)

    def _keeper(self, topic: str) -> Callable[[Any], None]:
        return lambda msg: self.received[topic].append(msg)

    def send(self, topic: str, value: float | tuple[float, float]) -> None:
        if topic == "external_wrench":
            msg = WrenchStamped()
            msg.wrench.force.x, msg.wrench.force.z = value  # type: ignore[misc]
        else:
            msg = Float64(data=float(value))  # type: ignore[arg-type]
        self.publishers[topic].publish(msg)

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.01)

    def spin_until(self, predicate: Callable[[], bool], timeout: float = 10.0) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return True
            self.executor.spin_once(timeout_sec=0.01)
        return predicate()

    def wait_for_connection(self, count: int = 1, timeout: float = 10.0, topic: str = "pose") -> None:
        """Wait until discovery has matched our publishers and subscriptions."""
        def matched() -> bool:
            subs = all(pub.get_subscription_count() >= count
                       for topic, pub in self.publishers.items() if topic != "target_speed")
            return subs and len(self.received[topic]) > 0
        assert self.spin_until(matched, timeout), "the node under test never connected"
        # Our publishers know the node's readers; the readers must know our writers too, or a command
        # sent at once can be dropped by a reader that has not matched us yet.  A node in this process
        # says so itself; of a node in another process nothing tells, and a moment is all we can give.
        if self._nodes:
            assert self.spin_until(self.readers_know_our_writers, timeout), "the node never matched our writers"
        else:
            self.spin_for(0.3)

    def readers_know_our_writers(self) -> bool:
        """Every reader of the in-process nodes on a topic we publish has matched every writer
        on that topic in this process (ours among them)."""
        writers: dict[str, int] = defaultdict(int)
        for node in (self.node, *self._nodes):
            for publisher in node.publishers:
                writers[publisher.topic_name] += 1
        ours = {publisher.topic_name for publisher in self.publishers.values()}
        return all(subscription.get_publisher_count() >= writers[subscription.topic_name]
                   for node in self._nodes for subscription in node.subscriptions
                   if subscription.topic_name in ours)

    def set_parameter(self, node: str, name: str, value: object) -> tuple[bool, str]:
        """``ros2 param set`` through ``node``'s parameter services: (successful, reason)."""
        if node not in self._clients:
            self._clients[node] = AsyncParameterClient(self.node, node)
            assert self._clients[node].wait_for_services(15.0), f"{node} offers no parameter services"
        future = self._clients[node].set_parameters([Parameter(name, value=value)])
        assert self.spin_until(future.done, 15.0), f"{node} did not answer setting {name}"
        (result,) = future.result().results
        return result.successful, result.reason

    def set_parameters_atomically(self, node: str, values: dict[str, object]) -> tuple[bool, str]:
        """One SetParametersAtomically call to ``node``'s service: (successful, reason)."""
        if node not in self._clients:
            self._clients[node] = AsyncParameterClient(self.node, node)
            assert self._clients[node].wait_for_services(15.0), f"{node} offers no parameter services"
        future = self._clients[node].set_parameters_atomically(
            [Parameter(name, value=value) for name, value in values.items()])
        assert self.spin_until(future.done, 15.0), f"{node} did not answer the atomic set"
        result = future.result().result
        return result.successful, result.reason

    def control(self, name: str, node: str = "slider") -> Any:
        """Call ``node``'s simulation-control service ``~/name`` (pause, resume,
        step, reset: std_srvs/Trigger); the response (success, message)."""
        from std_srvs.srv import Trigger

        service = f"{self.namespace}/{node}/{name}"
        if service not in self._services:
            self._services[service] = self.node.create_client(Trigger, service)
            assert self._services[service].wait_for_service(10.0), f"no service {service}"
        future = self._services[service].call_async(Trigger.Request())
        assert self.spin_until(future.done, 10.0), f"{service} did not answer"
        return future.result()

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=0.0)
        self.node.destroy_node()


def kill_if_running(process: subprocess.Popen[str]) -> None:
    """Test clean-up: a node process a failed test left running is killed."""
    if process.poll() is None:
        process.kill()
        process.communicate()


#: This file: run as a script, it is the flooder (see :func:`flood`).
HARNESS = Path(__file__).resolve()
#: An invalid flood cycles through these drive forces: half NaN or inf, half finite but out of range.
INVALID = (math.nan, math.inf, 1e308, -5e6, math.nan, -math.inf, 2e6, -1e300)
#: The value of the last message of a flood with a final valid command.
LAST = 0.75
#: The value of the one valid command the flooder sends before its flood (see :func:`flood`).
MARK = 0.65


def flood_value(kind: str, n: int) -> float:
    """The n-th drive force of a flood of ``kind``: "valid" (0.7 ... 0.71 N, each
    a real change), "invalid" (:data:`INVALID`), or "mixed" (valid, NaN, valid,
    +-inf, ...: half of them invalid)."""
    valid = 0.7 + 1e-4 * (n % 100)
    if kind == "valid":
        return valid
    if kind == "invalid":
        return INVALID[n % len(INVALID)]
    if n % 4 == 1:
        return math.nan
    if n % 4 == 3:
        return math.inf if n % 8 == 3 else -math.inf
    return valid


def flood(namespace: str, rate: int, seconds: float, kind: str = "valid", last: bool = False,
          confirm: bool = False) -> int:
    """Publish ``rate`` x ``seconds`` drive_force commands of ``kind``
    (:func:`flood_value`), at most ``rate`` per second, once a reader has matched (run in its own process); print
    "flooding" when the flood begins.  With ``last``, end with one valid
    command, :data:`LAST`.  Returns how many were sent (the mark not counted).

    Our writer matching the node's reader does not tell that the reader has matched our writer, and
    until it has, what we publish is not taken at once.  So the flooder first publishes one valid
    command, :data:`MARK`.  With ``confirm`` it prints "matched" and floods only after a line on its
    stdin: the test sends it once the node has taken the mark (a message from this writer got
    through).  Without it (the benches) it floods once every matched reader has acknowledged the
    mark: the node's reader has then matched this writer too."""
    rclpy.init()
    node = rclpy.create_node("flooder", namespace=namespace)
    publisher = node.create_publisher(Float64, "drive_force", 10)
    deadline = time.monotonic() + 15.0
    while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.01)  # poll interval: waiting for the subscription to match
    publisher.publish(Float64(data=MARK))  # reliable, and alone in the history: it arrives once matched
    if confirm:
        print("matched", flush=True)
        sys.stdin.readline()
    elif not publisher.wait_for_all_acked(Duration(seconds=15.0)):
        raise SystemExit("flooder: the node's reader never acknowledged the mark in 15 s")
    print("flooding", flush=True)
    # A fixed count, paced at ``rate`` at most: a slow machine floods for longer,
    # never with fewer commands.
    start, sent, msg, total = time.monotonic(), 0, Float64(), int(rate * seconds)
    while sent < total:
        due = min(total, int((time.monotonic() - start) * rate))
        while sent < due:
            msg.data = flood_value(kind, sent)
            publisher.publish(msg)
            sent += 1
        time.sleep(0.001)  # pacing of the flood at `rate` (what is sent is counted, not timed)
    if last:
        msg.data = LAST
        publisher.publish(msg)
        sent += 1
    # A writer destroyed with samples not yet acknowledged drops them: the last must reach the node.
    publisher.wait_for_all_acked(Duration(seconds=15.0))
    node.destroy_node()
    rclpy.shutdown()
    return sent


if __name__ == "__main__":
    # python test/ros_harness.py NAMESPACE RATE SECONDS [KIND [last] [confirm]]
    print(flood(sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), *sys.argv[4:5], last="last" in sys.argv[5:],
                confirm="confirm" in sys.argv[5:]))
