"""The batch core: N independent sliders at once (issue 12, item 1).

:func:`run_batch` takes any field of :class:`~friction_sim.core.model.params.SliderParams`
and :class:`~friction_sim.core.model.params.Inputs` as a scalar or a 1-D array (one
value per slider; scalars broadcast, missing fields take their defaults),
starts every slider like ``Slider(params, inputs)`` (t0 = 0, x0 = 0, phase 0,
stuck; a resonant slider's exciter in steady state, or, with ``initial``, from
rest or the steady state of another drive level or frequency:
:meth:`Population.slider`) and returns, per slider, the mean velocity over ``periods`` whole
excitation periods after ``settle_periods``, the flight and stick fractions
and the event counts over the same window, and on request the exact state at
given sample times.

The window is bounded by the period starts (the phase passing 2*pi*n
exactly, as the scalar core's :class:`~friction_sim.core.model.events.CycleMark`):
the mean velocity is (x at the start of period settle+periods - x at the
start of period settle)/(periods/f).  An event that happens exactly at a
period start belongs to the period it starts (the scalar core's order).

Two engines give the same numbers:

* ``"compiled"`` (the default): :mod:`friction_sim.core.engine.compiled`, the
  single slider's physics (the same plain functions) compiled with Numba, each
  slider advanced event by event to its own end, in parallel over cores.  A
  slider's window is the single slider's bit for bit; a slider's result does
  not depend on the other sliders of its batch, so a sweep may chunk freely.
  With ``periodic_shortcut`` a motion that repeats bit for bit is
  extrapolated over the rest of its window.
* ``"scalar"``: a loop over :class:`~friction_sim.core.engine.single.Slider`,
  the interpreted reference (and the baseline of bench/batch.py).

The first compiled run on a machine compiles (seconds), later ones load the
on-disk cache; ``bench/batch.py`` gives the throughputs.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from friction_sim.core.engine.single import Slider
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import nondimensional_speed
from friction_sim.core.model.events import EventKind
from friction_sim.core.model.params import Inputs, SliderParams, plant_from
from friction_sim.core.model.records import share
from friction_sim.core.physics.plant import can_ever_slip
from friction_sim.errors import ParameterError

#: The engines of :func:`run_batch`.
ENGINES = ("compiled", "scalar")
#: Every field a batch may set per slider, with its setting.
FIELDS: dict[str, spec.Setting] = {**spec.PLANT, **spec.INPUTS}
#: Event kinds in the order of the count columns.
EVENT_KINDS: tuple[str, ...] = tuple(kind.value for kind in EventKind)

Floats = NDArray[np.float64]


@dataclass(frozen=True)
class BatchSamples:
    """The exact state of every slider at the sample times: ``t`` (K,), the
    others (N, K); ``mode`` is -1/0/1 (slip back, stuck, slip forward) or 2 (flight)."""

    t: Floats
    x: Floats
    v: Floats
    z: Floats
    vz: Floats
    mode: NDArray[np.int8]


@dataclass(frozen=True)
class BatchResult:
    """Per-slider results of :func:`run_batch` (arrays of length ``n``).

    mean_velocity [m/s] over the window of ``periods`` whole excitation
    periods after ``settle_periods``; ``u`` = mean_velocity*f/(g*mu);
    flight_fraction and stick_fraction: the time off the track and stuck over
    the window, as fractions of it; event_counts: events of every kind
    (EventKind values as keys) in the window; samples: the sampled states, or None.
    """

    n: int
    settle_periods: int
    periods: int
    mean_velocity: Floats
    u: Floats
    flight_fraction: Floats
    stick_fraction: Floats
    event_counts: dict[str, NDArray[np.int64]]
    samples: BatchSamples | None = None


@dataclass(frozen=True)
class Population:
    """The validated per-slider values: every field as an array of length ``n``
    (floats; ``landing_friction`` as an array of str); ``initial``: the inputs of
    :data:`~friction_sim.core.model.spec.EXCITER_START` whose steady state a resonant
    slider's exciter starts from at t = 0, where they are not its own (see :func:`run_batch`)."""

    n: int
    columns: dict[str, NDArray[Any]]
    initial: dict[str, NDArray[Any]] = field(default_factory=dict)

    def plant(self, i: int) -> tuple[SliderParams, Inputs]:
        """Slider ``i``'s parameters and inputs as the single slider takes them."""
        return plant_from({name: _item(column[i]) for name, column in self.columns.items()})

    def slider(self, i: int, **options: Any) -> Slider:
        """Slider ``i`` as a single slider at t = 0 (``options``: its logs), its exciter
        started as the batch starts it: in the steady state of its ``initial`` inputs,
        then stepped to its own at once (:meth:`Slider.set_inputs`), the transient running."""
        params, inputs = self.plant(i)
        start = inputs.replace(**{name: float(column[i]) for name, column in self.initial.items()})
        if not params.resonant or start == inputs:
            return Slider(params, inputs, **options)
        slider = Slider(params, start, **options)
        slider.set_inputs(inputs)
        return slider


