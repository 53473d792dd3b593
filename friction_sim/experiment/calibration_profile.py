"""Profile-likelihood intervals: honest where the linearized ones are not.

The linearized interval, estimate +- quantile x standard error, assumes the
cost is a paraboloid in the parameters.  Two parameters that correlate
strongly and nonlinearly (mu and mu_s/mu over stick-slip points, -0.9 to
-0.97) bend its valley, and the linearized intervals of both then covered the
truth in about 70 % of seeds, not 95 %.

The profile of parameter i is the cost with the others re-fitted,
P_i(theta) = min over the others of the cost, and its 95 % interval the
thetas where P_i rises above the minimum by no more than the rise 95 %
confidence allows: chi2_1(0.95)/2 with known deviations (a ``std`` column),
else the F form, t(0.975, n - p)^2 times the residual variance over 2.  In
terms of the signed root

    r(theta) = sign(theta - estimate) sqrt(2 (P_i(theta) - P_min) / variance)

(variance 1 with known deviations, else the residual variance 2 P_min/(n - p)),
the ends are where r = -q and r = +q, q = z(0.975) or t(0.975, n - p): the
linearized interval is the same rule with r taken as linear.  An end that
reaches the parameter's bound before r does is that bound, flagged open.

Every end of every parameter is searched at once, 2p problems: each
re-fit of the others is a few Levenberg-Marquardt steps (iteratively
reweighted for a robust loss), and each step evaluates the residuals and
the finite-difference Jacobian of every problem in one call of the model
(one population-engine run).  The ends are found by regula falsi on r from
the linearized ends (r is nearly linear in theta: two or three steps).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from friction_sim.experiment.calibration_fit import Floats, Problem, correlation_of, step_sizes

#: An end is found when |r| is within this of q (an interval end to a thousandth of a standard error).
ROOT_TOLERANCE = 1e-3
#: A re-fit of the others ends when a step lowers the cost by less than this times the variance
#: (r, near q, then moves by less than 1e-5 / q).
REFIT_TOLERANCE = 1e-5
#: Steps of the search for each end, and of each re-fit of the other parameters.
END_STEPS, REFIT_STEPS = 40, 40
#: A search that has not crossed q yet grows its step at most this much at a time.
MAX_GROWTH = 10.0
#: The first step of a search: at least this much of max(1, |estimate|) (a linearized standard
#: error at a kink of the model, or at a bound, can be a rounding error).
FIRST_STEP = 1e-6
#: How far the others' warm start moves along the linearized valley, at most (relative to max(1, |value|)).
MAX_SHIFT = 0.1


@dataclass(frozen=True)
class Profile:
    """One parameter's profile: the ``values`` tried (ascending), the signed root
    ``root`` there, and the interval [low, high] (an end flagged open when it is
    the parameter's bound, where r is still below q)."""

    name: str
    values: Floats
    root: Floats
    low: float
    high: float
    open_low: bool
    open_high: bool


def loss_cost(residuals: Floats, loss: str, f_scale: float) -> Floats:
    """SciPy's cost of each row of residuals: 0.5 C^2 sum rho((r/C)^2)."""
    z = (np.asarray(residuals) / f_scale) ** 2
    if loss == "soft_l1":
        rho = 2.0 * (np.sqrt(1.0 + z) - 1.0)
    elif loss == "huber":
        rho = np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0)
    else:
        rho = z
    return np.asarray(0.5 * f_scale**2 * np.sum(rho, axis=-1))


def _weights(residuals: Floats, loss: str, f_scale: float) -> Floats:
    """rho'((r/C)^2): the weights of the iteratively reweighted Gauss-Newton step."""
    z = (residuals / f_scale) ** 2
    if loss == "soft_l1":
        return np.asarray(1.0 / np.sqrt(1.0 + z))
    if loss == "huber":
        return np.asarray(np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0))))
    return np.ones_like(residuals)


