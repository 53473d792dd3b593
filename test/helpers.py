"""Helpers shared by the core tests: a time limit that turns a hang into a
test failure (some inputs once looped forever at the edges of the slip
window), and the mirror image of a command schedule."""

from __future__ import annotations

import contextlib
import signal
import time
from typing import Iterator

from friction_sim.simulation import Command


class EndlessLoop(AssertionError):
    """A call that should take microseconds did not return."""


@contextlib.contextmanager
def time_limit(seconds: float, what: str) -> Iterator[None]:
    """Raise EndlessLoop if the block runs longer than ``seconds`` (SIGALRM;
    an outer timer such as pytest-timeout's is put back afterwards)."""

    def on_alarm(signum: int, frame: object) -> None:
        raise EndlessLoop(f"{what} did not return within {seconds} s")

    started = time.monotonic()
    old_handler = signal.signal(signal.SIGALRM, on_alarm)
    old_delay, _ = signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old_handler)
        if old_delay > 0.0:
            signal.setitimer(signal.ITIMER_REAL, max(old_delay - (time.monotonic() - started), 1e-3))


def mirrored(schedule: list[Command]) -> list[Command]:
    """The schedule with every tangential force reversed (Fd -> -Fd, Fx -> -Fx)."""
    out = []
    for command in schedule:
        changes = dict(command.changes)
        for name in ("drive_force", "external_force_x"):
            if name in changes:
                changes[name] = -changes[name]
        out.append(Command(command.t, changes))
    return out