def _item(value: Any) -> Any:
    return str(value) if isinstance(value, np.str_) else float(value)


def population(values: Mapping[str, Any], initial: Mapping[str, Any] | None = None) -> Population:
    """Validate ``values`` (field -> scalar or 1-D array) and ``initial`` (the same, of
    the inputs in :data:`~friction_sim.core.model.spec.EXCITER_START`, named
    ``initial.<field>`` in errors) and broadcast them to one common length N; refuse
    a bad one with a :class:`ParameterError` that names the field, the first bad
    value, its index and the limit."""
    if not isinstance(values, Mapping):
        raise ParameterError("values", type(values).__name__, "must be a mapping of field names to values")
    if initial is None:
        initial = {}
    if not isinstance(initial, Mapping):
        raise ParameterError("initial", type(initial).__name__, "must be a mapping of input names to values")
    n = 0
    length_of = ""
    raw: dict[str, NDArray[Any]] = {}
    entries = [(str(name), name, value) for name, value in values.items()]
    entries += [(f"initial.{name}", name, value) for name, value in initial.items()]
    for label, name, value in entries:
        setting = FIELDS.get(name)
        if label != name and name not in spec.EXCITER_START:
            raise ParameterError(label, value if np.ndim(value) == 0 else "<array>",
                                 f"unknown start of the exciter; known: {', '.join(spec.EXCITER_START)}")
        if setting is None:
            raise ParameterError(label, value if np.ndim(value) == 0 else "<array>",
                                 f"unknown field; known: {', '.join(FIELDS)}")
        array = _as_array(setting, value)
        if array.ndim > 1:
            raise ParameterError(label, f"<array of shape {array.shape}>", "must be a scalar or a 1-d array")
        if array.ndim == 1:
            if array.size == 0:
                raise ParameterError(label, "<empty array>", "must hold one value per slider (at least one)")
            if n and array.size != n:
                raise ParameterError(label, f"<array of length {array.size}>",
                                     f"must have the length of {length_of} ({n}), or be a scalar")
            n, length_of = array.size, label
        raw[label] = array
    n = max(n, 1)
    columns: dict[str, NDArray[Any]] = {}
    for name, setting in FIELDS.items():
        if name in raw:
            columns[name] = _checked(setting, raw[name], n)
        elif setting.kind is str:
            columns[name] = np.full(n, str(setting.default))
        else:
            columns[name] = np.full(n, float(setting.default))
    starts: dict[str, NDArray[Any]] = {}
    for name in spec.EXCITER_START:
        if f"initial.{name}" in raw:
            try:
                starts[name] = _checked(FIELDS[name], raw[f"initial.{name}"], n)
            except ParameterError as error:
                raise ParameterError(f"initial.{name}", error.value, error.limit) from None
    return Population(n, columns, starts)


def _as_array(setting: spec.Setting, value: Any) -> NDArray[Any]:
    """``value`` as an array of the setting's kind (a value of the wrong type refused)."""
    if setting.kind is str:
        array = np.asarray(value)
        if array.dtype.kind != "U":
            first = array.flat[0] if array.size else value
            setting.check(first.item() if isinstance(first, np.generic) else first)  # raises: not a string
            raise ParameterError(setting.name, value if array.ndim == 0 else "<array>", "must be strings")
        return array
    array = np.asarray(value)
    mixed_bool = isinstance(value, (list, tuple)) and any(isinstance(item, (bool, np.bool_)) for item in value)
    if mixed_bool or array.dtype.kind == "b" or array.dtype.kind not in "iuf":
        # the error path: find the first item Setting.check refuses, and say where it is
        items = np.asarray(value, dtype=object)
        for index, item in enumerate(items.ravel()):
            try:
                setting.check(item.item() if isinstance(item, np.generic) else item)
            except ParameterError as error:
                raise _at(error, index, items.ndim) from None
        raise ParameterError(setting.name, "<array>", "must hold numbers")
    return array.astype(np.float64)


