"""The one chooser between the closed form and the simulation: what mean speed a plant gives.

Kostek's model below lift-off has the paper's exact U relation
(:func:`~friction_sim.core.meanspeed.urelation.kostek_prediction`); every
other plant has the general mean speed, read off the exact motion
(:func:`~friction_sim.core.meanspeed.general.mean_speed`).  :func:`predict`
decides which (by :func:`~friction_sim.core.physics.plant.closed_form_applies`,
the one rule) for the nodes, the reports and the CLI.
"""

from __future__ import annotations

from friction_sim.core.meanspeed.general import mean_speed
from friction_sim.core.meanspeed.urelation import Prediction, kostek_prediction
from friction_sim.core.model.dimensionless import amplitude_ratio, drive_ratio
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import steady_excitation


def predict(params: SliderParams, inputs: Inputs) -> Prediction:
    """The mean speed for ``params`` and ``inputs`` (inf when the slider
    accelerates without bound): the exact closed form for Kostek's model
    below lift-off (:func:`kostek_prediction`), else the general mean speed
    of :func:`friction_sim.core.meanspeed.general.mean_speed` (a simulation of the
    exact motion, milliseconds), whose groups are the plain ones (effective
    gravity g: its U is V*f/(g*mu))."""
    exact = kostek_prediction(params, inputs)
    if exact is not None:
        return exact
    result = mean_speed(params, inputs)
    phi = drive_ratio(inputs.tangential_force, params.mu, params.weight)
    ratio = amplitude_ratio(steady_excitation(params, inputs)[0], params.weight)  # (the resonant actuator's steady Pa)
    return Prediction(
        phi=drive_ratio(inputs.drive_force, params.mu, params.weight), amplitude_ratio=ratio, u=result.u,
        mean_velocity=result.mean_velocity, effective_phi=phi, effective_amplitude_ratio=ratio,
        effective_gravity=params.gravity,
    )


__all__ = ["Prediction", "predict"]
