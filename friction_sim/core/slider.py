"""The exact, event-driven stick-slip core (no ROS, numpy only).

Model (R. Kostek): a rigid slider of mass m on a slideway with one Coulomb
friction coefficient mu, pushed by a tangential force Ft = Fd + Fx and unloaded
by a normal harmonic force, so that the normal reaction is

    R(t) = m*g + Fz - Pa*sin(theta(t)),   d(theta)/dt = 2*pi*f.

Stuck (v = 0) while |Ft| <= mu*R; slipping, m*dv/dt = Ft - mu*R*sign(v).

Between two events every quantity has a closed form, because the acceleration
is a constant plus a sinusoid.  Writing s = +-1 for the slip direction and
w = s*v >= 0 for the speed, over a slip that starts at (t0, x0, w0, theta0):

    w(tau)  = w0 + B0*tau + (B1/omega)*(cos(theta0) - cos(theta0 + omega*tau))
    B0 = (s*Ft - mu*(m*g + Fz)) / m,   B1 = mu*Pa/m >= 0

and x is its integral.  Events are the roots of simple equations:

* stick -> slip: |Ft| rises above mu*R, i.e. Pa*sin(theta) > m*g + Fz - |Ft|/mu,
  solved in closed form with asin;
* slip -> stick or reversal: w returns to 0.  w is monotone between the zeros
  of w' = B0 + B1*sin(theta), so the root is bracketed on the first falling
  stretch that ends at or below zero (found in closed form, because the minima
  of w grow by exactly B0*T from one period to the next) and polished with a
  Newton iteration guarded by bisection.

So there is no step size anywhere, a stuck slider does not creep (x is held,
not integrated), and because a segment is evaluated from its own start, how the
time axis is cut into :meth:`Slider.advance_to` calls does not change the
result.  Every slip from rest at the same phase with the same inputs is the same
slip, which is why the periodic regime is cheap: its stop time is cached.

The design follows scipy's ``_ivp`` solvers: one object owns the state and
advances it; detecting the next event (:func:`next_slip_start`,
:func:`slip_stop_delay`) is kept apart from acting on it
(:meth:`Slider._apply`); results come back as typed records
(:class:`SliderState`, :class:`Event`, :class:`Trajectory`).
"""

from __future__ import annotations

import math
from fractions import Fraction
from collections import deque
from dataclasses import dataclass, fields
from enum import Enum, IntEnum
from types import ModuleType
from typing import Any, Deque, NamedTuple

import numpy as np

from friction_sim.errors import ParameterError
from friction_sim.core.params import Inputs, SliderParams, check_contact, require_finite

TWO_PI = 2.0 * math.pi
NEVER = math.inf

#: Phase tolerance [rad] below which a rounding-level distance from the slip
#: window's edge counts as being on the edge (a full period is never skipped).
_PHASE_EDGE = 1e-12
_CACHE_LIMIT = 256
#: Slips predicted to last longer than this many excitation periods never stop.
_LONGEST_SLIP = 1e12


class Mode(IntEnum):
    """What the slider is doing: its slip direction, or stuck."""

    BACKWARD = -1
    STUCK = 0
    FORWARD = 1


_MODES = {-1: Mode.BACKWARD, 0: Mode.STUCK, 1: Mode.FORWARD}


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
        columns = (self.t, self.x, self.v, self.acceleration, self.friction_force, self.normal_force, self.phase)
        return [SliderState(*(float(c[k]) for c in columns), Mode(int(self.mode[k]))) for k in range(self.t.size)]


# --------------------------------------------------------------------------
# Event detection: pure functions of one segment's data.
# --------------------------------------------------------------------------


