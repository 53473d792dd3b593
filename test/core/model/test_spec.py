"""The one vocabulary: every setting checks its own range, and the reference's
tables (doc/reference/nodes.md) and the shipped parameter files say exactly what the spec says."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from friction_sim.core.model import spec
from friction_sim.core.model.commands import COMMANDS, PARAMETERS, Command, apply
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.errors import ParameterError

ROOT = Path(__file__).resolve().parents[3]
NUMERIC = [s for table in (spec.SLIDER_NODE, spec.CONTROLLER_NODE, spec.INPUTS) for s in table.values()
           if s.kind in (int, float) and s.low is not None]


def test_the_reference_parameter_tables_are_the_spec() -> None:
    reference = (ROOT / "doc" / "reference" / "nodes.md").read_text()
    for table in (spec.SLIDER_NODE, spec.CONTROLLER_NODE):
        assert spec.markdown_table(table) in reference


@pytest.mark.parametrize(("path", "table"), [("config/slider.yaml", spec.SLIDER_NODE),
                                             ("config/controller.yaml", spec.CONTROLLER_NODE)])
def test_shipped_parameter_files_hold_the_spec_defaults(path: str, table: dict[str, spec.Setting]) -> None:
    values = yaml.safe_load((ROOT / path).read_text())["/**"]["ros__parameters"]
    assert values, path
    for name, value in values.items():
        assert name in table, f"{path}: {name} is not a parameter of the node"
        assert value == table[name].default, f"{path}: {name} = {value!r}, spec default {table[name].default!r}"
        assert type(value) is table[name].kind, f"{path}: {name} has the wrong type"


def test_defaults_are_inside_their_ranges_and_are_the_papers_case() -> None:
    for setting in NUMERIC:
        assert setting.check(setting.default) == setting.default
    assert (SliderParams(), Inputs()) == (SliderParams(1.0, 0.1, 10.0), Inputs(0.7, 5.0, 50.0, 0.0, 0.0))


@pytest.mark.parametrize("setting", NUMERIC, ids=lambda s: s.name)
def test_every_range_refuses_what_lies_outside_with_field_value_and_limit(setting: spec.Setting) -> None:
    outside = [math.nan, math.inf, -math.inf, True, "1"]
    if setting.low is not None:
        outside.append(setting.low - max(1.0, abs(setting.low)))
    if setting.high is not None:
        outside.append(setting.high * 2 + 1)
    for value in outside:
        with pytest.raises(ParameterError) as excinfo:
            setting.check(value)
        message = str(excinfo.value)
        assert excinfo.value.field == setting.name and setting.name in message and repr(value) in message


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_a_command_is_applied_whole_or_refused_whole(value: float) -> None:
    params, inputs = SliderParams(), Inputs()
    command = Command(0.0, "external_wrench", {"external_force_x": 0.0, "external_force_z": value})
    try:
        new_params, new_inputs = apply(command, params, inputs)
    except ParameterError as error:
        assert error.field == "external_force_z"
        return
    assert new_params == params and new_inputs.external_force_z == value
    assert new_inputs.excitation_amplitude == inputs.excitation_amplitude  # the rest as it was
    assert math.isfinite(value) and abs(value) <= spec.MAX_FORCE  # no contact rule: a lifting force flies


def test_the_command_table_names_fields_the_plant_has() -> None:
    for entry in COMMANDS.values():
        assert len(entry.fields) == len(entry.message_fields)
        for field in entry.fields:
            assert field in spec.INPUTS or field in spec.CONTROLLER_NODE
    with pytest.raises(ParameterError, match="must be one of"):
        Command(0.0, "no_such_topic", {})
    with pytest.raises(ParameterError, match="unknown field"):
        Command(0.0, "drive_force", {"mass": 1.0})
    assert Command(0.0, PARAMETERS, {"mass": 2.0, "drive_force": 0.1}).plant == {"mass": 2.0}


@pytest.mark.parametrize("value", [math.inf, -math.inf, math.nan])
def test_an_open_bound_lets_no_non_finite_value_through(value: float) -> None:
    """A setting with no bound on one side still refuses +-inf and NaN (the
    in-range fast path compares against the bounds)."""
    open_setting = spec.Setting("open", 0.0, "m", "an unbounded float")
    with pytest.raises(ParameterError, match="open"):
        open_setting.check(value)
