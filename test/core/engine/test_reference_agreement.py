"""The exact core against the independent numerical reference.

friction_sim.reference integrates the same model with scipy's DOP853 at
rtol=1e-10, atol=1e-14 and locates events with brentq; it shares no code and
no closed-form reasoning with friction_sim.core.

Tolerances:

* x and v: 1e-8 relative to max|x| and max|v| of the run.  The reference's
  local error per step is ~rtol = 1e-10 of the state; over a run of ~40
  periods with max_step = T/20 (~800+ steps) the global error grows at most
  ~linearly (a few 1e-9 in the worst case; velocity errors are reset to
  exactly 0 at every stick), so 1e-8 leaves a margin of a few while still
  being ~1e4 times tighter than any modelling mistake (a wrong slip phase by
  one sample of a 2000-point grid already shows at ~1e-3).
* event times: 1e-9 s.  Each event is a root polished to ~1e-15 s by both
  sides; errors in the state at the event enter the stop time only through
  dw/dt, which is O(mu*g) away from zero at a stick.
* U against the brute-force fixed-step integrator: 1e-3 relative (it is first
  order in its step at the transitions; ~1e-5 with its default step).
"""

import dataclasses

import numpy as np
import pytest

from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.urelation import u_map
from friction_sim.core.model.commands import Command
from friction_sim.core.model.dimensionless import dimensional_speed
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.runtime.simulation import random_schedule, run_schedule

import reference
from helpers import grouped, rescaled_drive

ReferenceInputs = reference.ReferenceInputs

X_TOL = 1e-8
V_TOL = 1e-8
EVENT_TOL = 1e-9


def reference_schedule(start, schedule):
    """The core's (initial Inputs, Commands) as the reference's piecewise list."""
    known = {item.name for item in dataclasses.fields(ReferenceInputs)}  # (the force actuator's inputs)
    current = {name: value for name, value in dataclasses.asdict(start).items() if name in known}
    out = [(0.0, ReferenceInputs(**current))]
    for command in grouped(schedule):
        current = {**current, **command.values}
        out.append((command.t, ReferenceInputs(**current)))
    return out


def compare(params, start, schedule, t_end, n_samples=2001, extra_times=()):
    times = np.unique(np.concatenate([np.linspace(0.0, t_end, n_samples), np.asarray(extra_times, float)]))
    slider = Slider(params, start, event_log_size=None)
    traj = run_schedule(slider, schedule, times)
    ref = reference.reference_solution(
        params.mass, params.mu, params.gravity, reference_schedule(start, schedule), times,
        rtol=1e-10, atol=1e-14,
    )
    core_kinds = tuple(e.kind.value for e in slider.events)
    assert core_kinds == ref.event_kinds, (core_kinds, ref.event_kinds)
    core_times = np.array([e.t for e in slider.events])
    if core_times.size:
        assert np.max(np.abs(core_times - ref.event_times)) <= EVENT_TOL
    x_scale = np.max(np.abs(ref.x))
    v_scale = np.max(np.abs(ref.v))
    assert np.max(np.abs(traj.x - ref.x)) <= X_TOL * x_scale
    assert np.max(np.abs(traj.v - ref.v)) <= V_TOL * v_scale
    # stuck samples of the core are exactly still
    stuck = traj.mode == 0
    assert np.all(traj.v[stuck] == 0.0)
    return slider, traj, ref


@pytest.mark.parametrize("external", [False, True])
@pytest.mark.parametrize("seed", range(7))
def test_random_schedules_agree_with_reference(seed, external):
    rng = np.random.default_rng(1000 + seed)
    t_end = 0.8  # 40 periods at the nominal 50 Hz (frequency varies 25..100 Hz)
    schedule = random_schedule(rng, t_end, external=external)
    assert len(schedule) >= 3
    slider, _traj, ref = compare(SliderParams(), Inputs(), schedule, t_end)
    assert len(slider.events) >= 4
    assert np.max(np.abs(ref.x)) > 0.0


@pytest.mark.parametrize("seed", range(3))
def test_random_schedules_other_plant_agree_with_reference(seed):
    """Another plant (m, mu, g) and frequency, scaled inputs."""
    rng = np.random.default_rng(2000 + seed)
    params = SliderParams(mass=2.5, mu=0.23, gravity=9.81)
    weight = params.weight
    t_end = 1.0  # ~30 periods at 30 Hz
    schedule = random_schedule(rng, t_end, frequency=30.0, weight=weight, external=True)
    # random_schedule scales drive forces for mu ~ 0.1; rescale to this mu
    schedule = rescaled_drive(schedule, params.mu / 0.1)
    start = Inputs(drive_force=0.8 * params.mu * weight, excitation_amplitude=0.4 * weight,
                   excitation_frequency=30.0)
    slider, _, _ = compare(params, start, schedule, t_end)
    assert len(slider.events) >= 4


