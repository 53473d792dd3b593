"""The general core (flight, inclined vibration, slope, static friction) against
the independent solve_ivp reference of test/reference_general.py.

The reference integrates the same model with DOP853 at rtol 1e-13 and finds
its events with solve_ivp's event functions and brentq; it shares no code and
no closed-form reasoning with ``friction_sim.core``.  For random parameter
sets in every regime of issue 11 the core must agree with it to 1e-9:

* event kinds in the same order, event times within 1e-9 of the run's length;
* x at 400 sample times and at every event within 1e-9 of the largest travel
  |x - x0| of the run; z within 1e-9 of the largest height of the run (or of
  the excitation's length scale g/omega^2 when it never flies); v within 1e-9
  of the largest |v|; the mode (stuck, slip direction, flight) the same at
  every sample not within 1e-9 of an event.

The reference's own error is ~1e-13 (its self-checks: the Kostek periodic slip
against the exact U, free flight against the closed form, the one-period flight
at Gamma = sqrt(1 + pi^2) to 1e-15), so a failure here is the core's.  The runs
are short (6-12 periods): in the hopping regimes the landing map may stretch a
difference by a factor per flight, and a few periods keep that stretch far below
the tolerance while still passing every kind of event many times.

The worst agreement reached per regime is printed by the last test
(``pytest -s`` or the captured output) for the closing note of issue 11.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.params import Inputs, SliderParams

import reference_exact
import reference_general as rg
from helpers import time_limit

TOL = 1e-9
SAMPLES = 400
SETS_PER_REGIME = 4
#: The reference's rtol: in the bouncing regimes the landing map stretches its ~rtol error by a
#: few hundred over 6 periods (1e-12 gives landing times 1.4e-12 s from the core's, 1e-13 gives
#: 2e-13 s, 3e-14 gives 1.4e-14 s: it converges onto the core), so 1e-13 keeps a margin.
RTOL = 1e-13
CORE_SECONDS = 5.0  # the core needs milliseconds for these runs
WORST: dict[str, dict[str, float]] = {}


def core_floor() -> float | None:
    """The core's documented plastic-landing floor [m/s] for these params (None: the reference's default)."""
    return None


@dataclass
class Case:
    params: SliderParams
    inputs: Inputs
    periods: int
    phase0: float


def kind_name(kind: Any) -> str:
    return str(getattr(kind, "value", kind))


def compare(case: Case) -> tuple[dict[str, float], rg.GeneralResult, list[Any]]:
    """Run core and reference on one case; return the relative disagreements."""
    f = case.inputs.excitation_frequency
    t_end = case.periods / f
    times = np.linspace(0.0, t_end, SAMPLES + 1)
    slider = Slider(case.params, case.inputs, phase0=case.phase0, event_log_size=None)
    with time_limit(CORE_SECONDS, f"the core on {case}"):
        trajectory = slider.sample(times)
    core_events = list(trajectory.events)
    model = rg.GeneralModel.from_core(case.params, case.inputs, plastic_speed=core_floor())
    ref = rg.solve(model, t_end, phase0=case.phase0, rtol=RTOL)
    expected = ref.evaluate(times)

    empty = [(a, b) for a, b in itertools.pairwise(core_events)
             if kind_name(a.kind) == "lift_off" and kind_name(b.kind) == "landing" and b.t == a.t]
    assert not empty, f"the core flies for no time (lift_off, then a landing at the same instant): {empty[0]} in {case}"
    core_kinds = [(kind_name(e.kind), int(e.before), int(e.after)) for e in core_events]
    ref_kinds = [(e.kind, e.before, e.after) for e in ref.events]
    if core_kinds != ref_kinds:
        first = next((i for i, (a, b) in enumerate(zip(core_kinds, ref_kinds)) if a != b),
                     min(len(core_kinds), len(ref_kinds)))
        lo = max(0, first - 2)
        raise AssertionError(
            f"event sequences differ at #{first} ({len(core_kinds)} core, {len(ref_kinds)} reference) for {case}:\n"
            f"  core: {core_events[lo:first + 3]}\n  ref:  {ref.events[lo:first + 3]}")
    travel = max(float(np.max(np.abs(expected["x"] - expected["x"][0]))), 1e-300)
    omega = 2.0 * math.pi * f
    height = max(float(np.max(expected["z"])), case.params.gravity / omega**2)
    speed = max(float(np.max(np.abs(expected["v"]))), 1e-300)
    t_core = np.array([e.t for e in core_events])
    t_ref = np.array([e.t for e in ref.events])
    x_core = np.array([e.x for e in core_events])
    x_ref = np.array([e.x for e in ref.events])
    near_event = np.zeros(times.shape, dtype=bool)
    for t in t_ref:
        near_event |= np.abs(times - t) <= TOL * t_end
    wrong_mode = (trajectory.mode.astype(int) != expected["mode"].astype(int)) & ~near_event
    assert not wrong_mode.any(), f"modes differ at t = {times[wrong_mode][:3]} for {case}"
    errors = {
        "t": float(np.max(np.abs(t_core - t_ref), initial=0.0)) / t_end,
        "x": max(float(np.max(np.abs(trajectory.x - expected["x"]))),
                 float(np.max(np.abs(x_core - x_ref), initial=0.0))) / travel,
        "z": float(np.max(np.abs(trajectory.z - expected["z"]))) / height,
        "v": float(np.max(np.abs(trajectory.v - expected["v"]))) / speed,
    }
    return errors, ref, core_events


# ---------------------------------------------------------------------------- the reference itself


def speed_scale(ref: rg.GeneralResult) -> float:
    """The largest |v| and |vz| of a reference run (sampled finely; the tolerances below
    take it as the speed scale of GeneralResult.position_error)."""
    fine = ref.evaluate(np.linspace(0.0, ref.t_final, 2001))
    return float(max(np.max(np.abs(fine["v"])), np.max(np.abs(fine["vz"]))))


def test_reference_reproduces_kostek_closed_form() -> None:
    """Kostek's periodic slip: slip starts at (n + theta_A/(2 pi))/f, n*D apart (mpmath).
    Tolerances: a slip start is a brentq root of a closed-form function of time (xtol
    4 eps), so its time is good to a few ulp of t (1e-12 relative is far outside that);
    x is integrated, so it is good to the reference's own error bound."""
    (fraction_hi, fraction_lo), _, travel = reference_exact.paper_case_slip(1.0, 0.1, 10.0, 0.7, 5.0, 50.0)
    ref = rg.solve(rg.GeneralModel(), 12 / 50.0)
    starts = [e for e in ref.events if e.kind == "slip_start"]
    assert len(starts) == 12
    x_error = ref.position_error(travel, speed_scale(ref))  # each slip is one section, from zero displacement
    for n, event in enumerate(starts):
        assert event.t == pytest.approx((n + fraction_hi + fraction_lo) / 50.0, rel=1e-12)
        assert abs(event.x - n * travel) <= x_error


