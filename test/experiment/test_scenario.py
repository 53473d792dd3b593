"""Scenario files: the shipped ones load, and every kind of bad file is refused
before anything starts, naming the line and the reason."""

from __future__ import annotations

from pathlib import Path

import pytest

from friction_sim.core.model import spec as settings
from friction_sim.core.model.commands import Command
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.controller import MODEL, config_of
from friction_sim.errors import ScenarioError
from friction_sim.experiment.acceptance import acceptance_scenarios, config_dir
from friction_sim.experiment.scenario import controller_law, load_scenario, parse_scenario

GOOD = """\
name: good
duration: 4.0
real_time_factor: 2.0
plant:
  mass: 2.0
  drive_force: 1.4
  excitation_amplitude: 10.0
controller:
  mu: 0.12
  integral_gain: 0.3
schedule:
  - {t: 0.5, excitation_amplitude: 12.0}
  - {t: 1.0, target_speed: 0.0002}
  - {t: 2.0, external_wrench: {x: 0.1, z: 1.5}}
  - {t: 3.0, excitation_frequency: 80.0}
expect:
  - {t: 1.0, within: 0.02, periods: 5}
"""


def test_a_good_scenario_parses_completely() -> None:
    scenario = parse_scenario(GOOD)
    assert scenario.name == "good" and scenario.duration == 4.0 and scenario.real_time_factor == 2.0
    assert scenario.params == SliderParams(mass=2.0)
    assert scenario.inputs == Inputs(drive_force=1.4, excitation_amplitude=10.0)
    assert scenario.controller == {"mu": 0.12, "integral_gain": 0.3}
    assert list(scenario.schedule) == [
        Command(0.5, "excitation_amplitude", {"excitation_amplitude": 12.0}),
        Command(1.0, "target_speed", {"target_speed": 0.0002}),
        Command(2.0, "external_wrench", {"external_force_x": 0.1, "external_force_z": 1.5}),
        Command(3.0, "excitation_frequency", {"excitation_frequency": 80.0})]
    assert scenario.expect[0].periods == 5
    assert scenario.output == Path("out/good")
    spec = scenario.spec()
    assert spec.controller and spec.controller_parameters["active"] is False, "stands by until the target"
    assert scenario.source == GOOD


def test_the_shipped_scenarios_load_and_judge_something() -> None:
    scenarios = acceptance_scenarios()
    assert [s.name for s in scenarios] == [
        "acceptance_1_matched", "acceptance_2_mu_plus_20", "acceptance_3_drive_step",
        "acceptance_4_unreachable", "acceptance_5_frequency_step", "acceptance_6_tilted_hopping",
        "acceptance_7_resonant_steps", "acceptance_8_resonant_load", "acceptance_9_resonant_noise"]
    assert all(s.expect and s.closed_loop for s in scenarios)
    demo = load_scenario(config_dir() / "demo.yaml")
    assert 14.0 <= demo.duration <= 16.0 and demo.closed_loop
    names = {c.name for c in demo.schedule}
    assert {"excitation_amplitude", "target_speed", "drive_force", "excitation_frequency"} <= names
    first_target = min(c.t for c in demo.schedule if c.name == "target_speed")
    assert any(c.name == "excitation_amplitude" and c.t < first_target for c in demo.schedule), "open loop first"


def test_plant_params_file_is_read(tmp_path: Path) -> None:
    (tmp_path / "plant.yaml").write_text("/**:\n  ros__parameters:\n    mass: 3.0\n    drive_force: 2.0\n")
    (tmp_path / "s.yaml").write_text("duration: 1.0\nplant_params: plant.yaml\n")
    scenario = load_scenario(tmp_path / "s.yaml")
    assert scenario.params.mass == 3.0 and scenario.inputs.drive_force == 2.0


