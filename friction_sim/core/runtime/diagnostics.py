"""The real-time slider's diagnostics: the figures of each diagnostics interval.

Kept apart from :class:`~friction_sim.core.runtime.realtime.RealtimeSlider`,
which advances the core and takes commands: this module only reads what that
left (the clock, the counters, the slider's state and records) and keeps what
an interval needs to be reported on its own: the tick statistics, the counts
at the interval's start and the mean-speed prediction of the plant in force
(made once per change).  A report starts the next interval.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.predict import predict
from friction_sim.core.meanspeed.urelation import NO_PREDICTION, Prediction
from friction_sim.core.model.commands import unused_input
from friction_sim.core.model.events import EventKind
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.model.records import share
from friction_sim.core.model.spec import NS_PER_S
from friction_sim.core.physics.plant import steady_excitation, steady_throw_number
from friction_sim.core.runtime.pace import Pace
from friction_sim.core.runtime.periods import PeriodMeans
from friction_sim.core.runtime.simclock import SimClock, TickStats


class Reported(Protocol):
    """What a diagnostics report reads of the real-time slider."""

    clock: SimClock
    slider: Slider
    publish_rate: float
    accepted: int
    rejected: int
    last_rejection: str
    pace: Pace
    period_means: PeriodMeans

    def now(self, wall_ns: int) -> float: ...


class DiagnosticsInterval:
    """The present diagnostics interval: its tick statistics and the counts at its start."""

    def __init__(self, wall_ns: int) -> None:
        self.stats = TickStats(interval_start_ns=wall_ns)
        self._rejected_before = 0
        self._behind_before = 0
        self._prediction: tuple[SliderParams, Inputs, Prediction] | None = None

    def count_tick(self, wall_ns: int, publish_rate: float) -> None:
        """Count a tick at ``wall_ns``: late if more than 1.5 periods of ``publish_rate`` after the last."""
        stats = self.stats
        if stats.last_wall_ns is not None and (wall_ns - stats.last_wall_ns) > 1.5 * NS_PER_S / publish_rate:
            stats.late_ticks += 1
            stats.total_late_ticks += 1
        stats.ticks += 1
        stats.last_wall_ns = wall_ns

    def prediction(self, params: SliderParams, inputs: Inputs) -> Prediction:
        """The mean-speed prediction for ``params`` and ``inputs``, computed once per
        change (kept for the last pair asked for); NaN where there is none."""
        cached = self._prediction
        if cached is None or cached[0] is not params or cached[1] is not inputs:
            try:
                value = predict(params, inputs)
            except Exception:  # noqa: BLE001 - diagnostics must answer whatever the inputs: nan = no prediction
                value = NO_PREDICTION
            cached = self._prediction = (params, inputs, value)
        return cached[2]

    def report(self, rt: Reported, wall_ns: int, prediction: Prediction) -> dict[str, Any]:
        """The figures of the interval ending at ``wall_ns``, with ``prediction``
        for the plant in force; starts a new interval."""
        stats = self.stats
        slider = rt.slider
        start = stats.interval_start_ns if stats.interval_start_ns is not None else wall_ns
        wall = (wall_ns - start) / NS_PER_S
        sim_now = rt.now(wall_ns)  # (never before a state already made: the slider may be ahead of its clock)
        tick_rate = stats.ticks / wall if wall > 0 else 0.0
        achieved_rtf = (sim_now - stats.interval_sim_start) / wall if wall > 0 else 0.0
        inputs = slider.inputs
        flight_time, lift_offs, landings = flight_record(slider)
        sim_elapsed = slider.t - stats.interval_slider_start
        last_period = rt.period_means.last
        report = {
            "sim_time": sim_now,
            "paused": rt.clock.paused,
            "real_time_factor": rt.clock.rate,
            "achieved_real_time_factor": achieved_rtf,
            "tick_rate": tick_rate,
            "publish_rate": rt.publish_rate,
            "late_ticks": stats.late_ticks,
            "late_ticks_total": stats.total_late_ticks,
            "commands_accepted": rt.accepted,
            "commands_rejected": rt.rejected,
            "commands_rejected_in_interval": rt.rejected - self._rejected_before,
            "ticks_behind_in_interval": rt.pace.behind - self._behind_before,
            "max_catch_up": rt.pace.max_catch_up, "stalls": rt.pace.stalls, "time_slipped": rt.pace.time_slipped,
            "last_rejection": rt.last_rejection,
            "drive_force": inputs.drive_force,
            "excitation_amplitude": input_shown(slider, "excitation_amplitude"),
            "excitation_frequency": inputs.excitation_frequency,
            "external_force_x": inputs.external_force_x,
            "external_force_z": inputs.external_force_z,
            "drive_level": input_shown(slider, "drive_level"),
            **exciter_report(slider),
            "throw_number": steady_throw_number(slider.params, inputs),
            # the groups the prediction is made of: with an external force, the effective ones
            "phi": prediction.effective_phi,
            "amplitude_ratio": prediction.effective_amplitude_ratio,
            "predicted_U": prediction.u,
            "predicted_mean_velocity": prediction.mean_velocity,
            "stick_fraction": last_period.stick_fraction if last_period else math.nan,
            "flight_fraction": last_period.flight_fraction if last_period else math.nan,
            "flight_fraction_in_interval": share(flight_time - stats.interval_flight_start, sim_elapsed,
                                                 empty=math.nan),
            "lift_offs": lift_offs,
            "landings": landings,
            "lift_offs_in_interval": lift_offs - stats.interval_lift_offs_start,
            "landings_in_interval": landings - stats.interval_landings_start,
            "measured_mean_velocity": last_period.mean_velocity if last_period else math.nan,
        }
        self._rejected_before = rt.rejected
        self._behind_before = rt.pace.behind
        stats.ticks = 0
        stats.late_ticks = 0
        stats.interval_start_ns = wall_ns
        stats.interval_sim_start = sim_now
        stats.interval_slider_start = slider.t
        stats.interval_flight_start, stats.interval_lift_offs_start, stats.interval_landings_start = (
            flight_time, lift_offs, landings)
        return report


def input_shown(slider: Slider, field: str) -> float | str:
    """The input ``field`` in force as diagnostics show it: its value, or, for
    the input the actuator in force does not use (and refuses), the value
    marked so (``5.0 (unused: actuator resonant)``), never as if it acted."""
    value: float = getattr(slider.inputs, field)
    actuator = slider.params.actuator
    return f"{value!r} (unused: actuator {actuator})" if field == unused_input(actuator) else value


def exciter_report(slider: Slider) -> dict[str, Any]:
    """The actuator and the excitation it makes now: the steady Pa of the inputs
    in force (the resonant actuator's m*u*A*G(f/f_n), the force actuator's Pa as
    set), the present amplitude of the part's normal excitation (the resonant
    exciter's state now: steady plus the transient's envelope) and its lag
    behind the drive (NaN for the force actuator), with the slideway's f_n and
    zeta in force."""
    state, params = slider.exciter, slider.params
    steady = steady_excitation(params, slider.inputs)[0]
    report = {"actuator": params.actuator, "natural_frequency": params.natural_frequency,
              "damping_ratio": params.damping_ratio, "steady_excitation_amplitude": steady}
    if state is None:
        return {**report, "excitation_envelope": steady, "exciter_lag_deg": math.nan}
    return {**report, "excitation_envelope": state.amplitude, "exciter_lag_deg": math.degrees(state.lag)}


def flight_record(slider: Slider) -> tuple[float, int, int]:
    """(time in flight [s], lift-offs, landings) since the start, up to the slider's time."""
    counts = slider.event_counts
    return slider.flight_time, counts.get(EventKind.LIFT_OFF, 0), counts.get(EventKind.LANDING, 0)


__all__ = ["DiagnosticsInterval", "Reported", "exciter_report", "flight_record", "input_shown"]
