"""Benchmark of the slider node over real topics (issue 3).

Starts the installed ``slider`` console script in its own process at
publish_rate 1000 Hz and measures from this process, over DDS on localhost:

  * messages per second per topic, tick interval p50/p99 (from the stamps),
    CPU share of the node process (from /proc), and the drift of simulation
    time against wall time, over a steady window (60 s by default);
  * command-to-effect latency p50/p99: a command published here until the
    first friction_force message that reflects it (excitation off, the
    external normal force toggled, so the reaction R jumps to a known value);
  * a flood of 10,000 commands per second for 5 s from a third process,
    valid ones and then invalid ones (half NaN or inf, half finite but out
    of range): the node's tick rate during each flood, the commands it
    handled, and its memory before and after;
  * all of the above four times in the same run: without and with recording
    to MCAP (log_rate 1000 Hz), and the recording's size per simulated
    minute; then with the Foxglove live view on (foxglove_port) and no
    client, and with a client in a third process subscribed to every
    channel (a websockets client speaking the SDK's protocol, decoding
    every message), which reports the messages per second it received.

Prints figures only; nothing here passes or fails on timing.
Run: make bench   (or .venv/bin/python bench/node.py [--duration 60])
"""

from __future__ import annotations

import argparse
import os
import random
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(1, 100)))

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
from rclpy.executors import SingleThreadedExecutor
from std_msgs.msg import Float64

BIN = Path(sys.executable).parent
HARNESS = Path(__file__).resolve().parents[1] / "test" / "ros_harness.py"
NAMESPACE = "/bench"
TOPICS = {"pose": PoseStamped, "velocity": TwistStamped, "friction_force": WrenchStamped,
          "mean_velocity": TwistStamped, "diagnostics": DiagnosticArray}
CLK_TCK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def rss_mib(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def stamp_ns(msg) -> int:  # type: ignore[no-untyped-def]
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


class Listener:
    """Receives every output of the node with the local receive time."""

    def __init__(self) -> None:
        self.node = rclpy.create_node("bench_listener", namespace=NAMESPACE)
        self.log: dict[str, list[tuple[int, object]]] = {topic: [] for topic in TOPICS}
        for topic, kind in TOPICS.items():
            self.node.create_subscription(kind, topic, self._keeper(topic), 1000)
        self.drive = self.node.create_publisher(Float64, "drive_force", 10)
        self.amplitude = self.node.create_publisher(Float64, "excitation_amplitude", 10)
        self.wrench = self.node.create_publisher(WrenchStamped, "external_wrench", 10)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)

    def _keeper(self, topic: str):  # type: ignore[no-untyped-def]
        log = self.log[topic]
        return lambda msg: log.append((time.monotonic_ns(), msg))

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.005)

    def clear(self) -> None:
        for log in self.log.values():
            log.clear()


def steady_window(listener: Listener, pid: int, seconds: float) -> dict[str, float]:
    listener.clear()
    cpu0, wall0 = cpu_seconds(pid), time.monotonic()
    listener.spin_for(seconds)
    cpu1, wall1 = cpu_seconds(pid), time.monotonic()
    elapsed = wall1 - wall0
    print(f"steady window: {elapsed:.1f} s at publish_rate 1000 Hz")
    for topic in ("pose", "velocity", "friction_force", "mean_velocity", "diagnostics"):
        print(f"    {topic:15s} {len(listener.log[topic]) / elapsed:8.1f} msg/s")
    stamps = np.array([stamp_ns(m) for _, m in listener.log["pose"]], dtype=np.int64)
    received = np.array([t for t, _ in listener.log["pose"]], dtype=np.int64)
    intervals = np.diff(stamps) / 1e6
    print(f"    tick interval (pose stamps) p50 {np.percentile(intervals, 50):.3f} ms, "
          f"p99 {np.percentile(intervals, 99):.3f} ms, max {intervals.max():.3f} ms")
    print(f"    CPU share of the node process: {100 * (cpu1 - cpu0) / elapsed:.1f} % of one core "
          "(target < 50 %)")
    offset = (stamps - received) / 1e6  # sim minus wall [ms], plus transport delay
    n = max(1, int(0.05 * offset.size))
    drift = np.median(offset[-n:]) - np.median(offset[:n])
    print(f"    drift of simulation time against wall time over the window: {drift:+.3f} ms "
          "(median of first vs last 5 % of samples; target < 1 ms)")
    return {"cpu": 100 * (cpu1 - cpu0) / elapsed, "rate": len(listener.log["pose"]) / elapsed,
            "p99": float(np.percentile(intervals, 99))}


