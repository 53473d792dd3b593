"""What consumes a run: the sink interface.

The slider node (and the offline recorder) hand everything that happens to a
list of sinks: the exact state samples, the events, the period means, every
command with its outcome, and the parameters.  The MCAP recorder is one sink;
a live view is another.  A sink must be cheap to call (the tick thread calls
it): queue the work, do it elsewhere.  A sink that must not lose anything
may make the caller wait when it falls behind (the recorder does, for as
long as its writer makes progress, and says how long in
:attr:`~friction_sim.io.recorder.Recorder.wait_seconds`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Protocol

from friction_sim.core.model.commands import Outcome
from friction_sim.core.model.events import Event, SliderState
from friction_sim.core.model.records import Acceleration, PeriodSummary, Tick


class Sink(Protocol):
    """A consumer of a run.  Times are simulation time [s].  A sink that sets
    ``published_states = True`` (the live view) is handed the states the node
    published, one per tick, instead of the recording's log grid."""

    def on_states(self, states: Sequence[SliderState], frame_id: str) -> None:
        """Exact states on the log grid, in time order."""

    def on_event(self, event: Event) -> None:
        """A transition of the motion (slip start, stick, reversal)."""

    def on_period(self, period: PeriodSummary, frame_id: str) -> None:
        """The mean velocity of the window ending with a completed period."""

    def on_accelerations(self, samples: Sequence[Acceleration], frame_id: str, noise: float) -> None:
        """The accelerometer's samples (noise included), in time order; ``noise`` is the
        standard deviation [m/s^2] the messages state as their covariance."""

    def on_command(self, outcome: Outcome, frame_id: str) -> None:
        """A command as handled: accepted, or refused with the reason."""

    def on_parameters(self, values: Mapping[str, Any], t: float, *, changed: bool) -> None:
        """Parameter values: the set at start (``changed`` False) or a later change."""

    def close(self) -> None:
        """The run is over: finish whatever was written (idempotent)."""


def deliver_tick(sinks: Sequence[Sink], tick: Tick, frame_id: str, noise: float = 0.0) -> None:
    """Hand what a real-time tick passed to every sink: the states on the log
    grid (a sink whose ``published_states`` is true, a live view, gets the
    state the tick published instead), the events, the period means and the
    accelerometer's samples (``noise``: its standard deviation)."""
    for sink in sinks:
        if tick.accelerations:
            sink.on_accelerations(tick.accelerations, frame_id, noise)
        states = (tick.state,) if getattr(sink, "published_states", False) else tick.samples
        if states:
            sink.on_states(states, frame_id)
        for event in tick.events:
            sink.on_event(event)
        for period in tick.periods:
            sink.on_period(period, frame_id)


__all__ = ["Sink", "deliver_tick"]
