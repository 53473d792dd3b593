"""The one progress-line writer of the command line (the jobs' Progress protocol).

On a terminal the line is redrawn in place (at most every ``tty_interval``
seconds); otherwise a line is printed at most every ``interval`` seconds of
wall time, or whenever the job's ``step`` changes (an experiment prints one
a simulated second), and always the final one.  A note gets a line of its own.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO


class TerminalProgress:
    """A :class:`~friction_sim.core.runtime.progress.Progress` on ``stream`` (stderr by default)."""

    def __init__(self, stream: TextIO | None = None, *, interval: float = 1.0, tty_interval: float = 0.0) -> None:
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.interval = tty_interval if self.tty else interval
        self._shown = -float("inf")
        self._step: int | None = None
        self._open = False

    def show(self, text: str, *, step: int | None = None, final: bool = False) -> None:
        """Put ``text`` up (see the module doc)."""
        now = time.monotonic()
        due = final or now - self._shown >= self.interval
        if step is not None and not self.tty:
            due = final or step != self._step
        if not due:
            return
        self._shown, self._step = now, step
        if self.tty:
            self.stream.write("\r" + text)
            self._open = True
        else:
            self.stream.write(text + "\n")
        self.stream.flush()

    def note(self, message: str) -> None:
        """``message`` on a line of its own."""
        if self._open:
            self.stream.write("\n")
            self._open = False
        self.stream.write(message + "\n")
        self.stream.flush()

    def close(self) -> None:
        """End a redrawn line."""
        if self._open:
            self.stream.write("\n")
            self.stream.flush()
            self._open = False


__all__ = ["TerminalProgress"]