def test_reference_reproduces_closed_form_flight() -> None:
    """Free flight from lift-off at sin(theta0) = 1/Gamma with a tilted vibration:
    z and x are polynomials plus sinusoids in closed form; the one-period flight
    at Gamma = sqrt(1 + pi^2).  The tolerances are the reference's own error bound
    (GeneralResult.position_error: rtol 1e-12 per step, added up over its steps): the
    actual error depends on the CPU (OpenBLAS's kernels inside the DOP853 steps: 4e-13
    of the height with Haswell's, 3e-12 with SkylakeX's), the bound does not."""
    g, f, gamma, beta = 10.0, 50.0, 2.0, 30.0
    omega = 2 * math.pi * f
    eps = float(np.finfo(float).eps)
    model = rg.GeneralModel(mu=0.3, drive_force=0.2, excitation_amplitude=gamma * g, excitation_angle=beta,
                            landing_friction="none")
    ref = rg.solve(model, 1.5 / f)
    lift = next(e for e in ref.events if e.kind == "lift_off")
    land = next(e for e in ref.events if e.kind == "landing")
    theta0 = math.asin(1 / gamma)
    assert lift.t == pytest.approx(theta0 / omega, rel=1e-14)  # a brentq root of -R(t), closed form: a few ulp
    pt = gamma * g / math.tan(math.radians(beta))

    def z(t: float) -> float:
        tau = t - lift.t
        return -g * tau**2 / 2 + gamma * g * (math.cos(theta0) * tau / omega - (math.sin(omega * t) - math.sin(theta0))
                                              / omega**2)

    def x(t: float) -> float:
        tau = t - lift.t
        return (lift.x + lift.v_after * tau + 0.2 * tau**2 / 2
                + pt * (math.cos(theta0) * tau / omega - (math.sin(omega * t) - math.sin(theta0)) / omega**2))

    times = np.linspace(lift.t, land.t, 9)[1:-1]
    got = ref.evaluate(times)
    fine = ref.evaluate(np.linspace(0.0, ref.t_final, 2001))
    speed = speed_scale(ref)
    z_error = ref.position_error(float(np.max(fine["z"])), speed)
    x_error = ref.position_error(float(np.ptp(fine["x"])), speed)
    assert np.max(np.abs(got["z"] - [z(t) for t in times])) <= z_error
    assert np.max(np.abs(got["x"] - [x(t) for t in times])) <= x_error
    # the reference lands where its own z is 0 (brentq, 4 eps of t): the closed form is off by its error
    assert abs(z(land.t)) <= z_error + abs(land.vz_before) * 4 * eps * land.t
    one_period = rg.GeneralModel(mu=0.5, drive_force=0.0, excitation_amplitude=math.sqrt(1 + math.pi**2) * g)
    one = rg.solve(one_period, 3.5 / f)
    lifts, lands = one.times("lift_off"), one.times("landing")
    assert len(lands) == 3
    # a landing time errs by the height's error over the landing speed (plus brentq's 4 eps of t)
    fine = one.evaluate(np.linspace(0.0, one.t_final, 2001))
    landing_speed = min(abs(e.vz_before) for e in one.events if e.kind == "landing")
    t_error = one.position_error(float(np.max(fine["z"])), speed_scale(one)) / landing_speed + 8 * eps * one.t_final
    assert np.max(np.abs((lands - lifts[:3]) * f - 1.0)) <= t_error * f


