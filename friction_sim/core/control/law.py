"""Mean-speed control through the U relation (numpy only, no ROS).

A feeder operator asks for a mean speed V*; the controller answers with the
excitation amplitude Pa.  Its model is the exact relation U(phi, a):

* feedforward: U* = V* f/(g mu) and phi = Fd/(mu m g) from the model's mass,
  mu and gravity; a_ff = a(U*, phi), the exact inverse of U;
* feedback: integral action on the mean-speed error.  Its state is the
  model's speed that is asked for, U_cmd = r * U*, applied as
  a = a(U_cmd, phi) clamped to [0, max_amplitude_ratio].  The first clean
  sample after a change moves U_cmd by integral_gain times the shortfall e (in
  units of U); later ones take the secant step e / s, where s is the measured
  slope of e against U_cmd from the last two clean samples, so the loop gain
  adapts to how far the model's slope is off (near the motion boundary, where
  U is flat in a, a mismatched model is off by a large factor).  A step never
  more than quadruples U_cmd or cuts it below a quarter, so the loop cannot
  jump over the cliff to a = 0.  Kept as the ratio r,
  the correction carries over to new targets, drive forces and frequencies:
  a wrong mu or mass in the model is mostly a wrong scale.  The integral
  term reported is U_cmd - U*;
* anti-windup: the state only moves on *clean* samples and never in the
  direction of a saturated output; an unreachable target (U* above
  U(phi, max_amplitude_ratio)) saturates, is flagged, and freezes it;
* the actuator's reach: an actuator that gives less than max_amplitude_ratio
  (the resonant exciter at full drive) tells the law its largest Pa
  (:meth:`MeanSpeedController.limit_actuator`); the ceiling of a is then the
  lower of the two, and saturation, anti-windup and the unreachable flag act
  there.  Every output names the fastest mean speed within the ceiling
  (``reachable_speed``), the number to quote with an unreachable target.

Beyond Kostek's model (an inclined vibration, a slope, mu_s > mu) or with
``max_amplitude_ratio`` >= 1 (a hopping slider) there is no closed form: the
law then inverts the general mean speed (:mod:`friction_sim.core.meanspeed.general`)
on its first stretch where U rises with a toward the target's sign
(:class:`~friction_sim.core.meanspeed.inverse.Branch`, built once per model, drive
force and limit, and cached).  The branch's end (a_end, U_end) takes the
place of max_amplitude_ratio: a target beyond it is unreachable and the
output saturates at a_end, the fastest the plant conveys; a target of
either sign is taken (the vibration conveys without a drive force), and
one the branch does not reach is flagged unreachable.  Kostek's model with
max_amplitude_ratio < 1 keeps the exact path above, unchanged.

Why "clean": every slip of the periodic regime starts from rest at the same
phase, so the plant reaches its new periodic motion in the first whole period
after Pa changes.  A mean-velocity sample whose window began before the last
change mixes old and new motion; integrating it would only add a transient
error.  :class:`SampleClock` decides from the sample's stamp (simulation time)
whether its window lies wholly after the change, timed in simulation time too;
on a loaded machine the margin grows by the delivery jitter it observes, since
the Pa on its way to the plant is delayed as much as the samples coming back.

Samples no plant in force could produce are refused (:class:`ParameterError`
naming the value and the limit), and the state never holds a non-finite
value, whatever the (finite, in range) inputs:

* a sample must be finite and within the speed limit of the plants in force
  (:func:`speed_limit`).  Coulomb friction only ever brakes the slider, so
  from rest it gains at most |Fd|/m of speed per second of slip; a slip of
  the periodic regime (|phi| < 1) starts from rest and ends within the
  period, so the mean speed of a window is at most |Fd|/(2 m f) (the exact
  relation never exceeds |Fd|/(2 pi m f)), backwards for a negative drive
  as well as forwards.  The limit is :data:`SPEED_LIMIT_FACTOR` |Fd|/(m f)
  (beyond Kostek's model: see :func:`speed_limit`),
  four times that: room for a slip that outlasts a period after a change, a
  plant lighter than the model, an external force the controller does not
  see.  With |phi| >= 1 the slider slides away and any speed comes in time:
  no limit.  After a change of drive force, frequency or mass, the limit of
  the plant before holds as well until :data:`LIMIT_SLACK_SAMPLES` samples
  past the window have come and one is within the new limit (windows that
  began before the change are still on their way);
* only samples within the present plant's own limit are integrated;
* the state r is kept within :data:`RATIO_LIMITS` and moves by a factor in
  [1/4, 4]; a target whose U* is zero in floating point (1e-321 m/s at
  1 mHz) asks for standing still (Pa = 0), and nothing is integrated for it;
* every input change is a transaction: if anything raises, the controller
  is left exactly as it was.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from friction_sim.core.control.sampleclock import SampleClock
from friction_sim.core.meanspeed.inverse import Branch, rising_branch
from friction_sim.core.meanspeed.urelation import amplitude_ratio_for, u_map
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import (
    amplitude_for,
    amplitude_ratio,
    beats_friction,
    dimensional_speed,
    drive_ratio,
    nondimensional_speed,
)
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import is_kostek, kostek_applies
from friction_sim.errors import ParameterError

#: The state r = U_cmd/U* stays within these bounds: a model may be off by a
#: factor of a million in scale, and r can neither overflow nor reach 0 (from
#: which a multiplicative step would never bring it back).
RATIO_LIMITS = (1e-6, 1e6)
#: The inputs the law follows, by name.
_INPUTS = {setting.name: setting for setting in (spec.TARGET_SPEED, spec.DRIVE_FORCE, spec.EXCITATION_FREQUENCY)}
#: A mean-velocity sample is refused beyond this many times |Fd|/(m f).
SPEED_LIMIT_FACTOR = 2.0
#: Beyond Kostek's model, samples up to this many times the model's fastest mean speed are accepted.
GENERAL_SPEED_MARGIN = 4.0 * math.pi
#: Samples past the mean window after a change of the plant before the limit
#: of the plant before the change is dropped (those still queued on their way).
LIMIT_SLACK_SAMPLES = 12


def speed_limit(drive_force: float, model: SliderParams, frequency: float,
                max_ratio: float = float(spec.MAX_AMPLITUDE_RATIO.default)) -> float:
    """The largest |mean velocity| [m/s] a slider of the model's mass, driven
    by ``drive_force`` at excitation ``frequency``, can show (see the module
    doc and :func:`speed_limit_formula`)."""
    return speed_limit_formula(drive_force, model, frequency, max_ratio)[0]


def speed_limit_formula(drive_force: float, model: SliderParams, frequency: float,
                        max_ratio: float = float(spec.MAX_AMPLITUDE_RATIO.default)) -> tuple[float, str]:
    """The speed limit and the formula that gives it, with its numbers (for
    the refusal's message: the words must be the rule that was applied).

    In Kostek's model below lift-off (:func:`uses_closed_form`) the limit is
    :data:`SPEED_LIMIT_FACTOR` |Fd|/(m f); inf when |phi| > 1 (it slides
    away, and reaches any speed in time: :func:`runs_away`).  Beyond it the tangential excitation
    Pt <= ``max_ratio``*m*g*|cot(beta)| and the slope's pull add to the drive:
    the limit is :data:`SPEED_LIMIT_FACTOR` (|Fd - m g sin(alpha)| + Pt)/(m f),
    and at least :data:`GENERAL_SPEED_MARGIN` times the fastest mean speed the
    model shows for a <= ``max_ratio``; inf when |Fd - m g sin(alpha)| >
    mu m g cos(alpha) or when the model runs away somewhere in that range (a
    hopping slider without landing friction can).
    """
    m_f = f"m = {model.mass:g} kg, f = {frequency:g} Hz"
    if uses_closed_form(model, max_ratio):
        force = abs(drive_force)
        if runs_away(drive_force, model):
            return math.inf, f"none: |Fd| = {force:g} N > mu m g = {model.mu * model.weight:g} N (|phi| > 1)"
        limit = SPEED_LIMIT_FACTOR * force / (model.mass * frequency)
        return limit, f"{SPEED_LIMIT_FACTOR:g} |Fd|/(m f) = {limit:.6g} m/s for Fd = {drive_force:g} N, {m_f}"
    if runs_away(drive_force, model):
        return math.inf, "none: |Fd - m g sin(alpha)| > mu m g cos(alpha) (the slider runs away)"
    samples = _branch(model, drive_force, max_ratio, 1).u
    if not np.all(np.isfinite(samples)):
        return math.inf, f"none: the model runs away somewhere in a <= {max_ratio:g}"
    fastest = dimensional_speed(float(np.max(np.abs(samples))), frequency, model.gravity, model.mu)
    tangential = amplitude_for(max_ratio, model.weight) * abs(model.tangential_ratio)  # Pt at the top
    pull = abs(drive_force - model.downhill_weight) + tangential
    by_pull = SPEED_LIMIT_FACTOR * pull / (model.mass * frequency)
    by_model = GENERAL_SPEED_MARGIN * fastest
    limit = max(by_pull, by_model)
    margin = f"{GENERAL_SPEED_MARGIN / math.pi:g} pi"
    return limit, (f"max({SPEED_LIMIT_FACTOR:g} (|Fd - m g sin(alpha)| + Pt)/(m f), {margin} x the fastest mean speed "
                   f"of the model {fastest:.6g} m/s) = max({by_pull:.6g}, {by_model:.6g}) = {limit:.6g} m/s for "
                   f"|Fd - m g sin(alpha)| + Pt = {pull:g} N, {m_f}")


def uses_closed_form(model: SliderParams, max_ratio: float) -> bool:
    """True where the law inverts Kostek's exact map (his model, a < 1: the
    controller of issue 10, unchanged); elsewhere it inverts the general mean
    speed on its rising branch (:mod:`friction_sim.core.meanspeed.inverse`)."""
    return bool(kostek_applies(model.excitation_angle, model.track_inclination, model.static_ratio,
                               amplitude_for(max_ratio, model.weight), model.weight, 0.0))  # the rule at the top


def runs_away(drive_force: float, model: SliderParams) -> bool:
    """True when the drive beats the friction whatever the excitation: |Fd -
    m g sin(alpha)| > mu m g cos(alpha) (Kostek: |phi| > 1).  Coulomb friction
    averages at most mu m g cos(alpha) over time (less when the slider hops),
    and the excitation averages to nothing, so the slider then accelerates.
    The boundary itself does not run away (:func:`~friction_sim.core.model.dimensionless.beats_friction`,
    the one rule, which the general mean speed's branch applies too); the closed
    form's U is inf only beyond |phi| = 1."""
    return beats_friction(drive_force - model.downhill_weight, model.normal_weight, model.mu)


@dataclass(frozen=True)
class ControllerConfig:
    """The controller's model of the plant and its tuning.

    integral_gain: fraction of each clean sample's error (in U) added to I.
    max_amplitude_ratio: the largest a = Pa/(m*g) applied (above 1 the slider hops; the law then, or
        for any model other than Kostek's, inverts the general mean speed on its rising branch).
    settle_margin: extra fraction of a period a sample's window must keep
        clear of the last change of Pa (message latencies), on top of the
        delivery jitter observed in the recent samples.
    secant: learn the plant's slope from two clean samples (off behind an inner loop: its residue is noise).
    """

    model: SliderParams = SliderParams()
    integral_gain: float = 0.4
    max_amplitude_ratio: float = 0.95
    mean_window_periods: int = 1
    settle_margin: float = 0.25
    secant: bool = True

    def __post_init__(self) -> None:
        for setting in (spec.INTEGRAL_GAIN, spec.MAX_AMPLITUDE_RATIO, spec.MEAN_WINDOW_PERIODS, spec.SETTLE_MARGIN):
            object.__setattr__(self, setting.name, setting.check(getattr(self, setting.name)))


@dataclass(frozen=True)
class ControlOutput:
    """What the controller decided and why (all of it goes to diagnostics)."""

    amplitude: float  # Pa [N] to apply
    target_speed: float  # V* [m/s]
    u_target: float  # U* in the model's units
    phi: float  # model phi = Fd/(mu m g)
    feedforward_ratio: float  # a_ff = a(U*, phi) (NaN when unreachable)
    applied_ratio: float  # a actually applied
    integral: float  # I [U]
    saturated: bool  # a clamped at max_amplitude_ratio (general model: at the rising branch's end)
    unreachable: bool  # U* > U(phi, max_amplitude_ratio) (beyond the branch's end), or no drive that way
    runaway: bool  # |phi| > 1 (|Fd - m g sin(alpha)| > mu m g cos(alpha)): it accelerates whatever Pa is
    #: The fastest mean speed [m/s] toward the target within the ceiling of a (NaN: no target, or no branch).
    reachable_speed: float = math.nan


class MeanSpeedController:
    """Turns a target mean speed into an excitation amplitude (see module doc)."""

    def __init__(self, config: ControllerConfig, *, drive_force: float, frequency: float,
                 target_speed: float = 0.0) -> None:
        self._config = config
        self._drive_force = float(spec.DRIVE_FORCE.check(drive_force))
        self._frequency = float(spec.EXCITATION_FREQUENCY.check(frequency))
        self._target = 0.0
        self._ratio = 1.0  # U_cmd / U*
        self._last_clean: tuple[float, float] | None = None  # (U_cmd, shortfall) for the secant
        self.clock = SampleClock()
        self.measured_speed = math.nan
        self._actuator_limit: float | None = None  # the largest Pa [N] the actuator gives (None: no limit)
        self._limit = speed_limit(self._drive_force, config.model, self._frequency, config.max_amplitude_ratio)
        self._envelope = self._limit  # the largest limit of the plants whose windows may still come
        self._settling = 0  # samples to come before the envelope may shrink to the limit
        self.output = self._decide()
        self.set_target(target_speed)

    @contextmanager
    def _transaction(self) -> Iterator[None]:
        """Undo every change of the state if the body raises (a refusal or a
        fault): the controller is as it was.  The sample clock's observations
        are facts about the plant and stay."""
        saved = dict(self.__dict__)
        try:
            yield
        except BaseException:
            self.__dict__.clear()
            self.__dict__.update(saved)
            raise

    # -- inputs ---------------------------------------------------------------

    def set_target(self, speed: float) -> ControlOutput:
        """A new target mean speed [m/s]; it must agree in sign with the drive force."""
        return self._set_one("target_speed", speed)

    def set_drive_force(self, force: float) -> ControlOutput:
        """A new drive force [N]; a target of the other sign becomes 0."""
        return self._set_one("drive_force", force)

    def set_frequency(self, frequency: float) -> ControlOutput:
        """A new excitation frequency [Hz]."""
        return self._set_one("excitation_frequency", frequency)

    def take(self, changes: Sequence[tuple[str, Any]]) -> list[ParameterError | None]:
        """Several input changes at one instant (``target_speed``,
        ``drive_force``, ``excitation_frequency``), in order: each is judged
        against the state the ones before it left and taken or refused on its
        own; the law then decides once.  Returns, per change, None or the
        refusal (naming field, value and limit)."""
        verdicts: list[ParameterError | None] = []
        with self._transaction():
            for name, value in changes:
                try:
                    self._set_input(name, value)
                except ParameterError as error:
                    verdicts.append(error)
                    continue
                verdicts.append(None)
            if any(verdict is None for verdict in verdicts):
                self._last_clean = None
                self._plant_changed()
                self._update()
        return verdicts

    def _set_one(self, name: str, value: Any) -> ControlOutput:
        (verdict,) = self.take([(name, value)])
        if verdict is not None:
            raise verdict
        return self.output

    def _set_input(self, name: str, value: Any) -> None:
        """One input change, checked against the state in force (no decision yet)."""
        if name not in _INPUTS:
            raise ParameterError(name, value, f"unknown input; known: {', '.join(_INPUTS)}")
        number = float(_INPUTS[name].check(value))
        kostek = is_kostek(self._config.model)  # elsewhere the vibration conveys too: any direction may be reachable
        if name == "target_speed":
            force = self._drive_force
            if kostek and number != 0.0 and (force == 0.0 or math.copysign(1.0, number) != math.copysign(1.0, force)):
                raise ParameterError(
                    "target_speed", number,
                    f"must have the sign of drive_force = {force!r} N (the slider only creeps that way)")
            self._target = number
        elif name == "drive_force":
            self._drive_force = number
            if kostek and self._target != 0.0 and math.copysign(1.0, self._target) != math.copysign(1.0, number):
                self._target = 0.0  # the old target now points the wrong way
        else:
            self._frequency = number

    def on_mean_velocity(self, speed: float, stamp: float, wall_ns: int) -> ControlOutput:
        """A measured mean speed [m/s] over the plant's last window, stamped with
        the simulation time at its end and received at ``wall_ns``.  Refused
        (:class:`ParameterError`, nothing changes) if it is not finite or no
        plant in force could produce it."""
        with self._transaction():
            speed = self._plausible(speed)
            self.measured_speed = speed
            config = self.config
            clean = self.clock.add(stamp, wall_ns, 1.0 / self._frequency, config.mean_window_periods,
                                   config.settle_margin)
            out = self.output
            if (clean and self._target != 0.0 and out.u_target != 0.0 and not out.unreachable
                    and not out.runaway and abs(speed) <= self._limit):
                self._integrate(speed, out)
            return self._update()

    def _plausible(self, speed: float) -> float:
        """``speed`` as a float, or a refusal: not finite, or beyond the limit
        of the plants in force.  Shrinks the envelope once the samples show
        the plant before the last change is gone."""
        if isinstance(speed, bool) or not isinstance(speed, numbers.Real):
            raise ParameterError("mean_velocity", speed, "must be a finite number [m/s]")
        speed = float(speed)
        if not math.isfinite(speed):
            raise ParameterError("mean_velocity", speed, "must be finite [m/s]")
        if self.beyond_limit(speed):
            raise ParameterError("mean_velocity", speed, self._limit_words())
        if self._settling > 0:
            self._settling -= 1
        elif abs(speed) <= self._limit:
            self._envelope = self._limit
        return speed

    def _limit_words(self) -> str:
        now = speed_limit_formula(self._drive_force, self.config.model, self._frequency,
                                  self.config.max_amplitude_ratio)[1]
        if self._envelope > self._limit:
            return (f"|mean_velocity| must be <= {self._envelope:.6g} m/s, the limit of the plant before the last "
                    f"change (now {now}); a faster sample is from no plant in force")
        return f"|mean_velocity| must be <= {now}; a faster sample is from no plant in force"

    def _plant_changed(self) -> None:
        """Drive force, frequency or the model's mass changed: a new speed
        limit, and the old one still holds for the windows on their way."""
        limit = speed_limit(self._drive_force, self._config.model, self._frequency,
                            self._config.max_amplitude_ratio)
        if limit != self._limit:
            self._envelope = max(self._envelope, limit)
            self._settling = self._config.mean_window_periods + LIMIT_SLACK_SAMPLES
            self._limit = limit

    def _integrate(self, speed: float, out: ControlOutput) -> None:
        """Move the state r on a clean sample (see the module doc)."""
        config = self.config
        # The shortfall in the target's direction, in units of U (finite: |speed| is within the limit).
        error = nondimensional_speed(math.copysign(1.0, self._target) * (self._target - speed), self._frequency,
                                     config.model.gravity, config.model.mu)
        if out.saturated and error > 0.0:
            return  # anti-windup: never further in the direction of a saturated output
        command = abs(out.u_target) * self._ratio
        if not (0.0 < command < math.inf):
            return  # U_cmd underflows: nothing to scale
        step = config.integral_gain * error
        if config.secant and self._last_clean is not None:
            previous_command, previous_error = self._last_clean
            moved = command - previous_command
            slope = (previous_error - error) / moved if moved != 0.0 else 0.0
            if slope > 0.0:
                step = error / slope
        new_command = min(max(command + step, 0.25 * command), 4.0 * command)
        ratio = _clamp(self._ratio * (new_command / command), *RATIO_LIMITS)
        if math.isfinite(ratio):
            self._last_clean = (command, error)
            self._ratio = ratio

    def limit_actuator(self, amplitude: float | None) -> ControlOutput:
        """The largest Pa [N] the actuator can give now (the resonant exciter at
        full drive, as its lock-in reads it), or None: no limit but
        max_amplitude_ratio.  The law saturates there (see the module doc); a
        value that is not a finite number >= 0 is no limit either."""
        if amplitude is not None and not (isinstance(amplitude, float) and math.isfinite(amplitude)
                                          and amplitude >= 0.0):
            amplitude = None
        if amplitude != self._actuator_limit:
            self._actuator_limit = amplitude
            self._update()
        return self.output

    @property
    def actuator_limit(self) -> float | None:
        """The largest Pa [N] the actuator gives, as last told (None: no limit)."""
        return self._actuator_limit

    def _ceiling(self) -> float:
        """The largest amplitude ratio a the law applies: max_amplitude_ratio, or
        less where the actuator gives less."""
        top, limit = self.config.max_amplitude_ratio, self._actuator_limit
        return top if limit is None else min(top, amplitude_ratio(limit, self.config.model.weight))

    def _speed(self, u: float) -> float:
        """The mean speed [m/s] of ``u`` in the model's units (U = V f/(g mu))."""
        model = self.config.model
        return dimensional_speed(u, self._frequency, model.gravity, model.mu)

    # -- the law ----------------------------------------------------------------

    @property
    def config(self) -> ControllerConfig:
        return self._config

    @config.setter
    def config(self, config: ControllerConfig) -> None:
        """A new model or tuning takes effect at once.  On Kostek's model the
        slider creeps only along the drive force: a target of the other sign
        (taken under a model whose vibration conveys by itself) becomes 0."""
        with self._transaction():
            self._config = config
            target, force = self._target, self._drive_force
            if is_kostek(config.model) and target != 0.0 and (
                    force == 0.0 or math.copysign(1.0, target) != math.copysign(1.0, force)):
                self._target = 0.0
            self._plant_changed()
            self.output = self._decide()

    def _update(self) -> ControlOutput:
        self.output = self._decide()
        return self.output

    def _decide(self) -> ControlOutput:
        model, top = self.config.model, self.config.max_amplitude_ratio
        phi = drive_ratio(self._drive_force, model.mu, model.weight)
        u_target = nondimensional_speed(self._target, self._frequency, model.gravity, model.mu)
        if not uses_closed_form(model, top):
            return self._decide_general(phi, u_target)
        runaway = abs(phi) > 1.0  # (runs_away in phi, the ratio the relation inverts: U(1, a) = a/(2*pi))
        if self._target == 0.0 or runaway:
            return self._output(0.0, u_target, phi, 0.0 if self._target == 0.0 else math.nan, False, False, runaway)
        if u_target == 0.0:
            # So slow that U* is zero in floating point (1e-321 m/s at 1 mHz): standing still is closest.
            return self._output(0.0, u_target, phi, 0.0, False, False, False)
        ceiling = self._ceiling()  # (top itself, unless the actuator gives less: then the same calls as ever)
        u_top = _u_top(phi, ceiling)
        reach = self._speed(u_top)
        if abs(u_target) > abs(u_top):
            return self._output(ceiling, u_target, phi, math.nan, True, True, False, reach)
        feedforward = _inverse(u_target, phi, top)
        u_command = u_target * self._ratio
        if abs(u_command) >= abs(u_top):
            # Anti-windup: no ratio beyond the ceiling (u_top / u_target <= r here, so no overflow).
            self._ratio = _clamp(abs(u_top) / abs(u_target), *RATIO_LIMITS)
            return self._output(ceiling, u_target, phi, feedforward, True, False, False, reach)
        ratio = _inverse(u_command, phi, top)
        if not 0.0 <= ratio <= top:  # not expected: the relation is exact and u_command < u_top
            raise ArithmeticError(f"the inverse U relation gave a = {ratio!r} for U = {u_command!r}, "
                                  f"phi = {phi!r} (expected 0 <= a <= {top!r})")
        # (u_command < U(ceiling): a is below the ceiling but for the inverse's rounding, which may not pass it)
        return self._output(min(ratio, ceiling), u_target, phi, feedforward, False, False, False, reach)

    def _decide_general(self, phi: float, u_target: float) -> ControlOutput:
        """The law on the general mean speed's rising branch toward U*'s sign:
        saturated at its end (the fastest it conveys), unreachable beyond it
        or where the branch does not exist, and kept from below its start."""
        model, top = self.config.model, self.config.max_amplitude_ratio
        runaway = runs_away(self._drive_force, model)
        if self._target == 0.0 or runaway:
            return self._output(0.0, u_target, phi, 0.0 if self._target == 0.0 else math.nan, False, False, runaway)
        if u_target == 0.0:
            return self._output(0.0, u_target, phi, 0.0, False, False, False)
        direction = 1 if u_target > 0.0 else -1
        branch = _branch(model, self._drive_force, top, direction)
        a_end, u_end = _branch_end(model, self._drive_force, top, direction, self._ceiling())
        reach = self._speed(u_end) if not branch.empty else math.nan

        def on_branch(u: float) -> bool:
            return branch.reachable(u) and direction * u <= direction * u_end

        if not on_branch(u_target):
            beyond = not branch.empty and direction * u_target > direction * u_end
            ratio = min(a_end if beyond else branch.a_start, self._ceiling())
            return self._output(ratio, u_target, phi, math.nan, beyond, True, False, reach)
        feedforward = _general_inverse(model, self._drive_force, top, direction, u_target)
        u_command = u_target * self._ratio
        if direction * u_command >= direction * u_end:
            self._ratio = _clamp(u_end / u_target, *RATIO_LIMITS)
            return self._output(a_end, u_target, phi, feedforward, True, False, False, reach)
        if not branch.reachable(u_command):  # below the start: the plant already moves that fast at a_start
            if direction * branch.u_start > 0.0:
                self._ratio = _clamp(branch.u_start / u_target, *RATIO_LIMITS)
            return self._output(branch.a_start, u_target, phi, feedforward, False, False, False, reach)
        ratio = _general_inverse(model, self._drive_force, top, direction, u_command)
        if not 0.0 <= ratio <= top:  # not expected: u_command is on the branch
            raise ArithmeticError(f"the general inverse gave a = {ratio!r} for U = {u_command!r} "
                                  f"(expected 0 <= a <= {top!r})")
        # (u_command < U(a_end): a is below a_end but for the inverse's rounding, which may not pass it)
        return self._output(min(ratio, a_end), u_target, phi, feedforward, False, False, False, reach)

    def _output(self, ratio: float, u_target: float, phi: float, feedforward: float,
                saturated: bool, unreachable: bool, runaway: bool, reachable_speed: float = math.nan) -> ControlOutput:
        amplitude = amplitude_for(ratio, self.config.model.weight)
        if self._actuator_limit is not None:  # (ratio <= limit/weight may round to a Pa an ulp above the limit)
            amplitude = min(amplitude, self._actuator_limit)
        return ControlOutput(
            amplitude=amplitude, target_speed=self._target, u_target=u_target,
            phi=phi, feedforward_ratio=feedforward, applied_ratio=ratio,
            integral=u_target * (self._ratio - 1.0),
            saturated=saturated, unreachable=unreachable, runaway=runaway, reachable_speed=reachable_speed,
        )

    def beyond_limit(self, speed: float) -> bool:
        """Whether a finite ``speed`` [m/s] is faster than any plant in force
        could creep (the refusal of :meth:`on_mean_velocity`)."""
        return math.isfinite(speed) and abs(speed) > self._envelope

    @property
    def sample_limit(self) -> float:
        """The largest |mean velocity| accepted now [m/s] (inf: any finite one)."""
        return self._envelope

    @property
    def drive_force(self) -> float:
        return self._drive_force

    @property
    def frequency(self) -> float:
        return self._frequency

    @property
    def target_speed(self) -> float:
        return self._target


def _clamp(value: float, low: float, high: float) -> float:
    return min(max(value, low), high)


# Once per sample, mostly on unchanged inputs: the last answers of the (exact, iterative) relation.
@lru_cache(maxsize=64)
def _u_top(phi: float, top: float) -> float:
    return float(u_map(phi, top))


@lru_cache(maxsize=64)
def _inverse(u: float, phi: float, top: float) -> float:
    return float(amplitude_ratio_for(u, phi, top))


@lru_cache(maxsize=16)
def _branch(model: SliderParams, drive_force: float, top: float, direction: int) -> Branch:
    return rising_branch(model, Inputs(drive_force=drive_force), top, direction)


def _branch_end(model: SliderParams, drive_force: float, top: float, direction: int,
                ceiling: float) -> tuple[float, float]:
    """(a, U) where the rising branch ends under a ceiling of a: its own end, or
    the ceiling (U there exactly) where the actuator gives less; the ceiling
    with the branch's start U where it lies below the start (nothing on the
    branch is reachable: the most the actuator gives is applied)."""
    branch = _branch(model, drive_force, top, direction)
    if branch.empty or ceiling >= branch.a_end:
        return branch.a_end, branch.u_end
    if ceiling <= branch.a_start:
        return ceiling, branch.u_start
    return ceiling, _u_on_branch(model, drive_force, top, direction, ceiling)


@lru_cache(maxsize=64)
def _u_on_branch(model: SliderParams, drive_force: float, top: float, direction: int, ratio: float) -> float:
    return _branch(model, drive_force, top, direction).u_at(ratio)


@lru_cache(maxsize=64)
def _general_inverse(model: SliderParams, drive_force: float, top: float, direction: int, u: float) -> float:
    return _branch(model, drive_force, top, direction).amplitude_ratio_for(u)
