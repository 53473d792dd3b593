"""``ros2 topic pub --once`` as ros2cli (Jazzy) runs it, for the README test.

ros2cli is not on PyPI, so the README's ``ros2 topic pub`` lines are run
through this stand-in, which does what ``ros2topic/verb/pub.py`` of
ros2/ros2cli (branch jazzy) does for ``--once``:

* its own node (``_ros2cli_<pid>``) in a new context, hence its own DDS
  participant, as the new ``ros2`` process has; the node spins ``--spin-time``
  (0.5 s) "to wait for discovery" (ros2cli's DirectNode), then creates the
  publisher, with the ``default`` QoS preset (reliable, volatile, keep last 10);
* ``-w N`` (``--wait-matching-subscriptions``; 1 by default with ``--once``):
  ``get_subscription_count()`` is polled every 0.1 s until at least N
  subscriptions have matched (ros2cli waits forever; here :data:`MAX_WAIT`,
  then :class:`NeverMatched` says how many did);
* then the message, filled from the YAML values (nested mappings set the
  fields of nested messages), is published once, the node stays up
  ``--keep-alive`` seconds (0.1 by default) "for the message to reach the wire",
  and ends.

A subscription that had not matched when the message went out never gets
it: the publisher is volatile and gone a moment later.  That is why ``-w``
must count every subscription of the topic.
"""

from __future__ import annotations

import argparse
import os
import shlex
import time
import uuid
from dataclasses import dataclass, field
from typing import Any

#: ros2cli's poll interval while it waits for matching subscriptions (DEFAULT_WAIT_TIME).
POLL = 0.1
#: How long ros2cli's node spins before the verb starts "to wait for discovery" (--spin-time).
SPIN_TIME = 0.5
#: How long the stand-in waits for ``-w N`` subscriptions before it gives up (ros2cli: forever).
MAX_WAIT = 30.0


class NeverMatched(AssertionError):
    """``-w N`` asked for more subscriptions than matched: ``ros2 topic pub`` would wait forever."""


@dataclass(frozen=True)
class TopicPub:
    """One ``ros2 topic pub --once`` line: topic, type, values, -w and --keep-alive."""

    topic: str
    message_type: str
    values: dict[str, Any] = field(default_factory=dict)
    wait: int = 1
    keep_alive: float = 0.1
    spin_time: float = SPIN_TIME


def _parser() -> argparse.ArgumentParser:
    """The options of ros2cli's ``topic pub`` that a ``--once`` line may use."""
    parser = argparse.ArgumentParser(prog="ros2 topic pub", exit_on_error=False, add_help=False)
    parser.add_argument("topic_name")
    parser.add_argument("message_type")
    parser.add_argument("values", nargs="?", default="{}")
    parser.add_argument("-1", "--once", action="store_true")
    parser.add_argument("-t", "--times", type=int, default=0)
    parser.add_argument("-w", "--wait-matching-subscriptions", type=int, default=None)
    parser.add_argument("--keep-alive", type=float, default=0.1)
    parser.add_argument("--spin-time", type=float, default=SPIN_TIME)
    return parser


def parse(command: str) -> TopicPub:
    """The ``ros2 topic pub`` line ``command`` (ValueError if it is none, or not ``--once``)."""
    import yaml

    words = shlex.split(command)
    if words[:3] != ["ros2", "topic", "pub"]:
        raise ValueError(f"not a ros2 topic pub line: {command}")
    try:
        args = _parser().parse_args(words[3:])
    except (argparse.ArgumentError, SystemExit) as error:
        raise ValueError(f"{command}: {error}") from None
    if not args.once:
        raise ValueError(f"{command}: only --once lines publish a known number of messages")
    values = yaml.safe_load(args.values)
    if not isinstance(values, dict):
        raise ValueError(f"{command}: the values must be a YAML mapping")
    wait = args.wait_matching_subscriptions
    return TopicPub(args.topic_name, args.message_type, values, 1 if wait is None else wait, args.keep_alive,
                    args.spin_time)


def fill(msg: object, values: dict[str, Any]) -> None:
    """Set ``msg``'s fields from ``values`` (nested mappings: nested messages),
    each value converted to the field's type; AssertionError for a field the
    message does not have."""
    for key, value in values.items():
        assert hasattr(msg, key), f"{type(msg).__name__} has no field {key}"
        if isinstance(value, dict):
            fill(getattr(msg, key), value)
        else:
            setattr(msg, key, type(getattr(msg, key))(value))


def publish(line: TopicPub, namespace: str = "", max_wait: float = MAX_WAIT) -> int:
    """Run ``line`` as ``ros2 topic pub`` does; the subscriptions matched when
    the message was published.  ``namespace`` moves an absolute topic into it
    (``/target_speed`` -> ``/ns/target_speed``), as for a setup started with
    ``-r __ns:=/ns``."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import qos_profile_default

    from friction_sim.io.messages import message_class

    topic = f"{namespace}{line.topic}" if namespace and line.topic.startswith("/") else line.topic
    kind = message_class(line.message_type)
    context = Context()
    rclpy.init(context=context)
    try:
        # ros2cli names its node _ros2cli_<pid>: one name per process, so one per terminal here
        node = rclpy.create_node(f"_ros2cli_{os.getpid()}_{uuid.uuid4().hex[:8]}", context=context,
                                 start_parameter_services=False)
        executor = SingleThreadedExecutor(context=context)
        try:
            executor.add_node(node)
            spun = time.monotonic() + line.spin_time
            while (left := spun - time.monotonic()) > 0.0:  # DirectNode: spins until its timer fires
                executor.spin_once(timeout_sec=left)
            publisher = node.create_publisher(kind, topic, qos_profile_default)
            waited = 0.0
            while publisher.get_subscription_count() < line.wait:
                if waited >= max_wait:
                    raise NeverMatched(f"ros2 topic pub {line.topic} -w {line.wait} would wait forever: "
                                       f"{publisher.get_subscription_count()} subscriptions matched in {max_wait:g} s")
                time.sleep(POLL)  # ros2cli polls the count at this interval
                waited += POLL
            msg = kind()
            fill(msg, line.values)
            matched = publisher.get_subscription_count()
            publisher.publish(msg)
            time.sleep(line.keep_alive)  # ros2cli's --keep-alive: "for the message to reach the wire"
            return matched
        finally:
            executor.shutdown(timeout_sec=0.0)
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
