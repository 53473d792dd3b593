"""The records a running slider hands on: a period's summary and a tick's result.

The real-time slider (:mod:`friction_sim.core.runtime.realtime`) makes them;
the sinks of :mod:`friction_sim.io` (the recorder, the live view) and the
nodes consume them.
"""

from __future__ import annotations

from dataclasses import dataclass

from friction_sim.core.model.events import Event, SliderState


@dataclass(frozen=True)
class PeriodSummary:
    """Published once per completed excitation period ``n`` (ending at ``t``):
    the mean velocity over the last ``window_periods`` periods, and the
    fractions of period ``n`` spent stuck and in flight (off the track)."""

    n: int
    t: float
    mean_velocity: float
    window_periods: int
    stick_fraction: float
    flight_fraction: float = 0.0


@dataclass(frozen=True)
class Tick:
    """The result of advancing to the present: the state now, the events on
    the way, the summaries of periods completed on the way and, when logging,
    the exact states on the log grid passed on the way."""

    state: SliderState
    events: list[Event]
    periods: list[PeriodSummary]
    samples: tuple[SliderState, ...] = ()
    #: Whether simulation time stands still (a paused tick passes no time).
    paused: bool = False


__all__ = ["PeriodSummary", "Tick"]
