"""The one exception hierarchy of friction_sim.

Every error a user can trigger derives from :class:`FrictionSimError`, so the
CLI and the nodes can catch exactly these, print one line and go on, while
programming errors still surface as tracebacks during development.
"""

from __future__ import annotations

from typing import Any


class FrictionSimError(Exception):
    """Base class of every error friction_sim raises on purpose."""


class ParameterError(FrictionSimError, ValueError):
    """A parameter or input value is out of its valid range.

    ``field`` names the offending field, ``value`` quotes the rejected value and
    ``limit`` says in words what would have been accepted, so that a message
    shown to a user is complete on one line.
    """

    def __init__(self, field: str, value: Any, limit: str) -> None:
        self.field = field
        self.value = value
        self.limit = limit
        super().__init__(f"{field} = {_quote(value)} rejected: {limit}")


class RecordingError(FrictionSimError):
    """A recording cannot be written or read (missing, not MCAP, not ours)."""


class RecordingPathError(RecordingError):
    """A recording cannot be written where ``field`` (e.g. ``log_path``) says:
    a directory, a missing folder, no permission, a full disk.  ``reason``
    is the OS's reason (``[Errno 28] No space left on device``) or the rule."""

    def __init__(self, field: str, value: str, reason: str) -> None:
        self.field = field
        self.value = value
        self.reason = reason
        super().__init__(f"{field} = {_quote(value)} rejected: {reason}")


class LiveViewError(FrictionSimError):
    """The live view cannot serve where ``field`` (``foxglove_port`` or
    ``foxglove_address``) says: the port is taken, the address is not one
    of this machine's, the value is out of range.  ``reason`` is the
    server's or the OS's reason (``Address already in use (os error 98)``)
    or the rule."""

    def __init__(self, field: str, value: Any, reason: str) -> None:
        self.field = field
        self.value = value
        self.reason = reason
        super().__init__(f"{field} = {_quote(value)} rejected: {reason}")


class ScenarioError(FrictionSimError):
    """A scenario file that cannot be run, with where and why."""


class ExperimentError(FrictionSimError):
    """An experiment cannot start (its nodes do not answer or refuse settings)."""


class SimulationFault(FrictionSimError):
    """The exact core failed while advancing under inputs it had taken, or its
    state stopped being finite: the run cannot go on.  The message says when
    and why, on one line."""


class NodeFault(FrictionSimError):
    """A node cannot go on; it has logged why (one line).  The node's ``main``
    ends with exit code 3 (``friction_sim.ros.run.EXIT_FAULT``)."""


def one_line(error: BaseException, *, with_type: bool = False) -> str:
    """``error`` as one line for a user or a log: its first line, whitespace
    collapsed (the type's name when it says nothing), ``Type: text`` with
    ``with_type``."""
    lines = str(error).strip().splitlines()
    text = " ".join(lines[0].split()) if lines else ""
    if with_type:
        return f"{type(error).__name__}: {text}" if text else type(error).__name__
    return text or type(error).__name__


def _quote(value: Any) -> str:
    """Format a rejected value unambiguously (repr: 0.1 stays 0.1, nan, inf, 'text')."""
    return repr(value)
