"""Long runs stay exact (issue 10, item 14).

Event times are anchored to the excitation phase, so their rounding errors do
not add up: a run started anywhere up to t0 = 2e9 s (ROS 2 time ends at
2**31 s) still starts every slip within a few units in the last place (ulp)
of t of its exact time after a million periods, loses no slip, and moves by
exactly the periodic displacement per period.

The expectations are independent of the core: the slip of period n starts at
t0 + (n + theta_A/(2*pi))/f with theta_A = asin((mu*m*g - Fd)/(mu*Pa)), and
the displacement per period D comes from the textbook closed form evaluated
in mpmath (test/reference_exact.py).  The error of a float time t against that
exact value is computed without rounding (t - t0 is exact by Sterbenz's
lemma, f*(t - t0) is split exactly with Dekker's product; see
reference_exact.ulps_from_exact), so an error of a fraction of an ulp is measured
as such.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from friction_sim.core.engine.single import Slider
from friction_sim.core.model.events import EventKind

from reference_exact import paper_case_slip, ulps_from_exact

#: (t0, periods, with period marks): the requirement's run length at the
#: requirement's latest start; shorter runs from the other starts and with the
#: marks (one more object per period) keep the suite quick.  bench/physics.py
#: prints the error after a million periods from each start.
LONG_RUNS = [(2e9, 1_000_000, False), (2e9, 100_000, True), (1e6, 100_000, True), (0.0, 100_000, True)]
CHUNKS = 10
#: "a few ulp": the anchored time is t_a + k/f + (phase - phase_a)/omega,
#: three roundings of at most half an ulp of t each (measured: <= 1 ulp).
MAX_ULPS = 2.0


def run_long(t0: float, periods: int, marks: bool) -> dict[str, NDArray[np.float64]]:
    """``periods`` periods of the paper's case from t0, in big advance_to steps:
    slip starts (t, x, phase), sticks (t) and period marks (t, x, n)."""
    slider = Slider(t0=t0, event_log_size=0, cycle_log_size=periods // CHUNKS + 2 if marks else 0)
    f = slider.inputs.excitation_frequency
    starts: list[tuple[float, float, float]] = []
    sticks: list[float] = []
    kept: list[tuple[float, float, int]] = []
    last_mark = -1
    for chunk in range(1, CHUNKS + 1):
        for event in slider.advance_to(t0 + chunk * (periods // CHUNKS) / f):
            if event.kind is EventKind.SLIP_START:
                starts.append((event.t, event.x, event.phase))
            elif event.kind is EventKind.STICK:
                sticks.append(event.t)
            else:
                raise AssertionError(f"unexpected {event}")
        if marks:
            new = slider.cycle_marks_after(last_mark)
            assert new and new[0].n == last_mark + 1  # the mark log never overflowed
            kept.extend((m.t, m.x, m.n) for m in new)
            last_mark = new[-1].n
    start = np.array(starts)
    mark = np.array(kept).reshape(-1, 3)
    return {"start_t": start[:, 0], "start_x": start[:, 1], "start_phase": start[:, 2],
            "stick_t": np.array(sticks), "mark_t": mark[:, 0], "mark_x": mark[:, 1], "mark_n": mark[:, 2]}


@pytest.fixture(scope="module")
def exact() -> tuple[tuple[float, float], float, float]:
    return paper_case_slip()


@pytest.mark.parametrize(("t0", "periods", "marks"), LONG_RUNS)
def test_long_runs_start_every_slip_within_ulps_and_move_exactly(t0, periods, marks, exact) -> None:
    fraction, theta_a, travel = exact
    run = run_long(t0, periods, marks)
    n = np.arange(periods, dtype=float)

    # No slip lost, none added: one slip start and one stick per period, in order.
    assert run["start_t"].size == periods and run["stick_t"].size == periods
    assert np.all(run["start_t"] < run["stick_t"]) and np.all(run["stick_t"][:-1] <= run["start_t"][1:])
    assert np.all(np.abs(run["start_phase"] - theta_a) <= 4e-16)

    # Every slip starts within a few ulp of t of its exact time, the last as well as the first.
    ulps = ulps_from_exact(run["start_t"], t0, 50.0, n, fraction)
    assert ulps.max() <= MAX_ULPS, (int(ulps.argmax()), float(ulps.max()))
    # Every period starts (phase 2*pi*n) within a few ulp of t0 + n/f.
    assert np.array_equal(run["mark_n"], np.arange(periods + 1) if marks else [])
    if marks:
        mark_ulps = ulps_from_exact(run["mark_t"], t0, 50.0, run["mark_n"], (0.0, 0.0))
        assert mark_ulps.max() <= MAX_ULPS, (int(mark_ulps.argmax()), float(mark_ulps.max()))

    # Displacement per period: x at the n-th slip start is n*D, exact to 1e-12 of
    # the distance for every n (the mean over any run from the start), and each
    # period's step is D to the resolution of a float position there.
    x = run["start_x"]
    assert x[0] == 0.0
    assert np.all(np.abs(x[1:] - n[1:] * travel) <= 1e-12 * n[1:] * travel)
    assert np.all(np.abs(np.diff(x) - travel) <= 2.0 * np.spacing(x[1:]) + 1e-15 * travel)
    assert np.all(np.abs(run["mark_x"] - run["mark_n"] * travel) <= 1e-12 * run["mark_n"] * travel)
    assert math.isclose((x[-1] - x[0]) / (periods - 1), travel, rel_tol=1e-14)


def test_the_ulp_measure_sees_one_ulp() -> None:
    """The error measure itself: a time one ulp off reads as one ulp."""
    t0, f = 2e9, 50.0
    exact_t = np.array([t0 + 1000.0 / f])  # 2e9 + 20 is a float: exact
    assert ulps_from_exact(exact_t, t0, f, np.array([1000.0]), (0.0, 0.0))[0] == 0.0
    off = np.nextafter(exact_t, np.inf)
    assert ulps_from_exact(off, t0, f, np.array([1000.0]), (0.0, 0.0))[0] == pytest.approx(1.0, rel=1e-12)
    small = np.array([0.02 * 3])  # t0 = 0: 3 periods, 0.06 is not exact in binary
    assert ulps_from_exact(small, 0.0, f, np.array([3.0]), (0.0, 0.0))[0] <= 0.5
