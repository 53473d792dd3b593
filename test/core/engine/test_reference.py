"""Tests of the independent numerical reference (friction_sim.reference) itself.

These tests check the reference against closed-form results and physical
invariants only; they deliberately do not use friction_sim.core.
"""

import ast
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from reference import (
    ReferenceInputs,
    brute_force_mean_velocity,
    reference_solution,
)

M, MU, G = 1.0, 0.1, 10.0
F = 50.0
T = 1.0 / F
OMEGA = 2.0 * math.pi * F
PAPER = ReferenceInputs(drive_force=0.7, excitation_amplitude=5.0, excitation_frequency=F)
# Paper case: |Fd| - mu*R = -0.3 + 0.5*sin(theta) > 0  <=>  sin(theta) > 0.6.
PAPER_SLIP_PHASE = math.asin(0.6)
MODULE = Path(__file__).resolve().parents[2] / 'reference.py'
#: The reference and its parts (none of them may use the core, nor import scipy at import).
MODULES = [MODULE.with_name(name) for name in ('reference.py', 'reference_schedule.py', 'reference_exact.py')]


def _paper_slip_velocity(t: float, t_s: float) -> float:
    """Closed-form slip velocity of the paper case from rest at t_s (phase 0 at t=0)."""
    return (0.7 - MU * M * G) * (t - t_s) - MU * 5.0 / OMEGA * (
        math.cos(OMEGA * t) - math.cos(OMEGA * t_s))


def _paper_slip_position(t: float, t_s: float) -> float:
    """Closed-form displacement of the paper case since the slip start at t_s."""
    return (0.7 - MU * M * G) * (t - t_s) ** 2 / 2 - MU * 5.0 / OMEGA * (
        (math.sin(OMEGA * t) - math.sin(OMEGA * t_s)) / OMEGA
        - math.cos(OMEGA * t_s) * (t - t_s))


@pytest.fixture(scope='module')
def paper_run():
    ts = np.linspace(0.0, 10 * T, 10 * 40 + 1)  # 40 samples per period
    return reference_solution(M, MU, G, [(0.0, PAPER)], ts)


# --------------------------------------------------------------------------- Pa = 0


def test_no_excitation_above_threshold_accelerates_uniformly():
    fd = 1.7
    a = (fd - MU * M * G) / M
    ts = np.linspace(0.0, 2.0, 21)
    res = reference_solution(M, MU, G, [(0.0, ReferenceInputs(drive_force=fd,
                                                               excitation_amplitude=0.0))], ts)
    np.testing.assert_allclose(res.x, a * ts ** 2 / 2, rtol=1e-9, atol=0.0)
    np.testing.assert_allclose(res.v, a * ts, rtol=1e-9, atol=0.0)
    assert res.event_kinds == ('slip_start',)
    assert res.event_times.tolist() == [0.0]


def test_no_excitation_below_threshold_never_moves():
    ts = np.linspace(0.0, 2.0, 21)
    res = reference_solution(M, MU, G, [(0.0, ReferenceInputs(drive_force=0.99,
                                                               excitation_amplitude=0.0))], ts)
    assert np.all(res.x == 0.0)
    assert np.all(res.v == 0.0)
    assert res.event_kinds == ()
    assert res.event_times.size == 0


def test_initial_velocity_decelerates_and_sticks():
    # Fd = 0, v0 = 1: a = -mu*g = -1 until v = 0 at t = 1 (x = 0.5), then stuck for good.
    ts = np.array([0.0, 0.5, 1.0, 1.5, 3.0])
    res = reference_solution(M, MU, G, [(0.0, ReferenceInputs(drive_force=0.0,
                                                               excitation_amplitude=0.0))],
                             ts, v0=1.0, x0=0.25)
    expected_x = 0.25 + np.where(ts < 1.0, ts - ts ** 2 / 2, 0.5)
    np.testing.assert_allclose(res.x, expected_x, rtol=1e-12)
    assert res.event_kinds == ('stick',)
    assert res.event_times[0] == pytest.approx(1.0, abs=1e-12)
    assert res.v[-1] == 0.0 and res.v[-2] == 0.0
    assert res.x[-1] == res.x[-2]


