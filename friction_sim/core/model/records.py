"""The records a running slider hands on: a period's summary and a tick's result.

The real-time slider (:mod:`friction_sim.core.runtime.realtime`) makes them;
the sinks of :mod:`friction_sim.io` (the recorder, the live view) and the
nodes consume them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import overload

import numpy as np
from numpy.typing import NDArray

from friction_sim.core.model.events import Event, SliderState


@overload
def share(part: float, whole: float, empty: float = 0.0) -> float: ...
@overload
def share(part: NDArray[np.float64], whole: float | NDArray[np.float64], empty: float = 0.0) -> NDArray[np.float64]: ...


def share(part: float | NDArray[np.float64], whole: float | NDArray[np.float64],
          empty: float = 0.0) -> float | NDArray[np.float64]:
    """``part / whole`` as a fraction (of a period stuck, say, or in flight), in
    [0, 1]: the two are differences of separately accumulated times, so their
    ratio may round a few ulp outside (1.0000000000003553 was seen); ``empty``
    where ``whole`` is not positive.  The one rule for every time fraction."""
    if isinstance(part, np.ndarray) or isinstance(whole, np.ndarray):
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.asarray(part, dtype=float) / whole
        return np.where(np.asarray(whole) > 0.0, np.clip(ratio, 0.0, 1.0), empty)
    if not whole > 0.0:
        return empty
    return min(max(part / whole, 0.0), 1.0)


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
class Acceleration:
    """One accelerometer sample at simulation time ``t`` [s]: the specific force
    [m/s^2] a sensor on the slideway reads in the track frame (x along the track,
    z normal to it, away from it): the slideway's acceleration less gravity, so
    at rest it reads +g*cos(alpha) on z, as REP 145 has it."""

    t: float
    x: float
    y: float
    z: float


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
    #: The accelerometer's samples on its grid passed on the way (none when it is off).
    accelerations: tuple[Acceleration, ...] = ()


__all__ = ["PeriodSummary", "Tick", "share"]
