"""Kostek's model on its own fast segments: normal excitation, a level track,
one friction coefficient, and a slider that never leaves the track.

The general segments (:mod:`friction_sim.core.motion`) cover this case too;
these are kept because they are the paper's case, bit for bit as before, and
because they are cheaper: a stuck segment needs no closed form at all, and a
slip from rest is the same slip every period (see :class:`Slider`'s cache).
The model and its closed form are described in :mod:`friction_sim.core.slider`.
"""

from __future__ import annotations

import math
from types import ModuleType
from typing import Any

from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.roots import TWO_PI, from_rest_b0, trig_remainders, two_sum

# --------------------------------------------------------------------------
# The segment: closed-form motion between two events.
# --------------------------------------------------------------------------


class KostekPlant:
    """The constants of the motion under one set of parameters and inputs,
    computed once per change rather than once per segment."""

    __slots__ = ("omega", "tangential", "load", "amplitude", "mu", "b1", "b0", "direction")

    def __init__(self, params: SliderParams, inputs: Inputs) -> None:
        self.omega = TWO_PI * inputs.excitation_frequency
        self.tangential = inputs.tangential_force
        self.load = params.weight - inputs.external_force_z
        self.amplitude = inputs.excitation_amplitude
        self.mu = params.mu
        self.b1 = self.mu * self.amplitude / params.mass
        #: b0 of dw/dt = b0 + b1*sin(theta) for a slip in direction d, at index d (0, +1, -1).
        self.b0 = tuple((d * self.tangential - self.mu * self.load) / params.mass for d in (0, 1, -1))
        #: the direction a slip from rest takes: sign(Ft)
        self.direction = 1 if self.tangential > 0.0 else -1


class KostekSegment:
    """Closed-form motion from (x0, w0, phase0) under constant inputs.

    ``direction`` 0 is stuck; +-1 is a slip, whose speed w = direction*v.
    ``phase0`` is in [0, 2*pi); ``cycles`` counts the whole excitation periods
    before it, so the total phase at its start is 2*pi*cycles + phase0.

    It starts at time ``t0``; ``s0`` is that start as an offset from the
    slider's phase anchor (see :class:`Slider`), before rounding to ``t0``, and
    the next event is timed from it, so event times do not inherit one
    another's rounding.  The position is a double-double
    ``x0 + xl``, so that a long run's travel is a sum without rounding drift.
    """

    __slots__ = (
        "t0", "s0", "x0", "xl", "w0", "phase0", "cycles", "direction", "plant", "omega", "b0", "b1", "g0",
        "cos0", "sin0", "stop",
    )

    def __init__(
        self, s0: float, t0: float, x0: float, xl: float, w0: float, phase0: float, cycles: int,
        direction: int, plant: KostekPlant,
    ) -> None:
        self.s0, self.t0 = s0, t0
        self.x0, self.xl, self.w0, self.phase0, self.direction = x0, xl, w0, phase0, direction
        self.cycles, self.plant, self.omega = cycles, plant, plant.omega
        #: (signed travel, raw phase) where the slip stops (None: it never stops)
        self.stop: tuple[float, float] | None = None
        if direction:  # a stuck segment needs none of a slip's constants
            self.b1 = plant.b1
            self.cos0, self.sin0 = math.cos(phase0), math.sin(phase0)
            self.b0 = from_rest_b0(w0, plant.b0[direction], self.b1, self.sin0)
            self.g0 = self.b0 + self.b1 * self.sin0

    def evaluate(self, t: Any, xp: ModuleType = math) -> tuple[Any, Any, Any, Any, Any, Any]:
        """(x, v, acceleration, friction force, normal force, phase) at time(s) t.

        The phase is counted from this segment's start of period, unreduced
        (see :func:`friction_sim.core.roots.reduce_phase`).  ``xp`` is ``math`` for one float or
        ``numpy`` for an array of times.
        """
        return self.after(t - self.t0, xp)

    def after(self, tau: Any, xp: ModuleType = math) -> tuple[Any, Any, Any, Any, Any, Any]:
        """:meth:`evaluate` at ``tau`` after the segment's start."""
        plant = self.plant
        theta = self.phase0 + self.omega * tau
        sin_theta = xp.sin(theta)
        normal = plant.load - plant.amplitude * sin_theta
        s = self.direction
        if s == 0:
            zero = tau * 0.0
            return self.x0 + zero, zero, zero, -plant.tangential + zero, normal, theta
        w, travel = self.speed_and_travel(tau, xp)
        acceleration = s * (self.b0 + self.b1 * sin_theta)
        return self.x0 + (self.xl + s * travel), s * w, acceleration, -s * plant.mu * normal, normal, theta

    def position(self, tau: float) -> tuple[float, float]:
        """The position ``tau`` into the segment as a double-double (hi, lo)."""
        if self.direction == 0:
            return self.x0, self.xl
        return two_sum(self.x0, self.xl + self.direction * self.speed_and_travel(tau)[1])

    def speed_and_travel(self, tau: Any, xp: ModuleType = math) -> tuple[Any, Any]:
        """Speed w and distance travelled (>= 0, along the slip) ``tau`` into a slip."""
        k = self.b1 / self.omega
        c1, s2, c2 = trig_remainders(self.omega * tau, xp)
        w = self.w0 + self.g0 * tau + k * (self.cos0 * c1 - self.sin0 * s2)
        travel = (
            self.w0 * tau + 0.5 * self.g0 * tau * tau
            + (k / self.omega) * (self.cos0 * s2 - self.sin0 * c2)
        )
        return w, travel

    def to_cycle(self, n: int) -> float:
        """tau at which the total phase reaches 2*pi*n (0 if it already had)."""
        whole = n - self.cycles
        if whole <= 0:
            return 0.0
        return (TWO_PI * whole - self.phase0) / self.omega


__all__ = ["KostekPlant", "KostekSegment"]
