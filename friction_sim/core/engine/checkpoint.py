"""A slider as it was, to put back exactly: what lets a change that fails half-way leave no trace.

The real-time slider takes every command under a guard (a checkpoint first,
then the change, then a check of the state it leaves); a failure restores
the checkpoint.  Kept apart from the slider itself: it knows nothing of the
physics, only how the slider's attributes are held.
"""

from __future__ import annotations

from collections import deque
from typing import Any


class Checkpoint:
    """An object's attributes as they were (a slider's:
    :meth:`~friction_sim.core.engine.single.Slider.checkpoint`), to put back if taking a change fails.

    The core's attributes are saved by reference (its records are immutable);
    its dicts are copied (a few entries); of its deques (the event and period
    logs, thousands of entries) only the last entry is remembered, and on
    restore whatever was appended after it is popped.  That costs about a
    microsecond, where copying the logs would cost twenty at every command.
    """

    __slots__ = ("attributes", "tails")

    def __init__(self, slider: object) -> None:
        self.attributes = dict(vars(slider))
        self.tails: dict[str, Any] = {}
        for name, value in self.attributes.items():
            if isinstance(value, (dict, list, set)):
                self.attributes[name] = value.copy()
            elif isinstance(value, deque):
                self.tails[name] = value[-1] if value else None

    def restore(self, slider: object) -> None:
        """Put the attributes back exactly; pop what was appended to the logs since."""
        for name, tail in self.tails.items():
            log: deque[Any] = self.attributes[name]
            while log and log[-1] is not tail:
                log.pop()
        vars(slider).clear()
        vars(slider).update(self.attributes)


__all__ = ["Checkpoint"]