def test_reversal_after_drive_force_flips():
    # Fd = +2 on [0, 1): a = +1, v(1) = 1.  Fd = -2 afterwards: a = -3 while v > 0, v = 0 at
    # t = 4/3 where |Fd| = 2 > mu*m*g = 1, so the slider reverses with a = -1.
    sched = [(0.0, ReferenceInputs(drive_force=2.0, excitation_amplitude=0.0)),
             (1.0, ReferenceInputs(drive_force=-2.0, excitation_amplitude=0.0))]
    ts = np.array([0.5, 1.0, 1.2, 2.0, 3.0])
    res = reference_solution(M, MU, G, sched, ts)

    def x_exact(t):
        if t <= 1.0:
            return t * t / 2
        if t <= 4 / 3:
            return 0.5 + (t - 1) - 1.5 * (t - 1) ** 2
        return 0.5 + 1 / 3 - 1.5 / 9 - (t - 4 / 3) ** 2 / 2

    np.testing.assert_allclose(res.x, [x_exact(t) for t in ts], rtol=1e-10)
    assert res.event_kinds == ('slip_start', 'reversal')
    assert res.event_times[1] == pytest.approx(4 / 3, abs=1e-12)
    assert res.v[-1] == pytest.approx(-(3.0 - 4 / 3), rel=1e-10)


# --------------------------------------------------------------------------- paper case


def test_paper_case_slip_starts_at_asin_phase(paper_run):
    starts = paper_run.event_times[np.array(paper_run.event_kinds) == 'slip_start']
    expected = PAPER_SLIP_PHASE / OMEGA + T * np.arange(10)
    assert starts.shape == expected.shape
    np.testing.assert_allclose(starts, expected, rtol=0.0, atol=1e-9)


def test_paper_case_one_slip_and_one_stick_per_period(paper_run):
    kinds = np.array(paper_run.event_kinds)
    assert set(paper_run.event_kinds) == {'slip_start', 'stick'}
    assert np.all(np.diff(paper_run.event_times) > 0.0)
    for k in range(10):
        in_period = (paper_run.event_times >= k * T) & (paper_run.event_times < (k + 1) * T)
        assert list(kinds[in_period]) == ['slip_start', 'stick'], k


def test_paper_case_stick_time_and_step_match_closed_form(paper_run):
    from scipy.optimize import brentq

    t_s = PAPER_SLIP_PHASE / OMEGA
    t_e = brentq(_paper_slip_velocity, t_s + 0.1 * T, t_s + 0.99 * T, args=(t_s,),
                 xtol=1e-16, rtol=1e-15)
    sticks = paper_run.event_times[np.array(paper_run.event_kinds) == 'stick']
    np.testing.assert_allclose(sticks, t_e + T * np.arange(10), rtol=0.0, atol=1e-9)
    step = _paper_slip_position(t_e, t_s)
    period_steps = paper_run.x[40::40] - paper_run.x[:-40:40]
    np.testing.assert_allclose(period_steps, step, rtol=1e-8)


def test_paper_case_moves_forward_periodically(paper_run):
    x, t = paper_run.x, paper_run.t
    i2, i10 = 2 * 40, 10 * 40
    mean_v = (x[i10] - x[i2]) / (t[i10] - t[i2])
    assert mean_v > 0.0
    # x(t + T) - x(t) does not depend on t (several phases inside the period).
    offsets = [x[i + 40] - x[i] for i in (40, 47, 93, 150, 222, 301)]
    np.testing.assert_allclose(offsets, offsets[0], rtol=1e-8)
    assert offsets[0] > 0.0
    assert np.all(np.diff(x) >= 0.0)  # never moves backwards


def test_mirror_symmetry():
    ts = np.linspace(0.0, 5 * T, 201)
    mirrored = ReferenceInputs(drive_force=-0.7, excitation_amplitude=5.0, excitation_frequency=F)
    fwd = reference_solution(M, MU, G, [(0.0, PAPER)], ts)
    bwd = reference_solution(M, MU, G, [(0.0, mirrored)], ts)
    assert np.max(np.abs(fwd.x)) > 1e-6
    np.testing.assert_allclose(bwd.x, -fwd.x, rtol=1e-12, atol=1e-20)
    np.testing.assert_allclose(bwd.v, -fwd.v, rtol=1e-12, atol=1e-20)
    assert bwd.event_kinds == fwd.event_kinds
    np.testing.assert_allclose(bwd.event_times, fwd.event_times, rtol=0.0, atol=1e-15)