def test_lift_off_from_a_slip_where_the_lift_form_rounds_to_zero() -> None:
    """A forward slip reaches R = 0 at a phase where -R evaluates to exactly 0:
    the flight must start (z'' >= 0) and last, not land at once and lift off
    again at the same instant forever (found by the mu_s > mu draws)."""
    params = SliderParams(mass=1.675030771495811, mu=0.40569079335967395, gravity=9.81,
                          static_ratio=1.8507494692753383, excitation_angle=65.26727941280993)
    inputs = Inputs(drive_force=4.990077334523417, excitation_amplitude=27.937905632542694,
                    excitation_frequency=35.51159675345847)
    case = Case(params, inputs, 3, 4.2261313825147795)
    errors, ref, _core_events = compare(case)
    lift = next(e for e in ref.events if e.kind == "lift_off")
    assert lift.before == rg.FORWARD and lift.t == pytest.approx(0.012037326723928899, rel=1e-14)
    assert max(errors.values()) <= TOL, errors


# ---------------------------------------------------------------------------- regimes
# Each draws (params, inputs, periods, phase0) and names a property of the
# reference run that proves the draw is in its regime.


def draw_stick_slip(rng: np.random.Generator) -> Case:
    """a < 1 (never leaves the track); tilted vibration and/or slope and/or mu_s > mu."""
    variant = rng.integers(3)
    beta = float(rng.uniform(25.0, 85.0)) if variant != 1 else 90.0
    alpha = float(rng.uniform(-8.0, 8.0)) if variant != 0 else 0.0
    ratio = float(rng.uniform(1.05, 2.0)) if variant != 2 else 1.0
    mu = float(rng.uniform(0.2, 0.6))
    params = SliderParams(mass=float(rng.uniform(0.5, 2.0)), mu=mu, gravity=9.81, static_ratio=ratio,
                          excitation_angle=beta, excitation_phase=float(rng.uniform(-90.0, 90.0)),
                          track_inclination=alpha)
    gamma = float(rng.uniform(0.3, 0.9))
    amplitude = gamma * params.normal_weight
    drive = float(rng.uniform(0.3, 0.9)) * mu * params.normal_weight + params.downhill_weight
    if beta == 90.0:
        drive = float(rng.uniform(0.6, 0.98)) * mu * params.normal_weight + params.downhill_weight
    inputs = Inputs(drive_force=drive, excitation_amplitude=amplitude, excitation_frequency=float(rng.uniform(20, 80)))
    return Case(params, inputs, 10, float(rng.uniform(0.0, 2.0 * math.pi)))


