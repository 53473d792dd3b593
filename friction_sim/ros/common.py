"""What every friction_sim node shares: running it, and describing parameters.

:func:`run_node` is the ``main()`` shape of ros2/demos ``demo_nodes_py``:
Ctrl-C (SIGINT) and SIGTERM end the node with exit code 0, and a bad start-up
parameter is one line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.callback_groups import CallbackGroup
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.subscription import Subscription

from friction_sim.core.spec import Setting
from friction_sim.errors import FrictionSimError

RCLError = _rclpy.RCLError
EXIT_OK = 0
EXIT_BAD_PARAMETER = 2


class PolledGroup(CallbackGroup):
    """A callback group no executor ever runs: its subscriptions are drained by
    their owner with :func:`take_all`, at a time of the owner's choosing.

    The slider takes its commands this way at the start of each tick, so a
    flood of commands costs a bounded amount of work per tick instead of an
    executor wake-up (and a wait-set rebuild in Python) per message.
    """

    def can_execute(self, entity: object) -> bool:
        return False

    def beginning_execution(self, entity: object) -> bool:
        return False

    def ending_execution(self, entity: object) -> None:
        return None


def take_all(subscription: Subscription, limit: int) -> list[object]:
    """Take up to ``limit`` waiting messages from ``subscription``, oldest first
    (rclpy's executor takes messages with the same call)."""
    messages = []
    handle = subscription.handle
    for _ in range(limit):
        with handle:
            taken = handle.take_message(subscription.msg_type, subscription.raw)
        if taken is None:
            break
        messages.append(taken[0])
    return messages


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
    return result


def declare_settings(node: Node, settings: Mapping[str, Setting]) -> dict[str, Any]:
    """Declare every setting as a parameter of ``node`` (default, descriptor)
    and return the values in force (the defaults, or the overrides given at start)."""
    for name, setting in settings.items():
        node.declare_parameter(name, setting.default, descriptor(setting))
    return {name: node.get_parameter(name).value for name in settings}


def wall_ns() -> int:
    """The monotonic wall clock every node measures simulation time by."""
    return time.monotonic_ns()


def run_node(
    factory: Callable[[], Node | Sequence[Node]], args: Sequence[str] | None = None,
    *, prog: str = "friction_sim",
) -> int:
    """Initialise rclpy, build the node(s), spin until shut down; return the exit code."""
    rclpy.init(args=list(args) if args is not None else None)
    nodes: list[Node] = []
    executor = SingleThreadedExecutor()
    try:
        made = factory()
        nodes = list(made) if isinstance(made, Sequence) else [made]
        for node in nodes:
            executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RCLError:
        # A signal shut the context down between the executor's ok() check and
        # its next wait set: that is a normal shutdown too.
        if rclpy.ok():
            raise
    except (FrictionSimError, ParameterException) as error:
        print(f"{prog}: error: {error}", file=sys.stderr)
        return EXIT_BAD_PARAMETER
    finally:
        for node in nodes:
            node.destroy_node()
        executor.shutdown(timeout_sec=0.0)
        rclpy.try_shutdown()
    return EXIT_OK
