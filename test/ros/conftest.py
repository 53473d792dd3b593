"""Fixtures of the ROS node tests (rclpy is imported here, never by test/conftest.py)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from friction_sim.core.model.commands import Outcome
from friction_sim.ros.slider import SliderNode

from ros_harness import CommandLog, Probe, namespace


@pytest.fixture
def rig(ros: None) -> Iterator[tuple[SliderNode, Probe, list[Outcome]]]:
    """An in-process slider node in a fresh namespace, a probe connected to it,
    and the outcomes of every command it took."""
    ns = namespace()
    node = SliderNode(namespace=ns)
    outcomes: list[Outcome] = []
    node.sinks.append(CommandLog(outcomes))
    probe = Probe(ns, node)
    probe.wait_for_connection()
    yield node, probe, outcomes
    probe.close()
    node.destroy_node()
