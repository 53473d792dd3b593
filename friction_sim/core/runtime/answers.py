"""The controller's side of lockstep, without ROS: which sample to answer, and when.

A slider in lockstep (:mod:`friction_sim.core.runtime.lockstep`) waits for the
controller's answer to each ``mean_velocity`` sample.  For the answer to be the
same every run, the controller must answer each sample once, in order, with
exactly what the plant had sent up to that sample's time:

* a sample is answered once the controller has its plant's model (the slider
  waits meanwhile, and publishes the sample again for a controller that joined late);
* with the inner loop, once the accelerometer's samples up to the sample's time
  have come (they travel on another topic, which DDS does not order with this
  one): they are fed to the loop up to that time, the later ones kept for the next;
* a sample seen again (published again while the slider waited) is answered
  again with the same answer; an older one is ignored.

Diagnostics come every ``diagnostics_period`` of simulation time, at the first
sample past each multiple of it.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from friction_sim.core.model.spec import NS_PER_S
from friction_sim.core.runtime.accelerometer import grid


@dataclass
class AnswerQueue:
    """Samples waiting for their answer, and the accelerometer samples not yet fed to the loop."""

    #: Simulation time [ns] from a sample to the moment its answer acts on the plant.
    delay_ns: int
    #: The plant's accelerometer rate [Hz] (0: none).
    accelerometer_rate: float
    #: Simulation time [ns] between diagnostics.
    diagnostics_ns: int
    _samples: deque[tuple[int, float]] = field(default_factory=deque)
    _accelerations: deque[tuple[int, float]] = field(default_factory=deque)
    _latest_acceleration_ns: int = -1
    #: The last sample answered [ns] and its answer (the values sent).
    last_ns: int = -1
    last_answer: dict[str, float] = field(default_factory=dict)
    _next_diagnostics_ns: int = 0

    def sample(self, stamp_ns: int, speed: float) -> str:
        """Queue a sample: 'new', 'repeat' (the last one answered: send its answer
        again) or 'old' (ignored)."""
        if stamp_ns == self.last_ns:
            return "repeat"
        if stamp_ns < self.last_ns or any(stamp_ns == queued for queued, _ in self._samples):
            return "old"
        self._samples.append((stamp_ns, speed))
        return "new"

    def acceleration(self, stamp_ns: int, normal: float) -> None:
        """Keep an accelerometer sample until the answer that needs it."""
        self.accelerations(((stamp_ns, normal),))

    def accelerations(self, readings: Sequence[tuple[int, float]]) -> None:
        """Keep accelerometer samples (stamp [ns], normal), in the order they came, until the answers that need them."""
        if readings:
            self._accelerations.extend(readings)
            self._latest_acceleration_ns = max(self._latest_acceleration_ns, max(stamp for stamp, _ in readings))

    def next_ready(self, needs_accelerometer: bool) -> tuple[int, float, list[tuple[int, float]]] | None:
        """The oldest sample that can be answered now, with the accelerometer samples
        up to its time (taken off the queue), or None."""
        if not self._samples:
            return None
        stamp_ns, speed = self._samples[0]
        if needs_accelerometer and self.accelerometer_rate > 0.0 and \
                self._latest_acceleration_ns < self._last_reading_ns(stamp_ns):
            return None
        self._samples.popleft()
        fed = []
        while self._accelerations and self._accelerations[0][0] <= stamp_ns:
            fed.append(self._accelerations.popleft())
        return stamp_ns, speed, fed

    @property
    def waiting(self) -> bool:
        """Whether a sample waits for its answer."""
        return bool(self._samples)

    def _last_reading_ns(self, stamp_ns: int) -> int:
        """The stamp [ns] of the last reading on the grid k/rate stamped at or before ``stamp_ns``
        (the slider stamps a reading with its time in whole ns: one on the sample's own
        nanosecond may lie a fraction of one past it; -1 before the first)."""
        rate = self.accelerometer_rate
        k = len(grid(rate, 0, 0.0, (stamp_ns + 1) / NS_PER_S))
        while k > 0 and round((k - 1) / rate * NS_PER_S) > stamp_ns:
            k -= 1
        return round((k - 1) / rate * NS_PER_S) if k > 0 else -1

    def answered(self, stamp_ns: int, values: dict[str, float]) -> None:
        self.last_ns, self.last_answer = stamp_ns, dict(values)

    def diagnostics_due(self, stamp_ns: int) -> bool:
        """Whether diagnostics are due at the sample stamped ``stamp_ns``."""
        if stamp_ns < self._next_diagnostics_ns:
            return False
        while self._next_diagnostics_ns <= stamp_ns:
            self._next_diagnostics_ns += self.diagnostics_ns
        return True

    def values(self) -> dict[str, Any]:
        return {"lockstep": True, "actuation_delay": self.delay_ns / NS_PER_S,
                "lockstep_last_answered": self.last_ns / NS_PER_S if self.last_ns >= 0 else float("nan"),
                "lockstep_samples_waiting": len(self._samples)}


__all__ = ["AnswerQueue"]
