"""What both nodes share (friction_sim/ros/{run,parameters,intake,graph}.py): the mirror of rclpy's
own parameter checks agrees with rclpy, refused input is warned about on a
cheap throttle, and run_node's exit codes."""

from __future__ import annotations

import itertools
import math
import os
import signal
import time
from collections.abc import Iterator
from typing import Any

import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter

from friction_sim.core.model import spec
from friction_sim.errors import FrictionSimError
from friction_sim.ros import intake
from friction_sim.ros.intake import ThrottledWarning
from friction_sim.ros.parameters import declare_settings, descriptor_refusal
from friction_sim.ros.run import EXIT_BAD_PARAMETER, EXIT_FAULT, FaultSignal, run_node

from ros_harness import namespace

CANDIDATES: list[Any] = [
    math.nan, math.inf, -math.inf, 0.0, -0.0, 1e-300, 1e308, -1e308, 1.0, 0.5, 2.5, 50.0, 1e6, 1e9,
    0, 1, 2, 10_000, 10_001, -1, True, False, "text", "", [1.0, 2.0],
]


def edges(setting: spec.Setting) -> list[float]:
    """Values just inside and just outside the range, where rclpy's tolerance decides."""
    found: list[float] = []
    for bound in (setting.low, setting.high):
        if bound is not None:
            for factor in (1 - 2e-6, 1 - 5e-7, 1.0, 1 + 5e-7, 1 + 2e-6):
                found.append(bound * factor if bound else (factor - 1.0))
    return found


@pytest.fixture
def bare(ros: None) -> Iterator[Node]:
    """A node with the slider's parameters and descriptors, and no callbacks of ours."""
    node = Node("bare", namespace=namespace())
    declare_settings(node, spec.SLIDER_NODE)
    yield node
    node.destroy_node()


def test_the_mirror_of_rclpys_checks_agrees_with_rclpy(bare: Node) -> None:
    checked = 0
    for (name, _setting), value in itertools.chain(
            itertools.product(spec.SLIDER_NODE.items(), CANDIDATES),
            ((item, value) for item in spec.SLIDER_NODE.items() for value in edges(item[1]))):
        parameter = Parameter(name, value=value)
        verdict = bare._apply_descriptors([parameter], bare._descriptors, True)  # noqa: SLF001 - rclpy's own
        mirror = descriptor_refusal(bare, parameter, spec.SLIDER_NODE)
        assert bool(mirror) == (not verdict.successful), (name, value, mirror, verdict.reason)
        if mirror:
            assert mirror.startswith(name) and "rejected" in mirror, mirror
            checked += 1
    assert checked > 200
    unknown = descriptor_refusal(bare, Parameter("no_such", value=1.0), spec.SLIDER_NODE)
    assert "no such parameter" in unknown and "mass" in unknown


def test_refusals_name_field_value_and_limit_in_the_vocabularys_words(bare: Node) -> None:
    def why(name: str, value: Any) -> str:
        return descriptor_refusal(bare, Parameter(name, value=value), spec.SLIDER_NODE)

    assert why("mass", math.nan) == "mass = nan rejected: must be finite in [1e-06, 1e+06] kg"
    assert why("mean_window_periods", 0) == "mean_window_periods = 0 rejected: must be an integer in [1, 10000] periods"
    assert why("mass", 2) == ("mass = 2 rejected: must be a floating-point number, not an integer "
                              "(write 2.0, not 2)")
    assert why("publish_clock", "yes") == "publish_clock = 'yes' rejected: must be true or false, not a string"
    assert "read-only" in why("log_rate", 10.0) and "log_rate = 10.0" in why("log_rate", 10.0)