def _checked(setting: spec.Setting, array: NDArray[Any], n: int) -> NDArray[Any]:
    """The column of ``setting``: every value checked as Setting.check would, broadcast to ``n``."""
    if setting.kind is str:
        for value in np.unique(array):
            try:
                setting.check(str(value))
            except ParameterError as error:
                index = int(np.flatnonzero(array.ravel() == value)[0]) if array.ndim else 0
                raise _at(error, index, array.ndim) from None
        return np.broadcast_to(array, (n,)).astype(str)
    low = -math.inf if setting.low is None else float(setting.low)
    high = math.inf if setting.high is None else float(setting.high)
    good = np.isfinite(array) & (array >= low) & (array <= high)
    if not np.all(good):
        index = int(np.flatnonzero(~np.atleast_1d(good))[0])
        try:
            setting.check(float(np.atleast_1d(array)[index]))
        except ParameterError as error:
            raise _at(error, index, array.ndim) from None
    return np.array(np.broadcast_to(array, (n,)), dtype=np.float64)


def _at(error: ParameterError, index: int, ndim: int) -> ParameterError:
    """``error`` with the slider index added (for an array)."""
    if ndim == 0:
        return error
    return ParameterError(error.field, error.value, f"{error.limit} (at index {index})")


def _count(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ParameterError(name, value, f"must be an integer >= {low}")
    return int(value)


def _sample_times(sample_times: ArrayLike | None) -> Floats | None:
    if sample_times is None:
        return None
    try:
        times = np.asarray(sample_times, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError("sample_times", "<not numbers>", "must be a 1-d array of times [s]") from None
    if times.ndim != 1 or times.size == 0:
        raise ParameterError("sample_times", f"<shape {times.shape}>", "must be a non-empty 1-d array")
    bad = ~np.isfinite(times) | (times < 0.0) | (times > 2.0**53)
    if np.any(bad):
        index = int(np.flatnonzero(bad)[0])
        raise ParameterError("sample_times", float(times[index]), f"must be finite, in [0, 2**53] s (at index {index})")
    if np.any(np.diff(times) < 0.0):
        index = int(np.flatnonzero(np.diff(times) < 0.0)[0]) + 1
        raise ParameterError("sample_times", float(times[index]), f"must ascend (at index {index})")
    return times


def run_batch(values: Mapping[str, Any], *, settle_periods: int, periods: int,
              sample_times: ArrayLike | None = None, engine: str = "compiled",
              periodic_shortcut: bool = True, threads: int | None = None,
              progress: Callable[[str], None] | None = None, initial: Mapping[str, Any] | None = None) -> BatchResult:
    """Advance N independent sliders, each from rest at t = 0, phase 0, x = 0,
    exactly, and return their means over the window (see the module doc).

    ``values``: field -> scalar or 1-D array (all of one length N), any field
    of SliderParams and Inputs; ``engine``: "compiled" (the physics compiled,
    in parallel over ``threads`` cores, all by default) or "scalar" (a loop over
    the single slider, the reference).  ``periodic_shortcut`` (compiled engine)
    lets a slider whose motion repeats bit for bit extrapolate its window
    instead of stepping through it (exact: a repeat of the state decides the
    future).  ``progress`` hears, in one line, when the engine is compiling.

    ``initial`` (resonant sliders): the inputs, of
    :data:`~friction_sim.core.model.spec.EXCITER_START`, whose steady state the
    exciter starts from at t = 0, each a scalar or one value per slider: a step
    to the slider's own drive level and frequency at t = 0, whose transient both
    engines run exactly (``{"drive_level": 0.0}``: a start from rest, a sweep's
    ``initial: rest``; :data:`~friction_sim.core.model.spec.INITIAL_INPUTS`).  A
    field not given, or equal to the slider's own: the exciter starts in its
    steady state (the default, no transient).  The single slider that does the
    same is :meth:`Population.slider`.
    """
    pop = population(values, initial)
    settle = _count("settle_periods", settle_periods, 0)
    count = _count("periods", periods, 1)
    times = _sample_times(sample_times)
    if engine == "scalar":
        return _run_scalar(pop, settle, count, times)
    if engine != "compiled":
        raise ParameterError("engine", engine, f"must be one of {', '.join(ENGINES)}")
    if threads is not None:
        _count("threads", threads, 1)
    from friction_sim.core.engine import compiled

    window, counts, samples, modes = compiled.run(
        pop.columns, lambda i: can_ever_slip(*pop.plant(i)), settle, count, times,
        bool(periodic_shortcut), threads, progress, pop.initial)
    batch_samples = None
    if times is not None and samples is not None and modes is not None:
        batch_samples = BatchSamples(times, samples[:, :, 0], samples[:, :, 1], samples[:, :, 2], samples[:, :, 3],
                                     modes)
    return finish(pop, settle, count, (window[:, 0, 0], window[:, 1, 0]), (window[:, 0, 1], window[:, 1, 1]),
                  (window[:, 0, 2], window[:, 1, 2]), counts[:, 1] - counts[:, 0], batch_samples)


def finish(pop: Population, settle: int, count: int, x: tuple[Floats, Floats], stuck: tuple[Floats, Floats],
           flight: tuple[Floats, Floats], counts: NDArray[np.int64], samples: BatchSamples | None) -> BatchResult:
    """The result from the window's two period starts (begin, end) per slider."""
    frequency = pop.columns["excitation_frequency"]
    duration = count / frequency
    velocity = (x[1] - x[0]) / duration
    return BatchResult(
        n=pop.n, settle_periods=settle, periods=count, mean_velocity=velocity,
        u=nondimensional_speed(velocity, frequency, pop.columns["gravity"], pop.columns["mu"]),
        flight_fraction=share(flight[1] - flight[0], duration), stick_fraction=share(stuck[1] - stuck[0], duration),
        event_counts={kind: counts[:, k].copy() for k, kind in enumerate(EVENT_KINDS)}, samples=samples)


def _run_scalar(pop: Population, settle: int, count: int, times: Floats | None) -> BatchResult:
    """The reference engine: one :class:`Slider` per slider, in a loop."""
    return finish(pop, settle, count, *scalar_windows(pop, settle, count, times))


Windows = tuple[tuple[Floats, Floats], tuple[Floats, Floats], tuple[Floats, Floats], NDArray[np.int64],
                BatchSamples | None]


def scalar_windows(pop: Population, settle: int, count: int, times: Floats | None) -> Windows:
    """Per slider, with the scalar core: x, stuck and flight time at the
    window's two period starts, the event counts in the window and the samples."""
    n = pop.n
    x = (np.empty(n), np.empty(n))
    stuck = (np.empty(n), np.empty(n))
    flight = (np.empty(n), np.empty(n))
    counts = np.zeros((n, len(EVENT_KINDS)), dtype=np.int64)
    column = {kind: k for k, kind in enumerate(EVENT_KINDS)}
    sampled: list[Any] = []
    for i in range(n):
        frequency = float(pop.columns["excitation_frequency"][i])
        slider = pop.slider(i, event_log_size=0, cycle_log_size=2)
        for side, mark_n in enumerate((settle, settle + count)):
            boundary = mark_n / frequency  # the scalar core times period n's start at exactly n/f
            for event in slider.advance_to(boundary):
                # an event at the boundary itself comes after the period start (it is in period n)
                inside = event.t >= boundary if side == 0 else event.t < boundary
                if inside:
                    counts[i, column[event.kind.value]] += 1
            mark = slider.cycle_marks[-1]
            assert mark.n == mark_n
            x[side][i], stuck[side][i], flight[side][i] = mark.x, mark.stuck_time, mark.flight_time
        if times is not None:
            sampled.append(pop.slider(i, event_log_size=0).sample(times))
    samples = None
    if times is not None:
        samples = BatchSamples(t=times, x=np.array([s.x for s in sampled]), v=np.array([s.v for s in sampled]),
                               z=np.array([s.z for s in sampled]), vz=np.array([s.vz for s in sampled]),
                               mode=np.array([s.mode for s in sampled], dtype=np.int8))
    return x, stuck, flight, counts, samples


__all__ = ["ENGINES", "EVENT_KINDS", "FIELDS", "BatchResult", "BatchSamples", "Population", "population",
           "run_batch", "scalar_windows"]
