"""The nodes' parameters: declared from the one vocabulary, and every refusal reported.

:func:`declare_settings` declares a node's settings (core/model/spec.py) with
descriptors that carry their ranges; :func:`watch_parameter_refusals` makes the
values rclpy itself refuses (descriptor ranges, types, read-only, undeclared)
warned about and counted like every other refusal.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from friction_sim.core.model.spec import Setting
from friction_sim.errors import FrictionSimError


def descriptor(setting: Setting) -> ParameterDescriptor:
    """The ROS parameter descriptor of a setting of the one vocabulary
    (:mod:`friction_sim.core.model.spec`): its description with the unit, its range
    (rclpy refuses a value outside it before any callback runs), and read-only
    for a setting that takes effect at start-up only."""
    unit = f" [{setting.unit}]" if setting.dimensioned else ""
    text = f"{setting.description}{unit}" + (f"; {setting.rule}" if setting.rule else "")
    result = ParameterDescriptor(description=text, read_only=setting.start_only)
    if setting.kind is float and setting.low is not None and setting.high is not None:
        result.floating_point_range = [FloatingPointRange(from_value=setting.low, to_value=setting.high, step=0.0)]
    elif setting.kind is int and setting.low is not None and setting.high is not None:
        result.integer_range = [IntegerRange(from_value=int(setting.low), to_value=int(setting.high), step=1)]
    if setting.choices:  # rclpy has no choice constraint: the node's set callback refuses other values
        result.additional_constraints = f"one of: {', '.join(setting.choices)}"
    return result


def declare_settings(node: Node, settings: Mapping[str, Setting]) -> dict[str, Any]:
    """Declare every setting as a parameter of ``node`` (default, descriptor)
    and return the values in force (the defaults, or the overrides given at start)."""
    for name, setting in settings.items():
        node.declare_parameter(name, setting.default, descriptor(setting))
    return {name: node.get_parameter(name).value for name in settings}


#: What a refusal reports: the parameter's name, the value refused, the one-line reason.
RefusalCallback = Callable[[str, Any, str], None]
_TYPE_WORDS = {
    Parameter.Type.BOOL: "true or false", Parameter.Type.INTEGER: "an integer",
    Parameter.Type.DOUBLE: "a floating-point number", Parameter.Type.STRING: "a string",
}


def descriptor_refusal(node: Node, parameter: Parameter, settings: Mapping[str, Setting]) -> str:
    """Why rclpy will refuse to set ``parameter`` on ``node`` before any
    callback of ours runs ('' if it will not), in the words of the one
    vocabulary (field, value, limit).

    This mirrors rclpy's own checks (Jazzy ``Node._apply_descriptor``: read-only,
    type, then integer or floating-point range with rclpy's edge tolerance;
    and undeclared parameters), through public API; a test holds it to
    rclpy's verdict.
    """
    name, value, kind = parameter.name, parameter.value, parameter.type_
    if not node.has_parameter(name):
        return f"{name} = {value!r} rejected: no such parameter (known: {', '.join(settings) or 'none'})"
    descriptor = node.describe_parameter(name)
    setting = settings.get(name)
    if descriptor.read_only:
        return f"{name} = {value!r} rejected: read-only, read at start-up only (--ros-args -p {name}:=...)"
    if descriptor.dynamic_typing:
        return ""
    if kind == Parameter.Type.NOT_SET:
        return f"{name} rejected: a declared parameter cannot be unset"
    expected = Parameter.Type(descriptor.type)
    if kind != expected:
        hint = " (write 2.0, not 2)" if expected == Parameter.Type.DOUBLE and kind == Parameter.Type.INTEGER \
            else ""
        return (f"{name} = {value!r} rejected: must be {_TYPE_WORDS.get(expected, expected.name.lower())}"
                f", not {_TYPE_WORDS.get(kind, kind.name.lower())}{hint}")
    if kind == Parameter.Type.DOUBLE and descriptor.floating_point_range:
        span = descriptor.floating_point_range[0]
        low, high = min(span.from_value, span.to_value), max(span.from_value, span.to_value)
        tolerance = Node.PARAM_REL_TOL
        if math.isclose(value, low, rel_tol=tolerance) or math.isclose(value, high, rel_tol=tolerance):
            return ""
        if not low < value < high:
            return _range_refusal(name, value, setting, low, high)
    if kind == Parameter.Type.INTEGER and descriptor.integer_range:
        span_i = descriptor.integer_range[0]
        low_i, high_i = min(span_i.from_value, span_i.to_value), max(span_i.from_value, span_i.to_value)
        if value in (low_i, high_i):
            return ""
        if not low_i < value < high_i or (span_i.step and (value - low_i) % span_i.step):
            return _range_refusal(name, value, setting, low_i, high_i)
    return ""


def _range_refusal(name: str, value: Any, setting: Setting | None, low: float, high: float) -> str:
    """The spec's own refusal of an out-of-range value, or the descriptor's range in words."""
    if setting is not None:
        try:
            setting.check(value)
        except FrictionSimError as error:
            return str(error)
    return f"{name} = {value!r} rejected: must be in [{low:g}, {high:g}]"


def watch_parameter_refusals(node: Node, settings: Mapping[str, Setting], on_refused: RefusalCallback) -> None:
    """Warn about (one line each) and report to ``on_refused`` every parameter
    value that rclpy refuses before the node's own callbacks see it: NaN or
    out of its range, wrong type, read-only, undeclared.  (The node counts it
    with its other refusals.)  Each is warned: a parameter set costs a service
    round trip, far more than the warning, so no throttle is needed here.

    rclpy checks a set (one ``ros2 param set``, or an atomic set) parameter
    by parameter and refuses it at the first failure; so does this, through a
    pre-set callback that changes nothing.
    """
    logger = node.get_logger()

    def check(parameters: list[Parameter]) -> list[Parameter]:
        for parameter in parameters:
            why = descriptor_refusal(node, parameter, settings)
            if why:
                logger.warning(f"parameter {why}; value kept")
                on_refused(parameter.name, parameter.value, why)
                break
        return parameters

    node.add_pre_set_parameters_callback(check)
