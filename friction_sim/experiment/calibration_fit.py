"""What every calibration fit shares (operating points, recordings, frequency sweeps).

A fit is a :class:`Problem`: named plant parameters, their bounds from
``spec.py``, and a function from *rows* of parameter vectors to rows of
residuals (each in units of its deviation), so that a model that can evaluate
many parameter sets at once (the population engine) is asked once for all of
them: the finite-difference Jacobian's columns, the draws of a start, the
points of a profile.

* **Starting points.** The user's (``--start mu=0.2,static_ratio=1.3``,
  taken as given), then the reference (the settings given, else the
  defaults) if the problem admits it, then points drawn (seeded) across the
  bounds: log-uniform within a decade either side of the reference for a
  positive parameter whose range spans a decade or more, uniform otherwise,
  and kept only where the problem admits them (the operating points: where
  the part moves and does not run away, :mod:`~friction_sim.experiment.calibration_points`).
  A model that evaluates many parameter sets at once screens a few hundred
  such draws in one call and starts from the lowest in cost: the speed is
  not monotone in restitution or the vibration angle, and a local fit from
  a draw in another valley ends there.
* **Each start's outcome.** A start that ends where no residual changes
  with any parameter is *flat* and reported as such ("start 2 of 4: no point
  moves at mu = 1.1"); a parameter is called not identifiable only when
  every start that moved agrees that it changes nothing.
* **The linearized uncertainty** at the optimum: (J^T J)^-1 times the
  residual variance (1 when the deviations are known), the standard errors,
  the intervals estimate +- quantile x standard error and the correlation.

SciPy is called in :mod:`~friction_sim.experiment.calibration` only (the
least squares and the quantiles); this module is numpy.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from friction_sim.core.model import spec
from friction_sim.errors import FrictionSimError, ParameterError

Floats = NDArray[np.float64]
#: Parameters that may be fitted: the plant's numbers.
FITTABLE = {name: setting for name, setting in spec.PLANT.items() if setting.kind is float}
LOSSES = ("linear", "soft_l1", "huber")
#: Two fitted parameters correlated beyond this cannot be told apart by the data.
MAX_CORRELATION = 0.99
#: Two-sided 95 % quantile of the normal distribution (known deviations); its square is chi2_1(0.95).
Z95 = 1.959963984540054
#: Forward-difference step of the Jacobian, relative to max(1, |x|) (SciPy's rule for diff_step).
DIFF_STEP = 1e-7
#: Candidates drawn at a time for the starting points, and at most how many rounds of them.
DRAWS, DRAW_ROUNDS = 512, 8
#: Rounds after which the draws admitted so far are enough to screen (if they are enough to start from).
ENOUGH_ROUNDS = 4


class CalibrationError(FrictionSimError):
    """A calibration the data cannot determine (or cannot be set up), and why."""


def closest(name: str, names: Sequence[str]) -> str:
    """'; did you mean X?' for the name of ``names`` closest to ``name`` ('' if none is close)."""
    match = difflib.get_close_matches(name, list(names), n=1, cutoff=0.6)
    return f"; did you mean {match[0]}?" if match else ""


def parse_start(text: str, names: Sequence[str]) -> dict[str, float]:
    """A ``--start`` value, ``mu=0.2,static_ratio=1.3``: fitted names only, each value in its range."""
    start: dict[str, Any] = {}
    for part in (piece.strip() for piece in text.split(",") if piece.strip()):
        name, sep, value = (piece.strip() for piece in part.partition("="))
        if not sep:
            raise CalibrationError(f"--start {text!r}: expected name=value[,name=value]")
        try:
            start[name] = float(value)
        except ValueError:
            start[name] = value
    return check_start(start, names)


def check_start(start: dict[str, Any], names: Sequence[str]) -> dict[str, float]:
    """A starting point's values by name: fitted names only, each a number in its range."""
    checked = {}
    for name, value in start.items():
        if name not in names:
            raise CalibrationError(f"--start {name}: not a fitted parameter (fitted: {', '.join(names)})"
                                   + closest(name, names))
        try:
            checked[name] = float(FITTABLE[name].check(value))
        except ParameterError as error:
            raise CalibrationError(f"--start: {error}") from None
    return checked


