"""The controller's inner loop at run time, without ROS: what a controller of a
resonant plant does with the accelerometer and the slider's period boundaries.

:class:`RealtimeController <friction_sim.core.runtime.controller.RealtimeController>`
keeps one :class:`DriveRuntime` while the plant's actuator is resonant.  The
outer law asks for an excitation amplitude Pa; this runtime turns it into the
drive level (and, with resonance tracking, the drive frequency) to publish:

* with ``inner_loop`` (the default) the accelerometer's normal samples go to
  the lock-in (:mod:`friction_sim.core.control.lockin`) and each mean_velocity
  stamp (a window's end, drive phase a whole turn) is a boundary of
  :class:`~friction_sim.core.control.drive.DriveLoop`, which decides the level
  for the coming window from the model and the readings;
* without it, the level is the model's steady gain's answer (today's
  controller through the exciter: the drive stepped, no accelerometer).

The drive frequency this runtime published comes back to the controller twice
(its own message on ``excitation_frequency``, and the slider's parameter event),
possibly after the loop has moved on: a frequency among the last ones published
is an echo and is not taken as a command, so tracking never steps back.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from friction_sim.core.control.drive import DriveLoop, saturated_level
from friction_sim.core.control.lockin import LockIn, Vibration
from friction_sim.core.model import spec
from friction_sim.core.model.params import SliderParams
from friction_sim.core.physics.exciter import peak_gain, steady_response

#: The frequencies recently published that an echo may still bring back.
ECHOES = 16
#: How many windows past the latest window end taken an accelerometer sample may lie: the
#: windows whose mean_velocity samples may still be queued on their way (the controller's queue
#: keeps 10) and the one under way.  A sample stamped later is from no plant in force.
MAX_LEAD_WINDOWS = 11
#: An accelerometer reading beyond this many times (g + 2 A G_peak) is from no slideway of the
#: model: the steady amplitude is at most A G_peak at resonance, a transient adds as much again,
#: and the factor leaves room for a model that is off (a load), a sensor's bias and its noise.
PLAUSIBLE_FACTOR = 100.0


@dataclass(frozen=True)
class DriveCommand:
    """What the controller publishes at a boundary: the drive ``level`` in [0, 1]
    and ``frequency`` [Hz] (``frequency_changed``: tracking moved it, publish it
    too); ``per_drive`` [m/s^2]: the latest window's lock-in amplitude per unit
    of the drive level that drove it (nan until one is read)."""

    level: float
    frequency: float
    frequency_changed: bool
    per_drive: float


def outer_model(model: SliderParams) -> SliderParams:
    """The plant as the outer mean-speed law sees it: Pa set directly (the force
    actuator), whatever actuator makes it; the exciter is this runtime's business."""
    return model if model.actuator == "force" else model.replace(actuator="force")


def refusal_text(t: float, normal: float, why: str) -> str:
    """The one line that says an accelerometer sample (t, normal) was refused, and ``why``."""
    return f"accelerometer sample ({t!r} s, {normal!r} m/s^2) refused: {why}"


