"""Recording a run without a clock: what the slider node would record, as fast as it computes.

:func:`record_offline` drives :class:`~friction_sim.core.runtime.realtime.RealtimeSlider`
with a counter instead of a wall clock and hands what it produces to a
:class:`~friction_sim.io.recorder.Recorder` through the same sink calls as
the node (:func:`~friction_sim.io.sinks.deliver_tick`, a
:class:`~friction_sim.io.sinks.CommandRecord` per command, a
:class:`~friction_sim.io.sinks.ParametersRecord` at start), so an offline
recording and a live one are the same file.
Commands reach it as they reach the node: topic commands through
:meth:`~friction_sim.core.runtime.realtime.RealtimeSlider.commands` (a tick's
take), a ``parameters`` command through
:meth:`~friction_sim.core.runtime.realtime.RealtimeSlider.configure` (one
``ros2 param set``, atomic), a ``reset`` through
:meth:`~friction_sim.core.runtime.realtime.RealtimeSlider.reset` (the
``~/reset`` service).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from itertools import groupby
from typing import Any

from friction_sim.core.model.commands import CONTROLS, PARAMETERS, RESET, Command, Outcome
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.errors import ParameterError
from friction_sim.io.messages import seconds_to_ns
from friction_sim.io.recorder import Recorder, RecordingStats, plant_parameters, recording_metadata
from friction_sim.io.sinks import CommandRecord, ParametersRecord, deliver_tick


def record_offline(
    path: str | os.PathLike[str], params: SliderParams | None = None, inputs: Inputs | None = None,
    schedule: Sequence[Command] = (), duration: float = 1.0, log_rate: float = 1000.0, *,
    frame_id: str = "slideway", mean_window_periods: int = 1, tick_rate: float | None = None,
    metadata: Mapping[str, Any] | None = None, recorder_options: Mapping[str, Any] | None = None,
) -> RecordingStats:
    """Run the exact core for ``duration`` s of simulation time without a
    clock and record what the slider node records.

    Each :class:`~friction_sim.core.model.commands.Command` of ``schedule`` reaches
    the slider at its time (in whole nanoseconds, as the node stamps it), as
    it reaches the node (see the module); commands at the same time arrive at
    one instant, in schedule order, each a change of its own (as in the node:
    a paused instant's burst); each is recorded accepted or refused.  A reset
    is the ``~/reset`` service's; pause, resume and step are refused (no clock
    here to stop: commands at one time already arrive at one instant).
    States are logged on the grid ``k / log_rate``; the mean velocity comes
    from the core's period marks through :class:`RealtimeSlider`, ticked at
    ``tick_rate`` (default ``log_rate``), exactly as in the node.  ``recorder_options`` go to the
    :class:`~friction_sim.io.recorder.Recorder` (e.g. ``chunk_size``); it
    waits for the writer, so nothing is dropped.
    """
    params = params if params is not None else SliderParams()
    inputs = inputs if inputs is not None else Inputs()
    duration = _time("duration", duration)
    rate = float(tick_rate if tick_rate is not None else log_rate)
    rt = RealtimeSlider(params, inputs, wall_ns=0, real_time_factor=1.0, publish_rate=rate,
                        mean_window_periods=mean_window_periods, log_rate=log_rate)
    batches = _batches(schedule)
    extra = dict(metadata or {})
    extra.setdefault("recorded_by", "record_offline")
    extra.setdefault("mean_window_periods", mean_window_periods)
    options = {"block_when_full": True, "setting": "path", **(recorder_options or {})}
    with Recorder(path, recording_metadata(params, inputs, log_rate=log_rate, frame_id=frame_id, **extra),
                  **options) as recorder:
        recorder.write(ParametersRecord({**plant_parameters(params, inputs), "log_rate": float(log_rate),
                                         "frame_id": frame_id, "mean_window_periods": mean_window_periods}, 0.0, False))
        _run(rt, recorder, batches, seconds_to_ns(duration), rate, frame_id)
    return recorder.stats


def _run(rt: RealtimeSlider, recorder: Recorder, batches: list[tuple[int, list[Command]]], end_ns: int,
         rate: float, frame_id: str) -> None:
    """What the node does, with the clock replaced by a counter: before each
    tick, the commands due by then, each batch at its own time."""
    pending = list(reversed(batches))
    k = 0
    while True:
        tick_ns = min(round(k * 1e9 / rate), end_ns)
        while pending and pending[-1][0] <= tick_ns:
            t_ns, batch = pending.pop()
            for outcome in _handle(rt, batch, t_ns):
                recorder.write(CommandRecord(outcome, frame_id))
        deliver_tick([recorder], rt.tick(tick_ns), frame_id)
        if tick_ns >= end_ns:
            return
        k += 1


def _handle(rt: RealtimeSlider, batch: list[Command], t_ns: int) -> list[Outcome]:
    """The commands of one instant handled as the node handles them, in order,
    each a change of its own: a topic command as a tick takes it, a
    ``parameters`` command as one parameter set, a reset as a call of ``~/reset``."""
    return [rt.reset(t_ns) if command.name == RESET else
            rt.configure(command.values, t_ns) if command.name == PARAMETERS else
            rt.command(command, t_ns) for command in batch]


def _batches(schedule: Sequence[Command]) -> list[tuple[int, list[Command]]]:
    """The schedule as (time [ns], commands) in time order, a batch per time,
    schedule order within a batch; refuses times < 0 and commands the slider
    does not take."""
    for command in schedule:
        _time("t", command.t)
        if not command.for_slider:
            raise ParameterError("topic", command.name, "is not a slider input (record_offline runs no controller)")
        if command.name in CONTROLS and command.name != RESET:
            raise ParameterError("command", command.name, "is not offline: record_offline has no clock to pause "
                                                          "(commands at one time already arrive at one instant)")
    ordered = sorted(schedule, key=lambda command: seconds_to_ns(command.t))
    return [(t_ns, list(batch)) for t_ns, batch in groupby(ordered, key=lambda command: seconds_to_ns(command.t))]


def _time(name: str, value: float) -> float:
    """``value`` as a finite time >= 0 s, or a ParameterError naming ``name``."""
    value = float(value)
    if not (math.isfinite(value) and value >= 0.0):
        raise ParameterError(name, value, "must be a finite time >= 0 s")
    return value


__all__ = ["record_offline"]
