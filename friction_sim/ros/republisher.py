"""Republishing a recording on its topics with its timing, like ``ros2 bag play``.

The recorded messages are published as recorded (serialized CDR: rclpy
publishers take the bytes as they are), so nothing is decoded here; with
one exception: a file written before the ``external_wrench`` convention was
marked (force.z > 0 pressed the slider on the track) has its
``external_wrench`` messages published with force.z turned round, so that a
slider of today (force.z > 0 lifts) that takes them does what the recorded
one did.  The
file is streamed chunk by chunk (:meth:`Recording.iter_chunks`) and merged
into log-time order with a buffer of about one chunk, so memory stays
bounded whatever the recording's length.
"""

from __future__ import annotations

import gc
import heapq
import itertools
import math
import queue
import threading
import time
import uuid
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import rclpy
import yaml
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from friction_sim.core.runtime.progress import Progress
from friction_sim.errors import ParameterError
from friction_sim.io import cdr
from friction_sim.io.export import select_topics
from friction_sim.io.messages import NS_PER_S, ns_to_seconds
from friction_sim.io.reader import Channel, RawMessage, Recording

#: Messages read ahead of the one being published (a few chunks' worth at most).
PREFETCH = 20_000


@dataclass
class PublishResult:
    """What :func:`publish` sent: messages, loops, and the largest lateness
    of a publish call behind its scheduled wall time [s]."""

    messages: int = 0
    loops: int = 0
    max_late: float = 0.0
    interrupted: bool = False


def qos(channel: Channel) -> QoSProfile:
    """The publisher QoS of a recorded channel: depth 10, with the recorded
    reliability and durability (reliable, volatile unless recorded otherwise)."""
    profile = QoSProfile(depth=10)
    try:
        offered = yaml.safe_load(channel.metadata.get("offered_qos_profiles", "") or "[]") or []
        first = offered[0] if offered else {}
    except (yaml.YAMLError, IndexError, TypeError, KeyError):
        first = {}
    reliability, durability = first.get("reliability"), first.get("durability")
    if reliability in ("best_effort", 2):
        profile.reliability = ReliabilityPolicy.BEST_EFFORT
    if durability in ("transient_local", 1):
        profile.durability = DurabilityPolicy.TRANSIENT_LOCAL
    return profile


def publish(
    recording: Recording, *, rate: float = 1.0, loop: bool = False, topics: Sequence[str] | None = None,
    namespace: str = "", wait_for_subscribers: int = 0, wait_timeout: float = 5.0, delay: float = 0.0,
    progress: Progress | None = None, stop: threading.Event | None = None, node_name: str | None = None,
) -> PublishResult:
    """Republish the recorded messages (as recorded, serialized) on their
    topics, the recorded log times scaled by 1/``rate``; with ``loop`` start
    over until ``stop`` is set or Ctrl-C.  Topics keep their stored names
    (fully qualified, as rosbag2 stores them; an old file's relative names
    resolve in ``/``); with ``namespace`` they move there, relative to the
    recorded node (``/feeder1/pose`` recorded, ``/replay`` given:
    ``/replay/pose``).  With
    ``wait_for_subscribers`` it first waits (up to ``wait_timeout`` s) until
    every publisher has that many subscriptions, then waits ``delay`` s
    (discovery may need a moment to match both ends).  Progress goes to
    ``progress`` (the command line's line: a bar redrawn on a terminal).
    rclpy is initialised here if the caller has not done so.
    """
    if not (isinstance(rate, (int, float)) and math.isfinite(rate) and rate > 0.0):
        raise ParameterError("rate", rate, "must be a finite factor > 0")
    selected = select_topics(recording, topics)
    own_context = not rclpy.ok()
    if own_context:
        rclpy.init()
    node = None
    try:
        node = rclpy.create_node(node_name or f"friction_sim_replay_{uuid.uuid4().hex[:8]}",
                                 namespace=namespace or "/")
        publishers = _publishers(node, recording, selected, moved=bool(namespace))
        _wait_for_subscribers(publishers, wait_for_subscribers, wait_timeout, stop)
        if delay > 0.0:
            time.sleep(delay)
        return _play(recording, selected, publishers, rate, loop, progress, stop)
    finally:
        if node is not None:
            node.destroy_node()
        if own_context:
            rclpy.try_shutdown()


def _publishers(node: Node, recording: Recording, topics: list[str], moved: bool) -> dict[str, Any]:
    """A publisher per stored topic, of its recorded type and QoS: on the stored
    name, or (``moved``) on the name relative to the recorded node, which the
    node resolves in its namespace."""
    return {topic: node.create_publisher(recording.message_type(topic),
                                         recording.relative_name(topic) if moved else topic,
                                         qos(recording.topics[topic]))
            for topic in topics}


def _wait_for_subscribers(publishers: dict[str, Any], count: int, timeout: float,
                          stop: threading.Event | None) -> None:
    """Wait up to ``timeout`` s until every publisher has ``count`` subscriptions."""
    if count <= 0:
        return
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not (stop is not None and stop.is_set()):
        if all(p.get_subscription_count() >= count for p in publishers.values()):
            return
        time.sleep(0.01)


