"""Every parameter rejection of friction_sim's model edge.

Each refusal must be a :class:`ParameterError` (hence also a ``ValueError``
and a :class:`FrictionSimError`), name the offending field in ``.field`` and
quote both the field and the rejected value in its one-line message.  A
refused change to a running :class:`Slider` must leave it exactly as it was.
"""

import math

import numpy as np
import pytest

from friction_sim.core.params import Inputs, SliderParams, check_contact
from friction_sim.core.slider import Slider
from friction_sim.errors import FrictionSimError, ParameterError

NAN = float("nan")
INF = float("inf")


def assert_refused(excinfo, field, value_text):
    """The raised error is a complete ParameterError about ``field``."""
    err = excinfo.value
    assert isinstance(err, ParameterError)
    assert isinstance(err, ValueError)
    assert isinstance(err, FrictionSimError)
    assert err.field == field
    message = str(err)
    assert field in message, message
    assert value_text in message, f"{value_text!r} not in {message!r}"
    assert err.limit and err.limit in message
    assert "\n" not in message


# (bad value, how the message must quote it)
NOT_FINITE = [
    (NAN, "nan"),
    (INF, "inf"),
    (-INF, "-inf"),
]
NOT_A_NUMBER = [
    ("abc", "'abc'"),
    ("1.0", "'1.0'"),
    (True, "True"),
    (False, "False"),
    (None, "None"),
    ([1.0], "[1.0]"),
    (1 + 2j, "(1+2j)"),
]
NOT_POSITIVE = [
    (0, "0.0"),
    (0.0, "0.0"),
    (-0.0, "-0.0"),
    (-12, "-12.0"),
    (-12.0, "-12.0"),
    (-1e-300, "-1e-300"),
]


# --------------------------------------------------------------------------
# SliderParams
# --------------------------------------------------------------------------


@pytest.mark.parametrize("field", ["mass", "mu", "gravity"])
@pytest.mark.parametrize("bad, text", NOT_POSITIVE + NOT_FINITE + NOT_A_NUMBER)
def test_slider_params_refuses(field, bad, text):
    with pytest.raises(ParameterError) as excinfo:
        SliderParams(**{field: bad})
    assert_refused(excinfo, field, text)
    assert excinfo.value.value == bad or (isinstance(bad, float) and math.isnan(bad))


@pytest.mark.parametrize("field", ["mass", "mu", "gravity"])
@pytest.mark.parametrize("bad, text", [(-2.5, "-2.5"), (NAN, "nan"), (True, "True")])
def test_slider_params_replace_validates_like_new(field, bad, text):
    with pytest.raises(ParameterError) as excinfo:
        SliderParams().replace(**{field: bad})
    assert_refused(excinfo, field, text)


def test_slider_params_accepts_and_converts_positive_numbers():
    params = SliderParams(mass=2, mu=0.25, gravity=9.81)
    assert (params.mass, params.mu, params.gravity) == (2.0, 0.25, 9.81)
    assert all(type(v) is float for v in (params.mass, params.mu, params.gravity))
    assert params.weight == 2.0 * 9.81
    edges = SliderParams(mass=1e-6, mu=1e-6, gravity=1e3)
    assert (edges.mass, edges.mu, edges.gravity) == (1e-6, 1e-6, 1e3)


@pytest.mark.parametrize("field, value", [("mass", 5e-324), ("mu", 1e-300), ("gravity", 1e300), ("mass", 1e308)])
def test_slider_params_refuse_finite_but_absurd_values(field, value):
    # Finite is not enough: the documented ranges keep every state finite.
    with pytest.raises(ParameterError) as excinfo:
        SliderParams(**{field: value})
    assert_refused(excinfo, field, repr(value))


@pytest.mark.parametrize("value", [np.float64(2.0), np.float32(2.0), np.int64(2), np.int32(2)])
def test_numpy_scalars_are_real_numbers(value):
    # require_finite promises to accept any finite real number; numbers taken
    # from numpy arrays (a parameter grid, say) are such numbers.
    params = SliderParams(mass=value)
    assert params.mass == 2.0 and type(params.mass) is float
    inputs = Inputs(drive_force=value / 4, excitation_frequency=value * 25)
    assert inputs.drive_force == 0.5 and type(inputs.drive_force) is float


def test_slider_params_defaults_are_the_papers_fig2():
    params = SliderParams()
    assert (params.mass, params.mu, params.gravity) == (1.0, 0.1, 10.0)


# --------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------


