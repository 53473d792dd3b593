"""How far one advance of a real-time run may take simulation time.

Simulation time follows the wall clock (:class:`~friction_sim.core.runtime.simclock.SimClock`),
but one advance never goes all the way when that would be more than this
machine should do at once:

* After a stall of the host longer than ``max_catch_up`` (a garbage
  collection), the rest is not simulated: the clock slips (counted in
  :attr:`Pace.stalls` and :attr:`Pace.time_slipped`).  Simulating it at once
  would run the plant on ahead of its controllers' answers, which no real
  plant does.
* One advance makes at most :data:`~friction_sim.core.runtime.loggrid.MAX_SAMPLES_PER_ADVANCE`
  log samples; asked for more, the simulation falls behind the wall clock
  (counted in :attr:`Pace.behind`) and the next tick goes on from there.
"""

from __future__ import annotations

import math

from friction_sim.core.model.spec import NS_PER_S
from friction_sim.core.runtime.loggrid import MAX_SAMPLES_PER_ADVANCE
from friction_sim.core.runtime.simclock import SimClock


class Pace:
    """The limits on one advance of ``clock``'s simulation time, and their counts.

    ``log_rate`` [Hz] is the log grid's (None: no log, no sample budget)."""

    def __init__(self, clock: SimClock, log_rate: float | None) -> None:
        self.clock = clock
        self.log_rate = log_rate
        #: ``max_catch_up`` [s] as set (None: no limit; see :meth:`set_catch_up`).
        self.max_catch_up: float | None = None
        #: Stalls of the host whose rest was not simulated, and the simulated seconds given up.
        self.stalls, self.time_slipped = 0, 0.0
        #: Advances cut short by MAX_SAMPLES_PER_ADVANCE (the simulation fell behind real time).
        self.behind = 0

    def set_catch_up(self, seconds: float | None, publish_rate: float) -> None:
        """``max_catch_up``, never under two ticks of ``publish_rate`` (None, for a synthetic
        clock or a test: no limit)."""
        self.max_catch_up = seconds
        self.clock.catch_up_ns = None if seconds is None else round(max(seconds, 2.0 / publish_rate) * NS_PER_S)

    def reachable(self, t: float, slider_t: float, wall_ns: int) -> float:
        """``t`` (after a stall: the clock's catch-up limit, where the rest slips), or the time
        :data:`MAX_SAMPLES_PER_ADVANCE` log samples after ``slider_t`` (the slider's time) if
        sooner; simulation time is held there."""
        if slipped := self.clock.slip(wall_ns):
            self.stalls += 1
            self.time_slipped += slipped / NS_PER_S
        if self.log_rate is None or t - slider_t <= MAX_SAMPLES_PER_ADVANCE / self.log_rate:
            return t
        limit_ns = math.floor((slider_t + MAX_SAMPLES_PER_ADVANCE / self.log_rate) * NS_PER_S)
        self.clock.fall_behind(limit_ns, wall_ns)
        self.behind += 1
        return max(limit_ns / NS_PER_S, slider_t)


__all__ = ["Pace"]
