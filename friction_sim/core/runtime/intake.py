"""The checks a command of the real-time slider passes on its way to the core.

:class:`~friction_sim.core.runtime.realtime.RealtimeSlider` handles commands
one at a time, each as a change of its own; :func:`take_checked` is the gate
each passes: its values against their own ranges first (cheap: a flood of bad
commands is refused there), then the core's one gate with the real-time load
rule, guarded (:func:`~friction_sim.core.runtime.guard.take_guarded`).
"""

from __future__ import annotations

from friction_sim.core.engine.single import Slider
from friction_sim.core.model import spec
from friction_sim.core.model.commands import Command
from friction_sim.core.model.params import check_load
from friction_sim.core.runtime.guard import take_guarded

_PHYSICS = {**spec.PLANT, **spec.INPUTS}


def take_checked(slider: Slider, command: Command, real_time_factor: float) -> str:
    """Take ``command`` into ``slider`` through the one gate plus the real-time load
    rule at ``real_time_factor``; '' if it was taken, else why not (nothing changed).

    Each value is first checked against its own range alone: a NaN, inf or
    out-of-range value (what a flood of bad commands is made of) is refused
    there, in a few microseconds, without building new plant and inputs
    (a :class:`~friction_sim.errors.ParameterError` raised).
    """
    for field, value in command.values.items():
        _PHYSICS[field].check(value)
    return take_guarded(slider, command,
                        lambda params, inputs: check_load(inputs.excitation_frequency, real_time_factor))


__all__ = ["take_checked"]
