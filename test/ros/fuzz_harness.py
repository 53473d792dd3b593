"""The fuzz suite's two ends: a node in its own process (:class:`NodeProcess`)
and the hostile client in the test process (:class:`FuzzClient`), which
publishes any message to it, sets any parameter, and checks everything the
node publishes as it arrives (every number finite, pose stamps never going back)."""

from __future__ import annotations

import math
import operator
import os
import re
import signal
import subprocess
import sys
import time
from collections import Counter, deque
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_srvs.srv import Trigger

from ros_harness import stamp_ns

BIN = Path(sys.executable).parent
#: Generous bounds for a shared 2-core machine: an answer, a message, a start-up.
ANSWER_TIMEOUT = 15.0
START_TIMEOUT = 30.0

#: The numbers of each message type a node publishes, by path.
_NUMBERS: dict[str, tuple[str, ...]] = {
    "PoseStamped": tuple(f"pose.position.{a}" for a in "xyz") + tuple(f"pose.orientation.{a}" for a in "xyzw"),
    "TwistStamped": tuple(f"twist.{k}.{a}" for k in ("linear", "angular") for a in "xyz"),
    "WrenchStamped": tuple(f"wrench.{k}.{a}" for k in ("force", "torque") for a in "xyz"),
    "Float64": ("data",),
}
_GETTERS = {kind: [(path, operator.attrgetter(path)) for path in paths] for kind, paths in _NUMBERS.items()}


def non_finite(msg: Any) -> list[str]:
    """The paths of the numbers in ``msg`` that are nan or inf."""
    return [f"{path} = {getter(msg)!r}" for path, getter in _GETTERS[type(msg).__name__]
            if not math.isfinite(getter(msg))]


def set_path(msg: Any, path: str, value: Any) -> None:
    """Set ``msg.a.b.c = value`` for path ``a.b.c``."""
    *parents, leaf = path.split(".")
    holder = msg
    for parent in parents:
        holder = getattr(holder, parent)
    setattr(holder, leaf, value)


#: A Python warning as the warnings module prints it: ``path:line: SomeWarning: message``.
_PYTHON_WARNING = re.compile(r"^\S+:\d+: \w*Warning: .*$", re.MULTILINE)


class NodeProcess:
    """A console script run in its own process, its output in a file."""

    def __init__(self, argv: Sequence[str], log_dir: Path, label: str) -> None:
        self.argv = list(argv)
        self.log_dir = log_dir
        self.label = label
        self.starts = 0
        self.process: subprocess.Popen[bytes] | None = None
        self.log: Path | None = None
        self._checked = 0  # characters of the output checked so far

    def start(self) -> None:
        self.starts += 1
        self.log = self.log_dir / f"{self.label}-{self.starts}.log"
        self._checked = 0
        with self.log.open("wb") as out:
            self.process = subprocess.Popen(self.argv, stdout=out, stderr=out, env=dict(os.environ))

    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def output(self) -> str:
        """Everything it wrote to stdout and stderr so far."""
        return self.log.read_text(errors="replace") if self.log is not None else ""

    def tail(self, lines: int = 25) -> str:
        return "\n".join(self.output().splitlines()[-lines:])

    def check(self) -> None:
        """Alive, and no traceback or Python warning on its output (a user sees
        one-line log messages, never the code's insides)."""
        assert self.process is not None
        code = self.process.poll()
        assert code is None, f"{self.label} died (exit code {code}); its output ends:\n{self.tail()}"
        whole = self.output()
        text, self._checked = whole[self._checked:], len(whole)  # each problem is reported once
        assert "Traceback" not in text and "Exception in thread" not in text, \
            f"{self.label} printed a traceback:\n{self.tail(40)}"
        warnings = list(dict.fromkeys(_PYTHON_WARNING.findall(text)))
        assert not warnings, f"{self.label} printed Python warnings:\n" + "\n".join(warnings)

    def python_warnings(self) -> list[str]:
        return list(dict.fromkeys(_PYTHON_WARNING.findall(self.output())))

    def interrupt(self, timeout: float = 20.0) -> tuple[int | None, str]:
        """SIGINT (Ctrl-C): (exit code, what it printed after the signal)."""
        assert self.process is not None
        before = len(self.output())
        self.process.send_signal(signal.SIGINT)
        try:
            code: int | None = self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            code = None
            self.kill()
        return code, self.output()[before:]

    def kill(self) -> None:
        if self.process is not None:
            self.process.kill()
            self.process.wait(timeout=10)