def test_reversal_heavy_schedule_agrees_with_reference():
    """Drive force flipping sign every ~1.3 periods, often mid-slip."""
    flips = [Command(0.026 * k + 0.003, "drive_force", {"drive_force": (-1) ** k * 0.85}) for k in range(1, 30)]
    slider, _, _ = compare(SliderParams(), Inputs(drive_force=0.85, excitation_amplitude=6.0),
                           flips, 0.8)
    kinds = [e.kind.value for e in slider.events]
    assert "reversal" in kinds


def test_event_times_used_as_samples_agree():
    """Sampling exactly at the core's event times: still the same states."""
    rng = np.random.default_rng(77)
    schedule = random_schedule(rng, 0.5, external=True)
    probe = Slider(event_log_size=None)
    run_schedule(probe, schedule, np.array([0.5]))
    event_times = [e.t for e in probe.events]
    compare(SliderParams(), Inputs(), schedule, 0.5, n_samples=101, extra_times=event_times)


def test_reference_sees_a_brief_return_to_rest():
    """A backward slip that decelerates to v = 0 where |Ft| < mu*R must stick.

    From v0 < 0 the backward law m*dv/dt = Ft + mu*R(t) has the closed form
    below; v first reaches 0 at t* ~ 0.264 ms and would then turn positive for
    only ~0.4 ms -- shorter than one solver step (max_step = T/20 = 1.4 ms).
    The core finds this stick (a random schedule, seed 131 of a 150-seed
    fuzz, is how it showed up); the reference must too.
    """
    from scipy.optimize import brentq

    m, mu, g = 3.303024945183361, 0.4928846653308694, 11.582013567825095
    inputs = ReferenceInputs(drive_force=-16.55540011563017, excitation_amplitude=19.274444896712595,
                             excitation_frequency=36.308604383562205, external_force_x=-0.3806132807973947,
                             external_force_z=-2.770832334496362)
    v0, theta0 = -5.928363747229046e-05, 0.2409504149232461
    omega = 2.0 * np.pi * inputs.excitation_frequency
    load = m * g - inputs.external_force_z
    ft = inputs.drive_force + inputs.external_force_x

    def v_backward(t):
        return (v0 + (ft + mu * load) / m * t
                + mu * inputs.excitation_amplitude / m * (np.cos(theta0 + omega * t) - np.cos(theta0)) / omega)

    t_star = brentq(v_backward, 0.0, 5e-4, xtol=1e-16)
    reaction = load - inputs.excitation_amplitude * np.sin(theta0 + omega * t_star)
    assert abs(ft) < mu * reaction  # so it sticks at t*
    times = np.linspace(0.0, 1e-3, 1001)
    ref = reference.reference_solution(m, mu, g, [(0.0, inputs)], times, v0=v0, phase0=theta0)
    assert len(ref.event_kinds) >= 1 and ref.event_kinds[0] == "stick", (ref.event_times, ref.event_kinds)
    assert abs(ref.event_times[0] - t_star) <= EVENT_TOL
    assert np.all(ref.v <= 0.0)


# --------------------------------------------------------------------------
# the U relation against the brute-force integrator
# --------------------------------------------------------------------------

BRUTE_POINTS = [
    # (mass, mu, gravity, Fd, Pa, f)
    (1.0, 0.1, 10.0, 0.7, 5.0, 50.0),  # the paper's Fig. 2: phi = 0.7, a = 0.5
    (2.0, 0.2, 9.81, 0.9 * 0.2 * 2.0 * 9.81, 0.3 * 2.0 * 9.81, 30.0),  # phi = 0.9, a = 0.3
    (0.5, 0.156, 10.0, -0.5 * 0.156 * 5.0, 0.8 * 5.0, 100.0),  # phi = -0.5, a = 0.8
]


@pytest.mark.timeout(20)
@pytest.mark.parametrize("m, mu, g, fd, pa, f", BRUTE_POINTS)
def test_u_map_against_brute_force(m, mu, g, fd, pa, f):
    phi, a = fd / (mu * m * g), pa / (m * g)
    exact_v = dimensional_speed(u_map(phi, a), f, g, mu)
    brute_v = reference.brute_force_mean_velocity(
        m, mu, g, fd, pa, f, periods=10, settle_periods=1
    )
    assert exact_v != 0.0
    assert abs(brute_v - exact_v) <= 1e-3 * abs(exact_v), (brute_v, exact_v)
