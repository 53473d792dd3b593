"""The inverse of the general mean-speed relation: the amplitude for a speed.

For Kostek's model below lift-off U rises monotonically with a = Pa/(m*g)
from the motion boundary, and :func:`~friction_sim.core.meanspeed.urelation.amplitude_ratio_for`
inverts it exactly.  In general (an inclined vibration, a slope, a hopping
slider) U(a) rises from where motion starts, peaks, and may fall, jump or
turn irregular beyond: only the first rising stretch, the *branch*, is
inverted, and its end is reported.  A :class:`Branch` is built once per plant
and direction (it is cached: the controller asks once per sample):

* U is sampled at ``samples`` amplitude ratios evenly spaced on
  [0, max_ratio] with :func:`~friction_sim.core.meanspeed.general.mean_speed`
  (exact for the closed-form cases, the exact simulated motion elsewhere,
  an irregular one averaged over :data:`BRANCH_PERIODS` after
  :data:`BRANCH_SETTLE_PERIODS`); where the drive beats friction
  (|Fd + Fx - m g sin(alpha)| > mu (m g cos(alpha) - Fz)) every amplitude
  runs away and the branch is empty without a simulation;
* with s = +1 for a forward target and -1 for a backward one, the branch
  starts at the last sample before s*U first becomes positive (there
  s*U <= 0: the motion boundary lies between the two) and runs while s*U
  rises from sample to sample (or stays put, to :data:`PLATEAU_TOLERANCE`)
  and stays finite (a runaway ends it);
* if it ends before max_ratio its peak is refined by a golden-section search
  between the neighbouring samples (:data:`PEAK_STEPS` steps), giving
  (a_end, U_end);
* a target s*U* in (s*U_start, s*U_end] is bracketed between two samples of
  the branch and solved on the exact mean-speed function by the Illinois
  variant of regula falsi, to :data:`U_TOLERANCE` relative in U or until the
  bracket is a few ulps wide.  A target beyond the end (or before the
  start, where the plant already moves at a = 0) is unreachable: NaN.

U does not depend on the excitation frequency, so the branch is built at
:data:`~friction_sim.core.meanspeed.general.REFERENCE_FREQUENCY` and serves every
frequency; it depends on the plant, the drive force and the external forces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from friction_sim.core.meanspeed.general import REFERENCE_FREQUENCY, MeanSpeed, mean_speed
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import amplitude_for, amplitude_ratio, beats_friction
from friction_sim.core.model.params import Inputs, SliderParams, cos_degrees, sin_degrees
from friction_sim.core.physics.roots import illinois_update
from friction_sim.errors import ParameterError

#: Amplitude ratios sampled on [0, max_ratio] to find the branch.
DEFAULT_SAMPLES = 40
#: The window of every mean speed the branch is made of: a motion that does not repeat within
#: BRANCH_SETTLE_PERIODS is averaged over BRANCH_PERIODS (half mean_speed's defaults: the branch
#: takes some fifty of them, and a controller's model need not be finer than that).
BRANCH_SETTLE_PERIODS = 100
BRANCH_PERIODS = 100
#: Golden-section steps refining the peak that ends a branch (its bracket shrinks to 0.618**steps).
PEAK_STEPS = 10
#: A sample within this fraction below the one before still continues the branch: a stretch where U
#: stays put (a plateau: one at cot(beta)/(2 mu) follows the one-period flights) is rounding noise apart.
PLATEAU_TOLERANCE = 1e-9
#: The inverse stops where U meets the target to this fraction of it.
U_TOLERANCE = 1e-12
#: The largest amplitude ratio a branch may reach (that of the controller's max_amplitude_ratio).
MAX_RATIO = float(spec.MAX_AMPLITUDE_RATIO.high or 10.0)
#: Most mean-speed evaluations one inversion may take.
MAX_ITERATIONS = 60
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


@dataclass(frozen=True)
class Branch:
    """The first stretch where s*U rises with the amplitude ratio a (s = ``direction``).

    ``a`` and ``u`` are the samples of U(a) on [0, ``max_ratio``]
    (``periodic``: where the motion repeats, see :class:`~friction_sim.core.meanspeed.general.MeanSpeed`);
    (a_start, u_start) is the sample where the branch starts (s*U <= 0 there,
    unless the plant moves at a = 0 already) and (a_end, u_end) its end: its
    peak, or ``max_ratio``.  ``empty``: s*U never becomes positive (finitely)
    below ``max_ratio``, so no target in that direction is reachable.
    ``params`` and the forces are the plant's in units of its weight (mass
    1 kg, gravity 1 m/s^2, forces over m*g): U depends on nothing else.
    """

    params: SliderParams
    drive_force: float
    external_force_x: float
    external_force_z: float
    max_ratio: float
    direction: int
    a: NDArray[np.float64]
    u: NDArray[np.float64]
    periodic: NDArray[np.bool_]
    a_start: float
    u_start: float
    a_end: float
    u_end: float
    empty: bool
    #: The branch's samples (a, s*U), s*U strictly rising: where a target is bracketed.
    nodes_a: tuple[float, ...] = ()
    nodes_g: tuple[float, ...] = ()

    def u_at(self, ratio: float) -> float:
        """U at amplitude ratio ``ratio`` (the exact mean speed)."""
        return _u(self.params, self.plant_inputs(), ratio)

    def plant_inputs(self) -> Inputs:
        """The inputs the branch is made for (amplitude 0, the reference frequency)."""
        return Inputs(drive_force=self.drive_force, excitation_frequency=REFERENCE_FREQUENCY,
                      external_force_x=self.external_force_x, external_force_z=self.external_force_z)

    def reachable(self, u: float) -> bool:
        """True where ``u`` lies on the branch: s*u in (s*u_start, s*u_end]."""
        target = self.direction * u
        return (not self.empty and self.direction * self.u_start < target <= self.direction * self.u_end
                and target > 0.0)

    def amplitude_ratio_for(self, u: float) -> float:
        """The amplitude ratio a on the branch with U(a) = ``u`` (NaN: not on it)."""
        if not self.reachable(u):
            return math.nan
        return _solve(self, self.direction * u)


def rising_branch(params: SliderParams, inputs: Inputs, max_ratio: float, direction: int = 1, *,
                  samples: int = DEFAULT_SAMPLES) -> Branch:
    """The :class:`Branch` of ``params`` under ``inputs`` (its drive and external
    forces; amplitude and frequency do not matter) for amplitude ratios up to
    ``max_ratio``, in ``direction`` +1 (U rises) or -1 (U falls).  Cached."""
    if not (isinstance(max_ratio, (int, float)) and math.isfinite(max_ratio) and max_ratio > 0.0):
        raise ParameterError("max_ratio", max_ratio, "must be a finite number > 0")
    if direction not in (1, -1):
        raise ParameterError("direction", direction, "must be +1 or -1")
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 3:
        raise ParameterError("samples", samples, "must be an integer >= 3")
    if max_ratio > MAX_RATIO:
        raise ParameterError("max_ratio", max_ratio, f"must be <= {MAX_RATIO:g}")
    # U depends on the forces only through their ratios to the weight: the branch is built for the plant
    # in units of its weight (1 kg at 1 m/s^2), so every mass and gravity of one shape shares it.
    weight = params.weight
    unit = params.replace(mass=1.0, gravity=1.0)
    return _branch(unit, amplitude_ratio(inputs.drive_force, weight), amplitude_ratio(inputs.external_force_x, weight),
                   amplitude_ratio(inputs.external_force_z, weight), float(max_ratio), direction, samples)


def amplitude_ratio_for_general(u: float, params: SliderParams, inputs: Inputs, max_ratio: float) -> float:
    """The amplitude ratio a <= ``max_ratio`` with mean speed U(a) = ``u`` on the
    rising branch of ``params`` under ``inputs`` (drive and external forces),
    NaN where ``u`` is not on it.  ``u`` = 0 gives 0 where the plant stands
    still without excitation."""
    u = float(u)
    if not math.isfinite(u):
        raise ParameterError("u", u, "must be finite")
    if u == 0.0:
        return 0.0 if _u(params, inputs, 0.0) == 0.0 else math.nan
    branch = rising_branch(params, inputs, max_ratio, 1 if u > 0.0 else -1)
    return branch.amplitude_ratio_for(u)


def _mean(params: SliderParams, inputs: Inputs, ratio: float) -> MeanSpeed:
    plant = inputs.replace(excitation_amplitude=amplitude_for(ratio, params.weight),
                           excitation_frequency=REFERENCE_FREQUENCY)
    return mean_speed(params, plant, settle_periods=BRANCH_SETTLE_PERIODS, periods=BRANCH_PERIODS)


def _u(params: SliderParams, inputs: Inputs, ratio: float) -> float:
    return _mean(params, inputs, ratio).u


@lru_cache(maxsize=32)
def _branch(params: SliderParams, drive: float, fx: float, fz: float, max_ratio: float, direction: int,
            samples: int) -> Branch:
    inputs = Inputs(drive_force=drive, excitation_frequency=REFERENCE_FREQUENCY, external_force_x=fx,
                    external_force_z=fz)
    a = max_ratio * np.arange(samples) / (samples - 1)
    a[-1] = max_ratio
    pull, load = drive + fx - sin_degrees(params.track_inclination), cos_degrees(params.track_inclination) - fz
    if beats_friction(pull, load, params.mu):
        # The drive (with the slope's pull) beats the most friction the track can give on average: every
        # amplitude runs away (the excitation averages to nothing), no simulation needed to say so.
        u = np.full(samples, math.copysign(math.inf, pull))
        periodic = np.zeros(samples, dtype=bool)
    else:
        means = [_mean(params, inputs, float(ratio)) for ratio in a]
        u = np.array([mean.u for mean in means])
        periodic = np.array([mean.periodic for mean in means])
    g = direction * u
    finite = np.isfinite(g)
    positive = np.nonzero(finite & (g > 0.0))[0]

    def made(nodes_a: list[float], nodes_g: list[float]) -> Branch:
        empty = not nodes_a
        first_a, first_g = (0.0, float(g[0])) if empty else (float(nodes_a[0]), float(nodes_g[0]))
        last_a, last_g = (0.0, float(g[0])) if empty else (float(nodes_a[-1]), float(nodes_g[-1]))
        return Branch(params=params, drive_force=drive, external_force_x=fx, external_force_z=fz,
                      max_ratio=max_ratio, direction=direction, a=a, u=u, periodic=periodic, a_start=first_a,
                      u_start=direction * first_g, a_end=last_a, u_end=direction * last_g, empty=empty,
                      nodes_a=tuple(float(x) for x in nodes_a), nodes_g=tuple(float(x) for x in nodes_g))

    if positive.size == 0:
        return made([], [])
    first = int(positive[0])
    start = max(first - 1, 0)
    if first > 0 and not (finite[start] and g[start] < g[first]):
        start = first  # a runaway sample before it: the branch starts where U is finite
    end = first
    while end + 1 < samples and finite[end + 1] and g[end + 1] >= g[end] - PLATEAU_TOLERANCE * abs(g[end]):
        end += 1
    nodes_a, nodes_g = [float(a[start])], [float(g[start])]
    for index in range(start + 1, end + 1):  # strictly rising nodes: a plateau keeps its first sample
        if g[index] > nodes_g[-1]:
            nodes_a.append(float(a[index]))
            nodes_g.append(float(g[index]))
    if end + 1 < samples and periodic[end]:  # a peak of irregular means is noise: not refined
        peak_a, peak_g = _peak(params, inputs, direction, float(a[end - 1] if end > start else a[end]),
                               float(a[end + 1]), float(a[end]), float(g[end]))
        if peak_g > nodes_g[-1]:
            position = int(np.searchsorted(nodes_a, peak_a))
            if position == len(nodes_a) or peak_g > nodes_g[position - 1]:
                nodes_a, nodes_g = nodes_a[:position] + [peak_a], nodes_g[:position] + [peak_g]
    return made(nodes_a, nodes_g)


def _peak(params: SliderParams, inputs: Inputs, direction: int, low: float, high: float, best_a: float,
          best_g: float) -> tuple[float, float]:
    """The largest s*U found by a golden-section search on [low, high] (best so far given)."""
    def g(ratio: float) -> float:
        value = direction * _u(params, inputs, ratio)
        return value if math.isfinite(value) else -math.inf

    x1, x2 = high - _GOLDEN * (high - low), low + _GOLDEN * (high - low)
    g1, g2 = g(x1), g(x2)
    for _ in range(PEAK_STEPS):
        for ratio, value in ((x1, g1), (x2, g2)):
            if value > best_g:
                best_a, best_g = ratio, value
        if g1 >= g2:
            high, x2, g2 = x2, x1, g1
            x1 = high - _GOLDEN * (high - low)
            g1 = g(x1)
        else:
            low, x1, g1 = x1, x2, g2
            x2 = low + _GOLDEN * (high - low)
            g2 = g(x2)
    for ratio, value in ((x1, g1), (x2, g2)):
        if value > best_g:
            best_a, best_g = ratio, value
    return best_a, best_g


def _solve(branch: Branch, target: float) -> float:
    """a with s*U(a) = target on the branch (target in (g_start, g_end])."""
    nodes_a, nodes_g = branch.nodes_a, branch.nodes_g
    j = int(np.searchsorted(nodes_g, target, side="left"))  # nodes_g[j-1] < target <= nodes_g[j]
    j = min(max(j, 1), len(nodes_g) - 1)
    lo, hi = nodes_a[j - 1], nodes_a[j]
    f_lo, f_hi = nodes_g[j - 1] - target, nodes_g[j] - target
    if f_hi == 0.0:
        return hi
    inputs = branch.plant_inputs()
    eps = np.finfo(float).eps
    side = 0
    best_a, best_f = hi, f_hi
    for _ in range(MAX_ITERATIONS):
        x = hi - f_hi * (hi - lo) / (f_hi - f_lo)
        if not lo < x < hi:
            x = 0.5 * (lo + hi)
        value = branch.direction * _u(branch.params, inputs, x)
        f = value - target if math.isfinite(value) else math.inf
        if abs(f) < abs(best_f):
            best_a, best_f = x, f
        if abs(f) <= U_TOLERANCE * target:
            return x
        lo, f_lo, hi, f_hi, side = illinois_update(lo, f_lo, hi, f_hi, side, x, f, f > 0.0)
        if hi - lo <= 4.0 * eps * hi:
            break
    return best_a


__all__ = ["Branch", "DEFAULT_SAMPLES", "amplitude_ratio_for_general", "rising_branch"]
