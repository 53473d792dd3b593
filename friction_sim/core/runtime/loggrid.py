"""Advancing the exact slider along the log grid and the accelerometer's grid.

A real-time run (:mod:`friction_sim.core.runtime.realtime`) records the exact
state at every point ``k / log_rate`` of simulation time and, with an
accelerometer, a reading at every point of its own grid, in time order, with
the events on the way.  :class:`LogGrid` holds the grids' position and what
advancing produced since the last tick, which the tick then takes
(:meth:`LogGrid.take`).  Cutting the time axis at grid points does not change
the motion: the core's advance is exact wherever it stops.
"""

from __future__ import annotations

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.events import Event, SliderState
from friction_sim.core.model.records import Acceleration
from friction_sim.core.runtime.accelerometer import Accelerometer, grid
from friction_sim.core.runtime.guard import non_finite

#: Log samples one advance takes at most (a few ms of work).  Asked for more
#: (real_time_factor x log_rate beyond what this machine computes), the
#: simulation falls behind the wall clock instead, as it does for a slow
#: recorder: one tick never holds the node for seconds, parameter sets stay
#: answered, and diagnostics report the achieved real-time factor.
MAX_SAMPLES_PER_ADVANCE = 1000


class LogGrid:
    """The log grid (``k / log_rate`` in simulation time; None: no log) and the
    accelerometer's (None: off), and the events, log samples and readings that
    advancing along them produced since the last :meth:`take`."""

    def __init__(self, log_rate: float | None, accelerometer: Accelerometer | None) -> None:
        self.log_rate = log_rate
        self.accelerometer = accelerometer
        self._next_log_index = 0  # the log grid is k / log_rate in simulation time
        # What advancing produced since the last tick (commands advance too).
        self._events: list[Event] = []
        self._samples: list[SliderState] = []
        self._accelerations: list[Acceleration] = []

    def advance(self, slider: Slider, t: float, *, chunked: bool = False) -> None:
        """Advance ``slider`` to ``t``, keeping the events and log samples on the
        way; ``chunked``: in pieces of :data:`MAX_SAMPLES_PER_ADVANCE` samples
        (a step).  Whatever the core raises is left to the caller."""
        while True:
            end = t
            if chunked and self.log_rate is not None:
                end = min(t, slider.t + MAX_SAMPLES_PER_ADVANCE / self.log_rate)
            self._log_samples(slider, end)
            self._events.extend(slider.advance_to(end))
            if end >= t:
                break

    def _log_samples(self, slider: Slider, t: float) -> None:
        """Advance through the log grid points up to ``t`` not logged yet, keeping
        the exact state at each (and the events on the way), and through the
        accelerometer's grid, reading it at each: a segment at a time
        (:meth:`~friction_sim.core.engine.single.Slider.sample_grids`), which
        gives each state and reading as advancing to its time does, bit for bit."""
        accelerometer = self.accelerometer
        due = accelerometer.due(slider.t, t) if accelerometer is not None else range(0)
        rate = self.log_rate or 1.0
        logged = grid(rate, self._next_log_index, slider.t, t) if self.log_rate else range(0)
        self._next_log_index = max(self._next_log_index, logged.stop)
        if not logged and not due:
            return
        # (a point the rounded grid puts a hair before where the slider stands is read where it stands)
        now = slider.t
        reading_times = [max(k / accelerometer.rate, now) for k in due] if accelerometer is not None else []
        states, readings, events = slider.sample_grids([max(k / rate, now) for k in logged], reading_times)
        self._events.extend(events)
        self._samples.extend(states)
        if accelerometer is not None:
            self._accelerations.extend(accelerometer.readings(slider.params, due, reading_times, readings))

    def non_finite(self) -> str:
        """'' if every log sample kept is finite, else what the first that is not holds."""
        for sample in self._samples:
            problem = non_finite(sample)
            if problem:
                return problem
        return ""

    def take(self) -> tuple[list[Event], tuple[SliderState, ...], tuple[Acceleration, ...]]:
        """The events, log samples and accelerometer readings kept since the last
        call, in time order; they are handed over, not kept."""
        events, samples, accelerations = self._events, tuple(self._samples), tuple(self._accelerations)
        self._events, self._samples, self._accelerations = [], [], []
        return events, samples, accelerations


__all__ = ["MAX_SAMPLES_PER_ADVANCE", "LogGrid"]