def next_slip_start(phase: float, b0: float, b1: float, *, closing: bool = False) -> tuple[float, float]:
    """``(delta, start)``: the phase still to run until a stuck slider starts to
    slip (0: at once, ``inf``: never), seen from excitation phase ``phase``,
    and the phase in [0, 2*pi) at which it starts.

    ``b0`` and ``b1`` >= 0 are the coefficients the slip would have in its
    direction s = sign(Ft): dw/dt = b0 + b1*sin(theta) with
    b0 = (|Ft| - mu*(m*g + Fz))/m and b1 = mu*Pa/m.  The slider is stuck
    exactly while that would be <= 0 (|Ft| <= mu*R), so the slip window is
    (beta, pi - beta) with beta = asin(-b0/b1), the same expression
    :func:`slip_stop_delay` uses: onset and stop can never disagree.

    ``closing`` is set for a slider that has just come to rest from a slip in
    the same direction.  It stopped because it was decelerating, so on the
    closing side of the window (where mu*R rises again, cos(theta) <= 0) an
    at-once restart could only come from rounding; it waits for the window to
    open again instead.  That guarantees progress at the window's closing edge.
    """
    if b1 <= 0.0:
        return (0.0, phase) if b0 > 0.0 and not closing else (NEVER, NEVER)
    if b0 + b1 <= 0.0:
        return NEVER, NEVER
    closing = closing and math.cos(phase) <= 0.0
    if b0 + b1 * math.sin(phase) > 0.0 and not closing:
        return 0.0, phase
    ratio = -b0 / b1
    if ratio < -1.0:  # the window covers every phase; only rounding kept us here
        return (TWO_PI, phase) if closing else (0.0, phase)
    start = math.asin(ratio) % TWO_PI
    delta = (start - phase) % TWO_PI
    if closing:
        return (delta, start) if delta > 0.0 else (TWO_PI, start)
    if delta > TWO_PI - _PHASE_EDGE:  # a hair past the edge: starts now
        return 0.0, phase
    return delta, start


def can_ever_slip(params: SliderParams, inputs: Inputs) -> bool:
    """Whether |Ft| > mu*(m*g + Fz - Pa): the slider can slip at some phase.

    Decided in exact rational arithmetic on the given binary values, so that a
    slider on the motion boundary phi = 1 - a (up to its last bit) never
    moves, not even by a rounding-sized step.
    """
    excess_f = abs(inputs.tangential_force)
    least_f = params.weight + inputs.external_force_z - inputs.excitation_amplitude
    margin = excess_f - params.mu * least_f
    if abs(margin) > 1e-9 * (excess_f + params.mu * abs(least_f)):  # clear either way
        return margin > 0.0
    excess = abs(Fraction(inputs.drive_force) + Fraction(inputs.external_force_x))
    least_load = (
        Fraction(params.mass) * Fraction(params.gravity)
        + Fraction(inputs.external_force_z) - Fraction(inputs.excitation_amplitude)
    )
    return excess > Fraction(params.mu) * least_load


def slip_stop_delay(w0: float, b0: float, b1: float, phase0: float, omega: float) -> float:
    """Time until the speed w = s*v of a slip returns to zero (``inf``: never).

    ``w0`` >= 0 is the speed at the start, ``b0`` and ``b1`` >= 0 the constant
    and sinusoidal parts of dw/dt = b0 + b1*sin(phase0 + omega*tau).  A slip
    predicted to last more than ``_LONGEST_SLIP`` excitation periods is taken
    as endless (its drift b0 is then within rounding of zero).
    """
    b0 = from_rest_b0(w0, b0, b1, math.sin(phase0))
    if b1 <= 0.0:
        if b0 >= 0.0:
            return NEVER
        return w0 / -b0
    if b0 >= b1:  # dw/dt >= 0 everywhere: it never comes back
        return NEVER
    if b0 <= -b1:  # dw/dt <= 0 everywhere: one falling stretch from now on
        if w0 == 0.0:
            return 0.0
        hi = (w0 + (b1 / omega) * (1.0 + math.cos(phase0))) / -b0
        return _falling_root(w0, b0, b1, phase0, omega, 0.0, hi)
    return _stop_with_turning_points(w0, b0, b1, phase0, omega)