def latency(listener: Listener, samples: int) -> dict[str, float]:
    """Excitation off, so R = m*g - Fz exactly (Fz > 0 lifts); toggle Fz and time the change."""
    listener.amplitude.publish(Float64(data=0.0))
    listener.spin_for(0.5)
    delays = []
    for k in range(samples):
        value = 0.25 + 0.001 * (k % 200) if k % 2 == 0 else 0.0
        msg = WrenchStamped()
        msg.wrench.force.z = value
        log = listener.log["friction_force"]
        start_index = len(log)
        sent = time.monotonic_ns()
        listener.wrench.publish(msg)
        deadline = time.monotonic() + 1.0
        found = None
        while found is None and time.monotonic() < deadline:
            listener.executor.spin_once(timeout_sec=0.001)
            for received, message in log[start_index:]:
                if abs(message.wrench.force.z - (10.0 - value)) < 1e-9:  # Fz > 0 lifts: R = m g - Fz
                    found = received
                    break
            start_index = len(log) if found is None else start_index
        if found is not None:
            delays.append((found - sent) / 1e6)
        listener.spin_for(0.01)
    listener.amplitude.publish(Float64(data=5.0))
    listener.wrench.publish(WrenchStamped())
    d = np.array(delays)
    print(f"command-to-effect latency over {d.size}/{samples} commands: p50 {np.percentile(d, 50):.3f} ms, "
          f"p99 {np.percentile(d, 99):.3f} ms (target p50 < 2 ms)")
    return {"latency_p50": float(np.percentile(d, 50)), "latency_p99": float(np.percentile(d, 99))}


def flood(listener: Listener, pid: int, rate: int, seconds: float, kind: str) -> dict[str, float]:
    """``kind`` "valid" or "invalid" commands at ``rate`` per second; the tick-rate figures."""
    listener.spin_for(1.0)
    rss_before = rss_mib(pid)
    listener.clear()
    # The same flooder the tests use (test/ros_harness.py), in its own process.
    flooder = subprocess.Popen([sys.executable, str(HARNESS), NAMESPACE, str(rate), str(seconds), kind],
                               stdout=subprocess.PIPE, text=True)
    listener.spin_for(seconds + 1.0)
    sent = int(flooder.communicate(timeout=30)[0].split()[-1])
    rss_during = rss_mib(pid)
    stamps = np.array([stamp_ns(m) for _, m in listener.log["pose"]], dtype=np.int64) / 1e9
    reports = [{kv.key: kv.value for kv in m.status[0].values} for _, m in listener.log["diagnostics"]]
    rates = [float(values["tick_rate"]) for values in reports]
    handled = [int(values["commands_accepted"]) + int(values["commands_rejected"]) for values in reports]
    # Tick rate per whole second of the flood, from the pose stamps.
    per_second = np.histogram(stamps, bins=np.arange(stamps[0], stamps[-1], 1.0))[0]
    listener.spin_for(3.0)
    rss_after = rss_mib(pid)
    print(f"flood of {rate} {kind} commands/s for {seconds:g} s from another process (sent {sent}):")
    print(f"    pose messages per second during the flood: min {per_second.min()}, "
          f"median {int(np.median(per_second))} (target >= 950)")
    print(f"    tick rate reported by the node's diagnostics: {', '.join(f'{r:.0f}' for r in rates)} Hz")
    if len(handled) >= 2:
        print(f"    commands handled (accepted + rejected) by the node during the window: {handled[-1] - handled[0]}")
    print(f"    node memory (RSS): before {rss_before:.1f} MiB, right after {rss_during:.1f} MiB, "
          f"3 s later {rss_after:.1f} MiB")
    return {"median": float(np.median(per_second)), "min": float(per_second.min())}


def main() -> int:
    parser = argparse.ArgumentParser(description="slider node benchmark")
    parser.add_argument("--duration", type=float, default=60.0, help="steady window [s] per pass (60)")
    args = parser.parse_args()
    print(f"bench/node.py  (ROS_DOMAIN_ID {os.environ['ROS_DOMAIN_ID']}, localhost only)")
    rclpy.init()
    listener = Listener()
    figures = {}
    passes = {"recording off": (False, False), "recording on": (True, False),
              "live view, no client": (False, None), "live view, a client on every channel": (False, True)}
    try:
        with tempfile.TemporaryDirectory() as folder:
            for label, (logging, client) in passes.items():
                log = Path(folder) / "bench.mcap"
                print(f"\n=== slider at publish_rate 1000 Hz, {label}" + (" (log_rate 1000 Hz)" if logging else ""))
                figures[label] = run_node_pass(listener, args.duration, log if logging else None, client)
                if logging:
                    size = log.stat().st_size
                    print(f"    recording: {size / 1e6:.2f} MB for {figures[label]['simulated']:.1f} s simulated = "
                          f"{size / 1e6 * 60 / figures[label]['simulated']:.2f} MB per simulated minute")
    finally:
        listener.node.destroy_node()
        rclpy.try_shutdown()
    off = figures["recording off"]
    print()
    for label, row in figures.items():
        print(f"{label:38s} CPU {row['cpu']:5.1f} % of one core (x{row['cpu'] / off['cpu']:.2f} of recording off), "
              f"pose {row['rate']:.1f} msg/s, tick p99 {row['p99']:.3f} ms, latency p50 {row['latency_p50']:.3f} ms")
    for label, row in figures.items():
        print(f"tick rate under 10,000 commands/s, {label}: valid median {row['valid_median']:.0f} Hz "
              f"(min {row['valid_min']:.0f}), invalid median {row['invalid_median']:.0f} Hz "
              f"(min {row['invalid_min']:.0f}); invalid/valid {row['invalid_median'] / row['valid_median']:.2f}")
    return 0