class _Refits:
    """Re-fits of the other parameters with one held, for many problems at once."""

    def __init__(self, problem: Problem, loss: str, f_scale: float) -> None:
        self.problem, self.loss, self.f_scale = problem, loss, f_scale
        self.low, self.high = problem.bounds
        self.p = len(problem.names)

    def evaluate(self, xs: Floats, held: np.ndarray) -> tuple[Floats, Floats, Floats]:
        """Residuals, cost and the Jacobian over the free parameters of each row
        of ``xs`` (row k holds parameter ``held[k]``), in one call of the model."""
        k, p = xs.shape
        free = [np.array([j for j in range(p) if j != i]) for i in held]
        rows = [xs]
        steps = np.zeros((k, max(p - 1, 0)))
        for c in range(p - 1):
            columns = np.array([f[c] for f in free])
            step = step_sizes(xs[np.arange(k), columns], self.low[columns], self.high[columns])
            shifted = xs.copy()
            shifted[np.arange(k), columns] += step
            steps[:, c] = step
            rows.append(shifted)
        values = np.asarray(self.problem.residuals(np.vstack(rows)), dtype=float).reshape(p, k, -1) if p > 1 else \
            np.asarray(self.problem.residuals(xs), dtype=float)[None]
        residuals = values[0]
        jacobian = np.stack([(values[1 + c] - residuals) / steps[:, c:c + 1] for c in range(p - 1)], axis=-1) \
            if p > 1 else np.zeros(residuals.shape + (0,))
        return residuals, loss_cost(residuals, self.loss, self.f_scale), jacobian

    def minimize(self, xs: Floats, held: np.ndarray, tolerance: float) -> tuple[Floats, Floats]:
        """The rows of ``xs`` with their free parameters re-fitted (Levenberg-Marquardt,
        bounded by clipping) until a step gains less than ``tolerance``, and the cost there."""
        xs = np.array(xs, dtype=float)
        residuals, cost, jacobian = self.evaluate(xs, held)
        if self.p == 1:
            return xs, cost
        k = xs.shape[0]
        free = np.array([[j for j in range(self.p) if j != i] for i in held])
        damping = np.full(k, 1e-3)
        active = np.ones(k, dtype=bool)
        for _ in range(REFIT_STEPS):
            if not np.any(active):
                break
            rows = np.nonzero(active)[0]
            trial = xs[rows].copy()
            for n, row in enumerate(rows):
                w = _weights(residuals[row], self.loss, self.f_scale)
                jw = jacobian[row] * w[:, None]
                normal = jacobian[row].T @ jw
                gradient = jw.T @ residuals[row]
                scale = np.maximum(np.diag(normal), 1e-300)
                try:
                    step = np.linalg.solve(normal + damping[row] * np.diag(scale), -gradient)
                except np.linalg.LinAlgError:
                    step = np.zeros(self.p - 1)
                columns = free[row]
                trial[n, columns] = np.clip(trial[n, columns] + step, self.low[columns], self.high[columns])
            t_residuals, t_cost, t_jacobian = self.evaluate(trial, held[rows])
            for n, row in enumerate(rows):
                if np.isfinite(t_cost[n]) and t_cost[n] <= cost[row]:
                    gain = cost[row] - t_cost[n]
                    xs[row], residuals[row], jacobian[row] = trial[n], t_residuals[n], t_jacobian[n]
                    cost[row] = t_cost[n]
                    damping[row] = max(damping[row] / 3.0, 1e-12)
                    if gain <= tolerance:
                        active[row] = False
                else:
                    damping[row] *= 4.0
                    if damping[row] > 1e12:
                        active[row] = False
        return xs, cost


