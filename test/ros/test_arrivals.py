"""intake.Arrivals: a loop that drains its own subscriptions sleeps until a
message waits or its timeout passes (the lockstep slider's wait)."""

from __future__ import annotations

import time
import uuid
from collections.abc import Iterator
from typing import Any

import pytest
from std_msgs.msg import Float64

from friction_sim.ros.intake import Arrivals, PolledGroup, take_all


@pytest.fixture
def node(ros: None) -> Iterator[Any]:
    import rclpy

    made = rclpy.create_node(f"arrivals_{uuid.uuid4().hex[:8]}")
    yield made
    made.destroy_node()


def _pair(node: Any) -> tuple[Any, Any]:
    topic = f"arrivals_{uuid.uuid4().hex[:8]}"
    subscription = node.create_subscription(Float64, topic, lambda msg: None, 10, callback_group=PolledGroup())
    publisher = node.create_publisher(Float64, topic, 10)
    deadline = time.monotonic() + 10.0
    while publisher.get_subscription_count() < 1:  # discovery: the thing itself, not a fixed time
        assert time.monotonic() < deadline, "the subscription was never matched"
        time.sleep(0.001)  # poll interval
    return subscription, publisher


def test_a_waiting_message_ends_the_wait_and_is_still_there_to_take(node: Any) -> None:
    subscription, publisher = _pair(node)
    arrivals = Arrivals([subscription], node.context)
    publisher.publish(Float64(data=2.5))
    started = time.monotonic()
    arrivals.wait(30.0)  # a message is (or is about to be) waiting: long before the timeout
    assert time.monotonic() - started < 25.0
    assert [msg.data for msg in take_all(subscription, 10)] == [2.5], "the wait takes nothing itself"
    arrivals.destroy()


def test_without_a_message_the_wait_lasts_its_timeout(node: Any) -> None:
    subscription, _ = _pair(node)
    arrivals = Arrivals([subscription], node.context)
    started = time.monotonic()
    arrivals.wait(0.2)
    assert time.monotonic() - started >= 0.19
    arrivals.destroy()