@pytest.mark.parametrize("field", ["drive_force", "external_force_x", "external_force_z"])
@pytest.mark.parametrize("bad, text", NOT_FINITE + NOT_A_NUMBER)
def test_inputs_refuse_non_finite_forces(field, bad, text):
    with pytest.raises(ParameterError) as excinfo:
        Inputs(**{field: bad})
    assert_refused(excinfo, field, text)


@pytest.mark.parametrize(
    "bad, text",
    [(-0.5, "-0.5"), (-1e-300, "-1e-300"), (-5, "-5.0")] + NOT_FINITE + NOT_A_NUMBER,
)
def test_inputs_refuse_bad_excitation_amplitude(bad, text):
    with pytest.raises(ParameterError) as excinfo:
        Inputs(excitation_amplitude=bad)
    assert_refused(excinfo, "excitation_amplitude", text)


@pytest.mark.parametrize("bad, text", NOT_POSITIVE + NOT_FINITE + NOT_A_NUMBER)
def test_inputs_refuse_bad_excitation_frequency(bad, text):
    with pytest.raises(ParameterError) as excinfo:
        Inputs(excitation_frequency=bad)
    assert_refused(excinfo, "excitation_frequency", text)


@pytest.mark.parametrize(
    "field, bad, text",
    [
        ("drive_force", NAN, "nan"),
        ("excitation_amplitude", -1.0, "-1.0"),
        ("excitation_frequency", 0.0, "0.0"),
        ("external_force_z", -INF, "-inf"),
    ],
)
def test_inputs_replace_validates_like_new(field, bad, text):
    with pytest.raises(ParameterError) as excinfo:
        Inputs().replace(**{field: bad})
    assert_refused(excinfo, field, text)


def test_inputs_accept_valid_edges():
    inputs = Inputs(drive_force=-3, excitation_amplitude=0, excitation_frequency=1e-3,
                    external_force_x=-1e6, external_force_z=-2)
    assert inputs.excitation_amplitude == 0.0
    assert type(inputs.drive_force) is float and inputs.drive_force == -3.0
    assert inputs.tangential_force == -3.0 + -1e6
    assert Inputs(excitation_frequency=20000.0, drive_force=1e6).excitation_frequency == 20000.0


@pytest.mark.parametrize("field, value", [
    ("drive_force", 1e308), ("drive_force", -1.0000001e6), ("excitation_frequency", 1e-300),
    ("excitation_frequency", 25000.0), ("external_force_x", 1e308), ("external_force_z", -1e9),
    ("excitation_amplitude", 1e300),
])
def test_inputs_refuse_finite_but_absurd_values(field, value):
    with pytest.raises(ParameterError) as excinfo:
        Inputs(**{field: value})
    assert_refused(excinfo, field, repr(value))
    assert Inputs(drive_force=0.7, external_force_x=0.25).tangential_force == 0.7 + 0.25


# --------------------------------------------------------------------------
# check_contact: the normal reaction must stay positive at every phase
# --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "params, amplitude, fz, text",
    [
        (SliderParams(), 10.0, 0.0, "10.0"),  # Pa == m*g
        (SliderParams(), 12.0, 0.0, "12.0"),  # Pa > m*g
        (SliderParams(), 12.0, 1.5, "12.0"),  # Pa > m*g + Fz
        (SliderParams(), 11.5, 1.5, "11.5"),  # Pa == m*g + Fz
        (SliderParams(), 4.0, -6.0, "4.0"),  # Fz unloads below Pa
        (SliderParams(mass=2.0, gravity=3.0), 6.0, 0.0, "6.0"),
    ],
)
def test_check_contact_refuses_lift_off_amplitude(params, amplitude, fz, text):
    inputs = Inputs(excitation_amplitude=amplitude, external_force_z=fz)
    with pytest.raises(ParameterError) as excinfo:
        check_contact(params, inputs)
    assert_refused(excinfo, "excitation_amplitude", text)
    mean_load = params.weight + fz
    assert repr(mean_load) in str(excinfo.value)  # the limit quotes m*g + Fz


@pytest.mark.parametrize("fz, amplitude, text", [(-10.0, 0.0, "-10.0"), (-1e6, 3.0, "-1000000.0")])
def test_check_contact_refuses_fz_at_or_below_minus_weight(fz, amplitude, text):
    # m*g + Fz <= 0: no excitation amplitude (>= 0) could make this valid, so
    # the error must name external_force_z whatever was changed last.
    inputs = Inputs(excitation_amplitude=amplitude, external_force_z=fz)
    with pytest.raises(ParameterError) as excinfo:
        check_contact(SliderParams(), inputs)
    assert_refused(excinfo, "external_force_z", text)