@dataclass(frozen=True)
class FitOptions:
    """What to fit and how: ``fit`` the parameter names; ``loss`` and ``f_scale``
    (in standard deviations) as SciPy's; ``starts`` starting points in all, the
    user's ``start_points`` first (a mapping of fitted names each; the others
    at the reference), drawn with ``seed``; the mean speed over ``periods``
    whole periods after ``settle_periods``; ``profile``: profile-likelihood
    intervals beside the linearized ones."""

    fit: tuple[str, ...]
    loss: str = "linear"
    f_scale: float = 1.0
    starts: int = 4
    seed: int = 0
    settle_periods: int = 100
    periods: int = 100
    start_points: tuple[dict[str, float], ...] = ()
    profile: bool = True

    def __post_init__(self) -> None:
        if not self.fit:
            raise CalibrationError("--fit names no parameter (e.g. --fit mu,static_ratio)")
        unknown = [name for name in self.fit if name not in FITTABLE]
        if unknown:
            raise CalibrationError(f"--fit {unknown[0]!r}: not a plant parameter that can be fitted "
                                   f"(one of {', '.join(FITTABLE)}){closest(unknown[0], list(FITTABLE))}")
        if len(set(self.fit)) != len(self.fit):
            raise CalibrationError(f"--fit {','.join(self.fit)}: a parameter named twice")
        if self.loss not in LOSSES:
            raise CalibrationError(f"--loss {self.loss!r}: one of {', '.join(LOSSES)}")
        if not (self.f_scale > 0.0 and math.isfinite(self.f_scale)) or self.starts < 1:
            raise CalibrationError("--f-scale must be > 0 and --starts >= 1")
        for start in self.start_points:
            check_start({name: float(value) for name, value in start.items()}, self.fit)


@dataclass(frozen=True)
class Estimate:
    """One fitted parameter: its value, standard error and linearized 95 %
    interval [low, high]; the profile-likelihood interval [profile_low,
    profile_high] (NaN: not computed), each end flagged when it is the
    parameter's bound (the data do not close the interval there)."""

    name: str
    value: float
    std_error: float
    low: float
    high: float
    profile_low: float = math.nan
    profile_high: float = math.nan
    open_low: bool = False
    open_high: bool = False


@dataclass(frozen=True)
class Problem:
    """A least-squares problem: ``residuals`` maps rows of parameter vectors
    (k, p) to rows of residuals (k, n) in units of their deviations, in one
    call; ``flat`` says why nothing changes at a point (for a start's report);
    ``violations`` (optional) counts, for rows of parameter vectors, the data
    a start there could not fit (0: admitted as a start); ``subject`` names
    one residual in messages ("point's mean speed"); ``screen``: how many
    admitted draws to evaluate at once for the drawn starts, the best kept (0:
    none, each evaluation is dear)."""

    names: tuple[str, ...]
    residuals: Callable[[Floats], Floats]
    flat: Callable[[Floats], str] = field(default=lambda x: "nothing changes")
    violations: Callable[[Floats], NDArray[np.int64]] | None = None
    subject: str = "residual"
    screen: int = 0

    @property
    def bounds(self) -> tuple[Floats, Floats]:
        return bounds_of(self.names)


def bounds_of(names: Sequence[str]) -> tuple[Floats, Floats]:
    """The fitted parameters' ranges from spec.py (+-inf where open)."""
    low = np.array([-math.inf if (bound := FITTABLE[n].low) is None else float(bound) for n in names])
    high = np.array([math.inf if (bound := FITTABLE[n].high) is None else float(bound) for n in names])
    return low, high


def words(names: Sequence[str], x: Floats) -> str:
    """``mu = 0.173, static_ratio = 1.25``."""
    return ", ".join(f"{name} = {float(value):.6g}" for name, value in zip(names, x))