BAD = [
    ("duration: 1.0\nspeed: 3\n", 2, ("unknown key 'speed'",)),
    ("plant: {mass: 1.0}\n", 1, ("missing key 'duration'",)),
    ("duration: -1\n", 1, ("duration", "-1", "> 0")),
    ("duration: .nan\n", 1, ("duration", "nan", "finite")),
    ("duration: 2e1\n", 1, ("duration", "'2e1'", "finite", "YAML read it as text: write 2.0e1")),
    ("duration: 1.0\nplant: {mu: 1e-1}\n", 2, ("mu", "'1e-1'", "YAML read it as text: write 1.0e-1")),
    ("duration: 1.0\nplant:\n  mass: 1.0\n  excitation_amplitude: -12.0\n", 4,
     ("excitation_amplitude", "-12.0", "[0, 1e+06] N")),
    ("duration: 1.0\nplant:\n  landing_friction: sticky\n", 3, ("landing_friction", "'sticky'", "impulsive, none")),
    ("duration: 1.0\nplant:\n  restitution: 1.0\n", 3, ("restitution", "1.0", "[0, 0.99]")),
    ("duration: 1.0\nplant:\n  excitation_angle: 0\n", 3, ("excitation_angle", "0.0", "[0.1, 90] deg")),
    ("duration: 1.0\nplant:\n  mass: 0\n", 3, ("mass", "0.0", "[1e-06, 1e+06] kg")),
    ("duration: 1.0\nplant:\n  masss: 1.0\n", 3, ("unknown key 'masss'", "mass")),
    ("duration: 1.0\nschedule:\n  - {t: 0.5, target_speed: 0.001}\n", 3, ("target_speed needs a controller",)),
    ("duration: 1.0\nschedule:\n  - {t: 2.0, drive_force: 0.5}\n", 3, ("t = 2.0", "duration")),
    ("duration: 1.0\nschedule:\n  - {t: 0.5, drive_force: 0.5}\n  - {t: 0.2, drive_force: 0.6}\n", 4,
     ("comes before",)),
    ("duration: 1.0\nschedule:\n  - {t: 0.5, drive_force: 0.5, excitation_amplitude: 1.0}\n", 3,
     ("exactly one",)),
    ("duration: 1.0\nschedule:\n  - {t: 0.5, excitation_amplitude: 2000000.0}\n", 3,
     ("excitation_amplitude", "2000000.0", "[0, 1e+06] N")),
    ("duration: 1.0\nschedule:\n  - {t: 0.5, external_wrench: {x: 0, z: -2000000.0}}\n", 3,
     ("external_force_z", "-2000000.0")),
    ("duration: 1.0\nschedule:\n  - {t: 0.5, external_wrench: {y: 1}}\n", 3, ("unknown key 'y'",)),
    ("duration: 1.0\nschedule:\n  - {t: 0.5, excitation_frequency: 0}\n", 3,
     ("excitation_frequency", "0.0", "[0.001, 20000] Hz")),
    ("duration: 1.0\nschedule:\n  - {t: 0.5, drive_force: fast}\n", 3, ("drive_force", "'fast'")),
    ("duration: 1.0\nschedule:\n  - {drive_force: 0.5}\n", 3, ("needs 't'",)),
    ("duration: 1.0\ncontroller:\n  gain: 3\n", 3, ("unknown key 'gain'",)),
    ("duration: 1.0\nexpect:\n  - {t: 0.3, within: 0.01, periods: 3}\n", 3, ("no scheduled command",)),
    ("duration: 1.0\ncontroller:\n  integral_gain: 5\n", 3, ("integral_gain", "5.0", "[0, 2]")),
    ("duration: 1.0\ncontroller:\n  target_speed: -0.001\n", 3, ("target_speed", "-0.001", "sign")),
    ("duration: 1.0\ncontroller: {}\nschedule:\n  - {t: 0.2, drive_force: -0.7}\n"
     "  - {t: 0.5, target_speed: 0.0002}\n", 5, ("target_speed", "0.0002", "-0.7")),
    ("duration: 1.0\noperator:\n  - {t: 0.5, send: {drive_force: 0.5}}\n", 3,
     ("drive_force = 0.5", "would take it")),
    ("duration: 1.0\nschedule:\n  - {t: 0.2, drive_force: 2.0}\noperator:\n"
     "  - {t: 0.5, send: {drive_force: 0.5}}\n", 5, ("would take it",)),
    ("duration: 1.0\noperator:\n  - {t: 0.5, calls: [pause, step]}\n", 3, ("end with resume",)),
    ("duration: 1.0\noperator:\n  - {t: 0.5, calls: [step]}\n", 3, ("step while running",)),
    ("duration: 1.0\noperator:\n  - {t: 0.5, calls: [pause, pause, resume]}\n", 3, ("pause while paused",)),
    ("duration: 1.0\noperator:\n  - {t: 0.5, calls: [stop]}\n", 3, ("pause, resume, step, reset",)),
    ("duration: 1.0\noperator:\n  - {t: 0.5}\n", 3, ("one of 'send' or 'calls'",)),
    ("duration: 1.0\noperator:\n  - {t: 1.5, calls: [reset]}\n", 3, ("t = 1.5", "duration")),
    ("duration: 1.0\noperator:\n  - {t: 0.5, send: {external_wrench: {x: 1.0}}}\n", 3, ("one-number",)),
    ("duration: 1.0\nschedule:\n  - {t: 0.5, parameters: {natural_frequency: 0.0}}\n", 3,
     ("natural_frequency", "0.0", "[0.001, 20000] Hz")),
    ("duration: 1.0\nschedule:\n  - {t: 0.5, parameters: {publish_rate: 10.0}}\n", 3,
     ("unknown key 'publish_rate'",)),
    ("duration: 1.0\nschedule:\n  - {t: 0.5, parameters: {}}\n", 3, ("at least one",)),
    ("duration: 1.0\naccelerometer_noise: -1\n", 2, ("accelerometer_noise", "-1", "[0, 1e+06]")),
    ("duration: 1.0\ncontroller: {}\nschedule:\n  - {t: 0.5, drive_force: 0.5}\nexpect:\n"
     "  - {t: 0.5, within: 0.02, periods: 9, quantity: amplitude_per_drive}\n", 6,
     ("amplitude_per_drive", "resonant")),
    ("duration: 1.0\nschedule:\n  - {t: 0.5, drive_force: 0.5}\nexpect:\n"
     "  - {t: 0.5, within: 0.02, periods: 9, quantity: speed}\n", 5, ("quantity", "'speed'", "mean_speed")),
    ("duration: [1\n", 2, ("not valid YAML",)),
    ("- just a list\n", None, ("mapping",)),
]