def test_the_general_models_descriptors_derive_from_the_spec(bare: Node) -> None:
    """Ranges of the new parameters come with their descriptors (rclpy refuses
    outside them); the string with choices states them (rclpy has no choice
    constraint: the node's set callback refuses the others, see test_slider_node)."""
    for name in ("static_ratio", "excitation_angle", "excitation_phase", "track_inclination", "restitution"):
        setting = spec.SLIDER_NODE[name]
        (span,) = bare.describe_parameter(name).floating_point_range
        assert (span.from_value, span.to_value) == (setting.low, setting.high), name
        assert bare.get_parameter(name).value == setting.default
    landing = bare.describe_parameter("landing_friction")
    assert landing.type == Parameter.Type.STRING.value and landing.additional_constraints == "one of: impulsive, none"
    assert bare.get_parameter("landing_friction").value == "impulsive"

    def why(name: str, value: Any) -> str:
        return descriptor_refusal(bare, Parameter(name, value=value), spec.SLIDER_NODE)

    assert why("restitution", 1.0) == "restitution = 1.0 rejected: must be in [0, 0.99]"
    assert why("excitation_angle", 0.0) == "excitation_angle = 0.0 rejected: must be in [0.1, 90] deg"
    assert why("landing_friction", 1.0) == ("landing_friction = 1.0 rejected: must be a string, "
                                            "not a floating-point number")
    assert why("landing_friction", "sticky") == "", "a string reaches the node's own check"


def test_the_throttled_warning_warns_once_per_interval_and_counts_the_rest(
        monkeypatch: pytest.MonkeyPatch) -> None:
    said: list[str] = []

    class Logger:
        def warning(self, text: str) -> None:
            said.append(text)

    now = [100.0]
    monkeypatch.setattr(intake.time, "monotonic", lambda: now[0])
    warn = ThrottledWarning(Logger(), interval=1.0)
    warn("first")
    for k in range(500):
        now[0] += 0.001
        warn(f"refused {k}")
    assert said == ["first"] and warn.suppressed == 500
    now[0] += 0.6
    warn("later")
    assert said[1] == "later (+500 more refused in the last 1 s, not shown)"
    assert warn.suppressed == 0


def test_run_node_exit_codes(ros: None) -> None:
    def bad() -> Node:
        raise FrictionSimError("mass = -1.0 rejected: must be > 0")

    # run_node initialises and shuts rclpy down itself: leave the module's context alone.
    import rclpy

    rclpy.try_shutdown()
    try:
        assert run_node(bad, ["test"]) == EXIT_BAD_PARAMETER
        assert run_node(lambda: _FaultyNode(), ["test"]) == EXIT_FAULT
        assert run_node(bad, ["test", "--help"]) == 0
        assert run_node(bad, ["test", "--no-such-flag"]) == EXIT_BAD_PARAMETER
        # An interrupt that reaches the loop disguised as another error (rclpy's bindings
        # report a KeyboardInterrupt raised while they convert an argument as their own
        # error) ends normally; the same error without an interrupt is a lost message
        # (test_lost_messages.py), and one every tick is no transient: an internal fault.
        assert run_node(lambda: _DisguisingNode(interrupt=True), ["test"]) == 0
        assert run_node(lambda: _DisguisingNode(interrupt=False), ["test"]) == EXIT_FAULT
    finally:
        rclpy.init()


class _DisguisingNode(Node):
    """From its first timer tick: an error as rclpy's bindings raise it when a
    SIGINT's KeyboardInterrupt comes during a conversion (after the SIGINT, with ``interrupt``)."""

    def __init__(self, interrupt: bool) -> None:
        super().__init__("disguising", namespace=namespace())
        self.interrupt = interrupt
        self.create_timer(0.05, self._tick)

    def _tick(self) -> None:
        try:
            if self.interrupt:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.5)  # (the handler raises KeyboardInterrupt here)
        except KeyboardInterrupt:
            pass
        raise RuntimeError("Unable to convert call argument '0' to Python object")


class _FaultyNode(Node):
    """Signals a fault from its first timer tick, as the slider's tick thread does."""

    def __init__(self) -> None:
        super().__init__("faulty", namespace=namespace())
        self.signal = FaultSignal(self)
        self.create_timer(0.05, self._tick)

    def _tick(self) -> None:
        if self.signal.claim("simulation fault at t = 1.0 s: x = inf"):
            self.signal.fire()
        assert not self.signal.claim("a second reason"), "a fault is claimed once"
