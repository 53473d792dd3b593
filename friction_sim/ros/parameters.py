"""The nodes' parameters: declared from the one vocabulary, and every refusal reported.

:func:`declare_settings` declares a node's settings (core/model/spec.py) with
descriptors that carry their ranges, so rclpy refuses a value outside them
with its own reason; :func:`watch_parameter_refusals` makes the sets rclpy
refuses (descriptor ranges, types, read-only, undeclared) warned about and
counted like every other refusal, without judging them again.
"""

from __future__ import annotations

import re
import threading
from collections.abc import Callable, Mapping
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterNotDeclaredException
from rclpy.node import Node
from rclpy.parameter import Parameter

from friction_sim.core.model.spec import Setting


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


def watch_parameter_refusals(node: Node, settings: Mapping[str, Setting], on_refused: RefusalCallback) -> None:
    """Warn about (one line each) and report to ``on_refused`` every parameter set
    that rclpy itself refuses before the node's own callbacks see it: a value out
    of its descriptor's range (NaN included), of the wrong type, read-only, or a
    parameter not declared.  (The node counts it with its other refusals.)  Each
    is warned: a parameter set costs a service round trip, far more than the
    warning, so no throttle is needed here.

    rclpy decides (Jazzy ``Node._apply_descriptor``: read-only, type, then the
    integer or floating-point range, the latter with its edge tolerance
    ``PARAM_REL_TOL``) and answers with its own reason, which names the field,
    the value and the limit; nothing here repeats those checks.  To tell that it
    was rclpy that refused, the node's set calls (rclpy's parameter services call
    ``set_parameters_atomically``) pass through :class:`_RefusalWatch`, which sees
    whether the set reached the on-set callbacks: a refusal that did not is
    rclpy's.  A value rclpy lets through its tolerance, the choices of a text
    setting and every cross-field rule are the node's own on-set callback's,
    which refuses (and counts) with its reason.
    """
    _RefusalWatch(node, settings, on_refused)


class _RefusalWatch:
    """Reports the sets rclpy refuses (see :func:`watch_parameter_refusals`)."""

    def __init__(self, node: Node, settings: Mapping[str, Setting], on_refused: RefusalCallback) -> None:
        self.node, self.settings, self.on_refused = node, settings, on_refused
        self._passed = threading.local()  # per set call: whether rclpy's checks let it through
        self._placed = False
        self._lock = threading.Lock()
        own = node.set_parameters_atomically

        def set_parameters_atomically(parameters: list[Parameter]) -> SetParametersResult:
            return self._watched(own, parameters)

        def set_parameters(parameters: list[Parameter]) -> list[SetParametersResult]:
            # as rclpy's own: each parameter set atomically, in order
            return [set_parameters_atomically([parameter]) for parameter in parameters]

        # The node's public set calls, watched (the nodes and rclpy's parameter services call them).
        setattr(node, "set_parameters_atomically", set_parameters_atomically)  # noqa: B010 - this node's own
        setattr(node, "set_parameters", set_parameters)  # noqa: B010 - as above
        node.add_pre_set_parameters_callback(self._starting)

    def _starting(self, parameters: list[Parameter]) -> list[Parameter]:
        """A set begins (rclpy's pre-set callback, before its checks).  The first time,
        :meth:`_through` is put first among the on-set callbacks (rclpy runs the latest
        added first): ahead of the node's own, which it adds after this watch."""
        if not self._placed:
            with self._lock:
                if not self._placed:
                    self.node.add_on_set_parameters_callback(self._through)
                    self._placed = True
        return parameters

    def _through(self, parameters: list[Parameter]) -> SetParametersResult:
        """rclpy's checks let the set through (the first on-set callback): the node's to judge."""
        self._passed.value = True
        return SetParametersResult(successful=True)

    def _watched(self, own: Callable[[list[Parameter]], SetParametersResult],
                 parameters: list[Parameter]) -> SetParametersResult:
        self._passed.value = False
        try:
            result = own(parameters)
        except ParameterNotDeclaredException:
            unknown = next(parameter for parameter in parameters if not self.node.has_parameter(parameter.name))
            self._report(unknown.name, unknown.value, f"{unknown.name} = {unknown.value!r} rejected: no such "
                                                      f"parameter (known: {', '.join(self.settings) or 'none'})")
            raise
        if not result.successful and not self._passed.value:
            self._refused_by_rclpy(parameters, result.reason)
        return result

    def _refused_by_rclpy(self, parameters: list[Parameter], reason: str) -> None:
        """Report rclpy's refusal of a set, with its reason: of the parameter the reason
        names, or the only one; else of the whole set (a wrong type is not named)."""
        named = [parameter for parameter in parameters if re.search(rf"\b{re.escape(parameter.name)}\b", reason)]
        culprits = named[:1] or parameters
        if len(culprits) == 1:
            (parameter,) = culprits
            setting = self.settings.get(parameter.name)
            hint = " (write 2.0, not 2)" if setting is not None and setting.kind is float \
                and parameter.type_ == Parameter.Type.INTEGER else ""
            self._report(parameter.name, parameter.value,
                         f"{parameter.name} = {parameter.value!r} rejected: {reason}{hint}")
            return
        names = ", ".join(parameter.name for parameter in culprits)
        self._report(names, {parameter.name: parameter.value for parameter in culprits},
                     f"{names} = {', '.join(repr(parameter.value) for parameter in culprits)} rejected: {reason}")

    def _report(self, name: str, value: Any, why: str) -> None:
        self.node.get_logger().warning(f"parameter {why}; value kept")
        self.on_refused(name, value, why)
