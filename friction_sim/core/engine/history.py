"""What a single slider has done: its events, the time it spent stuck and in flight, its period starts.

:class:`History` is the part of :class:`~friction_sim.core.engine.single.Slider`
that keeps the record: the bounded log of events and the count of every
kind, the time booked stuck and in flight up to now, and the start of every
excitation period (a :class:`~friction_sim.core.model.events.CycleMark`, timed
from the phase anchor, its position where the phase passes 2*pi*n exactly).
The slider advances the state and calls :meth:`History._mark_cycle` when a
period starts; everything here reads the state or appends to the logs.  Its
attributes are the slider's own (a checkpoint of the slider holds them).
"""

from __future__ import annotations

from collections import deque

from friction_sim.core.engine.transient_segment import Transient
from friction_sim.core.model.events import CycleMark, Event, EventKind
from friction_sim.core.physics.plant import Plant
from friction_sim.core.physics.roots import NEVER
from friction_sim.core.physics.segment import Segment
from friction_sim.core.physics.stepper import Anchor, moved, offset, period_start, spent, to_cycle


class History:
    """A slider's record of what it has done (see the module's docstring); a base of
    :class:`~friction_sim.core.engine.single.Slider`, which holds the state it reads."""

    _t: float
    _seg: Segment
    _plant: Plant
    _anchor: Anchor
    _transient: Transient
    _events: deque[Event]
    _counts: dict[EventKind, int]
    _marks: deque[CycleMark] | None
    _next_mark_n: int
    _next_mark_t: float
    _next_mark_s: float

    @property
    def events(self) -> list[Event]:
        """The most recent events, oldest first (bounded by ``event_log_size``)."""
        return list(self._events)

    @property
    def event_counts(self) -> dict[EventKind, int]:
        """How many events of each kind happened since the start."""
        return dict(self._counts)

    @property
    def stuck_time(self) -> float:
        """Total time [s] spent stuck since the start, up to :attr:`t`."""
        return spent(self._seg, self._t - self._seg.t0)[0]

    @property
    def flight_time(self) -> float:
        """Total time [s] spent off the track since the start, up to :attr:`t`."""
        return spent(self._seg, self._t - self._seg.t0)[1]

    @property
    def cycle_marks(self) -> list[CycleMark]:
        """The most recent period starts, oldest first (empty unless enabled)."""
        return list(self._marks) if self._marks is not None else []

    def cycle_marks_after(self, n: int) -> list[CycleMark]:
        """The kept period starts with a number above ``n``, oldest first."""
        newer: list[CycleMark] = []
        for mark in reversed(self._marks or ()):
            if mark.n <= n:
                break
            newer.append(mark)
        newer.reverse()
        return newer

    @property
    def next_mark_time(self) -> float:
        """When the next excitation period starts (inf when marks are not kept)."""
        return self._next_mark_t if self._marks is not None else NEVER

    def _schedule_mark(self) -> None:
        """Aim at the start of period ``_next_mark_n``, timed from the anchor."""
        if self._marks is not None:
            self._next_mark_s = offset(self._anchor, self._next_mark_n, 0.0)
            self._next_mark_t = self._anchor.t + self._next_mark_s

    def _mark_cycle(self) -> None:
        """Record the start of period ``_next_mark_n`` and aim at the next."""
        seg, n = self._seg, self._next_mark_n
        t = max(self._next_mark_t, seg.t0)  # a start that rounding put before this segment's is at it
        # Where the slider is when the phase passes 2*pi*n exactly (not at the rounded t).
        tau = to_cycle(n, seg.cycles, seg.phase0, self._plant.omega)
        transient = self._transient
        x, stuck, flight = period_start(seg, tau, moved(self._plant, seg, transient.c, transient.lam, tau))
        assert self._marks is not None
        self._marks.append(CycleMark(n, t, x, stuck, flight))
        self._next_mark_n += 1
        self._schedule_mark()


__all__ = ["History"]
