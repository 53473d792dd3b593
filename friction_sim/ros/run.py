"""Running a friction_sim node: ``main()``, ``--help``, exit codes, logging.

:func:`run_node` is the ``main()`` shape of ros2/demos ``demo_nodes_py``, with
``--help``: Ctrl-C (SIGINT) and SIGTERM end the node with exit code 0, a bad
start-up parameter is one line on stderr and exit code 2, a node that cannot
go on (:class:`NodeFault`) has said why on one line and exits with code 3,
never a traceback.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import textwrap
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import rclpy
import rclpy.logging
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.utilities import remove_ros_args

from friction_sim.core.model.commands import consumed_by
from friction_sim.core.model.spec import Setting
from friction_sim.errors import FrictionSimError, NodeFault, one_line
from friction_sim.ros.heap import limit_heap_arenas, run_heap
from friction_sim.ros.intake import LostMessages

RCLError = _rclpy.RCLError
#: Exit codes of the node executables (``slider``, ``controller``, ``friction-sim feeder``).
EXIT_OK = 0
EXIT_BAD_PARAMETER = 2
EXIT_FAULT = 3
EXIT_RECORDING_FAILED = 4
#: What each exit code means, for --help: every node's, then the slider's own.
_COMMON_EXITS = (f"{EXIT_OK} stopped by Ctrl-C or SIGTERM; {EXIT_BAD_PARAMETER} bad argument or start-up "
                 f"parameter")
CONTROLLER_EXIT_CODES = f"exit codes: {_COMMON_EXITS}; {EXIT_FAULT} an internal error stopped it (one line on stderr)"
SLIDER_EXIT_CODES = (
    f"exit codes: {_COMMON_EXITS}; {EXIT_FAULT} the simulation could not go on (reason logged); "
    f"{EXIT_RECORDING_FAILED} ran to the end but its recording failed (reason logged; the part written is "
    "readable)")
#: ``feeder`` runs both: the slider's codes (the controller's 3 is an error that stops the process too).
FEEDER_EXIT_CODES = SLIDER_EXIT_CODES
#: Line width of --help.
HELP_WIDTH = 100


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


class QuietNode(Node):
    """A node whose publishers and subscriptions have no rclpy event handlers unless given some.
    rclpy's default ones (a warning on an incompatible QoS) are each a waitable that its Python
    executor visits at every wake-up: 22 of them on the controller, which in lockstep wakes for
    every sample it answers.  (``ros2 topic info --verbose`` still shows each endpoint's QoS.)"""

    def create_publisher(self, *args: Any, **kwargs: Any) -> Any:
        kwargs.setdefault("event_callbacks", PublisherEventCallbacks(use_default_callbacks=False))
        return super().create_publisher(*args, **kwargs)

    def create_subscription(self, *args: Any, **kwargs: Any) -> Any:
        kwargs.setdefault("event_callbacks", SubscriptionEventCallbacks(use_default_callbacks=False))
        return super().create_subscription(*args, **kwargs)


class SpinThread:
    """A node spun by an executor of its own, in a thread of its own, until :meth:`stop`:
    in a lockstep experiment the controller answers every window, and in the experiment's
    executor each answer would wait for the driver's and the slider's callbacks and the
    rebuild of their wait set.  An error ends the spin and is said once (the slider then
    names the silent controller after its lockstep_timeout), never a thread dying in silence."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self._executor = SingleThreadedExecutor()
        self._executor.add_node(node)
        self._stop = threading.Event()
        #: Triggered by :meth:`stop`: a callback ready ends the executor's wait (a wake of the executor
        #: alone does not: it waits on until something is ready or its timeout).
        self._wake = node.create_guard_condition(lambda: None)
        self._thread = threading.Thread(target=self._spin, name=f"{node.get_name()}_spin", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set():
            try:
                self._executor.spin_once(timeout_sec=0.05)
            except Exception as error:  # noqa: BLE001 - said, never a thread that dies in silence
                if isinstance(error, RuntimeError) and LostMessages.lost(error):
                    continue
                print(f"{self.node.get_name()}: its executor stopped: {one_line(error, with_type=True)}",
                      file=sys.stderr)
                return

    def stop(self) -> None:
        """End the spin (the node stays: its owner destroys it)."""
        self._stop.set()
        self._wake.trigger()  # (out of its wait now, not at its timeout)
        self._thread.join(timeout=5.0)
        self.node.destroy_guard_condition(self._wake)
        self._executor.shutdown(timeout_sec=0.0)


def node_help(description: str, settings: Mapping[str, Setting], consumer: str,
              publications: Sequence[tuple[str, str, str]], exit_codes: str,
              more_subscriptions: Sequence[tuple[str, str, str]] = ()) -> str:
    """The ``--help`` text of a node after its usage line: what it does, its
    parameters with default, unit, range and meaning (from the one vocabulary),
    its topics (name, type, meaning: the command topics ``consumer`` takes,
    from the command table, then ``more_subscriptions``) and its own ``exit_codes``."""
    subscriptions = [(entry.name, entry.message_type, entry.description) for entry in consumed_by(consumer)]
    subscriptions += more_subscriptions
    def wrapped(text: str, indent: str = "") -> list[str]:
        return textwrap.wrap(text, width=HELP_WIDTH, initial_indent=indent, subsequent_indent=indent)

    lines = [*wrapped(description.strip()), "",
             "parameters (--ros-args -p NAME:=VALUE or --params-file FILE; ros2 param set at run time):"]
    for setting in settings.values():
        unit = setting.unit_suffix
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
    lines += ["", *wrapped(exit_codes)]
    return "\n".join(lines)


def wall_ns() -> int:
    """The monotonic wall clock every node measures simulation time by."""
    return time.monotonic_ns()


class _InterruptFlag:
    """Python's SIGINT handler, which raises KeyboardInterrupt, plus a flag that
    it did: the interrupt may reach the node's loop disguised as another error
    (see :func:`run_node`).  Installed from the main thread only (elsewhere it
    cannot be, and the flag stays down); :meth:`restore` puts the previous back."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self._previous: Any = None
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._on_interrupt)

    def _on_interrupt(self, signum: int, frame: Any) -> None:
        self._event.set()
        raise KeyboardInterrupt

    def is_set(self) -> bool:
        return self._event.is_set()

    def restore(self) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None