def draw_hopping(rng: np.random.Generator) -> Case:
    """Gamma in [1.5, 3], beta in [20, 60] deg, plastic landings: one flight per period."""
    mu = float(rng.uniform(0.2, 0.8))
    params = SliderParams(mass=float(rng.uniform(0.5, 2.0)), mu=mu, gravity=9.81,
                          static_ratio=float(rng.choice([1.0, rng.uniform(1.0, 1.5)])),
                          excitation_angle=float(rng.uniform(20.0, 60.0)),
                          track_inclination=float(rng.uniform(-3.0, 3.0)))
    inputs = Inputs(drive_force=float(rng.uniform(-0.2, 0.2)) * mu * params.normal_weight,
                    excitation_amplitude=float(rng.uniform(1.5, 3.0)) * params.normal_weight,
                    excitation_frequency=float(rng.uniform(20, 80)))
    return Case(params, inputs, 10, float(rng.uniform(0.0, 2.0 * math.pi)))


def draw_multi_period(rng: np.random.Generator) -> Case:
    """Gamma in [3.5, 5], e = 0: flights longer than a period."""
    mu = float(rng.uniform(0.2, 0.8))
    params = SliderParams(mass=float(rng.uniform(0.5, 2.0)), mu=mu, gravity=9.81,
                          excitation_angle=float(rng.uniform(20.0, 90.0)),
                          landing_friction=str(rng.choice(["impulsive", "none"])))
    inputs = Inputs(drive_force=float(rng.uniform(-0.2, 0.2)) * mu * params.normal_weight,
                    excitation_amplitude=float(rng.uniform(3.5, 5.0)) * params.normal_weight,
                    excitation_frequency=float(rng.uniform(20, 80)))
    return Case(params, inputs, 12, 0.0)


def draw_backward(rng: np.random.Generator) -> Case:
    """A slope (alpha in [8, 20] deg) and a weak drive: the slider slips back downhill."""
    alpha = float(rng.uniform(8.0, 20.0))
    mu = math.tan(math.radians(alpha)) * float(rng.uniform(1.05, 1.6))
    params = SliderParams(mass=float(rng.uniform(0.5, 2.0)), mu=mu, gravity=9.81,
                          static_ratio=float(rng.uniform(1.0, 1.3)),
                          excitation_angle=float(rng.uniform(30.0, 90.0)), track_inclination=alpha)
    inputs = Inputs(drive_force=float(rng.uniform(0.0, 0.1)) * params.downhill_weight,
                    excitation_amplitude=float(rng.uniform(0.5, 0.95)) * params.normal_weight,
                    excitation_frequency=float(rng.uniform(20, 80)))
    return Case(params, inputs, 10, float(rng.uniform(0.0, 2.0 * math.pi)))


def draw_static(rng: np.random.Generator) -> Case:
    """mu_s > mu (static_ratio in [1.2, 3]), stick-slip or hopping."""
    mu = float(rng.uniform(0.1, 0.5))
    params = SliderParams(mass=float(rng.uniform(0.5, 2.0)), mu=mu, gravity=9.81,
                          static_ratio=float(rng.uniform(1.2, 3.0)),
                          excitation_angle=float(rng.uniform(30.0, 90.0)))
    inputs = Inputs(drive_force=float(rng.uniform(0.5, 1.5)) * mu * params.weight,
                    excitation_amplitude=float(rng.uniform(0.5, 2.0)) * params.weight,
                    excitation_frequency=float(rng.uniform(20, 80)))
    return Case(params, inputs, 10, float(rng.uniform(0.0, 2.0 * math.pi)))


