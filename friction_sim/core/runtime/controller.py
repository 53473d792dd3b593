"""The controller's own runtime, without ROS: what it counts, refuses, waits for and reports.

The controller node is a thin ROS adapter around :class:`RealtimeController`,
as the slider node is around :class:`~friction_sim.core.runtime.realtime.RealtimeSlider`:

* commands come in batches (:meth:`RealtimeController.take_batch`): each is
  judged against the state the ones before it left, refusals are counted with
  the latest reason, and a target makes a standing-by controller active;
* mean-speed samples (:meth:`RealtimeController.take_sample`) are counted,
  accepted or refused;
* a target the node's own model refuses but the plant's may take waits for the
  plant's model (:meth:`RealtimeController.settle`);
* a parameter set is judged whole on a copy (:meth:`RealtimeController.with_parameters`);
* the conditions worth a warning (unreachable, runaway, a plant beyond its
  model) are reported once each time they begin (:meth:`RealtimeController.news`),
  and the status the node publishes on ``diagnostics`` is built here
  (:meth:`RealtimeController.status`).

A plant beyond its model: samples beyond the speed limit of every plant in
force are refused (a glitch, a wrong message), but not for ever.  Once
:func:`beyond_model_after` of them have come in a row (more than the windows
still on their way after a change), the samples are the plant's: it runs
faster than the model allows (it runs away, or its parameters are not the
model's).  Then the controller says so once (a WARN with the reason and the
plant it inverts), takes such samples again (counted in
``samples_beyond_model``, not refused), and sets Pa to 0, the one amplitude
that lets friction brake any slider of the model; the law's own state is
kept.  The first sample back within the limit ends it: regulation goes on
from that state.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from friction_sim.core.control.law import ControllerConfig, MeanSpeedController
from friction_sim.core.control.reach import ControlOutput
from friction_sim.core.control.relation import uses_closed_form
from friction_sim.core.control.speedlimit import LIMIT_SLACK_SAMPLES
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import amplitude_for
from friction_sim.core.model.params import SliderParams, plant_from
from friction_sim.core.runtime.drive import DriveCommand, DriveRuntime, drive_settings, outer_model, refusal_text
from friction_sim.errors import ParameterError

#: The plant's parameters that make up the controller's model (the resonant
#: exciter's data sheet among them: with that actuator the controller sets the
#: drive level through :mod:`friction_sim.core.runtime.drive`).
MODEL = tuple(name for name in spec.PLANT if name in spec.CONTROLLER_NODE)
#: Parameters that make up the ControllerConfig.
CONFIG = {*MODEL, "integral_gain", "max_amplitude_ratio", "settle_margin", "mean_window_periods", "inner_loop"}
#: Parameters the inner loop is built from (a change of one starts it afresh).
DRIVE = {*spec.EXCITER, "actuator", "inner_loop", "track_resonance", "mean_window_periods"}
#: The status's words while the controller has not yet taken its plant's model (an experiment
#: attached to running nodes waits for them to go before it sets the controller's parameters).
WAITING_FOR_PLANT = "waiting for the plant's parameters"
#: Diagnostic levels (diagnostic_msgs/DiagnosticStatus: OK, WARN, ERROR).
OK, WARN, ERROR = 0, 1, 2


def model_of(values: Mapping[str, Any]) -> SliderParams:
    """The controller's model of the plant, exciter included, from the node's parameter values."""
    return plant_from({name: values[name] for name in MODEL})[0]


def config_of(values: Mapping[str, Any]) -> ControllerConfig:
    """The law's configuration from the node's parameter values (its model sets Pa directly)."""
    return ControllerConfig(
        model=outer_model(model_of(values)),
        integral_gain=values["integral_gain"], max_amplitude_ratio=values["max_amplitude_ratio"],
        mean_window_periods=values["mean_window_periods"], settle_margin=values["settle_margin"],
        secant=not (values["actuator"] == "resonant" and drive_settings(values)[0]),
    )


def law_of(values: Mapping[str, Any], *, target: bool = True) -> MeanSpeedController:
    """The mean-speed law a controller builds from its parameter ``values`` (every
    parameter of the controller node): :func:`config_of`, the drive force and
    frequency, and the target (``target`` False: none yet).  The one build of a
    controller: the node's runtime and a scenario's check both call it, so they
    cannot differ.  A ParameterError names what the law refuses."""
    return MeanSpeedController(config_of(values), drive_force=values["drive_force"],
                               frequency=values["excitation_frequency"],
                               target_speed=values["target_speed"] if target else 0.0)


def beyond_model_after(config: ControllerConfig) -> int:
    """Samples beyond the limit, in a row, that show a plant beyond its model:
    past the mean window of samples still on their way after a change, and the
    slack the law allows them (see the module doc)."""
    return config.mean_window_periods + LIMIT_SLACK_SAMPLES


def plant_words(control: MeanSpeedController) -> str:
    """The plant the law inverts, in one line (for diagnostics and warnings)."""
    config = control.config
    model = config.model
    form = "Kostek's closed form" if uses_closed_form(model, config.max_amplitude_ratio) else "the general model"
    return (f"m = {model.mass:g} kg, mu = {model.mu:g}, g = {model.gravity:g} m/s^2, Fd = {control.drive_force:g} N, "
            f"f = {control.frequency:g} Hz ({form})")


def taken_words(values: Mapping[str, Any], drive_level: Any = None) -> str:
    """The plant's parameter ``values`` a controller took (and the ``drive_level`` it
    runs at, if known), in one line with their units, in the vocabulary's order."""
    settings = {**spec.PLANT, **spec.CONTROLLER_NODE, "drive_level": spec.DRIVE_LEVEL}
    taken = {**values, **({} if drive_level is None else {"drive_level": drive_level})}
    return ", ".join(f"{name} {taken[name]:g}{setting.unit_suffix}" if isinstance(taken[name], float)
                     else f"{name} {taken[name]}{setting.unit_suffix}"
                     for name, setting in settings.items() if name in taken)


