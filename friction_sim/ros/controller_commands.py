"""How the controller node takes its command topics: in batches.

While the node is quiet, a command wakes it at once; after each batch the
command topics are polled every :data:`COMMAND_HOLD_OFF` until they are quiet
again.  The commands of a batch are handed over in the order they arrived (by
their arrival stamps), so a flood of commands costs one small batch per
hold-off (at most the queue depth per topic), not an executor wake-up and a
control decision per message.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from friction_sim.core.model.commands import CONTROLLER, consumed_by
from friction_sim.io.messages import message_class
from friction_sim.ros.intake import PolledGroup, arrival, take_with_info

#: After a batch of commands, the command topics are polled this often [s]
#: until they are quiet; then a command wakes the node at once again.
COMMAND_HOLD_OFF = 0.02
#: Commands kept per topic (a subscription's queue).
QOS_DEPTH = 10
Guard = Callable[[str, Callable[..., Any]], Callable[..., Any]]
Batch = list[tuple[str, Any]]


class CommandBatches:
    """The command topics of the controller (target_speed, drive_force,
    excitation_frequency), handed to ``apply`` in batches (see the module);
    ``guarded`` wraps each callback so that an error in it is reported."""

    def __init__(self, node: Node, apply: Callable[[Batch], None], guarded: Guard) -> None:
        self._apply = apply
        self._gate = PolledGroup(open=True)
        self._subscriptions = [
            (entry.name, node.create_subscription(
                message_class(entry.message_type), entry.name,
                # rclpy passes the message info to a callback of two parameters (it inspects the
                # signature); its annotation names only the one-parameter kind.
                self._callback(entry.name, guarded),  # type: ignore[arg-type]
                QOS_DEPTH, callback_group=self._gate))
            for entry in consumed_by(CONTROLLER)
        ]
        self._hold_off = node.create_timer(COMMAND_HOLD_OFF, guarded("command polling", self._poll),
                                           clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._hold_off.cancel()

    @property
    def polling(self) -> bool:
        """True while the command topics are polled every hold-off (after a
        batch); False while the node is quiet and a command wakes it at once."""
        return not self._gate.open or not self._hold_off.is_canceled()

    def _callback(self, name: str, guarded: Guard) -> Callable[[Any, Any], None]:
        """The executor's callback for command topic ``name`` (two parameters:
        rclpy then passes the message info too, with the arrival time)."""
        run = guarded(f"{name} callback", functools.partial(self._first, name))

        def on_command(msg: Any, info: Any) -> None:
            run(msg, info)

        return on_command

    def _first(self, name: str, msg: Any, info: Any) -> None:
        """The first command after a quiet spell: take it and whatever else
        waits, apply them as one batch in the order they came, and shut the
        gate for a hold-off."""
        waiting = sorted([(arrival(info), name, msg), *self._waiting()], key=lambda item: item[0])
        self._gate.open = False
        self._hold_off.reset()
        self._apply([(topic, message) for _, topic, message in waiting])

    def _poll(self) -> None:
        """Every hold-off while the gate is shut: apply what came meanwhile, or
        open the gate again if nothing did."""
        waiting = sorted(self._waiting(), key=lambda item: item[0])
        if waiting:
            self._apply([(topic, message) for _, topic, message in waiting])
        else:
            self._hold_off.cancel()
            self._gate.open = True  # a message arriving from now on wakes the executor

    def _waiting(self) -> list[tuple[int, str, Any]]:
        """Every command waiting on the command topics (at most the queue depth
        each: the subscriptions keep the latest QOS_DEPTH) as (arrival, topic, message)."""
        return [(arrival(info), name, message) for name, subscription in self._subscriptions
                for message, info in take_with_info(subscription, QOS_DEPTH)]


__all__ = ["COMMAND_HOLD_OFF", "CommandBatches"]
