"""The single slider's resonant exciter: the slideway's motion across changes.

:class:`Exciter` keeps the slideway of :mod:`friction_sim.core.physics.exciter`
for a :class:`~friction_sim.core.engine.single.Slider` whose actuator is
resonant: its motion since the last change of parameters or inputs (the
steady response plus the transient), when that transient settles below
rounding, and the transient force a segment starts with.  The slider asks it
at every change and every segment start; the physics stays in the physics
modules.  A slider starts on a running feeder: the slideway in steady state.
"""

from __future__ import annotations

from typing import NamedTuple

from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.exciter import Slideway, eigenvalue, force_transient, slideway_state, steady_slideway
from friction_sim.core.physics.plant import Plant, slideway_amplitude
from friction_sim.core.physics.roots import NEVER
from friction_sim.core.physics.stepper import exciter_changed, settled_at, transient_window


class ExciterState(NamedTuple):
    """The exciter at a time, for diagnostics and the accelerometer: ``drive_level``
    u; ``amplitude`` [N], the steady amplitude of the part's normal excitation
    m*u*A*G plus the transient's present size (its envelope); ``lag`` [rad] of the
    steady response behind the drive; ``natural_frequency`` [Hz]; the slideway's
    normal displacement, velocity and acceleration (q, q', q'')."""

    drive_level: float
    amplitude: float
    lag: float
    natural_frequency: float
    q: float
    qd: float
    qdd: float


class Exciter:
    """The slideway of a resonant actuator, followed exactly across changes.
    Immutable (a change makes a new one), so a slider's checkpoint holds it by
    reference."""

    __slots__ = ("_inputs", "_params", "_t0", "_until", "_way")

    def __init__(self, params: SliderParams, inputs: Inputs, way: Slideway | None = None, t0: float = 0.0,
                 until: float = -NEVER) -> None:
        self._params, self._inputs = params, inputs
        self._way = way if way is not None else steady_slideway(*_steady(params, inputs), _eigenvalue(params))
        self._t0 = t0  # the time at which self._way starts
        self._until = until  # the transient has settled by then (-inf: there is none)

    @property
    def lam(self) -> complex:
        """The slideway's eigenvalue -zeta*omega_n + i*omega_d."""
        return self._way.lam

    @property
    def settles_at(self) -> float:
        """When the present transient falls below rounding (-inf: there is none)."""
        return self._until

    def active(self, t: float) -> bool:
        """Whether a segment starting at ``t`` feels a transient."""
        return t < self._until

    def change(self, params: SliderParams, inputs: Inputs, plant: Plant, t: float, theta: float) -> Exciter:
        """The exciter after a change of parameters or inputs at ``t`` (the drive at
        phase ``theta``; ``plant``: the new one): q and q' continuous, the new
        steady response and the transient that carries the difference."""
        amplitude, lag, omega = _steady(params, inputs)
        way, delay = exciter_changed(self._way, t - self._t0, theta, amplitude, lag, omega, _eigenvalue(params),
                                     params.mass, plant)
        return Exciter(params, inputs, way, t, t + delay if delay > 0.0 else -NEVER)

    def settled(self, t: float) -> Exciter:
        """The exciter from a cut of its transient's segment at ``t`` on: the transient
        dropped if it has settled by then (below rounding), else as it is."""
        way, t0, until = settled_at(self._way, self._t0, self._until, t)
        if way is self._way:
            return self
        return Exciter(self._params, self._inputs, way, t0, until)

    def window(self, t0: float, frequency: float) -> tuple[complex, float]:
        """(c, horizon) of a segment starting at ``t0``
        (:func:`~friction_sim.core.physics.stepper.transient_window`)."""
        return transient_window(self._way, self._t0, self._params.mass, self._until, t0, frequency)

    def force(self, t: float) -> complex:
        """c: the part's transient normal force is Re(c*exp(lambda*s)) s after ``t``."""
        return force_transient(self._way, self._params.mass, t - self._t0)

    def state(self, t: float, theta: float) -> ExciterState:
        """The exciter at ``t``, the drive at phase ``theta``."""
        q, qd, qdd = slideway_state(self._way, theta, t - self._t0)
        steady = self._params.mass * self._way.amplitude
        transient = abs(self.force(t)) if self.active(t) else 0.0
        return ExciterState(self._inputs.drive_level, steady + transient, self._way.lag,
                            self._params.natural_frequency, q, qd, qdd)


def _steady(params: SliderParams, inputs: Inputs) -> tuple[float, float, float]:
    """(a_s, lag, omega): the steady response to the drive in force."""
    acceleration, lag = slideway_amplitude(params, inputs)
    return acceleration, lag, TWO_PI * inputs.excitation_frequency


def _eigenvalue(params: SliderParams) -> complex:
    return eigenvalue(params.natural_frequency, params.damping_ratio)


__all__ = ["Exciter", "ExciterState"]
