"""Simulation time from a monotonic wall clock: :class:`SimClock`.

The real-time slider (:mod:`friction_sim.core.runtime.realtime`) reads simulation time
from here on every tick and command, so a late or missed tick never changes
the physics.  The clock can be paused (simulation time stands still, exactly)
and stepped while paused: the ``~/pause``, ``~/resume`` and ``~/step``
services of the slider node.
"""

from __future__ import annotations

from dataclasses import dataclass

from friction_sim.core.model.params import require_positive
from friction_sim.core.model.spec import NS_PER_S
from friction_sim.errors import ParameterError


class SimClock:
    """Simulation time from a monotonic wall clock, both in integer nanoseconds.

    t_sim = sim_start + rate * (wall - wall_start); changing the rate rebases,
    so simulation time stays continuous.  Simulation time is kept in whole
    nanoseconds, the resolution of a ROS header stamp, so the time a state or a
    command is stamped with is exactly the time the core computed it for.
    """

    def __init__(self, rate: float, wall_ns: int, sim_start_ns: int = 0, catch_up_ns: int | None = None) -> None:
        self._rate = require_positive("real_time_factor", rate)
        self._wall0 = wall_ns
        self._sim0 = sim_start_ns
        self._paused = False
        #: Wall time [ns] the clock may run past the simulation time reached
        #: (:meth:`reached`); None: any.  Beyond it readings stand still until
        #: :meth:`slip` gives the rest up (a stall of the host).
        self.catch_up_ns = catch_up_ns
        self._reached_ns = sim_start_ns

    @property
    def rate(self) -> float:
        return self._rate

    @property
    def paused(self) -> bool:
        """Whether simulation time stands still (:meth:`pause`)."""
        return self._paused

    def now_ns(self, wall_ns: int) -> int:
        """Simulation time [ns] at wall time ``wall_ns``."""
        if self._paused:
            return self._sim0
        now, cap = self._running_ns(wall_ns), self._cap_ns()
        return now if cap is None or now <= cap else cap

    def _running_ns(self, wall_ns: int) -> int:
        elapsed = wall_ns - self._wall0
        return self._sim0 + (elapsed if self._rate == 1.0 else round(self._rate * elapsed))

    def _cap_ns(self) -> int | None:
        if self.catch_up_ns is None:
            return None
        return self._reached_ns + (self.catch_up_ns if self._rate == 1.0 else round(self._rate * self.catch_up_ns))

    def reached(self, sim_ns: int) -> None:
        """The simulation has been advanced to ``sim_ns``: readings may run
        ``catch_up_ns`` of wall time past it."""
        self._reached_ns = sim_ns

    def slip(self, wall_ns: int) -> int:
        """After a stall: if the clock ran further than ``catch_up_ns`` past the
        time reached, it goes on from there (readings stood there meanwhile, so
        it never runs backwards); the rest of the stall is not simulated.
        Returns the simulated nanoseconds given up (0: no stall)."""
        cap = None if self._paused else self._cap_ns()
        now = self._running_ns(wall_ns)
        if cap is None or now <= cap:
            return 0
        self._sim0, self._wall0 = cap, wall_ns
        return now - cap

    def pause(self, wall_ns: int) -> None:
        """Stop simulation time at its value at ``wall_ns`` (exactly: it stays there)."""
        if not self._paused:
            self._sim0, self._wall0, self._paused = self.now_ns(wall_ns), wall_ns, True

    def resume(self, wall_ns: int) -> None:
        """Let simulation time run again from where it stood, from ``wall_ns`` on
        (no jump: the wall time that passed while paused is not simulated)."""
        if self._paused:
            self._wall0, self._paused = wall_ns, False

    def step(self, sim_ns: int) -> None:
        """While paused: move simulation time on by ``sim_ns`` (a ``~/step``)."""
        if not self._paused:
            raise ParameterError("step", sim_ns, "only while paused")
        self._sim0 += max(0, int(sim_ns))

    def now(self, wall_ns: int) -> float:
        """Simulation time [s] at wall time ``wall_ns`` (a whole number of ns)."""
        return self.now_ns(wall_ns) / NS_PER_S

    def hold(self, wall_ns: int) -> None:
        """Let ``wall_ns`` of wall time pass without simulation time (the caller
        waited for something, a recorder say): simulation time does not jump."""
        self._wall0 += max(0, int(wall_ns))

    def not_before(self, sim_ns: int, wall_ns: int) -> None:
        """Make it at least ``sim_ns`` from ``wall_ns`` on (running: the rate stays)."""
        if not self._paused and self.now_ns(wall_ns) < sim_ns:
            self._sim0, self._wall0 = sim_ns, wall_ns

    def fall_behind(self, sim_ns: int, wall_ns: int) -> None:
        """Make it ``sim_ns`` at ``wall_ns`` (not later than it was): the
        simulation could not keep up and goes on from there, at the same rate."""
        self._sim0, self._wall0 = min(sim_ns, self.now_ns(wall_ns)), wall_ns

    def set_rate(self, rate: float, wall_ns: int) -> None:
        """Change the real-time factor from ``wall_ns`` on (paused: from the resume on)."""
        rate = require_positive("real_time_factor", rate)
        self._sim0, self._wall0, self._rate = self.now_ns(wall_ns), wall_ns, rate


@dataclass
class TickStats:
    """Timer health over the current diagnostics interval."""

    ticks: int = 0
    late_ticks: int = 0
    total_late_ticks: int = 0
    last_wall_ns: int | None = None
    interval_start_ns: int | None = None
    interval_sim_start: float = 0.0
    #: The slider's time [s], its time in flight [s] and lift-off and landing counts at the interval's start.
    interval_slider_start: float = 0.0
    interval_flight_start: float = 0.0
    interval_lift_offs_start: int = 0
    interval_landings_start: int = 0


__all__ = ["SimClock", "TickStats"]
