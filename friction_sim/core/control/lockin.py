"""The slideway's vibration, period by period, from accelerometer samples: the
measurement of a controller that works through a resonant exciter (numpy only).

An industrial feeder controller does not see the excitation force; it sees the
slideway's acceleration.  Each excitation period of the slider ends where the
drive phase is a whole turn, and the slider stamps its ``mean_velocity`` sample
there, so a controller knows from two consecutive stamps t0 < t1 that the drive
phase was 2*pi*(t - t0)/(t1 - t0) in between.  Over the accelerometer's normal
readings of that period it fits, by least squares,

    a_z(t) = c + I*sin(theta) + Q*cos(theta),

three unknowns: exact for a vibration at the drive frequency plus a constant
(gravity, a bias) whatever the sample times, and the least-squares estimate
under white noise (its error is about the noise over sqrt(samples/2)).  In
steady state the part feels P = -m*q'' = m*u*A*G*sin(theta - lag)
(:mod:`friction_sim.core.physics.exciter`) and the sensor reads the slideway's
q'' = -P/m (the specific force, gravity aside): so the amplitude of P per unit
mass is hypot(I, Q) and its lag behind the drive is the phase of -(I + i*Q)
measured backwards, pi/2 at resonance.  While a transient decays the fit is the
period's best sinusoid at the drive frequency: the lock-in's reading of the
envelope, which is what a technician's instrument shows.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.physics.numerics import solve_positive_definite
from friction_sim.errors import ParameterError

#: A period's fit needs at least this many samples (three unknowns, and one to spare).
MIN_SAMPLES = 4
#: Samples kept at most while waiting for a window's end.
MAX_SAMPLES = 200_000


@dataclass(frozen=True)
class Vibration:
    """One period's reading: ``amplitude`` [m/s^2] of the slideway's normal
    acceleration at the drive frequency (the part feels mass times it), the
    ``lag`` [rad, in (-pi, pi]] of the part's force behind the drive (pi/2 at
    resonance, less below it, more above), the constant part ``offset``
    [m/s^2] (g*cos(alpha) and the sensor's bias), over [t_start, t_end] from
    ``samples`` readings at ``times``."""

    t_start: float
    t_end: float
    amplitude: float
    lag: float
    offset: float
    samples: int
    #: The sample times the fit was made from (a model's own reading can be made at the same times).
    times: tuple[float, ...] = ()
    #: Drive periods between t_start and t_end (the slider's mean window).
    cycles: int = 1


def fit_period(times: Iterable[float], normal: Iterable[float], t_start: float, t_end: float,
               cycles: int = 1) -> Vibration:
    """The least-squares reading of one window of ``cycles`` drive periods from
    the samples (t, a_z) in it (see the module doc); a :class:`ParameterError`
    if the window is empty, holds fewer than :data:`MIN_SAMPLES` samples, or
    holds them at too few phases of the drive to tell its sine from its cosine.

    The three unknowns solve the fit's normal equations, their sums correctly
    rounded (``math.fsum``) and solved in plain floats
    (:func:`~friction_sim.core.physics.numerics.solve_positive_definite`): the
    same reading on every CPU, which a LAPACK least-squares solve is not.
    Over a period the three columns are nearly orthogonal (they are orthogonal
    for evenly spread samples), so the normal equations lose nothing to their
    squared condition number."""
    t = times if isinstance(times, tuple) else tuple(_floats(times))
    z = normal if isinstance(normal, (list, tuple)) else _floats(normal)
    if not t_end > t_start:
        raise ParameterError("period", (t_start, t_end), "must end after it starts")
    if len(t) < MIN_SAMPLES or len(t) != len(z):
        raise ParameterError("samples", len(t), f"a period needs at least {MIN_SAMPLES} accelerometer samples")
    scale, span = TWO_PI * cycles, t_end - t_start
    sines, cosines = [], []
    for ti in t:
        theta = scale * (ti - t_start) / span
        sines.append(math.sin(theta))
        cosines.append(math.cos(theta))
    fsum = math.fsum
    sin_cos = fsum([s * c for s, c in zip(sines, cosines, strict=True)])
    gram = ((float(len(t)),), (fsum(sines), fsum([s * s for s in sines])),
            (fsum(cosines), sin_cos, fsum([c * c for c in cosines])))
    moments = (fsum(z), fsum([s * a for s, a in zip(sines, z, strict=True)]),
               fsum([c * a for c, a in zip(cosines, z, strict=True)]))
    solution = solve_positive_definite(gram, moments)
    if solution is None:
        raise ParameterError("samples", len(t), "the samples lie at too few phases of the drive to read its phase")
    offset, in_phase, quadrature = solution
    # q'' = -P/m = -R sin(theta - lag) = I sin(theta) + Q cos(theta): I = -R cos(lag), Q = R sin(lag)
    lag = math.atan2(quadrature, -in_phase)
    return Vibration(t_start, t_end, math.hypot(in_phase, quadrature), lag, offset, len(t), t, cycles)


def _floats(values: Iterable[float]) -> list[float]:
    """``values`` as Python floats (an array's through ``tolist``, one call)."""
    return np.asarray(values, dtype=float).tolist() if isinstance(values, np.ndarray) else [float(v) for v in values]


class LockIn:
    """Collects accelerometer readings and period boundaries (the slider's
    mean_velocity stamps), which may arrive in any order between the two
    topics, and reads each period once all its samples have come (a sample at
    or after its end has arrived: each topic arrives in order)."""

    def __init__(self, keep: float = 0.5, cycles: int = 1) -> None:
        #: Drive periods between two boundaries (the slider's mean_window_periods).
        self.cycles = cycles
        # Bounded if boundaries stop coming (a controller standing by): 200,000 samples, 2 s at the
        # accelerometer's top rate, more than any window needs at a rate that resolves its drive period.
        self._samples: deque[tuple[float, float]] = deque(maxlen=MAX_SAMPLES)
        self._bounds: deque[float] = deque(maxlen=4096)  # bounded if readings() is never asked for
        self._latest = -math.inf
        #: Whether every sample came at or after the one before (each topic arrives in order):
        #: then a period's samples are found from the newest back, not by a scan of all kept.
        self._in_order = True
        self._keep = keep  # seconds of samples kept before the oldest open period (a late boundary)

    def add_sample(self, t: float, normal: float) -> None:
        """An accelerometer reading: the normal specific force [m/s^2] at simulation time ``t``."""
        self.add_samples(((t, normal),))

    def add_samples(self, samples: Sequence[tuple[float, float]]) -> None:
        """Accelerometer readings (t, normal), in the order they came (a thousand a second: a
        controller hands over a window's at once)."""
        latest, in_order = self._latest, self._in_order
        for t, _ in samples:
            if t > latest:
                latest = t
            elif t < latest:
                in_order = False
        self._latest, self._in_order = latest, in_order
        self._samples.extend(samples)

    def add_boundary(self, t: float) -> None:
        """A period ended at ``t`` (drive phase a whole turn): a mean_velocity stamp."""
        if not self._bounds or t > self._bounds[-1]:
            self._bounds.append(t)

    def forget(self) -> None:
        """Drop everything (the plant was reset or its time jumped)."""
        self._samples.clear()
        self._bounds.clear()
        self._latest = -math.inf
        self._in_order = True

    def readings(self) -> list[Vibration]:
        """The periods completed since the last call, oldest first (a period with
        too few samples is skipped: the accelerometer is off or too slow; so is one
        whose samples lie at too few phases of the drive to read it: a rate a small
        multiple of the drive's, over more than one period)."""
        done: list[Vibration] = []
        while len(self._bounds) >= 2 and self._latest >= self._bounds[1]:
            start, end = self._bounds.popleft(), self._bounds[0]
            inside = self._inside(start, end)
            if len(inside) >= MIN_SAMPLES:
                times, normal = zip(*inside, strict=True)
                try:
                    done.append(fit_period(times, normal, start, end, self.cycles))
                except ParameterError:  # the phases cannot be told apart (the only refusal left here)
                    continue
        oldest = self._bounds[0] if self._bounds else self._latest
        while self._samples and self._samples[0][0] < oldest - self._keep:
            self._samples.popleft()
        return done

    def _inside(self, start: float, end: float) -> list[tuple[float, float]]:
        """The samples kept with start <= t <= end, in the order they came.  In time order
        (the usual case) they are the last ones before any after ``end``: a walk back from
        the newest stops at the first before ``start``, so a period costs its own samples,
        not the half second kept before it."""
        if not self._in_order:
            return [(t, z) for t, z in self._samples if start <= t <= end]
        inside: list[tuple[float, float]] = []
        for sample in reversed(self._samples):
            if sample[0] < start:
                break
            if sample[0] <= end:
                inside.append(sample)
        inside.reverse()
        return inside


__all__ = ["MAX_SAMPLES", "MIN_SAMPLES", "LockIn", "Vibration", "fit_period"]
