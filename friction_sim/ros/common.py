"""What every friction_sim node shares: running it, describing its parameters,
and the checks both nodes make on what users send them.

:func:`run_node` is the ``main()`` shape of ros2/demos ``demo_nodes_py``, with
``--help``: Ctrl-C (SIGINT) and SIGTERM end the node with exit code 0, a bad
start-up parameter is one line on stderr and exit code 2, a node that cannot
go on (:class:`NodeFault`) has said why on one line and exits with code 3,
never a traceback.

:class:`ThrottledWarning` warns about refused input at most once a second at
the cost of one clock read per call (rclpy's own ``throttle_duration_sec``
costs about 0.18 ms per call even when it prints nothing, which a flood of
bad commands turns into a starved node).  :func:`watch_parameter_refusals`
makes the values rclpy itself refuses (descriptor ranges, types, read-only,
undeclared) warned about and counted like every other refusal.
:class:`NameWatch` warns while another node has the same fully qualified name.
"""

from __future__ import annotations

import argparse
import logging
import math
import sys
import textwrap
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import rclpy
import rclpy.logging
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.callback_groups import CallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.subscription import Subscription
from rclpy.utilities import remove_ros_args

from friction_sim.core.commands import consumed_by
from friction_sim.core.spec import Setting
from friction_sim.errors import FrictionSimError, NodeFault, one_line

RCLError = _rclpy.RCLError
#: Exit codes of the node executables (``slider``, ``controller``, ``friction-sim feeder``).
EXIT_OK = 0
EXIT_BAD_PARAMETER = 2
EXIT_FAULT = 3
EXIT_RECORDING_FAILED = 4
EXIT_CODES = (
    f"exit codes: {EXIT_OK} stopped by Ctrl-C or SIGTERM; {EXIT_BAD_PARAMETER} bad argument or start-up "
    f"parameter; {EXIT_FAULT} the simulation could not go on (reason logged); {EXIT_RECORDING_FAILED} ran "
    "to the end but its recording failed (reason logged; the part written is readable)"
)
#: Line width of --help.
HELP_WIDTH = 100
#: At most one warning about refused input per this many seconds (and node).
WARN_INTERVAL = 1.0


class FaultSignal:
    """Ends the executor that spins ``node`` with a :class:`NodeFault`, from any
    thread: a guard condition wakes the executor, whose callback raises it.

    A fault is reported once: :meth:`claim` is true for the first reason only;
    the node then says why (log, diagnostics) and calls :meth:`fire`.
    """

    def __init__(self, node: Node) -> None:
        self.reason = ""
        self._lock = threading.Lock()
        self._guard = node.create_guard_condition(self._raise)

    def claim(self, reason: str) -> bool:
        """Record ``reason``; False if a fault was claimed already."""
        with self._lock:
            if self.reason:
                return False
            self.reason = reason
            return True

    def fire(self) -> None:
        """Make the executor raise :class:`NodeFault` (run_node then exits with EXIT_FAULT)."""
        self._guard.trigger()

    def _raise(self) -> None:
        raise NodeFault(self.reason)


class ThrottledWarning:
    """``logger.warning`` at most once per ``interval`` seconds; the calls in
    between cost one monotonic clock read, and the next warning says how many
    it stood for."""

    def __init__(self, logger: Any, interval: float = WARN_INTERVAL) -> None:
        self._logger = logger
        self.interval = interval
        self._next = -math.inf
        self.suppressed = 0

    def __call__(self, text: str) -> None:
        now = time.monotonic()
        if now < self._next:
            self.suppressed += 1
            return
        self._next = now + self.interval
        if self.suppressed:
            text += f" (+{self.suppressed} more refused in the last {self.interval:g} s, not shown)"
            self.suppressed = 0
        self._logger.warning(text)


class PolledGroup(CallbackGroup):
    """A callback group whose subscriptions their owner drains itself (with
    :func:`take_all`), at a time of its choosing, while the group is shut;
    while :attr:`open`, a waiting message wakes the executor, which runs one
    callback of the group at a time.  rclpy leaves an entity whose group cannot
    execute out of its wait set, so a shut group costs the executor nothing.

    The slider's group is always shut: it takes its commands at the start of
    each tick, so a flood costs a bounded amount of work per tick instead of an
    executor wake-up (and a wait-set rebuild in Python) per message.  The
    controller opens its group while quiet and shuts it for a hold-off after
    each batch.
    """

    def __init__(self, *, open: bool = False) -> None:
        super().__init__()
        self.open = open
        self._busy = False

    def can_execute(self, entity: object) -> bool:
        return self.open and not self._busy

    def beginning_execution(self, entity: object) -> bool:
        if not self.open or self._busy:
            return False
        self._busy = True
        return True

    def ending_execution(self, entity: object) -> None:
        self._busy = False


