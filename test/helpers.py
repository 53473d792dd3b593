"""Helpers shared by the core tests: a time limit that turns a hang into a
test failure (some inputs once looped forever at the edges of the slip
window), and the mirror image of a command schedule."""

from __future__ import annotations

import contextlib
import signal
from typing import Iterator

from friction_sim.core.simulation import Command


class EndlessLoop(AssertionError):
    """A call that should take microseconds did not return."""


@contextlib.contextmanager
def time_limit(seconds: float, what: str) -> Iterator[None]:
    """Raise EndlessLoop if the block uses more than ``seconds`` of CPU time.

    CPU time (ITIMER_PROF), not wall time: an endless loop burns CPU, while a
    process that a loaded machine merely holds back does not; and SIGPROF
    leaves pytest-timeout's SIGALRM alone."""

    def on_alarm(signum: int, frame: object) -> None:
        raise EndlessLoop(f"{what} did not return within {seconds} s of CPU time")

    old_handler = signal.signal(signal.SIGPROF, on_alarm)
    signal.setitimer(signal.ITIMER_PROF, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0)
        signal.signal(signal.SIGPROF, old_handler)


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
