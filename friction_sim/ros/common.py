"""What every friction_sim node shares: running it, and describing parameters.

:func:`run_node` is the ``main()`` shape of ros2/demos ``demo_nodes_py``:
Ctrl-C (SIGINT) and SIGTERM end the node with exit code 0, and a bad start-up
parameter is one line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import sys
import time
from typing import Callable, Sequence

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.callback_groups import CallbackGroup
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.subscription import Subscription

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


def float_descriptor(description: str, low: float, high: float) -> ParameterDescriptor:
    """A double parameter limited to [low, high]."""
    return ParameterDescriptor(
        description=description,
        floating_point_range=[FloatingPointRange(from_value=low, to_value=high, step=0.0)],
    )


def int_descriptor(description: str, low: int, high: int) -> ParameterDescriptor:
    """An integer parameter limited to [low, high]."""
    return ParameterDescriptor(
        description=description, integer_range=[IntegerRange(from_value=low, to_value=high, step=1)]
    )


def text_descriptor(description: str) -> ParameterDescriptor:
    return ParameterDescriptor(description=description)


def wall_ns() -> int:
    """The monotonic wall clock every node measures simulation time by."""
    return time.monotonic_ns()


def run_node(
    factory: Callable[[], Node | Sequence[Node]], args: Sequence[str] | None = None,
    *, prog: str = "friction_sim",
) -> int:
    """Initialise rclpy, build the node(s), spin until shut down; return the exit code."""
    rclpy.init(args=args)
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