#: More lost messages than this within :data:`LOST_WINDOW` seconds are no transient: the node stops.
MAX_LOST = 10
LOST_WINDOW = 10.0


def _spin(executor: SingleThreadedExecutor, interrupted: _InterruptFlag) -> None:
    """Spin until shut down.  A message rclpy took but could not convert, while
    no signal is on its way, is lost and counted (diagnostics ``messages_lost``,
    :class:`~friction_sim.ros.intake.LostMessages`) and the node spins on;
    more than :data:`MAX_LOST` of them within :data:`LOST_WINDOW` s end it as a fault."""
    recent: list[float] = []
    while True:
        try:
            executor.spin()
            return
        except RuntimeError as error:
            if interrupted.is_set() or not rclpy.ok() or not LostMessages.lost(error):
                raise
            now = time.monotonic()
            recent = [t for t in recent if now - t < LOST_WINDOW] + [now]
            if len(recent) > MAX_LOST:
                raise


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
    interrupted = _InterruptFlag()
    limit_heap_arenas()  # (before the middleware's threads start)
    rclpy.init(args=argv)  # (rclpy's own handler chains to ours)
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
        with run_heap():  # (the collector walks what the node makes, not the process's start-up)
            _spin(executor, interrupted)
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
        # A SIGINT's KeyboardInterrupt raised while rclpy's bindings convert an
        # argument comes out as their error ("Unable to convert call argument '0'
        # to Python object", seen in CI), and after a signal has shut the context
        # down the bindings may fail on the way out: both are a normal shutdown.
        if not interrupted.is_set() and rclpy.ok():
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
        interrupted.restore()
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