def run_node_pass(listener: Listener, duration: float, log: Path | None, client: bool | None) -> dict[str, float]:
    """Start a slider, measure it, stop it with SIGINT; return the steady figures.
    ``client``: None no live view; False a live view nobody watches; True
    watched by a client process subscribed to every channel."""
    extra = ["-p", f"log_path:={log}"] if log else []
    if client is not None:
        extra += ["-p", "foxglove_port:=-1"]  # the system chooses the port; the node logs its URL
    node_log = Path(tempfile.mkdtemp(prefix="bench_node_")) / "slider.log"
    with node_log.open("w") as err:  # a file, not a pipe nobody reads: the node's log never blocks it
        node = subprocess.Popen(
            [str(BIN / "slider"), "--ros-args", "-r", f"__ns:={NAMESPACE}", "-p", "publish_rate:=1000.0", *extra],
            stdout=subprocess.DEVNULL, stderr=err, text=True)
    watcher = None
    started = time.monotonic()
    try:
        listener.clear()
        if not _wait_for_node(listener):
            raise RuntimeError("the slider node never published")
        if client:
            watcher = subprocess.Popen([sys.executable, "-c", WATCHER, str(CLIENT.parent), _served_url(node_log)],
                                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        listener.spin_for(2.0)  # let discovery and the first periods settle
        figures = steady_window(listener, node.pid, duration)
        figures.update(latency(listener, 200))
        for kind in ("valid", "invalid"):
            result = flood(listener, node.pid, 10_000, 5.0, kind)
            figures[f"{kind}_median"], figures[f"{kind}_min"] = result["median"], result["min"]
    finally:
        if watcher is not None:
            watcher.send_signal(2)
            out, err = watcher.communicate(timeout=20)
            print(f"    live-view client: {out.strip() or err.strip()[-300:]}")
        node.send_signal(2)
        try:
            node.wait(timeout=10)
        except subprocess.TimeoutExpired:
            node.kill()
    figures["simulated"] = time.monotonic() - started
    print(f"    node exit code after SIGINT: {node.returncode}")
    return figures


CLIENT = Path(__file__).resolve().parents[1] / "test" / "foxglove_client.py"
#: The live-view client process: subscribe to every channel (as they are
#: advertised), read and decode every frame as a viewer would, and say on SIGINT how
#: many state messages per second arrived.
WATCHER = """
import signal, sys, time
sys.path.insert(0, sys.argv[1])
from foxglove_client import FoxgloveClient
stop = []
signal.signal(signal.SIGINT, lambda *_: stop.append(1))
deadline = time.monotonic() + 20.0
while True:  # the node is up (it published); give its server a moment if the machine is busy
    try:
        client = FoxgloveClient(sys.argv[2]).__enter__()
        break
    except OSError:
        if time.monotonic() > deadline:
            raise
        time.sleep(0.2)
with client:
    subscribed, start, counts = set(), time.monotonic(), {}
    while not stop:
        fresh = set(client.channels) - subscribed
        if fresh:
            client.subscribe(*fresh)
            subscribed |= fresh
        for item in client.collect(0.2):
            counts[item.topic] = counts.get(item.topic, 0) + 1
    elapsed = time.monotonic() - start
print(f"{len(subscribed)} channels, " + ", ".join(f"{t} {n / elapsed:.1f}/s" for t, n in sorted(counts.items())))
"""


def _served_url(log: Path) -> str:
    """The live view's URL, from the line the slider logs once its server listens."""
    deadline = time.monotonic() + 20.0
    while not (found := re.search(r"live view: open (ws://\S+) in Foxglove", log.read_text())):
        if time.monotonic() > deadline:
            raise RuntimeError(f"the slider never said where its live view serves: {log.read_text()[-500:]}")
        time.sleep(0.05)
    return found[1]


def _wait_for_node(listener: Listener) -> bool:
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline:
        listener.executor.spin_once(timeout_sec=0.05)
        if listener.log["pose"]:
            return True
    return False


if __name__ == "__main__":
    sys.exit(main())