HOPS = """\
duration: 1.0
plant:
  excitation_amplitude: 25.0
  excitation_angle: 30.0
  track_inclination: 5.0
  static_ratio: 1.2
  restitution: 0.2
  landing_friction: none
schedule:
  - {t: 0.5, excitation_amplitude: 40.0}
  - {t: 0.6, external_wrench: {x: 0.0, z: -6.0}}
  - {t: 0.7, external_wrench: {x: 0.0, z: 12.0}}
"""


def test_a_hopping_plant_and_amplitudes_above_the_weight_are_valid() -> None:
    """No lift-off refusal any more: Pa above m g cos(alpha) hops, an external force may press
    (z < 0) or lift the slider off entirely (z > 0 beyond the weight)."""
    scenario = parse_scenario(HOPS)
    assert scenario.params == SliderParams(excitation_angle=30.0, track_inclination=5.0, static_ratio=1.2,
                                           restitution=0.2, landing_friction="none")
    assert scenario.inputs == Inputs(excitation_amplitude=25.0)
    assert [c.values for c in scenario.schedule] == [
        {"excitation_amplitude": 40.0}, {"external_force_x": 0.0, "external_force_z": -6.0},
        {"external_force_x": 0.0, "external_force_z": 12.0}]


def test_operator_actions_are_read_in_order_and_change_no_input() -> None:
    """Issue 23, defect 2 (the demo fills the refusal and control panels): a
    command the slider refuses (a negative amplitude) and control calls that
    leave the slider running, beside the schedule, not in it."""
    scenario = parse_scenario("duration: 2.0\nschedule:\n  - {t: 0.2, drive_force: 0.5}\noperator:\n"
                              "  - {t: 0.5, send: {excitation_amplitude: -1.0}}\n"
                              "  - {t: 0.8, calls: [pause, step, reset, resume, reset]}\n")
    first, second = scenario.operator
    assert first.t == 0.5 and first.send == Command(0.5, "excitation_amplitude", {"excitation_amplitude": -1.0})
    assert second.t == 0.8 and second.calls == ("pause", "step", "reset", "resume", "reset") and second.send is None
    assert scenario.spec().operator == scenario.operator and len(scenario.schedule) == 1