def _stop_with_turning_points(w0: float, b0: float, b1: float, phase0: float, omega: float) -> float:
    """slip_stop_delay for |b0| < b1, where w rises and falls once per period.

    In delta = phase - beta (beta = asin(-b0/b1), where w has its minimum)
    w rises on (0, pi - 2*beta) and falls on [pi - 2*beta, 2*pi], and so on
    every period; the minima (at delta = 2*pi*k) differ by exactly b0*T.
    """
    beta = math.asin(-b0 / b1)
    rise = math.pi - 2.0 * beta
    delta0 = (phase0 - beta) % TWO_PI
    if w0 == 0.0:
        if delta0 > TWO_PI - _PHASE_EDGE:
            delta0 = 0.0
        if delta0 >= rise:  # would start from rest while decelerating
            return 0.0
    period = TWO_PI / omega
    lo = max(0.0, (rise - delta0) / omega)
    hi = (TWO_PI - delta0) / omega
    k, cos0, sin0 = b1 / omega, math.cos(phase0), math.sin(phase0)
    g0 = initial_slope(w0, b0, b1, phase0)
    w_min = _speed(w0, g0, k, cos0, sin0, omega, hi)
    if w_min > 0.0:
        if b0 >= 0.0:  # the minima only grow: never back to rest
            return NEVER
        periods = math.ceil(w_min / (-b0 * period))
        if periods > _LONGEST_SLIP:
            return NEVER
        hi += max(1, periods) * period
        for _ in range(8):  # rounding guard: the formula's period may be one short
            if _speed(w0, g0, k, cos0, sin0, omega, hi) <= 0.0:
                break
            hi += period
        else:
            return NEVER
        lo = hi - (TWO_PI - rise) / omega
    return _falling_root(w0, b0, b1, phase0, omega, lo, hi)


def initial_slope(w0: float, b0: float, b1: float, phase0: float) -> float:
    """dw/dt at the start of a slip (b0 must come from :func:`from_rest_b0`)."""
    return b0 + b1 * math.sin(phase0)


def from_rest_b0(w0: float, b0: float, b1: float, sin0: float) -> float:
    """b0 as a slip from rest sees it.  A slip that starts from rest cannot
    start decelerating, so at the slip window's edge a rounding-sized negative
    slope b0 + b1*sin(phase0) is taken as zero, by moving b0 by that rounding
    residue; using the adjusted b0 everywhere keeps the slip's long-run drift
    b0 consistent with its start."""
    if w0 == 0.0 and b0 + b1 * sin0 < 0.0:
        return -b1 * sin0
    return b0


def trig_remainders(psi: Any, xp: ModuleType = math) -> tuple[Any, Any, Any]:
    """(1 - cos psi, psi - sin psi, psi**2/2 - (1 - cos psi)) without cancellation.

    Writing the motion with these remainders keeps tiny slips (at the motion
    boundary, or just after an event) accurate to the last bits, so a forward
    slip never shows a rounding-sized step backwards.  Taylor series below
    |psi| = 0.25 (truncation < 1e-18 relative); ``xp`` is math or numpy.
    """
    half = xp.sin(0.5 * psi)
    c1 = 2.0 * half * half
    p2 = psi * psi
    if xp is math and abs(psi) >= 0.25:
        return c1, psi - math.sin(psi), 0.5 * p2 - c1
    s2_series = psi * p2 * (1 / 6 - p2 * (1 / 120 - p2 * (1 / 5040 - p2 * (
        1 / 362880 - p2 * (1 / 39916800 - p2 / 6227020800)))))
    c2_series = p2 * p2 * (1 / 24 - p2 * (1 / 720 - p2 * (1 / 40320 - p2 * (
        1 / 3628800 - p2 * (1 / 479001600 - p2 / 87178291200)))))
    if xp is math:
        return c1, s2_series, c2_series
    small = np.abs(psi) < 0.25
    return c1, np.where(small, s2_series, psi - np.sin(psi)), np.where(small, c2_series, 0.5 * p2 - c1)


def _speed(w0: float, g0: float, k: float, cos0: float, sin0: float, omega: float, tau: float) -> float:
    """w(tau) of a slip segment: w0 + g0*tau + k*(cos0*(1 - cos psi) - sin0*(psi - sin psi))."""
    c1, s2, _ = trig_remainders(omega * tau)
    return w0 + g0 * tau + k * (cos0 * c1 - sin0 * s2)


