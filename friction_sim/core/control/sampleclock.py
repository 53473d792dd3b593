"""When a mean-velocity sample answers the controller's last change: :class:`SampleClock`.

The integral action of :mod:`friction_sim.core.control.law` learns only from
*clean* samples, whose window began after the last change of Pa took effect at
the plant.  Over ROS that time is not known exactly unless the node has the
plant's simulation clock; this module estimates it from the samples' stamps,
their arrival times and the delivery jitter they show (numpy-free, no ROS).
"""

from __future__ import annotations

import itertools
from collections import deque

from friction_sim.core.model.spec import NS_PER_S

JITTER_SAMPLES = 16  # the samples whose lateness is the current jitter (about 0.3 s at 50 Hz)


class SampleClock:
    """Tells whether a mean-velocity sample's window lies wholly after the last
    change of Pa, comparing simulation times.

    A sample's stamp is the simulation time its window ends.  The time the
    change took effect is the node's simulation clock when it has one
    (``use_sim_time`` with the slider's ``/clock``: exact, paused or not);
    otherwise it is estimated from the last sample: its stamp plus the wall
    time since it arrived times the plant's pace, but never more than one
    period (the samples' spacing, or the new period if longer) plus the
    delivery jitter past it, since a running plant would have sent the next
    sample by then (a plant that paused or stalled meanwhile has not moved
    on).  So a pause, a run of ``~/step`` calls or a reset on the slider
    never makes a window that mixes old and new motion look clean.
    """

    def __init__(self) -> None:
        self._samples: deque[tuple[float, int]] = deque(maxlen=64)  # ~1 s at 50 Hz: a steady rate
        self._change: float | None = None  # simulation time [s] the last change took effect
        self._change_pending = False  # a change before any sample: timed by the first one
        #: Lockstep: every change is noted with the simulation time it acts at, exactly, and
        #: samples come in simulation time only: no delivery jitter, no pace to learn.
        self.exact = False

    def note_change(self, wall_ns: int, period: float = 0.0, sim_time: float | None = None) -> None:
        """Pa was changed (published) at ``wall_ns``; ``sim_time`` is the node's
        simulation clock then, if it has one; ``period`` the excitation period [s]."""
        if sim_time is not None:
            self._change, self._change_pending = sim_time, False
        elif self._samples:
            stamp, arrived = self._samples[-1]
            since = max(0, wall_ns - arrived) / NS_PER_S * self.rate()
            # The next sample comes one period of the samples' own spacing later (the
            # frequency may just have changed: the longer of the two bounds it).
            spacing = stamp - self._samples[-2][0] if len(self._samples) >= 2 else period
            self._change, self._change_pending = stamp + min(since, max(period, spacing) + self.jitter()), False
        else:
            self._change, self._change_pending = None, True

    def rate(self) -> float:
        """Simulated seconds per wall second, from the recent samples (1 until known)."""
        if len(self._samples) < 2:
            return 1.0
        (t0, w0), (t1, w1) = self._samples[0], self._samples[-1]
        return (t1 - t0) / ((w1 - w0) / NS_PER_S) if w1 > w0 and t1 > t0 else 1.0

    def jitter(self) -> float:
        """The largest recent lateness of a sample relative to its predecessor,
        in simulated seconds: how far message delivery currently strays.

        A loaded machine delays the controller's Pa on its way to the plant
        as much as it delays the samples coming back; a window judged only by
        the fixed margin would then take old motion for the answer to the change.
        "Recent": the last :data:`JITTER_SAMPLES`, so one hiccup of delivery does
        not hold every window back for the whole history (a stepped feeder in CI
        integrated none of 40 periods)."""
        rate, samples = self.rate(), list(self._samples)[-JITTER_SAMPLES - 1:]
        lateness = [((w1 - w0) / NS_PER_S) * rate - (t1 - t0)
                    for (t0, w0), (t1, w1) in itertools.pairwise(samples)]
        return max([0.0, *lateness])

    @property
    def last_stamp(self) -> float | None:
        """The stamp [s] of the newest sample seen (None: none yet): which sample was taken last."""
        return self._samples[-1][0] if self._samples else None

    def observe(self, stamp: float, wall_ns: int) -> None:
        """Record a sample's stamp and arrival without judging it (a controller
        standing by still learns the plant's real-time factor this way)."""
        self._samples.append((stamp, wall_ns))

    def add(self, stamp: float, wall_ns: int, period: float, window_periods: int, margin: float) -> bool:
        """Record a sample; True when its window began after the last change,
        with ``margin`` periods plus the current delivery jitter to spare."""
        self.observe(stamp, wall_ns)
        if self._change_pending:  # changed before any sample: the first one may predate it
            self._change, self._change_pending = stamp, False
            return False
        if self._change is None:  # nothing of ours applied yet: not our plant's answer
            return False
        if self.exact:
            return stamp - window_periods * period >= self._change + margin * period
        if len(self._samples) < 3:
            # The real-time factor is not known yet (it needs two intervals): a
            # plant at half speed would have its mixed windows judged clean.
            return False
        return stamp - window_periods * period >= self._change + margin * period + self.jitter()


__all__ = ["JITTER_SAMPLES", "SampleClock"]