class FuzzClient:
    """The test's rclpy node: publishers to every input of one node, subscriptions
    to its outputs (checked as they arrive), and its parameter services."""

    def __init__(self, namespace: str, node_name: str, inputs: Mapping[str, type], outputs: Mapping[str, type],
                 checks: Mapping[str, Callable[[Any], str | None]] | None = None) -> None:
        self.node = rclpy.create_node(f"fuzzer_{node_name}", namespace=namespace)
        self.target = f"{namespace}/{node_name}"
        # Deep enough that a burst is not thinned out on our side: the node's own queue decides.
        deep = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
        self.publishers = {topic: self.node.create_publisher(kind, topic, deep) for topic, kind in inputs.items()}
        self.kinds = dict(inputs)
        self.counts: Counter[str] = Counter()
        self.last: dict[str, Any] = {}
        #: The last messages of each topic, with their number (counts[topic] when they arrived).
        self.recent: dict[str, deque[tuple[int, Any]]] = {topic: deque(maxlen=200) for topic in outputs}
        self.violations: list[str] = []
        self.last_pose_ns: int | None = None
        #: The message of the last diagnostics if its level is ERROR, else ''.
        self.error = ""
        self.diagnostics: list[tuple[float, dict[str, str], Any]] = []  # (arrival, values, message)
        self._checks = dict(checks or {})
        #: Called before a wait is declared failed (a dead node is then reported as such).
        self.when_silent: Callable[[], None] = lambda: None
        for topic, kind in outputs.items():
            self.node.create_subscription(kind, topic, self._receiver(topic), 100)
        self.parameters = AsyncParameterClient(self.node, self.target)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)

    def _receiver(self, topic: str) -> Callable[[Any], None]:
        def receive(msg: Any) -> None:
            self.counts[topic] += 1
            self.last[topic] = msg
            self.recent[topic].append((self.counts[topic], msg))
            if topic == "diagnostics":
                for status in msg.status:
                    self.diagnostics.append((time.monotonic(), {kv.key: kv.value for kv in status.values}, msg))
                    self.error = status.message if status.level == DiagnosticStatus.ERROR else ""
                    if self.error:
                        self.violations.append(f"diagnostics ERROR from {status.name}: {status.message}")
                del self.diagnostics[:-20]
                return
            bad = non_finite(msg)
            if bad:
                self.violations.append(f"{topic} published a non-finite state: {', '.join(bad)}")
            if topic == "pose":
                stamp = stamp_ns(msg)
                if self.last_pose_ns is not None and stamp < self.last_pose_ns:
                    self.violations.append(f"pose stamps went back from {self.last_pose_ns} ns to {stamp} ns")
                self.last_pose_ns = stamp
            check = self._checks.get(topic)
            problem = check(msg) if check is not None else None
            if problem:
                self.violations.append(f"{topic}: {problem}")
        return receive

    # -- spinning -----------------------------------------------------------------

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.005)

    def spin_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if predicate():
                return True
            self.executor.spin_once(timeout_sec=0.005)
        return predicate()

    def since(self, topic: str, number: int) -> list[Any]:
        """The messages on ``topic`` that arrived after the ``number``-th (of those still kept)."""
        return [msg for n, msg in self.recent[topic] if n > number]

    def wait_for(self, topic: str, count: int, timeout: float) -> bool:
        """Until ``count`` more messages arrived on ``topic``."""
        target = self.counts[topic] + count
        return self.spin_until(lambda: self.counts[topic] >= target, timeout)

    def connect(self, first_output: str) -> None:
        """Wait until the node's subscriptions match our publishers and its first output arrives."""
        matched = self.spin_until(
            lambda: all(p.get_subscription_count() > 0 for p in self.publishers.values())
            and self.counts[first_output] > 0, START_TIMEOUT)
        if not matched:
            self.when_silent()
        assert matched, f"{self.target} never connected (no {first_output})"
        assert self.parameters.wait_for_services(ANSWER_TIMEOUT), f"{self.target} offers no parameter services"
        # The node's readers need a moment to know our writers too.
        self.spin_for(0.3)

    # -- inputs ---------------------------------------------------------------------

    def message(self, topic: str, values: Mapping[str, Any]) -> Any:
        msg = self.kinds[topic]()
        for path, value in values.items():
            set_path(msg, path, value)
        return msg

    def publish(self, topic: str, msg: Any) -> None:
        self.publishers[topic].publish(msg)

    def flood(self, messages: Sequence[tuple[str, Any]], repeat: int) -> None:
        """Publish ``messages`` ``repeat`` times back to back, through writers
        of their own that are gone afterwards: what the node's queues dropped
        is then lost for good, rather than repaired by DDS up to a heartbeat
        period (3 s) later, after the node was judged to have handled the burst."""
        deep = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
        writers = {topic: self.node.create_publisher(self.kinds[topic], topic, deep) for topic, _ in messages}
        try:
            matched = self.spin_until(lambda: all(w.get_subscription_count() > 0 for w in writers.values()),
                                      ANSWER_TIMEOUT)
            assert matched, f"{self.target} never matched the burst's writers"
            self.spin_for(0.3)  # the node's readers need a moment to know them too
            for _ in range(repeat):
                for topic, msg in messages:
                    writers[topic].publish(msg)
            self.spin_for(0.2)
        finally:
            for writer in writers.values():
                self.node.destroy_publisher(writer)

    def _answer(self, future: Any, what: str) -> Any:
        if not self.spin_until(future.done, ANSWER_TIMEOUT):
            self.when_silent()
            raise AssertionError(f"{self.target} did not answer {what} within {ANSWER_TIMEOUT:g} s")
        return future.result()

    def set(self, kind: str, items: Sequence[tuple[str, Any]]) -> list[SetParametersResult]:
        """SetParameters (``set``: one result per parameter) or SetParametersAtomically (one result)."""
        parameters = [Parameter(name, value=value) for name, value in items]
        if kind == "atomic":
            return [self._answer(self.parameters.set_parameters_atomically(parameters), f"set {items}").result]
        return list(self._answer(self.parameters.set_parameters(parameters), f"set {items}").results)

    def trigger(self, service: str) -> Any:
        """Call the node's std_srvs/Trigger service ``~/service`` (its simulation control)."""
        client = self.node.create_client(Trigger, f"{self.target}/{service}")
        try:
            assert self.spin_until(lambda: client.service_is_ready(), ANSWER_TIMEOUT), f"no {service} service"
            return self._answer(client.call_async(Trigger.Request()), service)
        finally:
            self.node.destroy_client(client)

    def get(self, names: Sequence[str]) -> dict[str, Any]:
        answer = self._answer(self.parameters.get_parameters(list(names)), "get_parameters")
        assert len(answer.values) == len(names), f"get_parameters answered {len(answer.values)} of {len(names)}"
        return {name: parameter_value_to_python(value) for name, value in zip(names, answer.values)}

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=0.0)
        self.node.destroy_node()


def diagnostics_after(client: FuzzClient, newer: Callable[[float, dict[str, str], Any], bool],
                      timeout: float) -> dict[str, str]:
    """The values of the first diagnostics that ``newer`` accepts (computed after
    the inputs so far), waiting up to ``timeout`` (they come at 1 Hz)."""
    found: list[dict[str, str]] = []

    def arrived() -> bool:
        for arrival, values, msg in client.diagnostics:
            if newer(arrival, values, msg):
                found.append(values)
                return True
        return False

    if not client.spin_until(arrived, timeout):
        client.when_silent()
        raise AssertionError(f"no diagnostics from {client.target} within {timeout:g} s")
    return found[0]


def one_line(reason: str) -> bool:
    return bool(reason) and "\n" not in reason


__all__ = ["ANSWER_TIMEOUT", "BIN", "START_TIMEOUT", "FuzzClient", "NodeProcess", "diagnostics_after",
           "non_finite", "one_line", "set_path"]