def draw_restitution(rng: np.random.Generator, landing_friction: str) -> Case:
    """e in [0.2, 0.7], Gamma in [1.5, 3]: bounces."""
    mu = float(rng.uniform(0.2, 0.6))
    params = SliderParams(mass=float(rng.uniform(0.5, 2.0)), mu=mu, gravity=9.81,
                          excitation_angle=float(rng.uniform(20.0, 70.0)),
                          restitution=float(rng.uniform(0.2, 0.7)), landing_friction=landing_friction)
    inputs = Inputs(drive_force=float(rng.uniform(-0.1, 0.1)) * mu * params.weight,
                    excitation_amplitude=float(rng.uniform(1.5, 3.0)) * params.weight,
                    excitation_frequency=float(rng.uniform(20, 80)))
    return Case(params, inputs, 6, 0.0)


def in_stick_slip(ref: rg.GeneralResult, case: Case) -> bool:
    counts = ref.counts()
    return counts.get("lift_off", 0) == 0 and counts.get("slip_start", 0) >= 2


def in_hopping(ref: rg.GeneralResult, case: Case) -> bool:
    return ref.counts().get("landing", 0) >= case.periods - 2


def in_multi_period(ref: rg.GeneralResult, case: Case) -> bool:
    lifts = ref.times("lift_off")
    lands = ref.times("landing")
    period = 1.0 / case.inputs.excitation_frequency
    return any(land - max(lifts[lifts < land], default=land) > period for land in lands)


def in_backward(ref: rg.GeneralResult, case: Case) -> bool:
    return any(e.after == rg.BACKWARD for e in ref.events)


def in_static(ref: rg.GeneralResult, case: Case) -> bool:
    return ref.counts().get("slip_start", 0) >= 2


def in_restitution(ref: rg.GeneralResult, case: Case) -> bool:
    return sum(1 for e in ref.events if e.kind == "landing" and e.vz_after > 0.0) >= 2


REGIMES: dict[str, tuple[Callable[[np.random.Generator], Case], Callable[[rg.GeneralResult, Case], bool]]] = {
    "stick-slip only (a < 1, tilted/sloped/mu_s)": (draw_stick_slip, in_stick_slip),
    "hopping every period (Gamma 1.5-3)": (draw_hopping, in_hopping),
    "multi-period flights (Gamma 3.5-5, e = 0)": (draw_multi_period, in_multi_period),
    "backward slips on a slope": (draw_backward, in_backward),
    "mu_s > mu": (draw_static, in_static),
    "restitution e > 0, impulsive": (lambda rng: draw_restitution(rng, "impulsive"), in_restitution),
    "restitution e > 0, none": (lambda rng: draw_restitution(rng, "none"), in_restitution),
}


@pytest.mark.parametrize("regime", list(REGIMES))
def test_core_agrees_with_reference(regime: str) -> None:
    draw, realised = REGIMES[regime]
    rng = np.random.default_rng(11 + list(REGIMES).index(regime))
    worst = {"t": 0.0, "x": 0.0, "z": 0.0, "v": 0.0}
    done = tries = 0
    while done < SETS_PER_REGIME:
        tries += 1
        assert tries <= 6 * SETS_PER_REGIME, f"the draws of {regime!r} rarely reach the regime"
        case = draw(rng)
        errors, ref, _ = compare(case)
        if not realised(ref, case):
            continue
        done += 1
        for key, value in errors.items():
            worst[key] = max(worst[key], value)
        assert max(errors.values()) <= TOL, (regime, case, errors)
    WORST[regime] = worst


def test_report_worst_agreement(capsys: pytest.CaptureFixture[str]) -> None:
    """Print the worst agreement per regime (for the closing note)."""
    with capsys.disabled():
        if not WORST:
            print("\n(no regime test ran in this session: nothing to report)")
            return
        print("\nworst core/reference agreement per regime (relative: t to run length, x to travel, "
              "z to height, v to max|v|):")
        for regime, worst in WORST.items():
            print(f"  {regime:48s} t {worst['t']:.1e}  x {worst['x']:.1e}  z {worst['z']:.1e}  v {worst['v']:.1e}")
