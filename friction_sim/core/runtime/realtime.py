"""Running the exact core against a wall clock, without ROS.

The slider node is a thin ROS adapter around :class:`RealtimeSlider`, which
holds everything that is not message conversion:

* :class:`SimClock` turns a monotonic wall clock into simulation time
  (elapsed wall time times the real-time factor), so a late or missed timer
  tick never changes the physics: the next tick advances further, by at most
  ``max_catch_up``.  A longer stall of the host (a garbage collection) stalls the
  controllers too; simulating it at once would run the plant on ahead of their
  answers, which no real plant does: the rest is not simulated (time slips).
* Commands take effect at the simulation time at which they are handled,
  each as a change of its own (:func:`~friction_sim.core.model.commands.take`, as verify replays them),
  are validated once (:mod:`friction_sim.core.model.params`), and are counted; a
  rejected command leaves the last valid inputs in force.
* Once per completed excitation period it reports the mean velocity over
  the last ``mean_window_periods`` whole periods and the stick and flight
  fractions of the last period, from the core's exact period marks
  (:mod:`~friction_sim.core.runtime.periods`).
* It keeps the tick statistics the node publishes as diagnostics, with the
  lift-offs, landings and time in flight of each diagnostics interval
  (:mod:`~friction_sim.core.runtime.diagnostics`).
* One advance goes only as far as :mod:`~friction_sim.core.runtime.pace`
  allows (after a stall, or beyond a few ms of work), and on the way keeps the
  log samples and accelerometer readings of :mod:`~friction_sim.core.runtime.loggrid`.
* A change of plant or inputs is taken under a guard (:mod:`~friction_sim.core.runtime.guard`): if the core raises
  while taking it, or the state it leaves is not finite, everything is put
  back as it was and the command is refused with the reason.  If advancing
  ever fails (or the state stops being finite) under inputs the core had
  taken, the run cannot go on: :class:`SimulationFault` is raised, and from
  then on every call raises it again (the node reports it and stops).

Every outcome is a typed record, so the node only converts and publishes,
and a recorder can log exactly what happened and when.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.urelation import Prediction
from friction_sim.core.model import spec
from friction_sim.core.model.commands import (
    PARAMETERS,
    PAUSE,
    RESET,
    RESUME,
    STEP,
    Command,
    Outcome,
    apply,
    reason,
)
from friction_sim.core.model.params import Inputs, SliderParams, check_load
from friction_sim.core.model.records import PeriodSummary, Tick
from friction_sim.core.model.spec import NS_PER_S
from friction_sim.core.runtime.accelerometer import Accelerometer
from friction_sim.core.runtime.diagnostics import DiagnosticsInterval
from friction_sim.core.runtime.guard import non_finite, take_guarded
from friction_sim.core.runtime.intake import take_checked
from friction_sim.core.runtime.loggrid import LogGrid
from friction_sim.core.runtime.pace import Pace
from friction_sim.core.runtime.periods import PeriodMeans
from friction_sim.core.runtime.simclock import SimClock
from friction_sim.errors import ParameterError, SimulationFault, one_line

#: Period marks the core keeps; more than this many periods in one tick are
#: summarised only from the last ones (only at absurd real-time factors).
_MARK_BACKLOG = 4096
#: Log samples one ``~/step`` may make at most (they are kept in memory until
#: the next tick hands them to the recorder): 100 s at the default log rate.
MAX_STEP_SAMPLES = 100_000
#: Excitation periods one ``~/step`` may cover at most: it is computed at once,
#: with the node's tick waiting (about a second of work in the general model).
MAX_STEP_PERIODS = 100_000


class RealtimeSlider:
    """The exact slider advanced by a wall clock, with commands and statistics."""

    def __init__(
        self, params: SliderParams, inputs: Inputs, *, wall_ns: int,
        real_time_factor: float = 1.0, publish_rate: float = 1000.0, mean_window_periods: int = 1,
        log_rate: float | None = None, load_blame: str = "excitation_frequency",
        accelerometer: Accelerometer | None = None, max_catch_up: float | None = None,
    ) -> None:
        """``load_blame`` names the setting a refusal of f x real_time_factor
        blames (``excitation_frequency`` or ``real_time_factor``): the one the user set."""
        self.clock = SimClock(float(spec.REAL_TIME_FACTOR.check(real_time_factor)), wall_ns)
        check_load(inputs.excitation_frequency, self.clock.rate, load_blame)
        self.slider = Slider(params, inputs, event_log_size=1000, cycle_log_size=_MARK_BACKLOG)
        self.publish_rate = float(spec.PUBLISH_RATE.check(publish_rate))
        self.log_rate = float(spec.LOG_RATE.check(log_rate)) if log_rate is not None else None
        #: How far one advance may go (max_catch_up, the sample budget), and the stalls,
        #: the time slipped and the advances cut short so far.
        self.pace = Pace(self.clock, self.log_rate)
        self.pace.set_catch_up(None if max_catch_up is None else float(spec.MAX_CATCH_UP.check(max_catch_up)),
                               self.publish_rate)
        #: The per-period summaries made from the core's period marks (the mean window, the last period).
        self.period_means = PeriodMeans(mean_window_periods)
        self.accepted = 0
        self.rejected = 0
        self.last_rejection = ""
        #: The diagnostics interval: its tick statistics, counts and prediction.
        self.interval = DiagnosticsInterval(wall_ns)
        #: The slideway's accelerometer (None: off), sampled on its own grid while advancing.
        self.accelerometer: Accelerometer | None = accelerometer if accelerometer and accelerometer.rate else None
        #: The log and accelerometer grids, and what advancing produced since the last tick (commands advance too).
        self.grid = LogGrid(self.log_rate, self.accelerometer)
        self._periods: list[PeriodSummary] = []  # summaries made before a reset, for the next tick
        #: Why the run cannot go on ('' while it can): see :class:`SimulationFault`.
        self.fault = ""
        #: Period ends at or after this time [s] are reported later (lockstep: a hold stands there).
        self.marks_before = math.inf

    # -- commands -----------------------------------------------------------

    def now(self, wall_ns: int) -> float:
        """Simulation time [s] at wall time ``wall_ns`` (never before the slider's own)."""
        return max(self.clock.now(wall_ns), self.slider.t)

    def hold(self, waited_ns: int, wall_ns: int) -> None:
        """Let ``waited_ns`` of wall time pass without simulation time (a producer
        waited for the recorder), but never back past the slider's own time: a
        wait that held another thread (a parameter set recording its outcome)
        overlaps wall time the ticks have simulated since, and the clock must not
        read a time before states already made (diagnostics report it)."""
        self.clock.hold(waited_ns)
        self.clock.not_before(round(self.slider.t * NS_PER_S), wall_ns)

    def command(self, command: Command, wall_ns: int) -> Outcome:
        """Apply one command now, or refuse it (see :meth:`commands`)."""
        return self.commands([command], wall_ns)[0]

    def commands(self, batch: Sequence[Command], wall_ns: int) -> list[Outcome]:
        """Handle several commands at the same instant (now), in order, each on its own.

        Each is validated against the state the ones before it left (the core's
        one gate, :func:`~friction_sim.core.model.commands.apply`, and the
        real-time load rule) and, if valid, taken at once as a change of its own
        (:func:`~friction_sim.core.model.commands.take`, guarded: one the core
        cannot take is refused), never merged: as a recording holds them and
        verify replays them.  The outcomes carry the commands stamped with the
        time they took effect.
        """
        t = self._advance(wall_ns)
        outcomes: list[Outcome] = []
        for command in batch:
            stamped = command if command.t == t else command.at(t)  # the node stamps them already
            try:
                problem = take_checked(self.slider, stamped, self.clock.rate)
            except ParameterError as error:
                outcomes.append(self._refuse(stamped, reason(stamped, error)))
                continue
            if problem:
                outcomes.append(self._refuse(stamped, f"{stamped.name}: {problem}"))
                continue
            self.accepted += 1
            outcomes.append(Outcome(stamped))
        return outcomes

    def configure(self, values: Mapping[str, Any], wall_ns: int) -> Outcome:
        """A set of node parameters, checked and applied as one new state, now: one
        change of the core (:func:`~friction_sim.core.model.commands.take`); two sets are two changes.

        ``values`` may hold plant and input fields (the physics, applied as one ``parameters``
        command), ``real_time_factor``, ``publish_rate``, ``max_catch_up`` and ``mean_window_periods``.
        Everything is checked against the state in force before anything changes: the whole set
        takes effect, or none of it (the refusal names the field that was set).
        """
        t = self._advance(wall_ns)
        physics = {k: v if isinstance(v, str) else float(v) for k, v in values.items()
                   if k in spec.PLANT or k in spec.INPUTS}
        command = Command(t, PARAMETERS, physics)
        try:
            for name, value in values.items():  # each against its own range (rclpy's allows a tolerance)
                if name in spec.SLIDER_NODE:
                    spec.SLIDER_NODE[name].check(value)
            inputs = apply(command, self.slider.params, self.slider.inputs)[1]
            rate = float(spec.REAL_TIME_FACTOR.check(values.get("real_time_factor", self.clock.rate)))
            check_load(inputs.excitation_frequency, rate,
                       "real_time_factor" if "real_time_factor" in values else "excitation_frequency")
            publish_rate = float(spec.PUBLISH_RATE.check(values.get("publish_rate", self.publish_rate)))
            catch_up = float(spec.MAX_CATCH_UP.check(values["max_catch_up"])) if "max_catch_up" in values \
                else self.pace.max_catch_up
            window = int(spec.MEAN_WINDOW_PERIODS.check(values.get("mean_window_periods",
                                                                   self.period_means.window_periods)))
        except ParameterError as error:
            return self._refuse(command, str(error))
        problem = take_guarded(self.slider, command)  # (the gate again: the plant and inputs checked above)
        if problem:
            return self._refuse(command, f"{', '.join(values)}: {problem}")
        self.clock.set_rate(rate, wall_ns)
        self.publish_rate = publish_rate
        self.pace.set_catch_up(catch_up, publish_rate)
        self.period_means.set_window(window)
        if physics:
            self.accepted += 1
        return Outcome(command)

    def refuse(self, command: Command, why: str, wall_ns: int) -> Outcome:
        """Count a command that was refused before it reached the core (also
        after a fault: the refusal is still counted, at the time reached)."""
        return self._refuse(command.at(self.now(wall_ns) if self.fault else self._advance(wall_ns)), why)

    def _refuse(self, command: Command, why: str) -> Outcome:
        self.rejected += 1
        self.last_rejection = why
        return Outcome(command, why)

    # -- simulation control (the node's ~/pause, ~/resume, ~/step, ~/reset) ----------

    @property
    def paused(self) -> bool:
        """Whether simulation time stands still (:meth:`pause`)."""
        return self.clock.paused

    def pause(self, wall_ns: int) -> Outcome:
        """Stop simulation time now, exactly: nothing moves until :meth:`resume`
        or :meth:`step` (commands are still taken, at the time it stopped)."""
        t = self._advance(wall_ns)
        if self.clock.paused:
            return self._refuse(Command(t, PAUSE), f"pause: already paused at t = {t:.9f} s")
        self.clock.pause(wall_ns)
        return Outcome(Command(t, PAUSE))

    def resume(self, wall_ns: int) -> Outcome:
        """Let simulation time run again from where it stood (no jump)."""
        t = self._advance(wall_ns)
        if not self.clock.paused:
            return self._refuse(Command(t, RESUME), "resume: not paused")
        self.clock.resume(wall_ns)
        return Outcome(Command(t, RESUME))

    def step_length(self, step_periods: int, step_time: float) -> float:
        """How far one step goes [s]: ``step_time``, or ``step_periods`` periods
        of the excitation frequency in force when ``step_time`` is 0."""
        if step_time > 0.0:
            return float(spec.STEP_TIME.check(step_time))
        return int(spec.STEP_PERIODS.check(step_periods)) / self.slider.inputs.excitation_frequency

    def step(self, duration: float, wall_ns: int) -> Outcome:
        """While paused: advance simulation time by ``duration`` [s] (to the
        nanosecond of the stamps) at once, exactly as running would, keeping the
        events, log samples and period means for the next tick; stay paused."""
        t = self._advance(wall_ns)
        command = Command(t, STEP, {"duration": duration})
        step_ns = round(duration * NS_PER_S) if math.isfinite(duration) else 0
        if not self.clock.paused:
            return self._refuse(command, "step: the simulation is running; call pause first")
        if step_ns < 1:
            return self._refuse(command, f"step: duration = {duration!r} s rejected: must be >= 1 ns")
        samples = step_ns / NS_PER_S * (self.log_rate or 0.0)
        if samples > MAX_STEP_SAMPLES:
            return self._refuse(command, f"step: duration = {duration!r} s rejected: at log_rate {self.log_rate:g} Hz "
                                         f"that is {samples:.3g} recorded states, at most {MAX_STEP_SAMPLES} per step")
        periods = step_ns / NS_PER_S * self.slider.inputs.excitation_frequency
        if periods > MAX_STEP_PERIODS:
            return self._refuse(command, f"step: duration = {duration!r} s rejected: at "
                                         f"{self.slider.inputs.excitation_frequency:g} Hz that is {periods:.3g} "
                                         f"excitation periods, at most {MAX_STEP_PERIODS} per step")
        self.clock.step(step_ns)
        end = self.clock.now_ns(wall_ns) / NS_PER_S
        mark = self.slider.next_mark_time
        if end < mark <= end + 0.5 / NS_PER_S:  # a period that ends at this nanosecond ends in this step
            end = mark
        self._advance_sim(end, chunked=True)
        return Outcome(Command(t, STEP, {"duration": step_ns / NS_PER_S}))

    def reset(self, wall_ns: int) -> Outcome:
        """Back to the initial state now (at rest at x = 0, excitation phase 0),
        under the plant and inputs in force; time goes on, paused or not.  The
        mean-velocity window starts afresh: no mean spans the reset."""
        t = self._advance(wall_ns)
        self._periods.extend(self.period_means.new(self.slider, self.marks_before))
        problem = take_guarded(self.slider, Command(t, RESET))  # the one way a command reaches the core (see take)
        if problem:
            return self._refuse(Command(t, RESET), f"reset: {problem}")
        self.period_means.restart()
        return Outcome(Command(t, RESET))

    # -- the tick -------------------------------------------------------------

    def tick(self, wall_ns: int, paused: bool | None = None) -> Tick:
        """Advance to the present and collect what happened on the way; ``paused``:
        whether simulation time stands still, as the tick says (None: the clock's).

        Raises :class:`SimulationFault` if the state there (or at a log sample
        on the way) is not finite.
        """
        self.interval.count_tick(wall_ns, self.publish_rate)
        self._advance(wall_ns)
        state = self.slider.state()
        problem = non_finite(state) or self.grid.non_finite()
        if problem:
            self._fail(f"the state became non-finite ({problem})")
        periods = self._periods + self.period_means.new(self.slider, self.marks_before)
        events, samples, accelerations = self.grid.take()
        self._periods = []
        return Tick(state, events, periods, samples, paused=self.clock.paused if paused is None else paused,
                    accelerations=accelerations)

    def _advance(self, wall_ns: int) -> float:
        """Advance to the present, keeping the events and log samples on the way
        (a failure of the core is a :class:`SimulationFault`)."""
        if self.fault:
            raise SimulationFault(self.fault)
        try:
            t = self.pace.reachable(self.now(wall_ns), self.slider.t, wall_ns)
        except Exception as error:  # noqa: BLE001 - whatever the core raised, the run cannot go on
            self._fail(f"advancing failed ({one_line(error, with_type=True)})")
        self._advance_sim(t)
        return t

    def _advance_sim(self, t: float, *, chunked: bool = False) -> None:
        """Advance the core to ``t``, keeping the events and log samples on the
        way (:meth:`LogGrid.advance <friction_sim.core.runtime.loggrid.LogGrid.advance>`);
        ``chunked``: in pieces of :data:`~friction_sim.core.runtime.loggrid.MAX_SAMPLES_PER_ADVANCE`
        samples (a step).  A failure of the core is a :class:`SimulationFault`."""
        try:
            self.grid.advance(self.slider, t, chunked=chunked)
        except Exception as error:  # noqa: BLE001 - whatever the core raised, the run cannot go on
            self._fail(f"advancing failed ({one_line(error, with_type=True)})")
        self.clock.reached(round(self.slider.t * NS_PER_S))

    def _fail(self, why: str) -> None:
        """Stop for good: every later call raises the same fault."""
        slider = self.slider
        self.fault = (f"simulation fault at t = {slider.t!r} s: {why}, with inputs {slider.inputs} "
                      f"and plant {slider.params}")
        raise SimulationFault(self.fault)

    # -- diagnostics ------------------------------------------------------------

    def prediction(self, params: SliderParams | None = None, inputs: Inputs | None = None) -> Prediction:
        """The mean-speed prediction for ``params`` and ``inputs`` (default: those
        in force), computed once per change; NaN where there is none.

        Outside Kostek's model it is a simulation (:func:`~friction_sim.core.meanspeed.predict.predict`
        falls back on the general mean speed: a millisecond, up to ~0.4 s for a chattering
        plant), so a node asks for it outside its tick's lock and passes it to
        :meth:`diagnostics`.
        """
        return self.interval.prediction(self.slider.params if params is None else params,
                                        self.slider.inputs if inputs is None else inputs)

    def diagnostics(self, wall_ns: int, prediction: Prediction | None = None) -> dict[str, Any]:
        """The figures of the last diagnostics interval (:mod:`~friction_sim.core.runtime.diagnostics`);
        starts a new interval.  ``prediction`` is :meth:`prediction`'s, if the caller has made it."""
        return self.interval.report(self, wall_ns, self.prediction() if prediction is None else prediction)
