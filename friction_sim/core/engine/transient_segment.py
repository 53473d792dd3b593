"""The single slider's segments under the resonant exciter's transient.

A :class:`~friction_sim.core.engine.single.Slider` with the resonant actuator
carries the slideway's transient after a change (:class:`~friction_sim.core.engine.actuator.Exciter`);
while it lasts a segment's closed form is the steady one with the transient
force Re(c*exp(lam*tau)) added, its next event is sought by the compiled kernel
(:func:`~friction_sim.core.engine.transient_kernel.transient_step`) only up to a
look-ahead, and the segment is cut there (or where the transient settles) into
a new one from the same motion.  This module holds that handling: which
segment is under the transient (:class:`Transient`, a record per segment, so a
checkpoint of the slider holds it by reference), its motion and states, where
it stops holding, and the exciter a change or a boundary leaves.  The slider
keeps the state and the event loop; without a transient every function here
is the steady form of :mod:`friction_sim.core.physics.segment`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from friction_sim.core.engine import transient_kernel
from friction_sim.core.engine.actuator import Exciter, ExciterState
from friction_sim.core.engine.transient_kernel import transient_step
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics import stepper
from friction_sim.core.physics.numerics import Floats
from friction_sim.core.physics.plant import Plant
from friction_sim.core.physics.roots import NEVER
from friction_sim.core.physics.segment import Segment, Step, evaluate
from friction_sim.core.physics.stepper import transient_end
from friction_sim.core.physics.transient import slideway_acceleration, state_at

#: A state's numbers (x, v, acceleration, friction, normal force, phase, z, vz), at a time or at many.
States = tuple[Floats, Floats, Floats, Floats, Floats, Floats, Floats, Floats]


class Transient(NamedTuple):
    """The exciter's transient over the present segment: its force Re(c*exp(lam*tau))
    ``tau`` after the segment's start (``c`` = 0: none, the steady forms hold), and
    where the segment's search for its next event ends (``look_until`` [s])."""

    c: complex
    lam: complex
    look_until: float


#: A segment without a transient (the force actuator, or one that has settled).
STEADY = Transient(0j, 0j, -NEVER)


def start(exciter: Exciter | None, plant: Plant, seg: Segment, frequency: float) -> tuple[Transient, Step] | None:
    """The transient ``seg`` starts under and its next step, sought up to the look-ahead
    (``LOOK_AHEAD_PERIODS`` periods of ``frequency``) or the settling, whichever is sooner;
    None if the exciter has no transient at the segment's start (the steady step applies)."""
    if exciter is None or not exciter.active(seg.t0):
        return None
    c, horizon = exciter.window(seg.t0, frequency)
    step = transient_step(plant, c, exciter.lam, horizon, seg.mode, seg.phase0, seg.v0, seg.vz0, seg.z0, seg.closing,
                          seg.grounded)
    return Transient(c, exciter.lam, seg.t0 + horizon), step


def motion(plant: Plant, seg: Segment, transient: Transient, tau: float) -> tuple[float, float, float, float]:
    """(x(tau) - x(0), v, vz, z) ``tau`` into ``seg`` (with the exciter's transient, if it has one)."""
    return stepper.motion(plant, seg, transient.c, transient.lam, tau)


def states(plant: Plant, seg: Segment, transient: Transient, tau: Floats) -> States[Floats]:
    """The state ``tau`` into ``seg``, at a float or an array of times
    (:func:`~friction_sim.core.physics.segment.evaluate`); under the exciter's
    transient the states are
    :func:`~friction_sim.core.physics.transient.transient_evaluate`'s, one by one
    (so a sampled state is the scalar one, bit for bit)."""
    c, lam = transient.c, transient.lam
    if isinstance(tau, float):
        return state_at(plant, seg, c, lam, tau)
    if not c:
        return evaluate(plant, seg, tau)
    rows = zip(*(state_at(plant, seg, c, lam, each) for each in tau.tolist()))
    x, v, acc, friction, normal, theta, z, vz = (np.array(column, dtype=float) for column in rows)
    return x, v, acc, friction, normal, theta, z, vz