def in_time_order(chunks: Iterable[list[RawMessage]]) -> Iterator[RawMessage]:
    """The messages of ``chunks`` (file order) in log-time order, ties in file
    order.  A message is let out once a later chunk starts after it, so only
    about one chunk is held at a time (chunks overlap in time only at their
    edges: the recorder writes in time order)."""
    pending: list[tuple[int, int, RawMessage]] = []
    order = itertools.count()
    for block in chunks:
        if not block:
            continue
        start = min(raw.log_time for raw in block)
        while pending and pending[0][0] <= start:
            yield heapq.heappop(pending)[2]
        for raw in block:
            heapq.heappush(pending, (raw.log_time, next(order), raw))
    while pending:
        yield heapq.heappop(pending)[2]


def in_todays_convention(recording: Recording, messages: Iterator[RawMessage]) -> Iterator[RawMessage]:
    """``messages`` as a slider of today reads them: those of an old file's
    ``external_wrench`` (force.z > 0 loaded the contact) with force.z turned
    round; everything else (and everything of a file of today) as recorded."""
    wrench = recording.topic_name("external_wrench")
    if wrench is None or recording.external_force_z_sign > 0.0:
        yield from messages
        return
    for raw in messages:
        if raw.topic == wrench:
            msg = recording.decode(raw)
            msg.wrench.force.z = 0.0 - msg.wrench.force.z
            raw = raw._replace(data=cdr.serialize(msg))
        yield raw


class _Failed(NamedTuple):
    error: BaseException


def prefetched(messages: Iterator[RawMessage], size: int = PREFETCH) -> Iterator[RawMessage]:
    """``messages``, read ahead by a thread into a queue of ``size``: reading
    and decompressing the next chunk happens while this thread sleeps until
    the next publish, not in its way.  An error of the reader is raised here."""
    ahead: queue.Queue[RawMessage | _Failed | None] = queue.Queue(maxsize=size)
    done = threading.Event()

    def read() -> None:
        item: RawMessage | _Failed | None
        try:
            for item in messages:
                while not done.is_set():
                    try:
                        ahead.put(item, timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if done.is_set():
                    return
            item = None
        except BaseException as error:  # noqa: BLE001 - handed to the consumer
            item = _Failed(error)
        while not done.is_set():
            try:
                ahead.put(item, timeout=0.1)
                return
            except queue.Full:
                continue

    reader = threading.Thread(target=read, name="replay_reader", daemon=True)
    reader.start()
    try:
        while (item := ahead.get()) is not None:
            if isinstance(item, _Failed):
                raise item.error
            yield item
    finally:
        done.set()


def _play(recording: Recording, topics: list[str], publishers: dict[str, Any], rate: float, loop: bool,
          progress: Progress | None, stop: threading.Event | None) -> PublishResult:
    """Publish the messages of ``topics`` once, or in a loop until stopped."""
    result = PublishResult()
    bar = _Progress(progress, ns_to_seconds(recording.end_ns - recording.start_ns), rate)
    # A full garbage collection of a large heap can stall this thread for
    # ~100 ms; leave the objects that exist now out of collections while
    # playing, so the recorded timing holds.
    gc.freeze()
    try:
        while True:
            sent = result.messages
            _play_once(prefetched(in_todays_convention(recording, in_time_order(recording.iter_chunks(topics)))),
                       publishers, rate, result, bar, stop)
            if result.messages == sent:
                break  # nothing to publish
            result.loops += 1
            if not loop or (stop is not None and stop.is_set()):
                break
    except KeyboardInterrupt:
        result.interrupted = True
    finally:
        gc.unfreeze()
    if result.messages:
        bar.close(result)
    return result


def _play_once(messages: Iterator[RawMessage], publishers: dict[str, Any], rate: float, result: PublishResult,
               bar: _Progress, stop: threading.Event | None) -> None:
    """Publish every message at its recorded time (scaled by 1/rate) after the
    start (taken once the first message is at hand)."""
    head = next(messages, None)
    if head is None:
        return
    first = head.log_time
    start = time.monotonic() + 0.01
    for raw in itertools.chain([head], messages):
        if stop is not None and stop.is_set():
            result.interrupted = True
            return
        target = start + (raw.log_time - first) / NS_PER_S / rate
        _sleep_until(target)
        publishers[raw.topic].publish(raw.data)
        result.messages += 1
        result.max_late = max(result.max_late, time.monotonic() - target)
        bar.update(ns_to_seconds(raw.log_time - first), result.messages)


def _sleep_until(target: float) -> None:
    """Sleep until monotonic time ``target``: coarse sleep, then a short
    GIL-releasing spin for the last millisecond."""
    while True:
        remaining = target - time.monotonic()
        if remaining <= 0.0:
            return
        time.sleep(remaining - 0.001 if remaining > 0.002 else 0)


class _Progress:
    """``replay: [#####.....]  12.3/60.0 s  x1.0  1234 msgs`` on the caller's progress line."""

    def __init__(self, line: Progress | None, total: float, rate: float) -> None:
        self.line, self.total, self.rate = line, total, rate

    def update(self, t: float, count: int, *, force: bool = False) -> None:
        """Show progress at recorded time ``t`` (the line decides how often it is drawn)."""
        if self.line is None:
            return
        fraction = t / self.total if self.total > 0 else 1.0
        filled = round(30 * min(max(fraction, 0.0), 1.0))
        self.line.show(f"replay: [{'#' * filled}{'.' * (30 - filled)}] {t:9.3f}/{self.total:.3f} s  x{self.rate:g}  "
                       f"{count} msgs", final=force)

    def close(self, result: PublishResult) -> None:
        """The final line."""
        if self.line is None:
            return
        self.update(self.total, result.messages, force=True)
        self.line.close()


__all__ = ["PublishResult", "in_time_order", "in_todays_convention", "publish", "qos"]
