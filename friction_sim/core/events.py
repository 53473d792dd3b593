"""The records of the stick-slip motion: modes, events, states, trajectories.

Events are data (time, kind, state before and after), as in scipy's
``_ivp``: the slider (:mod:`friction_sim.core.slider`) produces them, the
nodes, the recorder and the reports consume them.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, IntEnum
from typing import NamedTuple

import numpy as np


class Mode(IntEnum):
    """What the slider is doing: its slip direction, or stuck."""

    BACKWARD = -1
    STUCK = 0
    FORWARD = 1


MODES = {-1: Mode.BACKWARD, 0: Mode.STUCK, 1: Mode.FORWARD}


class EventKind(str, Enum):
    """The transitions of the stick-slip motion."""

    SLIP_START = "slip_start"  # stuck -> slipping
    STICK = "stick"  # slipping -> stuck
    REVERSAL = "reversal"  # slipping one way -> slipping the other, through v = 0


class Event(NamedTuple):
    """One transition.  Position and velocity are continuous through it
    (v = 0 at every kind of event); what changes is the mode.  (A named
    tuple: the periodic regime makes two per period, so they must be cheap.)"""

    t: float
    kind: EventKind
    x: float
    phase: float
    before: Mode
    after: Mode


@dataclass(frozen=True, slots=True)
class CycleMark:
    """The start of excitation period ``n`` (the phase passes 2*pi*n): where the
    slider was and how long it had been stuck in all, for per-period means."""

    n: int
    t: float
    x: float
    stuck_time: float


@dataclass(frozen=True, slots=True)
class SliderState:
    """Everything about the slider at one instant (SI units, phase in [0, 2*pi))."""

    t: float
    x: float
    v: float
    acceleration: float
    friction_force: float
    normal_force: float
    phase: float
    mode: Mode

    @property
    def stuck(self) -> bool:
        """True while the slider sticks to the slideway."""
        return self.mode is Mode.STUCK


@dataclass(frozen=True)
class Trajectory:
    """Exact samples of the motion at given times, one array per quantity,
    and the events that happened while they were taken."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    acceleration: np.ndarray
    friction_force: np.ndarray
    normal_force: np.ndarray
    phase: np.ndarray
    mode: np.ndarray
    events: tuple[Event, ...] = ()

    def states(self) -> list[SliderState]:
        """The samples as :class:`SliderState` records, in time order."""
        return [
            SliderState(float(self.t[k]), float(self.x[k]), float(self.v[k]), float(self.acceleration[k]),
                        float(self.friction_force[k]), float(self.normal_force[k]), float(self.phase[k]),
                        Mode(int(self.mode[k])))
            for k in range(self.t.size)
        ]


__all__ = ["CycleMark", "Event", "EventKind", "Mode", "SliderState", "Trajectory"]
