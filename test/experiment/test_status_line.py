"""The experiment's status line shows each plant by the inputs it acts on: the
force actuator by its Pa, the resonant one by its drive level and the
slideway's amplitude (its Pa is no input of that plant, and a constant there
would say nothing)."""

from __future__ import annotations

import pytest

from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import steady_excitation
from friction_sim.experiment import runner
from friction_sim.experiment.job import ExperimentSpec, Status

from ros_harness import namespace


def _statuses(plant: SliderParams, inputs: Inputs) -> list[Status]:
    seen: list[Status] = []
    spec = ExperimentSpec(duration=0.1, plant=plant, inputs=inputs, lockstep=True)
    runner.run_experiment(spec, namespace=namespace(), progress=seen.append)
    return seen


def test_a_resonant_plant_is_shown_by_drive_level_and_slideway_amplitude(ros: None) -> None:
    plant, inputs = SliderParams(actuator="resonant", natural_frequency=52.0), Inputs(drive_level=0.6)
    last = _statuses(plant, inputs)[-1]
    slideway = steady_excitation(plant, inputs)[0] / plant.mass  # u*A*G(f/f_n) [m/s^2]
    assert last.drive_level == 0.6 and last.amplitude == pytest.approx(slideway, rel=1e-15)
    line = last.line()
    assert "drive 0.600" in line and f"slideway {slideway:6.3f} m/s^2" in line and "Pa " not in line


def test_the_force_actuator_is_shown_by_its_pa(ros: None) -> None:
    last = _statuses(SliderParams(), Inputs(excitation_amplitude=4.25))[-1]
    assert last.drive_level is None and last.amplitude == 4.25
    assert "Pa  4.250 N" in last.line() and "drive " not in last.line() and "slideway" not in last.line()