def states_at(plant: Plant, seg: Segment, transient: Transient, taus: list[float]) -> list[list[float]]:
    """The states at each of ``taus`` into ``seg``, as :func:`states` gives them at a float, bit
    for bit (:func:`~friction_sim.core.engine.transient_kernel.states_at`: compiled when ready)."""
    return transient_kernel.states_at(plant, seg, transient.c, transient.lam, taus)


def segment_end(seg: Segment, transient: Transient, next_t: float) -> tuple[float, bool]:
    """(time, cut): where ``seg``'s closed form stops holding, and whether it is cut
    there rather than ended by its next event (at ``next_t``).

    Under the exciter's transient a segment holds only up to its boundary,
    the end of its look-ahead or the time the transient settles (never
    before its start): its next event is sought no further (none found:
    ``next_t`` is inf), and there the slider starts a new segment from the
    same motion, whose next event is sought on.  The boundary cuts the
    segment unless its next event comes before it.  Advancing and sampling
    both end the segment here, so they evaluate every time in the same segment."""
    return transient_end(seg, transient.c, transient.look_until, next_t)


def cut_by(seg: Segment, transient: Transient, next_t: float, t: float, next_mark_t: float) -> float | None:
    """The boundary (:func:`segment_end`) that cuts ``seg`` by ``t`` and not after
    the next period start at ``next_mark_t`` (inf: none kept); None if there is none."""
    boundary, cut = segment_end(seg, transient, next_t)
    if not cut or boundary > t or boundary > next_mark_t:
        return None
    return boundary


def exciter_after(exciter: Exciter | None, params: SliderParams, inputs: Inputs, plant: Plant, t: float,
                  phase: float, boundary: bool) -> Exciter | None:
    """The exciter from a new segment at ``t`` (excitation ``phase``) on: at a
    ``boundary`` of its transient's segment nothing else changes (the transient is
    dropped if it has settled, else kept as it is); at a change of ``params`` and
    ``inputs`` (with ``plant``, theirs) the slideway's motion carries on into the
    new steady state (none with the force actuator)."""
    if boundary:
        assert exciter is not None
        return exciter.settled(t)
    if not params.resonant:
        return None
    if exciter is None:
        return Exciter(params, inputs, t0=t)
    return exciter.change(params, inputs, plant, t, phase)


class ExciterReadings:
    """What a slider's resonant exciter reads now: the exciter's state and the slideway's
    acceleration (a base of :class:`~friction_sim.core.engine.single.Slider`, which holds
    the state it reads)."""

    _t: float
    _seg: Segment
    _plant: Plant
    _exciter: Exciter | None
    _transient: Transient

    def slideway_acceleration(self) -> tuple[float, float]:
        """(along, normal) [m/s^2]: the slideway's acceleration now in the track frame
        (:func:`~friction_sim.core.physics.transient.slideway_acceleration`)."""
        seg = self._seg
        return slideway_acceleration(self._plant, seg.phase0, self._transient.c, self._lam(), self._t - seg.t0)

    def _accelerations_at(self, times: list[float]) -> list[list[float]]:
        """(along, normal) at each of ``times`` in the present segment, as
        :meth:`slideway_acceleration` gives them there, bit for bit (compiled when ready)."""
        seg = self._seg
        return transient_kernel.accelerations_at(self._plant, seg, self._transient.c, self._lam(),
                                                 [t - seg.t0 for t in times])

    def _lam(self) -> complex:
        """The exciter's eigenvalue (0 with the force actuator)."""
        return self._exciter.lam if self._exciter is not None else 0j

    @property
    def exciter(self) -> ExciterState | None:
        """The resonant exciter's state now (None with the force actuator)."""
        if self._exciter is None:
            return None
        seg = self._seg
        theta = seg.phase0 + self._plant.omega * (self._t - seg.t0)
        return self._exciter.state(self._t, theta)


__all__ = ["STEADY", "ExciterReadings", "States", "Transient", "cut_by", "exciter_after", "motion", "segment_end",
           "start", "states", "states_at"]
