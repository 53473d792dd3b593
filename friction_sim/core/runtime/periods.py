"""The real-time slider's period means: one summary per completed excitation period.

From the core's exact period marks (:class:`~friction_sim.core.model.events.CycleMark`)
it makes, for every period that ends, the mean velocity over the last
``mean_window_periods`` whole periods and the stick and flight fractions of
that period (:class:`~friction_sim.core.model.records.PeriodSummary`).  Kept
apart from :class:`~friction_sim.core.runtime.realtime.RealtimeSlider`, which
advances the core and takes commands: this only reads the marks it left.
"""

from __future__ import annotations

from collections import deque

from friction_sim.core.engine.single import Slider
from friction_sim.core.model import spec
from friction_sim.core.model.events import CycleMark
from friction_sim.core.model.records import PeriodSummary, share


class PeriodMeans:
    """The mean-velocity window over the last whole periods and where the summaries have got to."""

    def __init__(self, window_periods: int) -> None:
        self._window: deque[CycleMark] = deque(maxlen=2)
        self.set_window(window_periods)
        #: The number of the last period mark summarised (or skipped).
        self.last_mark_n = -1
        #: The summary of the last period that ended (None before the first).
        self.last: PeriodSummary | None = None

    def set_window(self, periods: int) -> None:
        """Average the mean velocity over the last ``periods`` whole periods."""
        periods = spec.MEAN_WINDOW_PERIODS.check(periods)
        self._window = deque(self._window, maxlen=periods + 1)

    @property
    def window_periods(self) -> int:
        assert self._window.maxlen is not None
        return self._window.maxlen - 1

    def restart(self) -> None:
        """Start the window afresh (after a reset: no mean spans it)."""
        self._window.clear()

    def new(self, slider: Slider, before: float) -> list[PeriodSummary]:
        """The summaries of the periods of ``slider`` that ended since the last call,
        up to the first mark at or after ``before`` [s] (reported later)."""
        summaries = []
        for mark in slider.cycle_marks_after(self.last_mark_n):
            if mark.t >= before:
                break
            self.last_mark_n = mark.n
            previous = self._window[-1] if self._window else None
            self._window.append(mark)
            if previous is None or previous.n != mark.n - 1:
                continue
            first = self._window[0]
            span = mark.t - first.t
            duration = mark.t - previous.t
            summaries.append(PeriodSummary(
                n=mark.n, t=mark.t, mean_velocity=(mark.x - first.x) / span if span > 0 else 0.0,
                window_periods=mark.n - first.n,
                stick_fraction=share(mark.stuck_time - previous.stuck_time, duration, empty=1.0),
                flight_fraction=share(mark.flight_time - previous.flight_time, duration),
            ))
        if summaries:
            self.last = summaries[-1]
        return summaries


__all__ = ["PeriodMeans"]