@pytest.mark.parametrize('drive_force, phase0', [
    (0.4, 0.0),            # phi = 0.4 < 1 - a = 0.5
    (0.5, 0.0),            # phi = 1 - a exactly: mu*R touches |Fd| once per period, no slip
    (0.5, math.pi / 2),    # ... starting at the touching point
])
def test_no_motion_when_phi_at_most_one_minus_a(drive_force, phase0):
    inputs = ReferenceInputs(drive_force=drive_force, excitation_amplitude=5.0,
                             excitation_frequency=F)
    ts = np.linspace(0.0, 100 * T, 1001)
    res = reference_solution(M, MU, G, [(0.0, inputs)], ts, phase0=phase0)
    assert np.all(res.x == 0.0)
    assert np.all(res.v == 0.0)
    assert res.event_kinds == ()


def test_brute_force_agrees_with_reference_mean_velocity():
    n_settle, n_avg = 5, 20
    ts = np.array([n_settle * T, (n_settle + n_avg) * T])
    res = reference_solution(M, MU, G, [(0.0, PAPER)], ts)
    v_ref = (res.x[1] - res.x[0]) / (n_avg * T)
    v_bf = brute_force_mean_velocity(M, MU, G, 0.7, 5.0, F, periods=n_avg,
                                     settle_periods=n_settle)
    assert v_ref > 0.0
    # Only ~1e-3 is required of the crude integrator; it actually reaches ~1e-11 here.
    assert v_bf == pytest.approx(v_ref, rel=1e-6)


# --------------------------------------------------------------------------- schedules


def test_splitting_the_schedule_without_changes_is_invisible():
    # Repeated identical entries, some falling in stick phases, some in slip phases.
    ts = np.linspace(0.0, 4 * T, 161)
    whole = reference_solution(M, MU, G, [(0.0, PAPER)], ts)
    changes = [0.0, 0.3 * T, 0.45 * T, 1.0 * T, 2.3 * T, 2.5 * T]
    split = reference_solution(M, MU, G, [(tc, PAPER) for tc in changes], ts)
    np.testing.assert_allclose(split.x, whole.x, rtol=0.0, atol=1e-15)
    np.testing.assert_allclose(split.v, whole.v, rtol=0.0, atol=1e-13)
    assert split.event_kinds == whole.event_kinds
    np.testing.assert_allclose(split.event_times, whole.event_times, rtol=0.0, atol=1e-14)


def test_frequency_change_keeps_phase_continuous():
    # Change f (and Fd) at t1 during a slip; restarting a fresh run from the state at t1 with
    # phase0 = theta(t1) = 2*pi*F*t1 must reproduce the continuation.
    t1 = 3.4 * T
    later = ReferenceInputs(drive_force=0.8, excitation_amplitude=5.0, excitation_frequency=73.0)
    ts = t1 + np.linspace(0.0, 0.1, 51)
    full = reference_solution(M, MU, G, [(0.0, PAPER), (t1, later)], ts)
    assert full.v[0] != 0.0  # the change happens during a slip phase
    restart = reference_solution(M, MU, G, [(0.0, later)], ts - t1, x0=full.x[0], v0=full.v[0],
                                 phase0=OMEGA * t1)
    np.testing.assert_allclose(restart.x, full.x, rtol=1e-9)
    np.testing.assert_allclose(restart.v, full.v, rtol=1e-7, atol=1e-12)
    assert restart.event_kinds == full.event_kinds[-len(restart.event_kinds):]


# --------------------------------------------------------------------------- edge cases


def test_slip_starting_exactly_on_threshold_at_t0():
    # phase0 = asin(0.6): the slip margin is exactly 0 and rising at t = 0.
    ts = np.linspace(0.0, 3 * T, 121)
    res = reference_solution(M, MU, G, [(0.0, PAPER)], ts, phase0=PAPER_SLIP_PHASE)
    assert res.event_kinds == ('slip_start', 'stick') * 3
    np.testing.assert_allclose(res.event_times[0::2], T * np.arange(3), rtol=0.0, atol=1e-9)
    shifted = reference_solution(M, MU, G, [(0.0, PAPER)], ts + PAPER_SLIP_PHASE / OMEGA)
    np.testing.assert_allclose(res.x, shifted.x, rtol=1e-8, atol=1e-18)


