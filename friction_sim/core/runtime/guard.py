"""The guard under which the real-time slider lets a command change the core.

A change of plant or inputs (or a restart) is taken under a checkpoint: if the
core raises while taking it, or the state it leaves is not finite, the core is
put back exactly as it was and the change is refused with the reason.  Kept
apart from :class:`~friction_sim.core.runtime.realtime.RealtimeSlider`, which
decides when commands are handled and counts them; this module decides only
whether the core can take one.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.commands import RESET, Command, take
from friction_sim.core.model.events import SliderState
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.errors import ParameterError, one_line

#: The numbers of a state that must be finite (its phase and mode follow from them).
_NUMBER_NAMES = ("t", "x", "v", "acceleration", "friction_force", "normal_force", "z", "vz")
_NUMBERS = operator.attrgetter(*_NUMBER_NAMES)


def non_finite(state: SliderState) -> str:
    """'' if every number of ``state`` is finite, else the first that is not (``x = inf``)."""
    values = _NUMBERS(state)
    if math.isfinite(sum(values)):
        return ""  # (a sum is finite only if every term is: each is looked at only when one is not)
    for name, value in zip(_NUMBER_NAMES, values, strict=True):
        if not math.isfinite(value):
            return f"{name} = {value!r}"
    return ""


def take_guarded(slider: Slider, command: Command,
                 check: Callable[[SliderParams, Inputs], object] | None = None) -> str:
    """Make ``command`` one change of ``slider`` (:func:`~friction_sim.core.model.commands.take`), guarded.

    Returns '' when the core took it (or it changed nothing), else why
    not: the core raised, or the state it leaves is not finite; then the
    core is put back exactly as it was (a checkpoint taken first).  A
    ParameterError of the gate or of ``check`` is raised, nothing changed.
    """
    checkpoint = slider.checkpoint()
    try:
        if not take(slider, command, check):
            return ""
        problem = non_finite(slider.state())
        if math.isnan(slider.next_event_time):
            problem = problem or "the next event time is nan"
    except ParameterError:
        slider.restore(checkpoint)
        raise
    except Exception as error:  # noqa: BLE001 - any failure of the core refuses the change
        problem = one_line(error, with_type=True)
    if problem:
        slider.restore(checkpoint)
        if command.name == RESET:
            return f"the simulation cannot restart ({problem})"
        return f"the simulation cannot take this state ({problem}); last valid state kept"
    return ""


__all__ = ["non_finite", "take_guarded"]