@pytest.mark.parametrize("fz, text", [(-10.0, "-10.0"), (-12.0, "-12.0")])
def test_check_contact_refuses_fz_at_or_below_minus_weight_when_changed(fz, text):
    inputs = Inputs(excitation_amplitude=0.0, external_force_z=fz)
    with pytest.raises(ParameterError) as excinfo:
        check_contact(SliderParams(), inputs, {"external_force_z"})
    assert_refused(excinfo, "external_force_z", text)


@pytest.mark.parametrize(
    "changed, field, text",
    [
        ({"external_force_z"}, "external_force_z", "-6.0"),
        ({"drive_force", "external_force_z"}, "external_force_z", "-6.0"),
        ({"excitation_amplitude"}, "excitation_amplitude", "5.0"),
        ({"external_force_z", "excitation_amplitude"}, "excitation_amplitude", "5.0"),
        ((), "excitation_amplitude", "5.0"),
        ({"drive_force"}, "excitation_amplitude", "5.0"),
    ],
)
def test_check_contact_blames_the_changed_field(changed, field, text):
    inputs = Inputs(excitation_amplitude=5.0, external_force_z=-6.0)  # m*g + Fz = 4 N
    with pytest.raises(ParameterError) as excinfo:
        check_contact(SliderParams(), inputs, changed)
    assert_refused(excinfo, field, text)


@pytest.mark.parametrize("changed, field, text", [({"mass"}, "mass", "0.4"), ({"gravity"}, "gravity", "12.0"),
                                                  ((), "excitation_amplitude", "5.0")])
def test_check_contact_blames_changed_params(changed, field, text):
    params = SliderParams(mass=0.4, gravity=12.0)  # m*g = 4.8 N < Pa = 5 N
    with pytest.raises(ParameterError) as excinfo:
        check_contact(params, Inputs(), changed)
    assert_refused(excinfo, field, text)


@pytest.mark.parametrize(
    "amplitude, fz",
    [
        (np.nextafter(10.0, 0.0), 0.0),
        (0.0, -9.999),
        (5.0, 0.0),
        (11.0, 1.5),
        (4.0, -5.5),
    ],
)
def test_check_contact_accepts_positive_reaction(amplitude, fz):
    check_contact(SliderParams(), Inputs(excitation_amplitude=amplitude, external_force_z=fz))


# --------------------------------------------------------------------------
# Slider construction
# --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "params, inputs, field, text",
    [
        (SliderParams(), Inputs(excitation_amplitude=10.0), "excitation_amplitude", "10.0"),
        (SliderParams(), Inputs(excitation_amplitude=12.0), "excitation_amplitude", "12.0"),
        (SliderParams(mass=0.5), Inputs(), "excitation_amplitude", "5.0"),
        (SliderParams(gravity=4.0), Inputs(), "excitation_amplitude", "5.0"),
        (SliderParams(), Inputs(excitation_amplitude=0.0, external_force_z=-10.0),
         "external_force_z", "-10.0"),
    ],
)
def test_slider_refuses_lift_off(params, inputs, field, text):
    with pytest.raises(ParameterError) as excinfo:
        Slider(params, inputs)
    assert_refused(excinfo, field, text)


@pytest.mark.parametrize("field", ["t0", "x0", "phase0"])
@pytest.mark.parametrize("bad, text", NOT_FINITE + [("abc", "'abc'"), (True, "True")])
def test_slider_refuses_non_finite_initial_state(field, bad, text):
    with pytest.raises(ParameterError) as excinfo:
        Slider(**{field: bad})
    assert_refused(excinfo, field, text)


# --------------------------------------------------------------------------
# Refused changes of a running slider leave it untouched
# --------------------------------------------------------------------------

# The paper's case slips on phases (asin(0.6), ~3.52) of every period, i.e.
# during t in (2.05 ms, 11.2 ms) of the first one.
MID_SLIP = 0.006
MID_STICK = 0.015


def _snapshot(slider):
    return (slider.t, slider.state(), slider.inputs, slider.params, slider.events,
            slider.event_counts, slider.next_event_time, slider.stuck_time)


def _future(slider, t_end=0.2):
    events = slider.advance_to(t_end)
    return [(e.t, e.kind, e.x) for e in events], slider.state()