@dataclass(frozen=True)
class Status:
    """What the node publishes on ``diagnostics``: a level, a message and the values."""

    level: int
    message: str
    values: dict[str, Any]


class RealtimeController:
    """The mean-speed law with the counters, the pending target and the reports of a running controller."""

    def __init__(self, values: Mapping[str, Any]) -> None:
        """Start from the node's parameter ``values`` (a ParameterError names a bad one).
        A target the node's own model refuses but the plant's may take (a target with
        no drive force, for a plant whose tilted vibration conveys) waits for the
        plant's model when ``plant_node`` is set: :meth:`settle` judges it then."""
        #: The target waiting for the plant's model, or None.
        self.pending_target: float | None = None
        try:
            self.control = law_of(values)
        except ParameterError:
            if not values["plant_node"] or values["target_speed"] == 0.0:
                raise
            self.control = law_of(values, target=False)
            self.pending_target = values["target_speed"]
        self.active: bool = values["active"]
        #: The inner loop while the plant's actuator is resonant, else None.
        self.drive: DriveRuntime | None = None
        #: The plant's drive level when the controller started (its parameter), if known.
        self.plant_drive_level: float | None = None
        self._drive_values: dict[str, Any] = {}
        self._rebuild_drive(values)
        self._limit_actuator()
        #: Commands taken; inputs refused (commands, parameter values, samples), with the latest reason.
        self.accepted = 0
        self.rejected = 0
        self.last_rejection = ""
        self.command_batches = 0
        #: mean_velocity samples judged (while regulating) and refused.
        self.samples_accepted = 0
        self.samples_rejected = 0
        self.last_sample_rejection = ""
        #: Unexpected errors in callbacks (each refused its input).
        self.internal_errors = 0
        self.last_internal_error = ""
        self.model_source = "own parameters"
        #: Every value taken from the plant node at start-up, in words ('' before, or without one).
        self.taken_from_plant = ""
        #: The plant node's fully qualified name ('' without one), and the changes of it followed.
        self.plant_node = ""
        self.plant_changes = 0
        #: Why the plant is taken to be beyond its model ('' while it is not), its samples, the run refused.
        self.beyond_model = ""
        self.samples_beyond_model = 0
        self._beyond_run = 0
        self._warned_beyond = False
        self._refused_before_interval = 0
        self._warned_unreachable = False
        self._warned_runaway = False

    # -- inputs ---------------------------------------------------------------------

    def refuse(self, reason: str) -> None:
        """Count a refused input and keep its reason."""
        self.rejected += 1
        self.last_rejection = reason

    def take_batch(self, changes: Sequence[tuple[str, float]]) -> list[str]:
        """Apply a batch of command changes (field, value) in order, each judged
        against the state the ones before it left; the reasons of the refused
        ones (counted), in order.  A target makes a standing-by controller active."""
        self.command_batches += 1
        refusals = []
        for (field, _), verdict in zip(changes, self.control.take(list(changes))):
            if verdict is not None:
                self.refuse(str(verdict))
                refusals.append(str(verdict))
                continue
            self.accepted += 1
            if field == "target_speed" and not self.active:
                self.active = True
                self._rebuild_drive(self._drive_values)  # the plant was steered by others meanwhile
            if field == "excitation_frequency" and self.drive is not None:
                self.drive.follow_frequency(self.control.frequency)
        self._limit_actuator()
        return refusals

    def take_sample(self, speed: float, t: float, now_ns: int, regulating: bool) -> ControlOutput | None:
        """A mean-speed sample at simulation time ``t``: the law's new output, or
        None (standing by: only the plant's pace is learnt).  ParameterError
        (counted) for a sample no plant in force could give."""
        if not regulating:
            self.control.clock.observe(t, now_ns)
            return None
        self._limit_actuator()
        if self.beyond_model:
            if self._beyond_limit(speed):
                return self._beyond(speed)
            self.beyond_model = ""  # back within the limit: regulate from the state kept
        try:
            output = self.control.on_mean_velocity(speed, t, now_ns)
        except ParameterError as error:
            self._beyond_run = self._beyond_run + 1 if self._beyond_limit(speed) else 0
            if self._beyond_run >= beyond_model_after(self.control.config):
                self.beyond_model = (
                    f"{self._beyond_run} mean_velocity samples in a row beyond the limit of every plant in force "
                    f"({self.control.sample_limit:.6g} m/s; the last {float(speed):.6g} m/s): the plant runs faster "
                    f"than its model allows (it runs away, or it is not {plant_words(self.control)}); Pa set to 0 "
                    "until a sample is back within the limit")
                return self._beyond(speed)
            self.samples_rejected += 1
            self.last_sample_rejection = str(error)
            self.refuse(str(error))
            raise
        self._beyond_run = 0
        self.samples_accepted += 1
        return output

    def _beyond_limit(self, speed: Any) -> bool:
        """A number the law refuses as faster than any plant in force could creep."""
        return isinstance(speed, (int, float)) and not isinstance(speed, bool) and self.control.beyond_limit(speed)

    def _beyond(self, speed: float) -> ControlOutput:
        """A sample of a plant beyond its model: taken (measured, counted), Pa 0."""
        self.samples_beyond_model += 1
        self.control.measured_speed = float(speed)
        return dataclasses.replace(self.control.output, amplitude=0.0, applied_ratio=0.0)

    def settle(self) -> str:
        """The model is settled: judge the pending target; '' or the refusal's reason (counted)."""
        pending, self.pending_target = self.pending_target, None
        if pending is None:
            return ""
        try:
            self.control.set_target(pending)
        except ParameterError as error:
            self.refuse(str(error))
            return str(error)
        return ""

    def with_parameters(self, values: Mapping[str, Any], current: Mapping[str, Any]) -> MeanSpeedController:
        """The law as a set of parameters ``values`` would leave it, judged whole on
        a copy (``current``: every parameter's value now); ParameterError, counted,
        if the set is refused (then nothing changes)."""
        candidate = copy.copy(self.control)
        try:
            for name, value in values.items():  # each against its own range (rclpy's allows a tolerance)
                if name in spec.CONTROLLER_NODE:
                    spec.CONTROLLER_NODE[name].check(value)
            if values.keys() & CONFIG:
                candidate.config = config_of({**current, **values})
            if "drive_force" in values:
                candidate.set_drive_force(values["drive_force"])
            if "excitation_frequency" in values:
                candidate.set_frequency(values["excitation_frequency"])
            if "target_speed" in values:
                candidate.set_target(values["target_speed"])
        except ParameterError as error:
            self.refuse(str(error))
            raise
        return candidate

    def adopt(self, control: MeanSpeedController, values: Mapping[str, Any], current: Mapping[str, Any]) -> None:
        """Take a parameter set judged by :meth:`with_parameters` (``current``:
        every parameter's value before it)."""
        self.control = control
        was_active = self.active
        if "active" in values or "target_speed" in values:
            self.active = values.get("active", True) or "target_speed" in values
        if values.keys() & DRIVE or (self.active and not was_active):
            self._rebuild_drive({**current, **values})
        elif "excitation_frequency" in values and self.drive is not None:
            self.drive.follow_frequency(control.frequency)
        self._limit_actuator()

    # -- the inner loop (resonant actuator) ---------------------------------------------

    def _rebuild_drive(self, values: Mapping[str, Any]) -> None:
        """The inner loop for the model in ``values`` (None for the force actuator),
        its model starting from the level the plant runs at (see below; unknown:
        the model's steady gain's level for the Pa asked for)."""
        self._drive_values = {name: values[name] for name in (*MODEL, *DRIVE) if name in values}
        model = model_of(values) if all(name in values for name in MODEL) else None
        if model is None or not model.resonant:
            self.drive = None
            return
        inner_loop, tracking, cycles = drive_settings(values)
        # The plant runs at the level it was read to run at (once, when its model is adopted), or
        # at the one this loop last drove.
        level = self.plant_drive_level if self.plant_drive_level is not None else (
            self.drive.loop.drive_level if self.drive is not None else None)
        self.plant_drive_level = None
        self.drive = DriveRuntime(model, self.control.frequency, self.wanted_amplitude(), inner_loop=inner_loop,
                                  tracking=tracking, cycles=cycles, level=level)

    def _limit_actuator(self) -> None:
        """Tell the law the largest Pa the actuator gives now: the exciter at full
        drive as the inner loop's model reads it (the data sheet corrected by the
        accelerometer; the data sheet alone without the inner loop), or no limit
        for the force actuator.  The law saturates there, with anti-windup."""
        drive = self.drive
        self.control.limit_actuator(
            None if drive is None else self.control.config.model.mass * drive.full_drive_amplitude)

    def wanted_amplitude(self) -> float:
        """The slideway's normal acceleration amplitude the law asks for [m/s^2]: Pa/m."""
        return self.control.output.amplitude / self.control.config.model.mass

    def take_acceleration(self, t: float, normal: float) -> None:
        """An accelerometer sample; one from no plant in force (not finite, stamped
        ahead of the plant, or beyond any slideway of the model: see
        :meth:`DriveRuntime.take_acceleration`) is refused (counted,
        ParameterError with the reason).  Without the inner loop it is only counted."""
        refused = self.take_accelerations(((t, normal),))
        if refused:
            raise refused[0]

    def take_accelerations(self, readings: Sequence[tuple[float, float]]) -> list[ParameterError]:
        """Accelerometer samples (t, normal) in the order they came, as
        :meth:`take_acceleration` takes each (a window's at once); the refused
        ones' errors, in order (counted, not raised)."""
        if self.drive is None:
            return []
        errors = []
        for t, normal, why in self.drive.take_accelerations(readings):
            self.refuse(refusal_text(t, normal, why))
            errors.append(ParameterError("accelerometer", (t, normal), why))
        return errors

    def drive_boundary(self, t: float) -> DriveCommand | None:
        """A window of the plant ended at ``t``: the drive for the next (None:
        the force actuator).  The law follows a drive frequency tracking moved."""
        if self.drive is None:
            return None
        command = self.drive.boundary(t, self.wanted_amplitude())
        if command.frequency_changed:
            self.control.set_frequency(command.frequency)
        return command

    def steady_drive(self) -> DriveCommand | None:
        """The drive level the model's steady gain gives for the Pa asked for now
        (each new Pa without the inner loop); None for the force actuator."""
        return self.drive.steady(self.wanted_amplitude()) if self.drive is not None else None

    def internal_error(self, reason: str) -> None:
        """Count an unexpected error (reported as ERROR from now on)."""
        self.internal_errors += 1
        self.last_internal_error = reason

    # -- reports --------------------------------------------------------------------

    def news(self, output: ControlOutput) -> tuple[list[str], bool]:
        """(warnings to log, whether to publish diagnostics now): the target
        becoming unreachable, the drive running away, or reachable again."""
        warnings: list[str] = []
        publish = False
        if output.unreachable and not self._warned_unreachable:
            config = self.control.config
            limit = self.control.actuator_limit
            ceiling = (f"Pa <= {config.max_amplitude_ratio:g} m g" if limit is None or
                       limit >= amplitude_for(config.max_amplitude_ratio, config.model.weight) else
                       f"Pa <= {limit:.4g} N, the actuator at full drive")
            if uses_closed_form(config.model, config.max_amplitude_ratio):
                where = f"with {ceiling}"
            else:
                where = (f"on the rising branch of the mean speed for {ceiling} "
                         "(it ends where U stops rising with Pa)")
            warnings.append(f"target {output.target_speed!r} m/s is unreachable {where}: the most it can give is "
                            f"{output.reachable_speed:.6g} m/s; Pa set to {output.amplitude:g} N")
            publish = True
        if output.runaway and not self._warned_runaway:
            warnings.append(f"phi = {output.phi:.3f}: the drive force (with the slope's pull) exceeds friction, the "
                            "slider slides on whatever the excitation; Pa set to 0")
        if output.unreachable != self._warned_unreachable and not output.unreachable:
            publish = True
        if bool(self.beyond_model) != self._warned_beyond:
            if self.beyond_model:
                warnings.append(self.beyond_model)
            publish, self._warned_beyond = True, bool(self.beyond_model)
        self._warned_unreachable, self._warned_runaway = output.unreachable, output.runaway
        return warnings, publish

    @property
    def plant_actuator(self) -> str:
        """The plant's actuator in the model: force (this node sets Pa) or resonant (the drive level)."""
        return "resonant" if self.drive is not None else "force"

    def status(self, *, namesake: str, ready: bool) -> Status:
        """The diagnostics status now (``namesake``: the graph's warning about a node
        of the same name, or ''; ``ready``: the model settled and the output heard).
        The count of inputs refused is the one since the previous status."""
        out = self.control.output
        refused_now, self._refused_before_interval = self.rejected - self._refused_before_interval, self.rejected
        problems = [text for flag, text in (
            (bool(namesake), namesake),
            (out.unreachable, f"target unreachable: the most it can give is {out.reachable_speed:.6g} m/s"),
            (out.saturated and not out.unreachable, "saturated"),
            (out.runaway, "the drive beats friction (phi > 1): no control over the speed"),
            (bool(self.beyond_model), "the plant runs beyond its model: Pa 0"),
            (not ready, WAITING_FOR_PLANT),
            (ready and not self.active, "standing by for a target"),
            (self.drive is not None and self.drive.inner_loop and self.active and self.drive.samples == 0,
             "no accelerometer samples: the inner loop drives by the model alone (set the slider's "
             "accelerometer_rate)"),
            (refused_now > 0, f"{refused_now} inputs refused ({self.last_rejection})"),
        ) if flag]
        if self.internal_errors:
            level = ERROR
            message = "; ".join([f"{self.internal_errors} internal errors, the last in {self.last_internal_error} "
                                 "(input refused, controller goes on)", *problems])
        else:
            level, message = (WARN, "; ".join(problems)) if problems else (OK, "regulating")
        values = {
            "target_speed": out.target_speed, "measured_mean_speed": self.control.measured_speed,
            "u_target": out.u_target, "phi": out.phi, "feedforward_ratio": out.feedforward_ratio,
            "applied_ratio": out.applied_ratio, "excitation_amplitude": out.amplitude,
            "integral": out.integral, "saturated": out.saturated, "unreachable": out.unreachable,
            "reachable_speed": out.reachable_speed,
            "actuator_limit": math.nan if self.control.actuator_limit is None else self.control.actuator_limit,
            "runaway": out.runaway, "drive_force": self.control.drive_force,
            "excitation_frequency": self.control.frequency, "model_source": self.model_source,
            "plant_node": self.plant_node, "taken_from_plant": self.taken_from_plant,
            "plant": plant_words(self.control), "plant_actuator": self.plant_actuator,
            "plant_changes_followed": self.plant_changes, "plant_beyond_model": bool(self.beyond_model),
            "samples_beyond_model": self.samples_beyond_model, "beyond_model_reason": self.beyond_model,
            "commands_accepted": self.accepted, "commands_rejected": self.rejected,
            "command_batches": self.command_batches,
            "last_rejection": self.last_rejection,
            "samples_accepted": self.samples_accepted, "samples_rejected": self.samples_rejected,
            "last_sample_rejection": self.last_sample_rejection, "sample_limit": self.control.sample_limit,
            "internal_errors": self.internal_errors, "last_internal_error": self.last_internal_error,
            **(self.drive.values() if self.drive is not None else {}),
        }
        return Status(level, message, values)


__all__ = [
    "CONFIG", "ERROR", "MODEL", "OK", "WAITING_FOR_PLANT", "WARN", "RealtimeController", "Status",
    "beyond_model_after", "config_of", "law_of", "plant_words", "taken_words",
]
