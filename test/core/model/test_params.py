"""Every parameter rejection of friction_sim's model edge.

Each refusal must be a :class:`ParameterError` (hence also a ``ValueError``
and a :class:`FrictionSimError`), name the offending field in ``.field`` and
quote both the field and the rejected value in its one-line message.  A
refused change to a running :class:`Slider` must leave it exactly as it was.
"""

import math

import numpy as np
import pytest

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.dimensionless import amplitude_ratio, throw_number
from friction_sim.core.model.events import EventKind, Mode
from friction_sim.core.model.params import (
    Inputs,
    SliderParams,
    cos_degrees,
    sin_degrees,
)
from friction_sim.core.physics.plant import is_kostek
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
# The general model's plant: angles, slope, static friction, restitution,
# landing friction
# --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "field, bad, text",
    [
        ("static_ratio", 0.999, "0.999"),  # mu_s < mu
        ("static_ratio", 101.0, "101.0"),
        ("excitation_angle", 0.0, "0.0"),  # a vibration along the track has no normal part
        ("excitation_angle", 90.5, "90.5"),
        ("excitation_angle", -30.0, "-30.0"),
        ("excitation_phase", 180.5, "180.5"),
        ("excitation_phase", -181.0, "-181.0"),
        ("track_inclination", 90.0, "90.0"),  # a vertical track holds nothing
        ("track_inclination", -89.5, "-89.5"),
        ("restitution", 1.0, "1.0"),  # e = 1 would bounce for ever
        ("restitution", -0.1, "-0.1"),
    ] + [(field, bad, text) for field in ("static_ratio", "excitation_angle", "excitation_phase",
                                           "track_inclination", "restitution")
         for bad, text in NOT_FINITE + [("abc", "'abc'"), (True, "True"), (None, "None")]],
)
def test_the_general_plant_refuses_values_outside_its_ranges(field, bad, text):
    with pytest.raises(ParameterError) as excinfo:
        SliderParams(**{field: bad})
    assert_refused(excinfo, field, text)
    with pytest.raises(ParameterError) as excinfo:
        SliderParams().replace(**{field: bad})
    assert_refused(excinfo, field, text)


@pytest.mark.parametrize("bad, text", [("plastic", "'plastic'"), ("", "''"), ("Impulsive", "'Impulsive'"),
                                       (" none", "' none'"), (1.0, "1.0"), (None, "None"), (True, "True")])
def test_landing_friction_takes_one_of_its_choices_and_names_them(bad, text):
    with pytest.raises(ParameterError) as excinfo:
        SliderParams(landing_friction=bad)
    assert_refused(excinfo, "landing_friction", text)
    if isinstance(bad, str):
        assert "impulsive" in str(excinfo.value) and "none" in str(excinfo.value)  # the choices
    assert SliderParams(landing_friction="none").landing_friction == "none"
    assert SliderParams().landing_friction == "impulsive"


def test_the_general_plant_accepts_its_edges():
    edges = SliderParams(static_ratio=100.0, excitation_angle=0.1, excitation_phase=-180.0, track_inclination=-89.0,
                         restitution=0.99, landing_friction="none")
    assert (edges.static_ratio, edges.excitation_angle, edges.excitation_phase, edges.track_inclination,
            edges.restitution) == (100.0, 0.1, -180.0, -89.0, 0.99)
    assert SliderParams(excitation_phase=180, track_inclination=89).excitation_phase == 180.0


def test_derived_forces_of_the_general_plant_are_exact_at_the_kostek_case():
    kostek = SliderParams()
    assert is_kostek(kostek) and kostek.tangential_ratio == 0.0  # cot(90 deg) exactly 0, not 6e-17
    assert (kostek.normal_weight, kostek.downhill_weight) == (10.0, 0.0)
    pa = Inputs().excitation_amplitude
    assert throw_number(pa, kostek.normal_weight) == 0.5 == amplitude_ratio(pa, kostek.weight)
    for angle in (-270.0, -180.0, -90.0, 0.0, 90.0, 180.0, 270.0, 360.0):  # exact at the right angles
        assert sin_degrees(angle) == round(math.sin(math.radians(angle)))
        assert cos_degrees(angle) == round(math.cos(math.radians(angle)))