@pytest.mark.parametrize("when", [MID_SLIP, MID_STICK])
@pytest.mark.parametrize(
    "changes, field, text",
    [
        ({"excitation_amplitude": 10.0}, "excitation_amplitude", "10.0"),
        ({"excitation_amplitude": 12.0}, "excitation_amplitude", "12.0"),
        # Fz = -6 leaves m*g + Fz = 4 N < Pa = 5 N: R would reach zero; the
        # error blames the field the user just changed.
        ({"external_force_z": -6.0}, "external_force_z", "-6.0"),
        ({"external_force_z": -6.0, "excitation_amplitude": 4.5}, "excitation_amplitude", "4.5"),
        ({"external_force_z": -10.0}, "external_force_z", "-10.0"),
        ({"drive_force": NAN}, "drive_force", "nan"),
        ({"excitation_frequency": -50.0}, "excitation_frequency", "-50.0"),
        ({"excitation_amplitude": -1.0}, "excitation_amplitude", "-1.0"),
    ],
)
def test_set_inputs_refusal_changes_nothing(when, changes, field, text):
    slider = Slider()
    control = Slider()
    slider.advance_to(when)
    control.advance_to(when)
    before = _snapshot(slider)
    assert before[1].stuck == (when == MID_STICK)

    with pytest.raises(ParameterError) as excinfo:
        slider.set_inputs(**changes)
    assert_refused(excinfo, field, text)

    assert _snapshot(slider) == before
    assert slider.inputs == Inputs()
    # ... and the future is exactly the one of a slider never asked to change.
    assert _future(slider) == _future(control)


def test_set_inputs_refuses_whole_inputs_object_and_changes_nothing():
    slider = Slider()
    slider.advance_to(MID_SLIP)
    before = _snapshot(slider)
    with pytest.raises(ParameterError) as excinfo:
        slider.set_inputs(Inputs(drive_force=0.2, excitation_amplitude=10.5))
    assert_refused(excinfo, "excitation_amplitude", "10.5")
    assert _snapshot(slider) == before


def test_set_inputs_accepts_a_valid_change():
    slider = Slider()
    slider.advance_to(MID_STICK)
    new = slider.set_inputs(drive_force=0.3)
    assert new == Inputs(drive_force=0.3)
    assert slider.inputs == new
    # phi = 0.3 <= 1 - a = 0.5: it never slips again.
    assert slider.next_event_time == math.inf


@pytest.mark.parametrize("when", [MID_SLIP, MID_STICK])
@pytest.mark.parametrize(
    "params, field, text",
    [
        # blamed on the changed field, not on the amplitude already in force
        (SliderParams(mass=0.5), "mass", "0.5"),  # m*g = 5 N == Pa
        (SliderParams(gravity=4.0), "gravity", "4.0"),  # m*g = 4 N < Pa
        (SliderParams(mass=0.4, gravity=12.0), "mass", "0.4"),  # 4.8 N < Pa
    ],
)
def test_set_params_refusal_changes_nothing(when, params, field, text):
    slider = Slider()
    control = Slider()
    slider.advance_to(when)
    control.advance_to(when)
    before = _snapshot(slider)
    with pytest.raises(ParameterError) as excinfo:
        slider.set_params(params)
    assert_refused(excinfo, field, text)
    assert _snapshot(slider) == before
    assert slider.params == SliderParams()
    assert _future(slider) == _future(control)


def test_set_params_accepts_a_valid_change():
    slider = Slider()
    slider.advance_to(MID_STICK)
    slider.set_params(SliderParams(mu=0.05))
    assert slider.params.mu == 0.05
    # phi = 0.7/(0.05*10) = 1.4 > 1: it slips away at once and never stops.
    slider.advance_to(0.1)
    assert not slider.state().stuck
    assert slider.next_event_time == math.inf


# --------------------------------------------------------------------------
# advance_to / sample arguments
# --------------------------------------------------------------------------


def test_advance_to_refuses_nan_and_the_past():
    slider = Slider()
    slider.advance_to(0.01)
    for bad, text in [(0.005, "0.005"), (NAN, "nan"), (-INF, "-inf")]:
        with pytest.raises(ParameterError) as excinfo:
            slider.advance_to(bad)
        assert_refused(excinfo, "t", text)
        assert slider.t == 0.01


def test_sample_refuses_bad_times():
    slider = Slider()
    slider.advance_to(0.01)
    for bad in [np.array([0.005, 0.02]), np.array([0.02, 0.015]), np.array([]),
                np.zeros((2, 2)) + 0.02]:
        with pytest.raises(ParameterError) as excinfo:
            slider.sample(bad)
        assert excinfo.value.field == "times"
        assert "times" in str(excinfo.value)
        assert slider.t == 0.01
