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
  The output, its ceiling and saturation are :mod:`friction_sim.core.control.reach`'s;
  the inputs and their checks are :mod:`friction_sim.core.control.inputs`'s;
  this module keeps the state and decides.

Beyond Kostek's model (an inclined vibration, a slope, mu_s > mu) or with
``max_amplitude_ratio`` >= 1 (a hopping slider) there is no closed form: the
law then inverts the general mean speed (:mod:`friction_sim.core.meanspeed.general`)
on its first stretch where U rises with a toward the target's sign
(:class:`~friction_sim.core.meanspeed.inverse.Branch`, built once per model, drive
force and limit, and cached: :mod:`friction_sim.core.control.relation`).  The branch's end (a_end, U_end) takes the
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
naming the value and the limit: :func:`~friction_sim.core.control.inputs.admit_sample`,
:mod:`friction_sim.core.control.speedlimit`),
and the state never holds a non-finite value, whatever the (finite, in
range) inputs:

* the state r is kept within :data:`~friction_sim.core.control.integral.RATIO_LIMITS`
  and moves by a factor in [1/4, 4] (:mod:`friction_sim.core.control.integral`); a
  target whose U* is zero in floating point (1e-321 m/s at 1 mHz) asks for
  standing still (Pa = 0), and nothing is integrated for it;
* every input change is a transaction: if anything raises, the controller
  is left exactly as it was.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from friction_sim.core.control.inputs import LawInputs, admit_sample
from friction_sim.core.control.integral import LastClean, integral_step
from friction_sim.core.control.reach import ControlOutput, decide
from friction_sim.core.control.sampleclock import SampleClock
from friction_sim.core.control.speedlimit import SampleLimit, speed_limit
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import nondimensional_speed
from friction_sim.core.model.params import SliderParams
from friction_sim.errors import ParameterError


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


class MeanSpeedController:
    """Turns a target mean speed into an excitation amplitude (see module doc)."""

    def __init__(self, config: ControllerConfig, *, drive_force: float, frequency: float,
                 target_speed: float = 0.0) -> None:
        self._config = config
        self._inputs = LawInputs.of(drive_force, frequency)
        self._ratio = 1.0  # U_cmd / U*
        self._last_clean: LastClean = None  # (U_cmd, shortfall) for the secant
        self.clock = SampleClock()
        self.measured_speed = math.nan
        self._actuator_limit: float | None = None  # the largest Pa [N] the actuator gives (None: no limit)
        self._limits = SampleLimit.of(speed_limit(self._inputs.drive_force, config.model, self._inputs.frequency,
                                                  config.max_amplitude_ratio))
        self._update()
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
        own (:meth:`~friction_sim.core.control.inputs.LawInputs.changed`); the
        law then decides once.  Returns, per change, None or the refusal
        (naming field, value and limit)."""
        verdicts: list[ParameterError | None] = []
        with self._transaction():
            for name, value in changes:
                try:
                    self._inputs = self._inputs.changed(name, value, self._config.model)
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

    def on_mean_velocity(self, speed: float, stamp: float, wall_ns: int) -> ControlOutput:
        """A measured mean speed [m/s] over the plant's last window, stamped with
        the simulation time at its end and received at ``wall_ns``.  Refused
        (:class:`ParameterError`, nothing changes) if it is not finite or no
        plant in force could produce it
        (:func:`~friction_sim.core.control.inputs.admit_sample`)."""
        with self._transaction():
            config = self.config
            inputs = self._inputs
            speed, self._limits = admit_sample(speed, self._limits, inputs, config.model,
                                               config.max_amplitude_ratio)
            self.measured_speed = speed
            clean = self.clock.add(stamp, wall_ns, 1.0 / inputs.frequency, config.mean_window_periods,
                                   config.settle_margin)
            out = self.output
            target = inputs.target_speed
            if (clean and target != 0.0 and out.u_target != 0.0 and not out.unreachable
                    and not out.runaway and self._limits.within(speed)):
                # The shortfall in the target's direction, in units of U (finite: |speed| is within the limit).
                error = nondimensional_speed(math.copysign(1.0, target) * (target - speed),
                                             inputs.frequency, config.model.gravity, config.model.mu)
                self._ratio, self._last_clean = integral_step(
                    self._ratio, self._last_clean, out.u_target, error, saturated=out.saturated,
                    gain=config.integral_gain, secant=config.secant)
            return self._update()

    def _plant_changed(self) -> None:
        """Drive force, frequency or the model's mass changed: a new speed
        limit, and the old one still holds for the windows on their way."""
        limit = speed_limit(self._inputs.drive_force, self._config.model, self._inputs.frequency,
                            self._config.max_amplitude_ratio)
        self._limits = self._limits.changed(limit, self._config.mean_window_periods)

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

    # -- the law ----------------------------------------------------------------

    @property
    def config(self) -> ControllerConfig:
        return self._config

    @config.setter
    def config(self, config: ControllerConfig) -> None:
        """A new model or tuning takes effect at once.  On Kostek's model the
        slider creeps only along the drive force: a target of the other sign
        (taken under a model whose vibration conveys by itself) becomes 0
        (:meth:`~friction_sim.core.control.inputs.LawInputs.for_model`)."""
        with self._transaction():
            self._config = config
            self._inputs = self._inputs.for_model(config.model)
            self._plant_changed()
            self._update()

    def _update(self) -> ControlOutput:
        """Decide for the state in force (:func:`~friction_sim.core.control.reach.decide`;
        anti-windup may cut the ratio), and keep the output."""
        config, inputs = self.config, self._inputs
        self.output, self._ratio = decide(config.model, config.max_amplitude_ratio, self._actuator_limit,
                                          inputs.drive_force, inputs.frequency, inputs.target_speed, self._ratio)
        return self.output

    def beyond_limit(self, speed: float) -> bool:
        """Whether a finite ``speed`` [m/s] is faster than any plant in force
        could creep (the refusal of :meth:`on_mean_velocity`)."""
        return self._limits.beyond(speed)

    @property
    def sample_limit(self) -> float:
        """The largest |mean velocity| accepted now [m/s] (inf: any finite one)."""
        return self._limits.envelope

    @property
    def drive_force(self) -> float:
        return self._inputs.drive_force

    @property
    def frequency(self) -> float:
        return self._inputs.frequency

    @property
    def target_speed(self) -> float:
        return self._inputs.target_speed