@pytest.mark.parametrize("alpha, beta", [(10.0, 30.0), (-20.0, 60.0), (5.0, 89.9), (0.0, 0.1)])
def test_derived_forces_of_a_tilted_vibration_on_a_slope(alpha, beta):
    params = SliderParams(mass=2.0, gravity=9.81, excitation_angle=beta, track_inclination=alpha)
    weight = 2.0 * 9.81
    assert not is_kostek(params)
    assert params.normal_weight == pytest.approx(weight * math.cos(math.radians(alpha)), rel=1e-15)
    assert params.downhill_weight == pytest.approx(weight * math.sin(math.radians(alpha)), rel=1e-15, abs=0.0)
    assert params.tangential_ratio == pytest.approx(1.0 / math.tan(math.radians(beta)), rel=1e-14)
    inputs = Inputs(excitation_amplitude=30.0)
    assert throw_number(inputs.excitation_amplitude, params.normal_weight) == pytest.approx(
        30.0 / (weight * math.cos(math.radians(alpha))), rel=1e-15)
    assert not is_kostek(SliderParams(static_ratio=1.5))


@pytest.mark.parametrize("amplitude, fz", [(10.0, 0.0), (12.0, 0.0), (4.0, 6.0), (0.0, 10.0), (1e6, -1e6),
                                           (5.0, 1e6)])
def test_an_amplitude_or_lifting_force_above_the_weight_is_accepted(amplitude, fz):
    # No lift-off refusal any more: the slider hops (the throw number above 1).
    inputs = Inputs(excitation_amplitude=amplitude, external_force_z=fz)
    assert (inputs.excitation_amplitude, inputs.external_force_z) == (amplitude, fz)
    assert throw_number(inputs.excitation_amplitude, SliderParams().normal_weight) == amplitude / 10.0


# --------------------------------------------------------------------------
# Slider construction
# --------------------------------------------------------------------------


@pytest.mark.parametrize("amplitude", [12.0, 15.0])
def test_the_slider_hops_above_the_weight(amplitude):
    # Gamma = Pa/(m g) > 1 from rest: in contact until R = m g - Pa sin(theta) reaches 0 at
    # sin(theta) = 1/Gamma, then off the track (z > 0) until it lands again.
    slider = Slider(SliderParams(), Inputs(excitation_amplitude=amplitude, drive_force=0.0))
    gamma = amplitude / 10.0
    omega = 2.0 * math.pi * 50.0
    events = slider.advance_to(0.1)
    lift_offs = [e for e in events if e.kind is EventKind.LIFT_OFF]
    landings = [e for e in events if e.kind is EventKind.LANDING]
    assert lift_offs and landings
    assert lift_offs[0].t == pytest.approx(math.asin(1.0 / gamma) / omega, rel=1e-12)
    assert lift_offs[0].after is Mode.FLIGHT and landings[0].before is Mode.FLIGHT
    assert landings[0].vz_before < 0.0 and landings[0].t > lift_offs[0].t
    in_flight = 0.5 * (lift_offs[0].t + landings[0].t)
    fresh = Slider(SliderParams(), Inputs(excitation_amplitude=amplitude, drive_force=0.0))
    fresh.advance_to(in_flight)
    state = fresh.state()
    assert state.in_flight and state.z > 0.0 and state.normal_force == 0.0 and state.friction_force == 0.0


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
        ({"excitation_amplitude": 1.5e6}, "excitation_amplitude", "1500000.0"),
        ({"external_force_z": -INF}, "external_force_z", "-inf"),
        ({"external_force_z": 1.0, "excitation_amplitude": -4.5}, "excitation_amplitude", "-4.5"),
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
        slider.set_inputs(Inputs(drive_force=0.2, excitation_amplitude=-10.5))
    assert_refused(excinfo, "excitation_amplitude", "-10.5")
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
    "changes, field, text",
    [
        ({"landing_friction": "sliding"}, "landing_friction", "'sliding'"),
        ({"restitution": 1.0}, "restitution", "1.0"),
        ({"mass": 0.5, "static_ratio": 0.5}, "static_ratio", "0.5"),
    ],
)
def test_set_params_refusal_changes_nothing(when, changes, field, text):
    # An invalid plant cannot even be built, so the running slider never sees it.
    slider = Slider()
    control = Slider()
    slider.advance_to(when)
    control.advance_to(when)
    before = _snapshot(slider)
    with pytest.raises(ParameterError) as excinfo:
        slider.set_params(slider.params.replace(**changes))
    assert_refused(excinfo, field, text)
    assert _snapshot(slider) == before
    assert slider.params == SliderParams()
    assert _future(slider) == _future(control)


@pytest.mark.parametrize("params", [SliderParams(mass=0.4), SliderParams(gravity=4.0)])
def test_a_lighter_plant_under_the_same_amplitude_now_hops(params):
    # m*g = 4 N < Pa = 5 N: once refused as a lift-off, now the flight regime.  (At m*g = Pa
    # exactly, R = m g (1 - sin(theta)) only touches zero: no lift-off.)
    slider = Slider()
    slider.advance_to(MID_STICK)
    slider.set_params(params)
    events = slider.advance_to(0.1)
    assert EventKind.LIFT_OFF in {e.kind for e in events}
    assert slider.params == params


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