def _falling_root(
    w0: float, b0: float, b1: float, phase0: float, omega: float, lo: float, hi: float
) -> float:
    """The root of w on [lo, hi], where w is monotone with w(lo) > 0 >= w(hi).

    Newton's method from the secant point, with every iterate kept inside the
    shrinking bracket (bisection when Newton would leave it), to full double
    precision.
    """
    k, cos0, sin0 = b1 / omega, math.cos(phase0), math.sin(phase0)
    g0 = initial_slope(w0, b0, b1, phase0)
    w_lo = _speed(w0, g0, k, cos0, sin0, omega, lo)
    w_hi = _speed(w0, g0, k, cos0, sin0, omega, hi)
    if w_hi >= 0.0:
        return hi
    if w_lo <= 0.0:
        return lo
    tau = lo + (hi - lo) * (w_lo / (w_lo - w_hi))
    sin = math.sin
    for _ in range(200):
        psi = omega * tau
        if psi >= 0.25:  # _speed inlined: this loop is the hot path of the periodic regime
            half = sin(0.5 * psi)
            w = w0 + g0 * tau + k * (cos0 * 2.0 * half * half - sin0 * (psi - sin(psi)))
        else:
            w = _speed(w0, g0, k, cos0, sin0, omega, tau)
        if w > 0.0:
            lo = tau
        elif w < 0.0:
            hi = tau
        else:
            return tau
        slope = b0 + b1 * sin(phase0 + psi)
        step = tau - w / slope if slope < 0.0 else math.nan
        if not lo < step < hi:
            step = 0.5 * (lo + hi)
        if step == tau or abs(step - tau) <= 2.2e-16 * abs(tau):
            return step
        tau = step
    return tau


# --------------------------------------------------------------------------
# The segment: closed-form motion between two events.
# --------------------------------------------------------------------------


class _Plant:
    """The constants of the motion under one set of parameters and inputs,
    computed once per change rather than once per segment."""

    __slots__ = ("omega", "tangential", "load", "amplitude", "mu", "b1", "b0", "direction")

    def __init__(self, params: SliderParams, inputs: Inputs) -> None:
        self.omega = TWO_PI * inputs.excitation_frequency
        self.tangential = inputs.tangential_force
        self.load = params.weight + inputs.external_force_z
        self.amplitude = inputs.excitation_amplitude
        self.mu = params.mu
        self.b1 = self.mu * self.amplitude / params.mass
        #: b0 of dw/dt = b0 + b1*sin(theta) for a slip in direction d, at index d (0, +1, -1).
        self.b0 = tuple((d * self.tangential - self.mu * self.load) / params.mass for d in (0, 1, -1))
        #: the direction a slip from rest takes: sign(Ft)
        self.direction = 1 if self.tangential > 0.0 else -1


class _Segment:
    """Closed-form motion from (t0, x0, w0, phase0) under constant inputs.

    ``direction`` 0 is stuck; +-1 is a slip, whose speed w = direction*v.
    ``phase0`` is in [0, 2*pi); ``cycles`` counts the whole excitation periods
    before it, so the total phase at t0 is 2*pi*cycles + phase0.
    """

    __slots__ = (
        "t0", "x0", "w0", "phase0", "cycles", "direction", "omega", "b0", "b1", "g0",
        "tangential", "load", "amplitude", "mu", "cos0", "sin0", "stop",
    )

    def __init__(
        self, t0: float, x0: float, w0: float, phase0: float, cycles: int, direction: int, plant: _Plant,
    ) -> None:
        self.t0, self.x0, self.w0, self.phase0, self.direction = t0, x0, w0, phase0, direction
        self.cycles = cycles
        self.omega, self.tangential, self.load = plant.omega, plant.tangential, plant.load
        self.amplitude, self.mu = plant.amplitude, plant.mu
        self.stop: tuple[float, float] | None = None  # (x - x0, raw phase) where a slip from rest stops
        if direction:  # a stuck segment needs none of a slip's constants
            self.b1 = plant.b1
            self.cos0, self.sin0 = math.cos(phase0), math.sin(phase0)
            self.b0 = from_rest_b0(w0, plant.b0[direction], self.b1, self.sin0)
            self.g0 = self.b0 + self.b1 * self.sin0

    def evaluate(self, t: Any, xp: ModuleType = math) -> tuple[Any, Any, Any, Any, Any, Any]:
        """(x, v, acceleration, friction force, normal force, phase) at time(s) t.

        The phase is counted from this segment's start of period, unreduced
        (see :func:`_reduce_phase`).  ``xp`` is ``math`` for one float or
        ``numpy`` for an array of times.
        """
        return self.after(t - self.t0, xp)

    def after(self, tau: Any, xp: ModuleType = math) -> tuple[Any, Any, Any, Any, Any, Any]:
        """:meth:`evaluate` at ``tau`` after the segment's start."""
        theta = self.phase0 + self.omega * tau
        sin_theta = xp.sin(theta)
        normal = self.load - self.amplitude * sin_theta
        s = self.direction
        if s == 0:
            zero = tau * 0.0
            return self.x0 + zero, zero, zero, -self.tangential + zero, normal, theta
        w, travel = self.speed_and_travel(tau, xp)
        acceleration = s * (self.b0 + self.b1 * sin_theta)
        return self.x0 + s * travel, s * w, acceleration, -s * self.mu * normal, normal, theta

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

    def time_of_cycle(self, n: int) -> float:
        """When the total phase reaches 2*pi*n (t0 if it already had)."""
        whole = n - self.cycles
        if whole <= 0:
            return self.t0
        return self.t0 + (TWO_PI * whole - self.phase0) / self.omega