class Evaluator:
    """The residuals and their forward-difference Jacobian at a parameter
    vector, the Jacobian's columns evaluated in one call of the problem with
    the point itself (reused when it was the last one evaluated)."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem
        self.low, self.high = problem.bounds
        self.rows = 0
        self._last: tuple[bytes, Floats] | None = None

    def many(self, xs: Floats) -> Floats:
        """Residual rows for rows of parameter vectors."""
        self.rows += xs.shape[0]
        return np.asarray(self.problem.residuals(np.asarray(xs, dtype=float)), dtype=float)

    def fun(self, x: Floats) -> Floats:
        key = np.asarray(x, dtype=float).tobytes()
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        values = self.many(np.asarray(x, dtype=float)[None, :])[0]
        self._last = (key, values)
        return values

    def jac(self, x: Floats) -> Floats:
        x = np.asarray(x, dtype=float)
        steps = step_sizes(x, self.low, self.high)
        shifted = x[None, :] + np.diag(steps)
        cached = self._last is not None and self._last[0] == x.tobytes()
        rows = self.many(shifted if cached else np.vstack([x[None, :], shifted]))
        base = self._last[1] if cached and self._last is not None else rows[0]
        if not cached:
            self._last = (x.tobytes(), rows[0])
            rows = rows[1:]
        return np.asarray(((rows - base[None, :]) / steps[:, None]).T)


def step_sizes(x: Floats, low: Floats, high: Floats) -> Floats:
    """Forward steps DIFF_STEP*max(1, |x|), backward where a step would cross the upper bound."""
    steps = DIFF_STEP * np.maximum(1.0, np.abs(x))
    return np.where(x + steps > high, -steps, steps)


def draws(names: Sequence[str], reference: Floats, count: int, rng: np.random.Generator) -> Floats:
    """``count`` parameter vectors drawn across the bounds (see the module doc)."""
    low, high = bounds_of(names)
    out = np.empty((count, len(names)))
    for i, (a, b, x0) in enumerate(zip(low, high, reference)):
        if a > 0.0 and b / a >= 10.0:  # a ratio spanning a decade or more: log-uniform
            lo, hi = max(a, x0 / 10.0), min(b, x0 * 10.0)
            out[:, i] = np.exp(rng.uniform(math.log(lo), math.log(hi), count))
        else:
            lo, hi = (a if math.isfinite(a) else x0 - 1.0), (b if math.isfinite(b) else x0 + 1.0)
            out[:, i] = rng.uniform(lo, hi, count)
    return out


def starting_points(problem: Problem, options: FitOptions, reference: Floats) -> list[Floats]:
    """``options.starts`` starting points in all (at least the user's): the user's,
    then the reference if admitted, then admitted draws; where the problem
    screens, ``problem.screen`` admitted draws are evaluated in one call and the
    lowest in cost kept (where too few are admitted: the draws that break the fewest)."""
    low, high = problem.bounds
    reference = np.clip(np.asarray(reference, dtype=float), low, high)
    points = [np.array([start.get(name, x0) for name, x0 in zip(problem.names, reference)])
              for start in options.start_points]
    wanted = max(options.starts, len(points))
    if len(points) < wanted and _broken(problem, reference[None, :])[0] == 0 and not any(
            np.array_equal(point, reference) for point in points):
        points.append(reference)
    if len(points) >= wanted:
        return points
    candidates = _admitted_draws(problem, reference, wanted - len(points), max(problem.screen, wanted - len(points)),
                                 np.random.default_rng(options.seed))
    if problem.screen and len(candidates) > wanted - len(points):
        cost = np.sum(np.asarray(problem.residuals(candidates)) ** 2, axis=1)
        candidates = candidates[np.argsort(np.where(np.isfinite(cost), cost, np.inf), kind="stable")]
    return points + list(candidates[:wanted - len(points)])


def _broken(problem: Problem, rows: Floats) -> NDArray[np.int64]:
    if problem.violations is None:
        return np.zeros(rows.shape[0], dtype=np.int64)
    return np.asarray(problem.violations(rows), dtype=np.int64)


def _admitted_draws(problem: Problem, reference: Floats, needed: int, count: int,
                    rng: np.random.Generator) -> Floats:
    """Up to ``count`` draws the problem admits, at least ``needed`` (topped up with
    those that break the fewest data); after a few rounds, what is admitted by then."""
    kept: list[Floats] = []
    spare: list[tuple[int, int, Floats]] = []
    for round_ in range(DRAW_ROUNDS if problem.violations is not None else 1):
        if len(kept) >= needed and round_ >= ENOUGH_ROUNDS:
            break
        candidates = draws(problem.names, reference, DRAWS if problem.violations is not None else count, rng)
        for broken, row in zip(_broken(problem, candidates), candidates):
            if broken == 0:
                kept.append(row)
            elif len(spare) < count:
                spare.append((int(broken), len(spare), row))
        if len(kept) >= count:
            break
    kept += [row for _, _, row in sorted(spare, key=lambda item: item[:2])]
    return np.array(kept[:count]).reshape(-1, len(problem.names))


@dataclass(frozen=True)
class Outcome:
    """Where one start ended: its least-squares result, the parameters whose
    Jacobian column is 0 there (``dead``) and, for a start where nothing
    changes at all, why (``flat``; '' for a start that moved)."""

    number: int
    start: Floats
    result: Any
    dead: tuple[str, ...]
    flat: str

    def note(self, total: int) -> str:
        return f"start {self.number} of {total}: {self.flat}" if self.flat else ""


def outcome(problem: Problem, number: int, start: Floats, result: Any) -> Outcome:
    """Classify a finished start (see :class:`Outcome`)."""
    jac = np.asarray(result.jac, dtype=float)
    dead = tuple(name for name, column in zip(problem.names, jac.T) if not np.any(column != 0.0))
    flat = problem.flat(np.asarray(result.x)) if len(dead) == len(problem.names) else ""
    return Outcome(number, start, result, dead, flat)


def chosen(problem: Problem, outcomes: Sequence[Outcome], threshold: float) -> Outcome:
    """The start to keep: the lowest cost among those that moved.  If a parameter
    changes nothing there, it is not identifiable when every start that moved
    agrees; else the best start where it matters is kept if its cost is within
    ``threshold`` of the best (the data cannot tell them apart), and the fit is
    refused otherwise."""
    total = len(outcomes)
    moved = [o for o in outcomes if not o.flat]
    if not moved:
        raise CalibrationError("every start ended where nothing changes: " + "; ".join(o.note(total) for o in outcomes)
                               + " (give a start where the part moves: --start name=value)")
    best = min(moved, key=lambda o: float(o.result.cost))
    if not best.dead:
        return best
    agreed = [name for name in best.dead if all(name in o.dead for o in moved)]
    if agreed:
        raise CalibrationError(f"{', '.join(agreed)} changes no {problem.subject} at any of the {len(moved)} "
                               f"start{'s' if len(moved) > 1 else ''} that moved: not identifiable from these data")
    alive = [o for o in moved if not o.dead]
    if alive:
        other = min(alive, key=lambda o: float(o.result.cost))
        if float(other.result.cost) - float(best.result.cost) <= threshold:
            return other
    raise CalibrationError(f"{', '.join(best.dead)} changes nothing at the best fit "
                           f"({words(problem.names, best.result.x)}), though it does where other starts "
                           "ended, at a worse fit: the data do not determine it; fix it, or measure where it acts")


def linearized(result: Any, names: tuple[str, ...], known: bool, dof: int, quantile: float,
               check: bool = True) -> tuple[tuple[Estimate, ...], Floats, Floats]:
    """Estimates with standard errors and intervals +- ``quantile`` standard
    errors, their correlation and covariance, from the linearized covariance at
    the optimum (residuals in units of their deviations: ``known``, or scaled by
    the residual variance over ``dof``); refused (``check``) if two parameters
    correlate beyond :data:`MAX_CORRELATION`."""
    jacobian = np.asarray(result.jac, dtype=float)
    variance = 1.0 if known else float(np.sum(np.asarray(result.fun) ** 2)) / dof
    covariance = np.linalg.pinv(jacobian.T @ jacobian) * variance
    errors = np.sqrt(np.diag(covariance))
    correlation = correlation_of(covariance)
    if check:
        check_correlation(correlation, names)
    estimates = tuple(Estimate(name, float(v), float(e), float(v - quantile * e), float(v + quantile * e))
                      for name, v, e in zip(names, result.x, errors))
    return estimates, correlation, covariance


def correlation_of(covariance: Floats) -> Floats:
    """The correlation matrix of ``covariance``.  A parameter whose variance is 0 or not
    finite (the data show no change of the residuals along it: its intervals say it is
    not determined) correlates with nothing: 0 off the diagonal, 1 on it, never a nan."""
    errors = np.sqrt(np.abs(np.diag(covariance)))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        correlation = np.asarray(covariance / np.outer(errors, errors), dtype=float)
    correlation[~np.isfinite(correlation)] = 0.0
    np.fill_diagonal(correlation, 1.0)
    return correlation


def check_correlation(correlation: Floats, names: tuple[str, ...]) -> None:
    """Refuse two parameters the data cannot tell apart."""
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            if abs(correlation[i, j]) > MAX_CORRELATION:
                raise CalibrationError(
                    f"{names[i]} and {names[j]} correlate {correlation[i, j]:+.4f} over these points (limit "
                    f"{MAX_CORRELATION}): the data cannot tell them apart; fix one, or measure where they act "
                    "differently")


def scatter(values: Floats) -> float:
    """The RMS of ``values`` (0 for none): a series' residual scatter."""
    return float(np.sqrt(np.mean(np.asarray(values) ** 2))) if np.size(values) else 0.0


def size(values: Floats) -> float:
    """A series' own size (its RMS), its unit in a first fit before its scatter is known (1 for all 0)."""
    rms = scatter(values)
    return rms if rms > 0.0 else 1.0


def scales(start: Floats, low: Floats, high: Floats) -> Floats:
    """The parameters' characteristic sizes for the trust region: their starting
    values (a tenth of the range for one that starts at 0).  Scaling by the
    Jacobian instead let a weak parameter (mu_s/mu near 1) take a step into the
    no-motion region, where every slope is 0 and the fit stops."""
    span = np.where(np.isfinite(high - low), 0.1 * (high - low), 1.0)
    return np.asarray(np.where(start != 0.0, np.abs(start), span))


__all__ = ["DIFF_STEP", "FITTABLE", "LOSSES", "MAX_CORRELATION", "Z95", "CalibrationError", "Estimate", "Evaluator",
           "FitOptions", "Outcome", "Problem", "bounds_of", "check_correlation", "check_start", "chosen", "closest",
           "draws", "linearized", "outcome", "parse_start", "scales", "scatter", "size", "starting_points",
           "step_sizes", "words"]
