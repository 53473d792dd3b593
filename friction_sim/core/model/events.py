"""The records of the stick-slip motion: modes, events, states, trajectories.

Events are data (time, kind, state before and after), as in scipy's
``_ivp``: the slider (:mod:`friction_sim.core.engine.single`) produces them, the
nodes, the recorder and the reports consume them.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, IntEnum
from typing import NamedTuple

import numpy as np


class Mode(IntEnum):
    """What the slider is doing: its slip direction, stuck, or in flight."""

    BACKWARD = -1
    STUCK = 0
    FORWARD = 1
    FLIGHT = 2  # off the track: no contact force, no friction


MODES = {-1: Mode.BACKWARD, 0: Mode.STUCK, 1: Mode.FORWARD, 2: Mode.FLIGHT}


class EventKind(str, Enum):
    """The transitions of the motion."""

    SLIP_START = "slip_start"  # stuck -> slipping
    STICK = "stick"  # slipping -> stuck
    REVERSAL = "reversal"  # slipping one way -> slipping the other, through v = 0
    LIFT_OFF = "lift_off"  # in contact -> flight: the contact force would become negative
    LANDING = "landing"  # flight -> contact (or a rebound, with restitution): z returns to 0


class Event(NamedTuple):
    """One transition at height z = 0.  Position is continuous through it; what
    changes is the mode, and at a landing the velocity (an impact).  ``v_*``
    are the tangential and ``vz_*`` the normal velocity just before and just
    after (all 0 at slip_start, stick and reversal, whose v is 0; vz is 0 at a
    lift-off).  (A named tuple: the periodic regime makes two per period, so
    they must be cheap.)"""

    t: float
    kind: EventKind
    x: float
    phase: float
    before: Mode
    after: Mode
    v_before: float = 0.0
    v_after: float = 0.0
    vz_before: float = 0.0
    vz_after: float = 0.0


@dataclass(frozen=True, slots=True)
class CycleMark:
    """The start of excitation period ``n`` (the phase passes 2*pi*n): where the
    slider was and how long it had been stuck and in flight in all, for
    per-period means."""

    n: int
    t: float
    x: float
    stuck_time: float
    flight_time: float = 0.0


@dataclass(frozen=True, slots=True)
class SliderState:
    """Everything about the slider at one instant (SI units, phase in [0, 2*pi)).

    ``acceleration`` is along x; ``normal_force`` is the contact force R
    (0 in flight), ``friction_force`` the friction along x (0 in flight);
    ``z`` >= 0 is the height above the track and ``vz`` its rate (0 in contact).
    """

    t: float
    x: float
    v: float
    acceleration: float
    friction_force: float
    normal_force: float
    phase: float
    mode: Mode
    z: float = 0.0
    vz: float = 0.0

    @property
    def stuck(self) -> bool:
        """True while the slider sticks to the slideway."""
        return self.mode is Mode.STUCK

    @property
    def in_flight(self) -> bool:
        """True while the slider is off the track."""
        return self.mode is Mode.FLIGHT


@dataclass(frozen=True)
class Trajectory:
    """Exact samples of the motion at given times, one array per quantity,
    and the events that happened while they were taken (``z`` and ``vz``:
    zeros when not given, for a motion that never leaves the track)."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    acceleration: np.ndarray
    friction_force: np.ndarray
    normal_force: np.ndarray
    phase: np.ndarray
    mode: np.ndarray
    events: tuple[Event, ...] = ()
    z: np.ndarray = None  # type: ignore[assignment]  # filled in __post_init__
    vz: np.ndarray = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        for name in ("z", "vz"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, np.zeros_like(self.t))

    def states(self) -> list[SliderState]:
        """The samples as :class:`SliderState` records, in time order."""
        return [
            SliderState(float(self.t[k]), float(self.x[k]), float(self.v[k]), float(self.acceleration[k]),
                        float(self.friction_force[k]), float(self.normal_force[k]), float(self.phase[k]),
                        Mode(int(self.mode[k])), float(self.z[k]), float(self.vz[k]))
            for k in range(self.t.size)
        ]


__all__ = ["CycleMark", "Event", "EventKind", "Mode", "SliderState", "Trajectory"]
