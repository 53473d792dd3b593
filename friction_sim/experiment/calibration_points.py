"""The model of measured operating points: each point's mean speed for rows of fitted values.

Every field of every point, for k parameter vectors at once, is one call of
the population engine (:func:`~friction_sim.core.engine.population.run_batch`)
over k x n sliders: the fixed settings, the point's own settings (derived keys
as in sweeps) and the parameters being fitted.

Where a start may lie is decided by the project's own rules, without
simulating (:func:`motion_at`): a part moves where the pull that friction must
hold, at the least normal load of a period, beats the static friction there
(the motion boundary, :func:`~friction_sim.core.meanspeed.urelation.motion_boundary`,
with mu_s and the tangential excitation; a part whose excitation exceeds its
load leaves the track and moves), and runs away where the pull beats mu times
the mean load (:func:`~friction_sim.core.model.dimensionless.beats_friction`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from friction_sim.core.engine.population import run_batch
from friction_sim.core.meanspeed.urelation import motion_boundary
from friction_sim.core.model.dimensionless import beats_friction
from friction_sim.core.model.params import cos_degrees, sin_degrees
from friction_sim.core.physics.plant import excitation
from friction_sim.experiment.calibration_fit import CalibrationError, FitOptions, Floats, words
from friction_sim.experiment.measurements import Measurements
from friction_sim.experiment.sweep import DERIVED, FIELDS, derive_fields

#: A point measured faster than this many standard deviations moves (a start must move it).
MOVING_STDS = 3.0
#: Below this many sliders a batch runs on one thread (the pool's start costs more than it saves).
ONE_THREAD_BELOW = 2000

_excitation = np.vectorize(excitation, otypes=[float, float])


def _per_value(function: Any, values: Floats) -> Floats:
    """``function`` of each element, called once per distinct value (angles repeat over the points)."""
    distinct, where = np.unique(values, return_inverse=True)
    return np.array([function(float(value)) for value in distinct])[where.reshape(values.shape)]


def _cos(degrees: Floats) -> Floats:
    return _per_value(cos_degrees, degrees)


def _sin(degrees: Floats) -> Floats:
    return _per_value(sin_degrees, degrees)


def motion_at(columns: dict[str, np.ndarray]) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """(moves, runs_away) of every point of ``columns`` (each field an array), by the
    rules of the module doc.  Pull and load along and normal to the track:
    Fd + Fx - m g sin(alpha) and m g cos(alpha) - Fz; the steady excitation
    Pa sin(theta) (the resonant actuator's steady Pa) and Pt = Pa cot(beta)
    at phase psi.  Held at rest each way while s*pull + Pt sin(theta + psi) <=
    mu_s (load - Pa sin(theta)) for every theta: the largest pull to hold is
    s*pull + |s Pt e^(i psi) + mu_s Pa| - mu_s Pa, over mu_s load the drive ratio
    phi_s; it moves where Pa/load > motion_boundary(phi_s)."""
    f = {name: np.asarray(values, dtype=float) for name, values in columns.items()
         if FIELDS[name].kind is not str}
    weight = f["mass"] * f["gravity"]
    pull = f["drive_force"] + f["external_force_x"] - weight * _sin(f["track_inclination"])
    load = weight * _cos(f["track_inclination"]) - f["external_force_z"]
    resonant = np.asarray(columns["actuator"]) == "resonant"
    pa = f["excitation_amplitude"].copy()
    if np.any(resonant):  # the force actuator's Pa is the amplitude set
        pa[resonant] = _resonant_pa(f, resonant)
    mu_s = f["mu"] * f["static_ratio"]
    tangential = pa * _cos(f["excitation_angle"]) / _sin(f["excitation_angle"]) * np.exp(
        1j * np.radians(f["excitation_phase"]))
    held = np.maximum(pull + np.abs(tangential + mu_s * pa), -pull + np.abs(-tangential + mu_s * pa)) - mu_s * pa
    positive = load > 0.0
    safe = np.where(positive, load, 1.0)
    moves = ~positive | (pa >= load) | (pa / safe > motion_boundary(held / (mu_s * safe)))
    return np.asarray(moves), np.asarray(beats_friction(pull, load, f["mu"]), dtype=bool)


def _resonant_pa(f: dict[str, Floats], rows: NDArray[np.bool_]) -> Floats:
    """The resonant actuator's steady Pa of the ``rows`` (:func:`~friction_sim.core.physics.plant.excitation`)."""
    pa, _ = _excitation(f["mass"][rows], True, f["excitation_amplitude"][rows], f["excitation_frequency"][rows],
                        f["natural_frequency"][rows], f["damping_ratio"][rows], f["full_drive_acceleration"][rows],
                        f["drive_level"][rows])
    return np.asarray(pa)


class PointsModel:
    """The mean speed of every point for rows of fitted values (see the module doc)."""

    def __init__(self, measurements: Measurements, fixed: dict[str, Any], options: FitOptions) -> None:
        clash = [name for name in options.fit if name in measurements.settings or name in fixed]
        if clash:
            raise CalibrationError(f"{clash[0]} is both fitted and given (in the measurements or the fixed "
                                   "settings): give a starting value with --start instead")
        self.measurements, self.fixed, self.options = measurements, fixed, options
        self.batches = 0
        n = measurements.count
        self.columns: dict[str, np.ndarray] = {
            name: np.full(n, setting.default) if setting.kind is str else np.full(n, float(setting.default))
            for name, setting in FIELDS.items()}
        for name, value in fixed.items():
            if name in FIELDS:
                self.columns[name] = np.full(n, value) if isinstance(value, str) else np.full(n, float(value))
        self.given = {name: np.full(n, float(value)) for name, value in fixed.items() if name in DERIVED}
        for name, values in measurements.settings.items():
            (self.given if name in DERIVED else self.columns)[name] = values

    @property
    def reference(self) -> Floats:
        """The fitted parameters' settings given, else their defaults: the first start."""
        return np.array([float(self.columns[name][0]) for name in self.options.fit])

    def values(self, xs: Floats) -> dict[str, np.ndarray]:
        """Every field of every point for each row of ``xs`` (k x n points, row by row), derived keys after."""
        xs = np.atleast_2d(np.asarray(xs, dtype=float))
        k = xs.shape[0]
        columns = {name: np.tile(values, k) for name, values in self.columns.items()}
        for i, name in enumerate(self.options.fit):
            columns[name] = np.repeat(xs[:, i], self.measurements.count)
        derive_fields(columns, {name: np.tile(values, k) for name, values in self.given.items()})
        return columns

    def speeds(self, xs: Floats) -> Floats:
        """The mean speed [m/s] of every point (columns) for each row of ``xs`` (rows)."""
        xs = np.atleast_2d(np.asarray(xs, dtype=float))
        self.batches += 1
        size = xs.shape[0] * self.measurements.count
        batch = run_batch(self.values(xs), settle_periods=self.options.settle_periods,
                          periods=self.options.periods, threads=1 if size < ONE_THREAD_BELOW else None)
        return np.asarray(batch.mean_velocity, dtype=float).reshape(xs.shape[0], self.measurements.count)

    def violations(self, xs: Floats) -> NDArray[np.int64]:
        """For each row of ``xs``: the points where the part would run away, or stand
        where it was measured moving (0: a start there can fit every point).  With
        a std column, moving means faster than 3 std: noise on a still point is not motion."""
        xs = np.atleast_2d(np.asarray(xs, dtype=float))
        moves, runs_away = motion_at(self.values(xs))
        shape = (xs.shape[0], self.measurements.count)
        m = self.measurements
        moving = np.abs(m.speed) > (0.0 if m.std is None else MOVING_STDS * m.std)
        measured = np.broadcast_to(moving, shape)
        bad = runs_away.reshape(shape) | (measured & ~moves.reshape(shape))
        return np.asarray(np.sum(bad, axis=1), dtype=np.int64)

    def flat(self, x: Floats) -> str:
        """Why no point's speed changes at ``x``: every one runs away, none moves, or neither."""
        where = words(self.options.fit, x)
        if np.all(motion_at(self.values(x))[1]):
            return f"every point runs away at {where}"
        if not np.any(self.speeds(x) != 0.0):
            return f"no point moves at {where}"
        return f"no point's mean speed changes at {where}"


__all__ = ["MOVING_STDS", "ONE_THREAD_BELOW", "PointsModel", "motion_at"]
