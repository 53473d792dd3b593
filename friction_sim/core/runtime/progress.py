"""What a long job says while it runs: one progress line, the protocol every job writes to.

A sweep, a recording being replayed and an experiment in progress each make
their own text; the command line owns the terminal and passes them one
writer (:class:`friction_sim.cli.progress.TerminalProgress`), which redraws
the line on a terminal and prints a line now and then otherwise.
"""

from __future__ import annotations

from typing import Protocol


class Progress(Protocol):
    """A progress line.  ``show`` puts ``text`` up (on a terminal at once, else
    a line at most every so often, or when ``step`` differs from the step last
    printed; ``final``: always); ``note`` says a line of its own; ``close`` ends
    the line."""

    def show(self, text: str, *, step: int | None = None, final: bool = False) -> None: ...

    def note(self, message: str) -> None: ...

    def close(self) -> None: ...


__all__ = ["Progress"]