def profiles(problem: Problem, estimate: Floats, cost_min: float, covariance: Floats, variance: float, q: float,
             loss: str = "linear", f_scale: float = 1.0) -> tuple[Profile, ...]:
    """Every parameter's profile and interval (see the module doc): ``estimate``
    the optimum, of cost ``cost_min``; ``covariance`` the linearized one (its
    intervals start the search); ``variance`` 1 or the residual variance; ``q``
    the quantile."""
    p = len(problem.names)
    if not variance > 0.0:  # an exact fit without deviations: no scatter, the intervals are the estimate
        return tuple(Profile(name, np.array([float(x)]), np.zeros(1), float(x), float(x), False, False)
                     for name, x in zip(problem.names, estimate))
    low, high = problem.bounds
    refits = _Refits(problem, loss, f_scale)
    errors = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    sides = [(i, s) for i in range(p) for s in (-1.0, 1.0)]
    held = np.array([i for i, _ in sides])
    sign = np.array([s for _, s in sides])
    bound = np.array([low[i] if s < 0 else high[i] for i, s in sides])
    tried: list[list[tuple[float, float]]] = [[(float(estimate[i]), 0.0)] for i in range(p)]
    # Each side's bracket of the crossing of r = q, as f = r - q: inside (f < 0, from the estimate,
    # f = -q) and outside (f > 0, NaN until found); ``last`` the side replaced last (Illinois' rule).
    inside = np.array([estimate[i] for i in held], dtype=float)
    f_inside = np.full(len(sides), -q)
    outside = np.full(len(sides), math.nan)
    f_outside = np.full(len(sides), math.nan)
    last = np.zeros(len(sides))
    warm = np.array([estimate] * len(sides))  # the others' values at the point inside: warm starts
    slope = np.array([covariance[:, i] / covariance[i, i] if covariance[i, i] > 0 else np.zeros(p) for i in held])
    theta = np.array([estimate[i] + s * max(q * errors[i], FIRST_STEP * max(1.0, abs(estimate[i])))
                      for i, s in sides])
    found = np.full(len(sides), math.nan)
    opened = np.zeros(len(sides), dtype=bool)
    for _ in range(END_STEPS):
        theta = np.where(sign < 0, np.maximum(theta, bound), np.minimum(theta, bound))
        rows = np.nonzero(np.isnan(found))[0]
        if rows.size == 0:
            break
        starts = warm[rows].copy()
        for n, row in enumerate(rows):
            i = held[row]
            limit = MAX_SHIFT * np.maximum(1.0, np.abs(starts[n]))
            starts[n] = np.clip(starts[n] + np.clip(slope[row] * (theta[row] - starts[n, i]), -limit, limit), low, high)
            starts[n, i] = theta[row]
        fitted, cost = refits.minimize(starts, held[rows], REFIT_TOLERANCE * variance)
        for n, row in enumerate(rows):
            i, t = held[row], float(theta[row])
            rise = max(float(cost[n]) - cost_min, 0.0) if np.isfinite(cost[n]) else math.inf
            r = math.sqrt(2.0 * rise / variance)
            tried[i].append((t, float(sign[row]) * r))
            f = r - q
            if abs(f) <= ROOT_TOLERANCE * q:
                found[row] = t
            elif f < 0.0 and t == bound[row]:
                found[row], opened[row] = t, True
            elif f < 0.0:
                if t != inside[row]:  # the valley's direction as found, for the next warm start
                    slope[row] = (fitted[n] - warm[row]) / (t - inside[row])
                inside[row], f_inside[row], warm[row] = t, f, fitted[n]
                f_outside[row] *= 0.5 if last[row] < 0 else 1.0
                last[row] = -1.0
            else:
                outside[row], f_outside[row] = t, f
                f_inside[row] *= 0.5 if last[row] > 0 else 1.0
                last[row] = 1.0
            if not np.isnan(found[row]):
                continue
            a, b, fa, fb = inside[row], outside[row], f_inside[row], f_outside[row]
            if math.isnan(b):  # not crossed yet: step out as if r were linear in theta, at most 4x
                growth = MAX_GROWTH if r <= 0.0 else min(max(q / r * 1.02, 1.001), MAX_GROWTH)
                theta[row] = estimate[i] + (a - estimate[i]) * growth
            elif abs(b - a) <= 1e-12 * max(1.0, abs(a)):
                found[row] = a
            elif math.isfinite(fb):
                theta[row] = b - fb * (b - a) / (fb - fa)
            else:
                theta[row] = 0.5 * (a + b)
    found = np.where(np.isnan(found), inside, found)
    result = []
    for i, name in enumerate(problem.names):
        points = sorted(set(tried[i]))
        lo_row, hi_row = 2 * i, 2 * i + 1
        result.append(Profile(name, np.array([v for v, _ in points]), np.array([r for _, r in points]),
                              float(found[lo_row]), float(found[hi_row]), bool(opened[lo_row]),
                              bool(opened[hi_row])))
    return tuple(result)


def chord_correlation(problem: Problem, estimate: Floats, profiled: tuple[Profile, ...], q: float) -> Floats:
    """The fitted parameters' correlation from chords across each one's profile
    interval (its half-width over q either side of the estimate, within the
    bounds; at least FIRST_STEP relative): the correlation over the region the
    data allow, which a kink of the model at the estimate (a regime boundary of
    one point, the switch to Kostek's closed forms at mu_s/mu = 1) does not
    upset as it upsets the tangent Jacobian there."""
    low, high = problem.bounds
    p = len(problem.names)
    rows = []
    for i, profile in enumerate(profiled):
        step = max((profile.high - profile.low) / (2.0 * q), FIRST_STEP * max(1.0, abs(float(estimate[i]))))
        for sign in (1.0, -1.0):
            x = np.array(estimate, dtype=float)
            x[i] = min(max(x[i] + sign * step, low[i]), high[i])
            rows.append(x)
    xs = np.array(rows)
    values = np.asarray(problem.residuals(xs), dtype=float)
    jacobian = np.stack([(values[2 * i] - values[2 * i + 1]) / (xs[2 * i, i] - xs[2 * i + 1, i]) for i in range(p)],
                        axis=-1)
    return correlation_of(np.linalg.pinv(jacobian.T @ jacobian))


__all__ = ["Profile", "chord_correlation", "loss_cost", "profiles"]