def _changed(old: Any, new: Any) -> set[str]:
    """Names of the dataclass fields that differ between ``old`` and ``new``."""
    return {f.name for f in fields(new) if getattr(old, f.name) != getattr(new, f.name)}


def _reduce_phase(theta: float, cycles: int) -> tuple[float, int]:
    """Split a phase counted from period ``cycles`` into [0, 2*pi) and whole periods."""
    whole = math.floor(theta / TWO_PI)
    phase = theta - whole * TWO_PI
    if phase >= TWO_PI:  # rounding at the very end of a period
        phase, whole = 0.0, whole + 1
    return phase, cycles + whole


# --------------------------------------------------------------------------
# The slider: owns the state, advances it event by event.
# --------------------------------------------------------------------------


class Slider:
    """One slider, advanced exactly in time.

    >>> slider = Slider()                 # the paper's Fig. 2 case
    >>> events = slider.advance_to(0.1)   # five excitation periods
    >>> round(slider.state().x * 1e6, 2)  # micrometres travelled
    19.97

    Inputs and parameters may change between calls; the change takes effect at
    the current time (:attr:`t`).  ``event_log_size`` bounds :attr:`events`
    (``None``: unbounded) so a slider that runs for hours keeps constant memory;
    :attr:`event_counts` always counts every event.  With ``cycle_log_size``
    other than 0 the slider also keeps a :class:`CycleMark` at the start of every
    excitation period (``None``: all of them), for per-period mean speeds.
    """

    def __init__(
        self,
        params: SliderParams | None = None,
        inputs: Inputs | None = None,
        *,
        t0: float = 0.0,
        x0: float = 0.0,
        phase0: float = 0.0,
        event_log_size: int | None = 100_000,
        cycle_log_size: int | None = 0,
    ) -> None:
        self._params = params if params is not None else SliderParams()
        self._inputs = inputs if inputs is not None else Inputs()
        check_contact(self._params, self._inputs)
        self._t = require_finite("t0", t0)
        phase, _ = _reduce_phase(require_finite("phase0", phase0), 0)  # -1e-300 % 2pi == 2pi
        if event_log_size is not None and not (isinstance(event_log_size, int) and event_log_size >= 0):
            raise ParameterError("event_log_size", event_log_size, "must be an integer >= 0 or None")
        if cycle_log_size is not None and not (isinstance(cycle_log_size, int) and cycle_log_size >= 0):
            raise ParameterError("cycle_log_size", cycle_log_size, "must be an integer >= 0 or None")
        self._events: Deque[Event] = deque(maxlen=event_log_size)
        self._counts = {kind: 0 for kind in EventKind}
        self._stuck_time = 0.0
        self._cache: dict[tuple[float, float, float, float, int], tuple[float, Any]] = {}
        self._marks: Deque[CycleMark] | None = None
        self._next_mark_n, self._next_mark_t = 1, NEVER
        x0 = require_finite("x0", x0)
        if cycle_log_size != 0:
            self._marks = deque(maxlen=cycle_log_size)
            if phase == 0.0:
                self._marks.append(CycleMark(0, self._t, x0, 0.0))
        self._can_slip = can_ever_slip(self._params, self._inputs)
        self._plant = _Plant(self._params, self._inputs)
        self._start_stuck(self._t, x0, phase, 0)

    # -- read-only views -------------------------------------------------------

    @property
    def t(self) -> float:
        """Current simulation time [s]."""
        return self._t

    @property
    def params(self) -> SliderParams:
        return self._params

    @property
    def inputs(self) -> Inputs:
        return self._inputs

    @property
    def events(self) -> list[Event]:
        """The most recent events, oldest first (bounded by ``event_log_size``)."""
        return list(self._events)

    @property
    def event_counts(self) -> dict[EventKind, int]:
        """How many events of each kind happened since the start."""
        return dict(self._counts)

    @property
    def stuck_time(self) -> float:
        """Total time [s] spent stuck since the start, up to :attr:`t`."""
        seg = self._seg
        return self._stuck_time + (self._t - seg.t0 if seg.direction == 0 else 0.0)

    @property
    def cycle_marks(self) -> list[CycleMark]:
        """The most recent period starts, oldest first (empty unless enabled)."""
        return list(self._marks) if self._marks is not None else []

    def cycle_marks_after(self, n: int) -> list[CycleMark]:
        """The kept period starts with a number above ``n``, oldest first."""
        newer: list[CycleMark] = []
        for mark in reversed(self._marks or ()):
            if mark.n <= n:
                break
            newer.append(mark)
        newer.reverse()
        return newer

    @property
    def next_event_time(self) -> float:
        """When the next event happens under the present inputs (inf: never)."""
        return self._next_t

    def state(self) -> SliderState:
        """The state at the current time :attr:`t`."""
        seg = self._seg
        x, v, acc, friction, normal, theta = seg.evaluate(self._t)
        return SliderState(self._t, x, v, acc, friction, normal, theta % TWO_PI, _MODES[seg.direction])

    # -- advancing -------------------------------------------------------------

    def advance_to(self, t: float) -> list[Event]:
        """Advance exactly to time ``t``; return the events that happened since the
        previous call (a slip that an input change starts at once belongs to
        the next call), up to and including ``t``."""
        if not (t >= self._t and math.isfinite(t)):
            raise ParameterError("t", t, f"must be finite and >= the current time {self._t!r} s")
        happened: list[Event] = []
        while True:
            if self._next_mark_t <= self._next_t:
                if self._next_mark_t > t:
                    break
                self._mark_cycle()
            elif self._next_t <= t:
                happened.append(self._apply())
            else:
                break
        self._t = float(t)
        return happened

    def sample(self, times: np.ndarray) -> Trajectory:
        """Advance through ascending ``times`` (>= :attr:`t`) and return the exact
        state at each, evaluated segment by segment with numpy."""
        times = np.asarray(times, dtype=float)
        if times.ndim != 1 or times.size == 0:
            raise ParameterError("times", times.shape, "must be a non-empty 1-d array")
        if times[0] < self._t or np.any(np.diff(times) < 0.0):
            raise ParameterError("times", float(times[0]), f"must ascend from >= {self._t!r} s")
        columns = [np.empty_like(times) for _ in range(7)]
        happened: list[Event] = []
        first = 0
        while first < times.size:
            last = int(np.searchsorted(times, self._next_t, side="left"))
            if last > first:
                seg = self._seg
                values = seg.evaluate(times[first:last], np)
                for column, value in zip(columns, values):
                    column[first:last] = value
                columns[5][first:last] %= TWO_PI
                columns[6][first:last] = seg.direction
                first = last
            if first < times.size:
                happened.extend(self.advance_to(self._next_t))
        happened.extend(self.advance_to(float(times[-1])))
        x, v, acc, friction, normal, phase, mode = columns
        return Trajectory(times, x, v, acc, friction, normal, phase, mode.astype(np.int8), tuple(happened))

    # -- changing inputs and parameters ----------------------------------------

    def set_inputs(self, inputs: Inputs | None = None, **changes: Any) -> Inputs:
        """Change the inputs at the current time; the phase stays continuous.

        Pass a whole :class:`Inputs` or field changes.  A change that would let
        the normal reaction reach zero is refused and nothing changes.
        """
        new = (inputs if inputs is not None else self._inputs).replace(**changes)
        check_contact(self._params, new, changes if inputs is None else _changed(self._inputs, new))
        self._rebase(self._params, new)
        return new

    def set_params(self, params: SliderParams) -> None:
        """Change mass, mu or gravity at the current time (refused if it would
        let the normal reaction reach zero under the present inputs)."""
        check_contact(params, self._inputs, _changed(self._params, params))
        self._rebase(params, self._inputs)

    # -- internals: acting on events -------------------------------------------

    def _rebase(self, params: SliderParams, inputs: Inputs) -> None:
        """Start a new segment at the current time from the current state."""
        seg = self._seg
        x, v, _, _, _, theta = seg.evaluate(self._t)
        phase, cycles = _reduce_phase(theta, seg.cycles)
        if seg.direction == 0:
            self._stuck_time += self._t - seg.t0
        self._params, self._inputs = params, inputs
        self._can_slip = can_ever_slip(params, inputs)
        self._plant = _Plant(params, inputs)
        w = seg.direction * v
        if seg.direction != 0 and w > 0.0:
            self._start_slip(self._t, x, w, phase, cycles, seg.direction)
        else:
            self._start_stuck(self._t, x, phase, cycles)

    def _start_stuck(self, t: float, x: float, phase: float, cycles: int, after_stop: int = 0) -> None:
        plant = self._plant
        self._seg = _Segment(t, x, 0.0, phase, cycles, 0, plant)
        direction = plant.direction
        delta, start_phase = NEVER, NEVER
        if self._can_slip:
            delta, start_phase = next_slip_start(phase, plant.b0[direction], plant.b1,
                                                 closing=after_stop == direction)
        self._next_t = t + delta / plant.omega
        # The start passes 2*pi on the way if it lies "behind" the present phase.
        wraps = start_phase < phase or (start_phase == phase and delta > 0.0)
        self._next_start = (start_phase, direction, cycles + 1 if wraps else cycles)
        self._schedule_mark()

    def _start_slip(
        self, t: float, x: float, w: float, phase: float, cycles: int, direction: int
    ) -> None:
        self._seg = seg = _Segment(t, x, w, phase, cycles, direction, self._plant)
        self._schedule_mark()
        if w == 0.0:
            # Every slip from rest at this phase under these inputs is this slip:
            # its stop (time, travel, phase) is computed once.
            key = (phase, seg.b0, seg.b1, seg.omega, direction)
            entry = self._cache.get(key)
            if entry is None:
                if len(self._cache) >= _CACHE_LIMIT:
                    self._cache.clear()
                delay = slip_stop_delay(0.0, seg.b0, seg.b1, phase, seg.omega)
                stop = None
                if delay < NEVER:
                    stop = (direction * seg.speed_and_travel(delay)[1], phase + seg.omega * delay)
                entry = self._cache[key] = (delay, stop)
            delay, seg.stop = entry
        else:
            delay = slip_stop_delay(w, seg.b0, seg.b1, phase, seg.omega)
        self._next_t = t + delay

    def _apply(self) -> Event:
        """Carry out the event at ``_next_t`` and start the segment after it."""
        seg, t = self._seg, self._next_t
        if seg.direction == 0:
            self._stuck_time += t - seg.t0
            phase, direction, cycles = self._next_start
            event = Event(t, EventKind.SLIP_START, seg.x0, phase, Mode.STUCK, _MODES[direction])
            self._start_slip(t, seg.x0, 0.0, phase, cycles, direction)
            return self._log(event)
        if seg.stop is not None:
            travel, theta = seg.stop
            x = seg.x0 + travel
        else:
            x, _, _, _, _, theta = seg.evaluate(t)
        phase, cycles = _reduce_phase(theta, seg.cycles)
        plant = self._plant
        direction = plant.direction
        before = _MODES[seg.direction]
        if direction == -seg.direction and self._can_slip and next_slip_start(
            phase, plant.b0[direction], plant.b1
        )[0] == 0.0:
            self._start_slip(t, x, 0.0, phase, cycles, direction)
            return self._log(Event(t, EventKind.REVERSAL, x, phase, before, _MODES[direction]))
        self._start_stuck(t, x, phase, cycles, after_stop=seg.direction)
        return self._log(Event(t, EventKind.STICK, x, phase, before, Mode.STUCK))

    def _schedule_mark(self) -> None:
        if self._marks is not None:
            self._next_mark_t = self._seg.time_of_cycle(self._next_mark_n)

    def _mark_cycle(self) -> None:
        """Record the start of period ``_next_mark_n`` and aim at the next."""
        seg, t = self._seg, self._next_mark_t
        if seg.direction == 0:  # only x is needed: no full state evaluation
            x, stuck = seg.x0, self._stuck_time + (t - seg.t0)
        else:
            x, stuck = seg.x0 + seg.direction * seg.speed_and_travel(t - seg.t0)[1], self._stuck_time
        assert self._marks is not None
        self._marks.append(CycleMark(self._next_mark_n, t, x, stuck))
        self._next_mark_n += 1
        self._schedule_mark()

    def _log(self, event: Event) -> Event:
        self._events.append(event)
        self._counts[event.kind] += 1
        return event