def test_slip_window_narrower_than_the_scan_step_is_found():
    # phi = 1 - a + 2e-6: slip is possible only while sin(theta) > 1 - 4e-6, a phase window of
    # ~5.7e-3 rad, far narrower than the scan step (2*pi/20).  phase0 = 0.1 keeps the peak off
    # the uniform scan grid.
    delta = 2e-6
    inputs = ReferenceInputs(drive_force=0.5 + delta, excitation_amplitude=5.0,
                             excitation_frequency=F)
    phase0 = 0.1
    res = reference_solution(M, MU, G, [(0.0, inputs)], [0.0, 3 * T], phase0=phase0)
    assert res.event_kinds == ('slip_start', 'stick') * 3
    theta_s = math.asin(1.0 - delta / (MU * 5.0))
    expected = (theta_s - phase0 + 2 * math.pi * np.arange(3)) / OMEGA
    np.testing.assert_allclose(res.event_times[0::2], expected, rtol=0.0, atol=1e-9)
    assert res.x[-1] > 0.0


def test_slip_from_rest_that_ends_immediately_terminates():
    # phase0 just before the end of the slip-possible window: a slip of ~1e-14 s, then stick,
    # then the regular cycle.  Must neither loop forever nor produce a zero-length slip.
    phase0 = math.pi - PAPER_SLIP_PHASE - 1e-12
    res = reference_solution(M, MU, G, [(0.0, PAPER)], [0.0, 0.5 * T, 2.5 * T],
                             phase0=phase0)
    assert res.event_kinds[:2] == ('slip_start', 'stick')
    assert 0.0 < res.event_times[1] < 1e-12
    assert abs(res.x[1]) < 1e-20
    assert res.event_kinds[2:] == ('slip_start', 'stick', 'slip_start', 'stick')


def test_sample_order_and_duplicates_are_preserved():
    ts = [0.3, 0.1, 0.2, 0.1]
    res = reference_solution(M, MU, G, [(0.0, PAPER)], ts)
    ref = reference_solution(M, MU, G, [(0.0, PAPER)], sorted(set(ts)))
    assert res.t.tolist() == ts
    lookup = dict(zip(ref.t.tolist(), ref.x.tolist()))
    assert res.x.tolist() == [lookup[t] for t in ts]


@pytest.mark.parametrize('kwargs, field', [
    ({'mass': 0.0}, 'mass'),
    ({'mu': -0.1}, 'mu'),
    ({'gravity': float('nan')}, 'gravity'),
    ({'schedule': [(0.0, ReferenceInputs(excitation_frequency=0.0))]}, 'excitation_frequency'),
    ({'schedule': [(0.0, ReferenceInputs(drive_force=float('inf')))]}, 'drive_force'),
    ({'schedule': [(0.0, ReferenceInputs(excitation_amplitude=10.0))]}, 'excitation_amplitude'),
    ({'schedule': [(0.0, ReferenceInputs(external_force_z=5.0))]}, 'excitation_amplitude'),
    ({'schedule': [(0.0, PAPER), (1.0, ReferenceInputs(external_force_x=float('nan')))]},
     'external_force_x'),
    ({'sample_times': [0.0, float('nan')]}, 'sample_times'),
    ({'x0': float('inf')}, 'x0'),
])
def test_invalid_input_raises_value_error_naming_the_field(kwargs, field):
    args = {'mass': M, 'mu': MU, 'gravity': G, 'schedule': [(0.0, PAPER)],
            'sample_times': [0.0, T]}
    args.update(kwargs)
    with pytest.raises(ValueError, match=field):
        reference_solution(**args)


def test_reference_is_independent_of_the_core_and_imports_scipy_lazily():
    imported = set()
    for module in MODULES:
        for node in ast.walk(ast.parse(module.read_text())):
            if isinstance(node, ast.Import):
                imported.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                imported.add('.' * node.level + (node.module or ''))
                imported.update(alias.name for alias in node.names)
    assert not any('core' in name or 'urelation' in name for name in imported), imported
    names = ', '.join(module.stem for module in MODULES)
    code = (f'import sys, {names}; '
            "sys.exit(int(any(m == 'scipy' or m.startswith('scipy.') for m in sys.modules)))")
    proc = subprocess.run([sys.executable, '-c', code], cwd=MODULE.parent, check=False)
    assert proc.returncode == 0, 'importing the reference must not import scipy'


