"""One integrated section of the test references: DOP853 up to a terminal event.

``integrate`` does what ``solve_ivp(rhs, (t0, t1), y0, method="DOP853",
dense_output=True, events=[event])`` does for one terminal event, with SciPy's
own DOP853 stepper, its dense output and the same root search (brentq on the
step's dense output to 4 eps).  The step loop is written out because SciPy
before 1.12 (Ubuntu 24.04 has 1.11.4) fails when the event's root falls exactly
on the previous step's end: it keeps that time twice and OdeSolution refuses
the repeat ("`ts` must be strictly increasing").  Here such a root ends the
section at that step end, as newer SciPy does.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Section:
    """The result: status (-1 failed, 0 reached t1, 1 stopped at the event), where it
    ended and the state there, the dense output over it (a scipy OdeSolution; None if the
    first step failed), the event's time (None: no event) and the number of steps taken
    (each keeps its local error estimate within atol + rtol*|y|: a bound of the global
    error of a run is that times its number of steps, see GeneralResult.error_bound)."""

    status: int
    message: str
    t_end: float
    y_end: Any
    dense: Any
    event_t: float | None
    steps: int


def integrate(rhs: Callable[[float, Any], Any], t0: float, t1: float, y0: Any,
              event: Callable[[float, Any], float], *, rtol: float, atol: Any, max_step: float) -> Section:
    """Integrate from t0 towards t1, stopping at the first root of ``event`` crossed in
    its ``direction`` attribute (0 or absent: either way), as solve_ivp's terminal events."""
    from scipy.integrate import DOP853, OdeSolution
    from scipy.optimize import brentq

    eps = float(np.finfo(float).eps)
    start = np.asarray(y0, dtype=float)
    solver = DOP853(rhs, t0, start, t1, rtol=rtol, atol=atol, max_step=max_step)
    direction = float(getattr(event, "direction", 0.0))
    ts: list[float] = [t0]
    pieces: list[Any] = []
    g = event(t0, start)
    while solver.status == "running":
        message = solver.step()
        if solver.status == "failed":
            dense = OdeSolution(ts, pieces) if pieces else None
            return Section(-1, str(message), ts[-1], dense(ts[-1]) if dense else start, dense, None, len(pieces))
        dense_step = solver.dense_output()
        g_new = event(solver.t, solver.y)
        up, down = g <= 0.0 <= g_new, g >= 0.0 >= g_new
        if (up and direction >= 0.0) or (down and direction <= 0.0):
            root = float(brentq(lambda u, dense=dense_step: event(u, dense(u)), solver.t_old, solver.t,
                                xtol=4.0 * eps, rtol=4.0 * eps))
            if root > ts[-1] or not pieces:  # (a root at t0 itself: a zero-length section, as solve_ivp's)
                ts.append(root)
                pieces.append(dense_step)
            return Section(1, "a termination event occurred", root, dense_step(root), OdeSolution(ts, pieces), root,
                           len(pieces))
        g = g_new
        ts.append(solver.t)
        pieces.append(dense_step)
    return Section(0, "the end of the interval was reached", ts[-1], solver.y, OdeSolution(ts, pieces), None,
                   len(pieces))
