"""What both nodes share (friction_sim/ros/{run,parameters,intake,graph}.py): what rclpy's own
parameter checks refuse is reported once each, in rclpy's words, and nothing else; refused input
is warned about on a cheap throttle; and run_node's exit codes."""

from __future__ import annotations

import itertools
import math
import os
import signal
import time
from collections.abc import Iterator
from typing import Any

import pytest
from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import ParameterNotDeclaredException
from rclpy.node import Node
from rclpy.parameter import Parameter

from friction_sim.core.model import spec
from friction_sim.errors import FrictionSimError
from friction_sim.ros import intake
from friction_sim.ros.intake import ThrottledWarning
from friction_sim.ros.parameters import declare_settings, watch_parameter_refusals
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
    """A node with the slider's parameters and descriptors, and no callbacks of ours: rclpy's verdicts."""
    node = Node("bare", namespace=namespace())
    declare_settings(node, spec.SLIDER_NODE)
    yield node
    node.destroy_node()


class Watched(Node):
    """A node with the slider's parameters, the refusal watch, and an on-set callback of its own,
    added after the watch as the nodes add theirs: it refuses a landing_friction outside the
    choices (as the slider does), which the watch must leave to it."""

    def __init__(self) -> None:
        super().__init__("watched", namespace=namespace())
        declare_settings(self, spec.SLIDER_NODE)
        self.reports: list[tuple[str, Any, str]] = []
        self.own_refusals = 0
        watch_parameter_refusals(self, spec.SLIDER_NODE, lambda *report: self.reports.append(report))
        self.add_on_set_parameters_callback(self._own)

    def _own(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name == "landing_friction" and parameter.value not in spec.LANDING_FRICTION.choices:
                self.own_refusals += 1
                return SetParametersResult(successful=False, reason="the node's own")
        return SetParametersResult(successful=True)

    def why(self, name: str, value: Any) -> str:
        """What the watch reported of setting ``name`` to ``value`` ('' if nothing)."""
        before = len(self.reports)
        self.set_parameters([Parameter(name, value=value)])
        assert len(self.reports) - before <= 1, "a refusal is reported once"
        return self.reports[-1][2] if len(self.reports) > before else ""


@pytest.fixture
def watched(ros: None) -> Iterator[Watched]:
    node = Watched()
    yield node
    node.destroy_node()


def test_the_watch_reports_exactly_what_rclpy_refuses(bare: Node, watched: Watched) -> None:
    """Each value rclpy's own checks refuse (on a node without callbacks) is reported once,
    with rclpy's own reason; what rclpy lets through is not, the node's own refusals included."""
    checked = 0
    for (name, _setting), value in itertools.chain(
            itertools.product(spec.SLIDER_NODE.items(), CANDIDATES),
            ((item, value) for item in spec.SLIDER_NODE.items() for value in edges(item[1]))):
        (verdict,) = bare.set_parameters([Parameter(name, value=value)])
        own_before = watched.own_refusals
        (answer,) = watched.set_parameters([Parameter(name, value=value)])
        own = watched.own_refusals - own_before
        assert answer.successful == (verdict.successful and not own), (name, value)
        if verdict.successful:
            assert len(watched.reports) == checked, (name, value, watched.reports[-1:])
            continue
        checked += 1
        assert not own, "rclpy refused it before the node's own callback"
        assert len(watched.reports) == checked, (name, value, verdict.reason)
        assert answer.reason == verdict.reason, "the caller hears rclpy's own reason"
        assert watched.reports[-1] == (name, value, f"{name} = {value!r} rejected: {verdict.reason}" + (
            " (write 2.0, not 2)" if type(value) is int and _setting.kind is float else ""))
    assert checked > 200
    assert watched.why("landing_friction", "sticky") == "" and watched.own_refusals >= 1, \
        "a string reaches the node's own check, which refuses it; the watch reports nothing"
    with pytest.raises(ParameterNotDeclaredException):
        watched.set_parameters_atomically([Parameter("no_such", value=1.0)])
    name, value, unknown = watched.reports[-1]
    assert (name, value) == ("no_such", 1.0) and "no such parameter" in unknown and "mass" in unknown


def test_an_atomic_set_rclpy_refuses_is_reported_once_naming_the_culprit(watched: Watched) -> None:
    result = watched.set_parameters_atomically([Parameter("mu", value=0.2), Parameter("mass", value=-1.0),
                                                Parameter("gravity", value=-1.0)])
    assert not result.successful and len(watched.reports) == 1
    name, value, why = watched.reports[0]
    assert (name, value) == ("mass", -1.0) and why.startswith("mass = -1.0 rejected: ") and "1e-06" in why
    result = watched.set_parameters_atomically([Parameter("mu", value=0.2), Parameter("mass", value=2)])
    assert not result.successful and len(watched.reports) == 2
    assert watched.reports[1][0] == "mu, mass", "rclpy's wrong-type reason names no parameter: the set is named"
    assert watched.set_parameters_atomically([Parameter("mu", value=0.2), Parameter("mass", value=2.0)]).successful
    assert len(watched.reports) == 2


def test_refusals_name_field_value_and_limit(watched: Watched) -> None:
    """rclpy's reason names the field, the value and the limit; the report begins with
    the field and the value in the vocabulary's words."""
    nan = watched.why("mass", math.nan)
    assert nan.startswith("mass = nan rejected: ") and "Min: 1e-06" in nan and "Max: 1000000.0" in nan
    window = watched.why("mean_window_periods", 0)
    assert window.startswith("mean_window_periods = 0 rejected: ") and "Min: 1, Max: 10000" in window
    assert watched.why("mass", 2).startswith("mass = 2 rejected: Wrong parameter type")
    assert watched.why("mass", 2).endswith("(write 2.0, not 2)")
    assert watched.why("publish_clock", "yes").startswith("publish_clock = 'yes' rejected: Wrong parameter type")
    assert "read-only" in watched.why("log_rate", 10.0) and "log_rate = 10.0" in watched.why("log_rate", 10.0)
    restitution = watched.why("restitution", 1.0)
    assert restitution.startswith("restitution = 1.0 rejected: ") and "Max: 0.99" in restitution
    angle = watched.why("excitation_angle", 0.0)
    assert angle.startswith("excitation_angle = 0.0 rejected: ") and "Min: 0.1" in angle
    assert watched.why("landing_friction", 1.0).startswith("landing_friction = 1.0 rejected: Wrong parameter type")


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