@pytest.mark.parametrize(("text", "line", "words"), BAD)
def test_bad_scenarios_are_refused_with_line_and_reason(text: str, line: int | None,
                                                        words: tuple[str, ...]) -> None:
    with pytest.raises(ScenarioError) as caught:
        parse_scenario(text, "bad.yaml")
    message = str(caught.value)
    assert message.startswith("bad.yaml: ")
    if line is not None:
        assert f"line {line}:" in message, message
    for word in words:
        assert word in message, message
    assert "\n" not in message


def test_unreadable_file_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario(tmp_path / "missing.yaml")


def test_the_documented_scenario_example_is_a_valid_scenario() -> None:
    """The experiments tutorial's annotated scenario (every key it documents) loads as written."""
    page = (Path(__file__).resolve().parents[2] / "doc" / "tutorials" / "experiments.md").read_text()
    start = page.index("```yaml\nname: demo") + len("```yaml\n")
    scenario = parse_scenario(page[start:page.index("```", start)], "experiments.md")
    assert scenario.accelerometer_noise > 0.0 and scenario.expect and scenario.operator
    assert "parameters" in {c.name for c in scenario.schedule}


RESONANT = """\
duration: 1.0
plant: {actuator: resonant, natural_frequency: 52.0, drive_level: 0.3}
controller: {target_speed: 0.0002, integral_gain: 0.3, inner_loop: %s}
schedule:
  - {t: 0.5, target_speed: 0.0003}
"""


@pytest.mark.parametrize("inner_loop", [True, False])
def test_a_scenarios_controller_is_the_nodes_build(inner_loop: bool) -> None:
    """The scenario checks the controller the node builds (config_of): its mean window
    and whether it learns the secant come along (behind an inner loop it does not)."""
    scenario = parse_scenario(RESONANT % str(inner_loop).lower())
    assert scenario.controller is not None
    law = controller_law(scenario.controller, scenario.params, scenario.inputs)
    node = {**settings.defaults(settings.CONTROLLER_NODE),  # the node's parameters once it took the plant's
            **{name: getattr(scenario.params, name) for name in MODEL},
            "mean_window_periods": settings.SLIDER_NODE["mean_window_periods"].default,
            "drive_force": scenario.inputs.drive_force, "excitation_frequency": scenario.inputs.excitation_frequency,
            **scenario.controller}
    assert law.config == config_of(node)
    assert law.config.secant is not inner_loop and law.config.integral_gain == 0.3
    assert law.config.mean_window_periods == node["mean_window_periods"]
    assert law.config.model.actuator == "force", "the outer law sets Pa directly"
    assert law.output.target_speed == 0.0002


def test_a_scenarios_controller_without_plant_node_keeps_its_own_model() -> None:
    scenario = parse_scenario("duration: 1.0\nplant: {mu: 0.1}\ncontroller: {mu: 0.12, plant_node: ''}\n")
    assert scenario.controller is not None
    assert controller_law(scenario.controller, scenario.params, scenario.inputs).config.model.mu == 0.12
    followed = parse_scenario("duration: 1.0\nplant: {mu: 0.1}\ncontroller: {mu: 0.12}\n")
    assert followed.controller is not None
    assert controller_law(followed.controller, followed.params, followed.inputs).config.model.mu == 0.1, \
        "the node takes its plant node's model at start-up"