class DriveRuntime:
    """The drive loop with its lock-in, counters and echoes (see the module doc)."""

    def __init__(self, model: SliderParams, frequency: float, wanted_amplitude: float, *, inner_loop: bool,
                 tracking: bool, cycles: int, level: float | None = None) -> None:
        """``level``: the drive level the plant is known to run at, in steady state
        (a slider starts on a running feeder); None: the steady gain's level for
        ``wanted_amplitude`` [m/s^2]."""
        self.model = model
        self.inner_loop = inner_loop
        start = self._steady_level(model, frequency, wanted_amplitude) if level is None else level
        #: The level the loop's model started from (the plant's, when known).
        self.start_level = start
        self.loop = DriveLoop(model, frequency, start, tracking=tracking and inner_loop, cycles=cycles)
        self.lockin = LockIn(cycles=cycles)
        #: Accelerometer samples taken and refused; windows read; the latest reading.
        self.samples = 0
        self.samples_refused = 0
        self.windows_read = 0
        self.last_reading: Vibration | None = None
        self.per_drive = math.nan
        self._published: deque[float] = deque(maxlen=ECHOES)
        self._last_boundary: float | None = None
        #: The largest |normal reading| [m/s^2] a slideway of the model can give (see PLAUSIBLE_FACTOR).
        self.plausible_reading = PLAUSIBLE_FACTOR * (model.gravity + 2.0 * model.full_drive_acceleration
                                                     * peak_gain(model.damping_ratio))

    @staticmethod
    def _steady_level(model: SliderParams, frequency: float, wanted_amplitude: float) -> float:
        """The level whose steady amplitude is ``wanted_amplitude`` [m/s^2] by the model, in [0, 1]."""
        per_level, _ = steady_response(1.0, model.full_drive_acceleration, frequency, model.natural_frequency,
                                       model.damping_ratio)
        return saturated_level(wanted_amplitude / per_level) if per_level > 0.0 else 0.0

    @property
    def frequency(self) -> float:
        """The drive frequency in force [Hz]."""
        return self.loop.frequency

    @property
    def settled(self) -> bool:
        """Whether the slideway's amplitude is where the outer loop asked (see
        :attr:`DriveLoop.steady`); always, without the inner loop (nothing to wait for)."""
        return self.loop.steady or not self.inner_loop

    def steady(self, wanted_amplitude: float) -> DriveCommand:
        """The level the model's steady gain gives for ``wanted_amplitude`` [m/s^2]
        at the frequency in force, in [0, 1] (the drive without the inner loop)."""
        self.loop.drive_level = saturated_level(self.loop.level_for(wanted_amplitude))
        return DriveCommand(self.loop.drive_level, self.loop.frequency, False, self.per_drive)

    @property
    def full_drive_amplitude(self) -> float:
        """The slideway's steady amplitude [m/s^2] at full drive, as the loop's model
        reads it now (the data sheet's, corrected by what the accelerometer taught)."""
        return self.loop.full_drive_amplitude

    def take_acceleration(self, t: float, normal: float) -> str:
        """An accelerometer sample (simulation time, normal specific force
        [m/s^2]); '' or why it was refused: not finite, stamped ahead of the
        plant (more than :data:`MAX_LEAD_WINDOWS` windows past the latest window
        end taken), or a reading no slideway of the model gives (:data:`PLAUSIBLE_FACTOR`)."""
        refused = self.take_accelerations(((t, normal),))
        return refusal_text(*refused[0]) if refused else ""

    def take_accelerations(self, readings: Sequence[tuple[float, float]]) -> list[tuple[float, float, str]]:
        """Accelerometer samples (t, normal) in the order they came, as
        :meth:`take_acceleration` takes each (a window's at once: a thousand a
        second); the refused ones (t, normal, why), in order."""
        refused: list[tuple[float, float, str]] = []
        taken: list[tuple[float, float]] = []
        latest = self._latest_reading()
        for t, normal in readings:
            why = self._implausible(t, normal, latest)
            if why:
                refused.append((t, normal, why))
            else:
                taken.append((t, normal))
        self.samples += len(taken)
        self.samples_refused += len(refused)
        if self.inner_loop:
            self.lockin.add_samples(taken)
        return refused

    def _latest_reading(self) -> float:
        """The latest time a reading may be stamped [s]: :data:`MAX_LEAD_WINDOWS` windows past
        the latest window end taken (inf before one is)."""
        if self._last_boundary is None:
            return math.inf
        return self._last_boundary + MAX_LEAD_WINDOWS * self.loop.cycles / self.loop.frequency

    def _implausible(self, t: float, normal: float, latest: float) -> str:
        """Why a sample (t, normal) is from no plant in force, or '' (``latest``: :meth:`_latest_reading`)."""
        if not (math.isfinite(t) and math.isfinite(normal)):
            return "must be finite"
        if abs(normal) > self.plausible_reading:
            return (f"|linear_acceleration.z| must be <= {self.plausible_reading:.6g} m/s^2, {PLAUSIBLE_FACTOR:g} x "
                    "(g + 2 A G_peak) of the model: no slideway of it vibrates harder")
        if t > latest:
            return (f"stamped ahead of the plant: must be <= {latest!r} s, the latest window end taken "
                    f"({self._last_boundary!r} s) plus {MAX_LEAD_WINDOWS} windows")
        return ""

    def boundary(self, t: float, wanted_amplitude: float) -> DriveCommand:
        """A window ended at ``t`` (a mean_velocity stamp): the drive for the next one.
        A stamp before the previous one (the slider was reset) starts the lock-in
        and the loop's model afresh from the level in force."""
        if self._last_boundary is not None and t < self._last_boundary:
            self._restart()
        self._last_boundary = t
        if not self.inner_loop:
            return self.steady(wanted_amplitude)
        self.lockin.add_boundary(t)
        readings = self.lockin.readings()
        for reading in readings:
            self._note(reading)
        before = self.loop.frequency
        level, frequency = self.loop.boundary(t, wanted_amplitude, readings)
        changed = frequency != before
        if changed:
            self._published.append(frequency)
        return DriveCommand(level, frequency, changed, self.per_drive)

    def _note(self, reading: Vibration) -> None:
        """Count a window read and keep its amplitude per unit of the level that drove it."""
        self.windows_read += 1
        self.last_reading = reading
        level = self.loop.level_of(reading)
        if level is not None and level > 0.0:
            self.per_drive = reading.amplitude / level

    def _restart(self) -> None:
        self.lockin.forget()
        loop = self.loop
        self.loop = DriveLoop(self.model, loop.frequency, loop.drive_level, tracking=loop.tracking,
                              cycles=loop.cycles)

    def follow_frequency(self, frequency: float) -> None:
        """The drive frequency was set from outside (a command, the plant's
        parameter), unless it is an echo of one this runtime published."""
        if frequency in self._published or frequency == self.loop.frequency:
            return
        self.loop.set_frequency(frequency)

    def values(self) -> dict[str, Any]:
        """The inner loop's state for diagnostics."""
        reading = self.last_reading
        return {
            "inner_loop": self.inner_loop, "track_resonance": self.loop.tracking,
            "drive_level": self.loop.drive_level, "drive_frequency": self.loop.frequency,
            "natural_frequency_estimate": self.loop.natural_frequency, "gain_ratio": self.loop.gain_ratio,
            "vibration_amplitude": reading.amplitude if reading else math.nan,
            "vibration_lag_deg": math.degrees(reading.lag) if reading else math.nan,
            "amplitude_per_drive": self.per_drive, "accelerometer_samples": self.samples,
            "accelerometer_samples_refused": self.samples_refused, "windows_read": self.windows_read,
        }


def drive_settings(values: Mapping[str, Any]) -> tuple[bool, bool, int]:
    """(inner_loop, track_resonance, mean_window_periods) from a controller's parameter values."""
    return (bool(values.get("inner_loop", spec.INNER_LOOP.default)),
            bool(values.get("track_resonance", spec.TRACK_RESONANCE.default)),
            int(values.get("mean_window_periods", spec.MEAN_WINDOW_PERIODS.default)))


__all__ = ["DriveCommand", "DriveRuntime", "drive_settings", "outer_model", "refusal_text"]