def take_all(subscription: Subscription, limit: int) -> list[object]:
    """Take up to ``limit`` waiting messages from ``subscription``, oldest first."""
    return [message for message, _ in take_with_info(subscription, limit)]


def take_with_info(subscription: Subscription, limit: int) -> list[tuple[Any, dict[str, Any]]]:
    """Up to ``limit`` waiting (message, message info) pairs, oldest first
    (rclpy's executor takes messages with the same call; the info holds the
    arrival time, ``received_timestamp`` in ns)."""
    taken_all = []
    handle = subscription.handle
    for _ in range(limit):
        with handle:
            taken = handle.take_message(subscription.msg_type, subscription.raw)
        if taken is None:
            break
        taken_all.append((taken[0], taken[1]))
    return taken_all


def descriptor(setting: Setting) -> ParameterDescriptor:
    """The ROS parameter descriptor of a setting of the one vocabulary
    (:mod:`friction_sim.core.spec`): its description with the unit, its range
    (rclpy refuses a value outside it before any callback runs), and read-only
    for a setting that takes effect at start-up only."""
    unit = f" [{setting.unit}]" if setting.unit not in ("", "-") else ""
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


class NameWatch:
    """Warns while another node in the graph has ``node``'s fully qualified name.

    Two nodes with one name both answer the same parameter services and
    publish on the same topics (interleaved, stamps going backwards).  ROS 2
    does not prevent it, so the graph is checked after discovery had time to
    see the others (at ``first`` s) and then every ``period`` s; :attr:`problem`
    is the text diagnostics show while it lasts ('' otherwise).
    """

    def __init__(self, node: Node, period: float = 1.0, first: float = 0.5) -> None:
        self._node = node
        self.problem = ""
        self._period = period
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = node.create_timer(first, self._first, clock=steady)

    def _first(self) -> None:
        self._node.destroy_timer(self._timer)
        self._timer = self._node.create_timer(self._period, self.check,
                                              clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.check()

    def check(self) -> str:
        """Look at the graph now; warn when a namesake appears, say when it is gone."""
        node = self._node
        name, namespace = node.get_name(), node.get_namespace()
        count = sum(1 for n, ns in node.get_node_names_and_namespaces() if n == name and ns == namespace)
        fqn = node.get_fully_qualified_name()
        problem = ""
        if count > 1:
            others = "another node" if count == 2 else f"{count - 1} other nodes"
            problem = f"{others} named {fqn} in the graph: both take the same commands and parameter sets"
        if problem and not self.problem:
            node.get_logger().warning(f"{problem}; give this one another name (--ros-args -r __node:=NAME "
                                      "or -r __ns:=/NAMESPACE)")
        elif self.problem and not problem:
            node.get_logger().info(f"the name {fqn} is unique again")
        self.problem = problem
        return problem


def node_help(description: str, settings: Mapping[str, Setting], consumer: str,
              publications: Sequence[tuple[str, str, str]], more_subscriptions: Sequence[tuple[str, str, str]] = ()
              ) -> str:
    """The ``--help`` text of a node after its usage line: what it does, its
    parameters with default, unit, range and meaning (from the one vocabulary),
    its topics (name, type, meaning: the command topics ``consumer`` takes,
    from the command table, then ``more_subscriptions``) and its exit codes."""
    subscriptions = [(entry.name, entry.message_type, entry.description) for entry in consumed_by(consumer)]
    subscriptions += more_subscriptions
    def wrapped(text: str, indent: str = "") -> list[str]:
        return textwrap.wrap(text, width=HELP_WIDTH, initial_indent=indent, subsequent_indent=indent)

    lines = [*wrapped(description.strip()), "",
             "parameters (--ros-args -p NAME:=VALUE or --params-file FILE; ros2 param set at run time):"]
    for setting in settings.values():
        unit = f" {setting.unit}" if setting.unit not in ("", "-") else ""
        default = str(setting.default).lower() if isinstance(setting.default, bool) else repr(setting.default)
        limits = "; ".join(part for part in (setting.range_text(), setting.rule) if part)
        meaning = setting.description + ("; start-up only" if setting.start_only else "")
        lines.append(f"  {setting.name} = {default}{unit}")
        lines += wrapped(meaning + (f" [{limits}]" if limits else ""), "      ")
    for title, topics in (("subscriptions", subscriptions), ("publications", publications)):
        lines += ["", f"{title} (names relative: --ros-args -r __ns:=/NAMESPACE moves them):"]
        for topic, kind, meaning in topics:
            lines.append(f"  {topic} ({kind})")
            lines += wrapped(meaning, "      ")
    lines += ["", *wrapped(EXIT_CODES)]
    return "\n".join(lines)


def wall_ns() -> int:
    """The monotonic wall clock every node measures simulation time by."""
    return time.monotonic_ns()


def run_node(
    factory: Callable[[], Node | Sequence[Node]], args: Sequence[str] | None = None,
    *, prog: str = "friction_sim", help_text: str = "",
) -> int:
    """Initialise rclpy, build the node(s), spin until shut down; return the exit code.

    ``--help`` (before ``--ros-args``) prints ``help_text`` under a usage line
    and returns 0 without starting anything; any other argument outside
    ``--ros-args`` is refused (exit code 2).  A node may set ``exit_code``
    (read after ``destroy_node``) to end with a code other than 0.
    """
    argv = list(args) if args is not None else list(sys.argv)
    refused = _own_arguments(prog, argv, help_text)
    if refused is not None:
        return refused
    rclpy.init(args=argv)
    bridge_python_logging()
    nodes: list[Node] = []
    executor = SingleThreadedExecutor()
    code = EXIT_OK
    try:
        try:
            made = factory()
        except (FrictionSimError, ParameterException) as error:
            print(f"{prog}: error: {one_line(error)}", file=sys.stderr)
            return EXIT_BAD_PARAMETER
        nodes = list(made) if isinstance(made, Sequence) else [made]
        for node in nodes:
            executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except NodeFault:
        code = EXIT_FAULT  # the node has logged why
    except RCLError as error:
        # A signal shut the context down between the executor's ok() check and
        # its next wait set: that is a normal shutdown too.
        if rclpy.ok():
            print(f"{prog}: error: {one_line(error)}", file=sys.stderr)
            code = EXIT_FAULT
    except Exception as error:  # noqa: BLE001 - one line, never a traceback
        print(f"{prog}: internal error, stopping: {one_line(error)}", file=sys.stderr)
        code = EXIT_FAULT
    finally:
        for node in nodes:
            try:
                node.destroy_node()
            except Exception as error:  # noqa: BLE001 - the others must still be destroyed
                print(f"{prog}: error while stopping {node.get_name()}: {one_line(error)}", file=sys.stderr)
                code = code or EXIT_FAULT
        executor.shutdown(timeout_sec=0.0)
        rclpy.try_shutdown()
    return code or max((int(getattr(node, "exit_code", EXIT_OK)) for node in nodes), default=EXIT_OK)


class RosLogHandler(logging.Handler):
    """Python logging records (the io layer logs with :mod:`logging`: a failed
    recording, say) as ROS log lines, with the ROS format, severity filter and
    console output the nodes' own lines have."""

    _SEVERITIES = ((logging.ERROR, "error"), (logging.WARNING, "warning"), (logging.INFO, "info"))

    def emit(self, record: logging.LogRecord) -> None:
        try:
            logger = rclpy.logging.get_logger(record.name)
            severity = next((name for level, name in self._SEVERITIES if record.levelno >= level), "debug")
            getattr(logger, severity)(self.format(record))
        except Exception:  # noqa: BLE001 - logging must never raise into the code that logs
            self.handleError(record)


def bridge_python_logging(name: str = "friction_sim") -> None:
    """Route the ``name`` logger hierarchy into ROS logging (once per process):
    one line per record, instead of Python's bare last-resort line as well."""
    logger = logging.getLogger(name)
    if not any(isinstance(handler, RosLogHandler) for handler in logger.handlers):
        logger.addHandler(RosLogHandler())
        logger.setLevel(logging.INFO)
        logger.propagate = False


def _own_arguments(prog: str, argv: list[str], help_text: str) -> int | None:
    """Handle the arguments outside ``--ros-args``: None to go on, else the exit code."""
    parser = argparse.ArgumentParser(
        prog=prog, usage=f"{prog} [-h] [--ros-args [-r __ns:=/NAMESPACE] [-p NAME:=VALUE ...] "
                         "[--params-file FILE]]",
        description=help_text or None, formatter_class=argparse.RawDescriptionHelpFormatter)
    try:
        parser.parse_args(remove_ros_args(argv)[1:])
    except SystemExit as stop:  # --help (0) or an unknown argument (2, one line after the usage)
        return int(stop.code or 0)
    return None

