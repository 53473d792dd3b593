"""The general mean speed (issue 11, item 2) and its inverse on the rising branch.

Independent expectations:

* Kostek's closed form (:func:`u_map`, itself checked against quadrature and
  mpmath in test_urelation*.py): the simulated path must reproduce it.
* A hand calculation for a hopping slider: at the throw number
  Gamma = sqrt(1 + pi^2) a plastic landing ends a flight of exactly one
  period at the next lift-off phase theta0 = asin(1/Gamma), and the slider
  leaves again at once.  With Fd = 0 on a level track the flight integrates
  m*x'' = Pt*sin(theta) over a whole period, so it lands with the speed it
  took off with: 0 after the first impulsive landing (which stops it).  Its
  speed is then v = Pt/(m*omega)*(cos(theta0) - cos(theta)), whose mean over
  the period is Pt*cos(theta0)/(m*omega); with Pt = Pa*cot(beta),
  Pa = Gamma*m*g and cos(theta0) = pi/Gamma that is U = cot(beta)/(2*mu).
* The independent solve_ivp reference (test/reference_general.py, no core
  code) for a period-1 hopping case the hand cannot do.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from friction_sim.core.meanspeed.general import MeanSpeed, MeanSpeedGrid, mean_speed, u_general
from friction_sim.core.meanspeed.inverse import amplitude_ratio_for_general, rising_branch
from friction_sim.core.meanspeed.predict import predict
from friction_sim.core.meanspeed.urelation import u_map
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.errors import ParameterError

from reference_general import GeneralModel, solve

GAMMA_1 = math.sqrt(1.0 + math.pi**2)  # one-period flights with a plastic landing


def plant_inputs(params: SliderParams, phi: float, a: float, frequency: float = 50.0) -> Inputs:
    return Inputs(drive_force=phi * params.mu * params.weight, excitation_amplitude=a * params.weight,
                  excitation_frequency=frequency)


# -- Kostek's model: the closed form, and the simulation reproducing it ------------------------


@pytest.mark.parametrize(("mass", "mu", "gravity", "frequency"), [(1.0, 0.1, 10.0, 50.0), (3.0, 0.4, 9.81, 7.0)])
@pytest.mark.parametrize(("phi", "a"), [(0.7, 0.5), (0.3, 0.75), (0.95, 0.1), (0.9, 0.99), (-0.7, 0.6),
                                        (0.999, 0.002), (0.5, 0.5), (0.2, 0.3)])
def test_the_simulated_mean_equals_the_closed_form(mass: float, mu: float, gravity: float, frequency: float,
                                                   phi: float, a: float) -> None:
    params = SliderParams(mass=mass, mu=mu, gravity=gravity)
    inputs = plant_inputs(params, phi, a, frequency)
    exact = mean_speed(params, inputs)
    simulated = mean_speed(params, inputs, simulate=True)
    expected = u_map(inputs.drive_force / (mu * params.weight), inputs.excitation_amplitude / params.weight)
    assert exact.exact and not simulated.exact
    assert exact.u == expected  # the closed form, bit for bit
    assert simulated.u == pytest.approx(expected, rel=1e-9, abs=1e-300)
    assert simulated.periodic and simulated.period_multiple == 1 and simulated.settle_periods <= 3
    assert simulated.flight_fraction == 0.0 and exact.flight_fraction == 0.0
    assert simulated.stick_fraction == pytest.approx(exact.stick_fraction, rel=1e-9)
    assert simulated.mean_velocity == pytest.approx(exact.mean_velocity, rel=1e-9, abs=1e-300)


def test_beyond_phi_one_both_paths_run_away() -> None:
    params = SliderParams()
    for simulate in (False, True):
        result = mean_speed(params, plant_inputs(params, 1.2, 0.5), simulate=simulate, settle_periods=20, periods=40)
        assert result.runaway and result.u == math.inf and not result.periodic and result.period_multiple == 0
    backwards = mean_speed(params, plant_inputs(params, -1.2, 0.5), simulate=True, settle_periods=20, periods=40)
    assert backwards.runaway and backwards.u == -math.inf
    assert (backwards.settle_periods, backwards.periods) == (20, 40)


def test_u_general_is_u_map_bit_for_bit_on_kostek_and_simulates_elsewhere() -> None:
    phi = np.linspace(-0.9, 0.9, 7)[:, None]
    a = np.array([0.0, 0.3, 0.6, 0.95])[None, :]
    assert np.array_equal(u_general(phi, a), u_map(phi, a))
    assert u_general(0.7, 0.5) == u_map(0.7, 0.5) and type(u_general(0.7, 0.5)) is float
    # above lift-off the same model is simulated, point by point
    grid = u_general(np.array([0.2, -0.2]), np.array([1.5, 1.5]), details=True)
    assert isinstance(grid, MeanSpeedGrid)
    assert not grid.exact.any() and grid.periodic.all() and (grid.flight_fraction > 0.5).all()
    assert grid.u[0] > 0.0 and grid.u[1] == pytest.approx(-grid.u[0], rel=1e-12)  # beta = 90: mirror symmetric
    single = mean_speed(SliderParams(), plant_inputs(SliderParams(), 0.2, 1.5))
    assert grid.u[0] == single.u
    with pytest.raises(ParameterError, match="amplitude_ratio"):
        u_general(0.5, -0.1)


# -- hopping ------------------------------------------------------------------------------


@pytest.mark.parametrize("beta", [30.0, 45.0, 60.0])
@pytest.mark.parametrize("mu", [0.3, 0.5])
def test_one_period_flights_convey_at_cot_beta_over_two_mu(beta: float, mu: float) -> None:
    """The hand calculation of the module doc."""
    params = SliderParams(mu=mu, excitation_angle=beta)
    result = mean_speed(params, Inputs(drive_force=0.0, excitation_amplitude=GAMMA_1 * params.weight))
    cot = math.cos(math.radians(beta)) / math.sin(math.radians(beta))
    assert result.u == pytest.approx(cot / (2.0 * mu), rel=1e-9)
    assert result.periodic and result.period_multiple == 1 and not result.exact
    assert result.flight_fraction == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize(("beta", "gamma", "phi"), [(30.0, 2.0, 0.0), (60.0, 1.5, 0.1)])
def test_a_hopping_mean_agrees_with_the_independent_reference(beta: float, gamma: float, phi: float) -> None:
    params = SliderParams(mu=0.5, excitation_angle=beta)
    inputs = plant_inputs(params, phi, gamma, frequency=20.0)
    result = mean_speed(params, inputs)
    assert result.periodic and result.period_multiple == 1 and 0.3 < result.flight_fraction < 0.9
    period = 1.0 / inputs.excitation_frequency
    first, last = result.settle_periods + 2, result.settle_periods + 6
    reference = solve(GeneralModel.from_core(params, inputs), (last + 0.5) * period)
    x = reference.evaluate(np.array([first, last]) * period)["x"]
    u_reference = (x[1] - x[0]) / ((last - first) * period) * inputs.excitation_frequency / (
        params.gravity * params.mu)
    assert result.u == pytest.approx(u_reference, rel=1e-8)


def test_period_doubling_and_a_stated_window_when_nothing_repeats() -> None:
    params = SliderParams(mu=0.5, excitation_angle=60.0)
    doubled = mean_speed(params, Inputs(drive_force=0.0, excitation_amplitude=45.0))
    assert doubled.periodic and doubled.period_multiple == 2 and doubled.periods == 2
    # the same motion averaged over a long stated window, with the repeat search switched off
    long = mean_speed(params, Inputs(drive_force=0.0, excitation_amplitude=45.0), max_multiple=1,
                      settle_periods=40, periods=400)
    assert not long.periodic and long.period_multiple == 0 and (long.settle_periods, long.periods) == (40, 400)
    assert long.u == pytest.approx(doubled.u, rel=1e-9)


def test_a_hopping_call_stops_at_the_first_repeat() -> None:
    """A periodic hopping motion is recognised within a few periods, not
    averaged over the default 200 + 200 (the time it takes: bench/step_vs_run.py)."""
    params = SliderParams(mu=0.5, excitation_angle=30.0)
    inputs = Inputs(drive_force=0.0, excitation_amplitude=20.0)
    result = mean_speed(params, inputs)
    assert result.periodic and result.settle_periods + result.periods * result.period_multiple <= 10, result


def test_predict_falls_back_to_the_general_mean_speed() -> None:
    params = SliderParams(mu=0.5, excitation_angle=60.0)
    inputs = Inputs(drive_force=0.0, excitation_amplitude=15.0)
    prediction = predict(params, inputs)
    assert prediction.u == mean_speed(params, inputs).u
    assert prediction.effective_gravity == params.gravity and prediction.effective_amplitude_ratio == 1.5
    kostek = predict(SliderParams(), Inputs())
    assert kostek.u == u_map(0.7, 0.5)


def test_bad_windows_are_refused_by_name() -> None:
    windows: list[dict[str, Any]] = [{"settle_periods": -1}, {"periods": 0}, {"max_multiple": 1.5}]
    for window in windows:
        with pytest.raises(ParameterError, match=next(iter(window))):
            mean_speed(SliderParams(), Inputs(), **window)


def test_records_are_frozen() -> None:
    result = mean_speed(SliderParams(), Inputs())
    assert isinstance(result, MeanSpeed)
    with pytest.raises(AttributeError):
        result.u = 0.0  # type: ignore[misc]


# -- the inverse on the rising branch ----------------------------------------------------------------


@pytest.mark.parametrize(("beta", "phi", "top"), [(60.0, 0.0, 5.0), (30.0, 0.0, 5.0), (60.0, 0.1, 0.95),
                                                  (90.0, 0.2, 3.0)])
def test_the_inverse_round_trips_on_the_rising_branch(beta: float, phi: float, top: float) -> None:
    params = SliderParams(mu=0.5, excitation_angle=beta)
    inputs = plant_inputs(params, phi, 0.0)
    branch = rising_branch(params, inputs, top)
    assert not branch.empty and 0.0 < branch.a_start < branch.a_end <= top and branch.u_end > 0.0
    assert np.all(np.diff(branch.nodes_g) > 0.0), "rising"
    for fraction in (1e-6, 1e-3, 0.1, 0.5, 0.9, 0.999, 1.0):
        u = fraction * branch.u_end
        a = amplitude_ratio_for_general(u, params, inputs, top)
        assert branch.a_start < a <= branch.a_end
        back = mean_speed(params, plant_inputs(params, phi, a)).u
        assert back == pytest.approx(u, rel=1e-11)
    # beyond the branch's end, and the wrong way: unreachable
    assert math.isnan(amplitude_ratio_for_general(1.0001 * branch.u_end, params, inputs, top))
    assert math.isnan(amplitude_ratio_for_general(-0.01, params, inputs, top))
    assert amplitude_ratio_for_general(0.0, params, inputs, top) == 0.0


def test_the_branch_ends_at_its_peak_before_the_top() -> None:
    """beta = 60 degrees, mu = 0.5: U rises to the one-period-flight value
    cot(beta)/(2 mu) at Gamma = 3.30, stays there (a plateau of flights that
    take off again at once), rises a little further in period-doubled motion
    (peak near Gamma = 3.9) and falls: the branch ends at that peak, not at
    max_amplitude_ratio = 6."""
    params = SliderParams(mu=0.5, excitation_angle=60.0)
    plateau = [mean_speed(params, Inputs(drive_force=0.0, excitation_amplitude=10.0 * gamma)).u
               for gamma in (3.35, 3.45, 3.6)]
    assert plateau == pytest.approx([1.0 / math.sqrt(3.0)] * 3, rel=1e-9)
    branch = rising_branch(params, Inputs(drive_force=0.0), 6.0)
    assert 3.6 < branch.a_end < 4.25
    assert 1.0 / math.sqrt(3.0) < branch.u_end < 1.02 / math.sqrt(3.0)
    assert branch.u_end >= np.nanmax(branch.u[branch.a <= branch.a_end])
    assert np.any(branch.u[branch.a > branch.a_end] < branch.u_end), "U falls after the end"
    assert mean_speed(params, Inputs(drive_force=0.0, excitation_amplitude=10.0 * branch.a_end)).u == \
        pytest.approx(branch.u_end, rel=1e-12)
    # targets on the plateau and just above it are reached
    for u in (1.0 / math.sqrt(3.0), 0.5 * (1.0 / math.sqrt(3.0) + branch.u_end)):
        a = branch.amplitude_ratio_for(u)
        assert mean_speed(params, Inputs(drive_force=0.0, excitation_amplitude=10.0 * a)).u == pytest.approx(
            u, rel=1e-11)


def test_kostek_with_a_top_below_one_is_the_exact_inverse() -> None:
    from friction_sim.core.meanspeed.urelation import amplitude_ratio_for

    params = SliderParams()
    for u in (1e-5, 0.005, 0.05):
        assert amplitude_ratio_for_general(u, params, Inputs(), 0.95) == pytest.approx(
            amplitude_ratio_for(u, 0.7, 0.95), rel=1e-11)