# --------------------------------------------------------------------------- brief returns to rest


def _dip_case(drive_force: float, theta_up: float, periods: int, depth: float):
    """Forward slip from v0 > 0 whose slip-law velocity dips to -depth at a minimum.

    With constant inputs and phase 0 at t = 0 the forward slip law integrates to
    v = v0 + w(t), x = v0*t + wx(t).  ``s*a`` turns positive at theta = theta_up, the
    minima of v; v0 is chosen so that v is -depth at the minimum after ``periods``
    periods (and positive at every earlier one).  Returns v0, w, wx, t* (first zero
    of v) and t_up (that minimum).
    """
    from scipy.optimize import brentq

    c = (drive_force - MU * M * G) / M

    def w(t):
        return c * t + MU * 5.0 * (1.0 - np.cos(OMEGA * t)) / (M * OMEGA)

    def wx(t):
        return c * t ** 2 / 2 + MU * 5.0 / (M * OMEGA) * (t - np.sin(OMEGA * t) / OMEGA)

    t_up = (theta_up + 2 * math.pi * periods) / OMEGA
    v0 = -w(t_up) - depth
    grid = np.linspace(0.0, t_up, 200_001)
    i = int(np.argmax(v0 + w(grid) <= 0.0))
    assert i > 0
    t_star = brentq(lambda t: v0 + w(t), grid[i - 1], grid[i], xtol=1e-16)
    return v0, w, wx, t_star, t_up


@pytest.mark.parametrize('direction', [1, -1])
@pytest.mark.parametrize('case', ['after_three_periods', 'narrow_acceleration_window'])
def test_velocity_dip_to_zero_within_one_solver_step_sticks(case, direction):
    """A return to rest that the slip law would undo within < 1 solver step is a stick.

    The velocity reaches 0 where |Ft| < mu*R (so the slider sticks) shortly before the
    slip law's velocity minimum and would come back within well under max_step = T/20;
    solve_ivp's event on v = 0 alone (sign change between step ends) steps over it.

    * after_three_periods: a dip ~0.24 ms wide at the 4th minimum; the slip before it
      lasts several periods (several integration sections).
    * narrow_acceleration_window: phi = 1 - a*cos(0.05): s*a > 0 only in a phase window
      of 0.1 rad (~T/63), so both zeros of a fall within one solver step.
    """
    if case == 'after_three_periods':
        fd, theta_up, periods, depth = 0.8, math.asin(0.4), 3, 1e-6
    else:
        fd, theta_up, periods, depth = 1.0 - 0.5 * math.cos(0.05), 0.5 * math.pi - 0.05, 2, 3e-8
    v0, w, wx, t_star, t_up = _dip_case(fd, theta_up, periods, depth)
    inputs = ReferenceInputs(drive_force=direction * fd, excitation_amplitude=5.0,
                             excitation_frequency=F)
    ts = np.linspace(0.0, t_up + 0.1 * T, 1001)
    res = reference_solution(M, MU, G, [(0.0, inputs)], ts, v0=direction * v0)
    # stick at t*; slip resumes (same direction) where the margin turns positive: theta_up
    assert res.event_kinds[:2] == ('stick', 'slip_start'), (res.event_kinds, res.event_times)
    np.testing.assert_allclose(res.event_times[:2], [t_star, t_up], rtol=0.0, atol=1e-9)
    x_star = v0 * t_star + wx(t_star)
    before, stuck = ts < t_star, (ts >= t_star) & (ts <= t_up)
    assert stuck.sum() > 0
    np.testing.assert_allclose(direction * res.v[before], v0 + w(ts[before]), rtol=0.0,
                               atol=1e-9 * v0)
    np.testing.assert_allclose(direction * res.x[before], v0 * ts[before] + wx(ts[before]),
                               rtol=0.0, atol=1e-9 * x_star)
    assert np.all(res.v[stuck] == 0.0)
    np.testing.assert_allclose(direction * res.x[stuck], x_star, rtol=1e-9)
    assert np.all(direction * res.v >= 0.0)
