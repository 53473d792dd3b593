"""The single slider's step under the exciter's transient: compiled once ready, plain until then.

While the exciter's transient decays, every event of a segment is found by
the branch-and-bound root search of :mod:`friction_sim.core.physics.transient`,
the single slider's hot path (about 130 us a segment interpreted).  Numba
compiles the same plain functions, as the population engine does with the
steady physics (:mod:`friction_sim.core.engine.compiled`), and the compiled
step is the plain one bit for bit: the same operations in the same order,
the same libm, no fused multiply-adds (a test checks it over random cases).
So the slider may switch to it at any instant without changing one number,
and a lockstep recording is the same whichever ran.

Compiling takes seconds on a machine's first run, then loads from the
population engine's on-disk cache in about one.  A node must never stall on
it, and must start without Numba, so the first transient step starts it on
a background thread (:data:`AUTO`) and the plain step runs until it is
ready.  :data:`COMPILED` waits for it instead (benchmarks, batch runs);
:data:`PLAIN` never compiles (the reference the compiled step is tested
against, or a platform without Numba).  If compiling fails, one warning
says why and the plain step stays: slower, never different.

Numba reads the process environment at every function it compiles, by
iterating ``os.environ``, which is not atomic: a variable that another
thread removes meanwhile (pytest does so between the phases of every test)
fails the compile with a ``KeyError`` naming it.  Such a failure says
nothing about the compile, so it is tried again (:func:`environment_changed`).
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from friction_sim.core.physics import exciter as _exciter
from friction_sim.core.physics import transient as _transient
from friction_sim.core.physics.exciter import Slideway
from friction_sim.core.physics.plant import Plant
from friction_sim.core.physics.segment import STUCK, Segment, Step

#: Compile on a background thread at the first transient step; plain until ready.
AUTO = "auto"
#: Compile at the first transient step and wait for it.
COMPILED = "compiled"
#: Never compile.
PLAIN = "plain"
MODES = (AUTO, COMPILED, PLAIN)

#: How many times a compile is tried while the environment keeps changing beneath it.
COMPILE_ATTEMPTS = 5

#: The root search's work in this process (see :data:`~friction_sim.core.physics.transient.Work`).
WORK: np.ndarray = np.zeros(1, np.int64)

_LOG = logging.getLogger(__name__)
StepFunction = Callable[..., Step]


class Kernel:
    """The step in use, and the compiling of the other (one per process)."""

    def __init__(self) -> None:
        self.mode = AUTO
        self.compiled: CompiledStep | None = None
        self.failure: str | None = None
        self.thread: threading.Thread | None = None
        self.lock = threading.Lock()
        #: The last plant checked against the compiled types, and whether it has them (one
        #: tuple, replaced whole: a slider on another thread never reads a half-written pair).
        self.checked: tuple[Plant | None, bool] = (None, False)

    def start(self, args: tuple[Any, ...]) -> threading.Thread | None:
        """Start compiling for the types of ``args`` (once); the thread, if one runs."""
        with self.lock:
            if self.thread is None and self.compiled is None and self.failure is None:
                self.thread = threading.Thread(target=self._compile, args=(args,), daemon=True,
                                               name="friction_sim-transient-compile")
                self.thread.start()
            return self.thread

    def _compile(self, args: tuple[Any, ...]) -> None:
        for attempt in range(1, COMPILE_ATTEMPTS + 1):
            try:
                self.compiled = compile_step(args)
                return
            except Exception as error:  # noqa: BLE001 (any failure leaves the plain step, which is never wrong)
                reason = f"{type(error).__name__}: {error}"
                if not environment_changed(error) or attempt == COMPILE_ATTEMPTS:
                    break
                _LOG.debug("compiling the exciter's transient again: the environment changed while Numba "
                           "read it (%s)", reason)
        self.failure = reason
        _LOG.warning("the exciter's transient runs interpreted (slower, same numbers): compiling it "
                     "failed with %s", reason)

    def entry(self, p: Plant) -> StepFunction | None:
        """The compiled step if it is ready and was compiled for the types of ``p``'s
        fields (checked once per plant: the other arguments are converted by the caller)."""
        compiled = self.compiled
        if compiled is None or self.mode == PLAIN:
            return None
        checked = self.checked
        if checked[0] is not p:  # (typing a plant costs more than a step: once per plant, either way)
            checked = self.checked = (p, compiled.fits(p))
        return compiled.entry if checked[1] else None


def environment_changed(error: Exception) -> bool:
    """Whether ``error`` is Numba's read of ``os.environ`` losing a race: a ``KeyError``
    naming a variable that is no longer set (removed by another thread while Numba
    iterated the environment), which a second compile does not meet."""
    return isinstance(error, KeyError) and len(error.args) == 1 and error.args[0] not in os.environ


class CompiledStep:
    """The compiled step's entry point, which skips Numba's dispatch (typing a
    :class:`Plant` of nested named tuples costs more than the step itself), and
    the test that a plant has the types it was compiled for; the compiled
    samplers of a segment (:func:`~friction_sim.core.physics.transient.states_into`,
    :func:`~friction_sim.core.physics.transient.accelerations_into`), entered the
    same way, and the shape of segment they were compiled for."""

    def __init__(self, entry: StepFunction, fits: Callable[[Plant], bool], states: Callable[..., None],
                 accelerations: Callable[..., None], slideway: Callable[..., None]) -> None:
        self.entry = entry
        self.fits = fits
        self.states = states
        self.accelerations = accelerations
        #: :func:`~friction_sim.core.physics.exciter.normal_accelerations_into`, for a slideway of floats.
        self.slideway = slideway
        #: The last segment checked against the samplers' types and the verdict (one tuple, replaced whole).
        self.segment_checked: tuple[Segment | None, bool] = (None, False)

    def segment_fits(self, seg: Segment) -> bool:
        """Whether ``seg`` has the types the samplers were compiled for (checked once per segment)."""
        checked = self.segment_checked
        if checked[0] is not seg:
            checked = self.segment_checked = (seg, _flat_fits(seg, _REST_SHAPE))
        return checked[1]


#: The process's kernel (one compile per process, like the on-disk cache it loads from).
KERNEL = Kernel()


def compile_step(args: tuple[Any, ...]) -> CompiledStep:
    """The compiled :func:`~friction_sim.core.physics.transient.transient_step` for the
    types of ``args`` (from the on-disk cache when it is there)."""
    import numba

    from friction_sim.core.engine.compiled import CACHE_DIR  # registers the physics, sets the cache

    assert CACHE_DIR.is_dir()
    typeof: Callable[[Any], Any] = numba.typeof  # (untyped in Numba)
    dispatcher: Any = numba.njit(cache=True)(_transient.transient_step)
    signature = tuple(typeof(arg) for arg in args)
    dispatcher.compile(signature)
    plant_type = signature[0]
    verdicts: dict[tuple[Any, ...], bool] = {}

    def fits(p: Plant) -> bool:
        """Whether ``p`` has the compiled types: Numba's typing (~70 us) once per shape of plant
        (~5 us): a controller that sets the drive level every period makes a plant a period."""
        key = _shape(p)
        verdict = verdicts.get(key)
        if verdict is None:
            try:
                verdict = bool(typeof(p) == plant_type)
            except ValueError:  # (a number Numba has no type for: an int beyond 64 bits)
                verdict = False
            verdicts[key] = verdict
        return verdict

    taus, states, accelerations = np.zeros(1), np.zeros((8, 1)), np.zeros((2, 1))
    sampler_types = (plant_type, typeof(_REST), typeof(0j), typeof(0j), typeof(taus))
    return CompiledStep(dispatcher.overloads[signature].entry_point, fits,
                        _entry(numba, _transient.states_into, (*sampler_types, typeof(states))),
                        _entry(numba, _transient.accelerations_into,
                               (plant_type, typeof(0.0), *sampler_types[2:], typeof(accelerations))),
                        _entry(numba, _exciter.normal_accelerations_into,
                               (typeof(_STILL), typeof(0.0), typeof(0.0), typeof(taus), typeof(taus))))


#: A segment of the types the stepper makes (the samplers are compiled for them).
_REST = Segment(STUCK, 0.0, 0.0, 0.0, 0.0, 0, False, 0.0, 0.0, 0.0, 0.0, 0, 0.0, 0.0, 0)
#: A slideway of the types a drive loop's model makes.
_STILL = Slideway(0.0, 0.0, 1.0, -1 + 1j, 0j)


def _flat_fits(value: tuple[Any, ...], shape: tuple[Any, ...]) -> bool:
    """Whether a flat tuple of numbers (a segment, a slideway) has ``shape``
    (:func:`_shape` of a sample of the compiled types): a look at each field's class,
    cheaper than taking its shape (an int's, also whether it fits 64 bits)."""
    return type(value) is shape[0] and all(
        type(field) is kind or (kind == (int, True) and type(field) is int and -2**63 <= field < 2**63)
        for field, kind in zip(value, shape[1:], strict=True))


def _entry(numba: Any, function: Callable[..., Any], signature: tuple[Any, ...]) -> Callable[..., Any]:
    """The entry point of ``function`` compiled for ``signature`` (from the on-disk cache when it is there)."""
    dispatcher: Any = numba.njit(cache=True)(function)
    dispatcher.compile(signature)
    entry: Callable[..., Any] = dispatcher.overloads[signature].entry_point
    return entry


def _shape(value: Any) -> tuple[Any, ...]:
    """What Numba's type of a tuple of numbers depends on: each level's class, and each
    leaf's (an int's also whether it fits 64 bits, which Numba's int64 holds)."""
    kinds: list[Any] = [type(value)]
    for field in value:  # (a loop, not a generator: once per plant, and a plant a period)
        kind = type(field)
        if kind is float:
            kinds.append(float)
        elif isinstance(field, tuple):
            kinds.append(_shape(field))
        elif kind is int:
            kinds.append((int, -2**63 <= field < 2**63))
        else:
            kinds.append(kind)
    return tuple(kinds)


#: The shapes the samplers were compiled for (:func:`_flat_fits`).
_REST_SHAPE, _STILL_SHAPE = _shape(_REST), _shape(_STILL)


def use(mode: str) -> None:
    """Choose how transient steps run from now on: :data:`AUTO`, :data:`COMPILED` or :data:`PLAIN`."""
    if mode not in MODES:
        raise ValueError(f"transient kernel mode {mode!r} is not one of {', '.join(MODES)}")
    KERNEL.mode = mode


def mode() -> str:
    """The mode chosen by :func:`use`."""
    return KERNEL.mode


def compiled_ready() -> bool:
    """Whether the compiled step is loaded."""
    return KERNEL.compiled is not None


def failure() -> str | None:
    """Why compiling failed, if it did."""
    return KERNEL.failure


def search_steps() -> int:
    """The intervals and bisection steps the root search has examined in this
    process (for tests: a bound on the work, whatever the machine)."""
    return int(WORK[0])


def prepare(p: Plant) -> None:
    """In :data:`AUTO` mode, start loading (from the cache) or compiling the step for plants
    like ``p`` now, in the background, rather than at the first transient step: a resonant
    slider's start-up (a node's discovery, an experiment's) then overlaps the ~0.5 s it takes
    to load, instead of its first simulated second running interpreted beside it."""
    kernel = KERNEL
    if kernel.compiled is None and kernel.mode == AUTO and kernel.failure is None:
        kernel.start(_arguments(p, 0j, 0j, 0.0, 0, 0.0, 0.0, 0.0, 0.0, 0, True))


def await_loading(timeout: float) -> bool:
    """Wait at most ``timeout`` s of wall time for the compiled step that :func:`prepare`
    (a resonant slider's creation) began to load; whether it is ready.  A run that goes as
    fast as it can (lockstep) waits for it before it starts: a load from the on-disk cache
    takes ~0.5 s, and a run started meanwhile steps interpreted, with the load taking the
    GIL from it.  A compile from scratch takes longer than any sensible ``timeout``: the run
    then starts interpreted and takes the compiled step when it is ready (same numbers)."""
    thread = KERNEL.thread
    if thread is not None and KERNEL.compiled is None:
        thread.join(timeout)
    return KERNEL.compiled is not None


def states_at(p: Plant, seg: Segment, c: complex, lam: complex, taus: list[float]) -> list[list[float]]:
    """The states ``taus`` into ``seg`` (x, v, acceleration, friction force, normal force,
    unreduced phase, z, vz each), the transient force Re(c*exp(lam*tau)) added unless ``c``
    is 0: :func:`~friction_sim.core.physics.transient.states_into`, compiled when it is ready
    and was compiled for the types of ``p`` and ``seg``, else plain (the same numbers)."""
    out, at = np.empty((8, len(taus))), np.array(taus, dtype=float)
    compiled = _sampler(p, seg)
    if compiled is not None:
        compiled.states(p, seg, complex(c), complex(lam), at, out)
    else:
        _transient.states_into(p, seg, c, lam, at, out)
    rows: list[list[float]] = out.T.tolist()
    return rows


def accelerations_at(p: Plant, seg: Segment, c: complex, lam: complex, taus: list[float]) -> list[list[float]]:
    """The slideway's (along, normal) acceleration ``taus`` into ``seg``:
    :func:`~friction_sim.core.physics.transient.accelerations_into`, compiled when ready
    (as :func:`states_at`)."""
    out, at = np.empty((2, len(taus))), np.array(taus, dtype=float)
    compiled = _sampler(p, seg)
    if compiled is not None:
        compiled.accelerations(p, float(seg.phase0), complex(c), complex(lam), at, out)
    else:
        _transient.accelerations_into(p, seg.phase0, c, lam, at, out)
    rows: list[list[float]] = out.T.tolist()
    return rows


def normal_accelerations(way: Slideway, frequency: float, t_start: float, times: Sequence[float]) -> list[float]:
    """q'' of the slideway ``way`` at ``times`` (see
    :func:`~friction_sim.core.physics.exciter.normal_accelerations_into`): compiled when it is
    ready and ``way`` holds floats and complex numbers as compiled, else plain (the same numbers)."""
    out, at = np.empty(len(times)), np.array(times, dtype=float)
    compiled = KERNEL.compiled if KERNEL.mode != PLAIN else None
    if compiled is not None and _flat_fits(way, _STILL_SHAPE):
        compiled.slideway(way, float(frequency), float(t_start), at, out)
    else:
        _exciter.normal_accelerations_into(way, frequency, t_start, at, out)
    values: list[float] = out.tolist()
    return values


def _sampler(p: Plant, seg: Segment) -> CompiledStep | None:
    """The compiled code if it is ready and fits ``p`` and ``seg`` (None: the plain samplers run)."""
    compiled = KERNEL.compiled
    if compiled is None or KERNEL.entry(p) is None or not compiled.segment_fits(seg):
        return None
    return compiled


def _arguments(p: Plant, c: complex, lam: complex, horizon: float, mode: int, phase0: float, v0: float,
               vz0: float, z0: float, closing: int, grounded: bool) -> tuple[Any, ...]:
    """The step's arguments as the compiled code takes them (its types)."""
    return (p, complex(c), complex(lam), float(horizon), int(mode), float(phase0), float(v0), float(vz0),
            float(z0), int(closing), bool(grounded), WORK)


def transient_step(p: Plant, c: complex, lam: complex, horizon: float, mode: int, phase0: float, v0: float,
                   vz0: float, z0: float, closing: int, grounded: bool) -> Step:
    """:func:`~friction_sim.core.physics.transient.transient_step`, compiled when ready."""
    args = _arguments(p, c, lam, horizon, mode, phase0, v0, vz0, z0, closing, grounded)
    kernel = KERNEL
    if kernel.compiled is None and kernel.mode != PLAIN and kernel.failure is None:
        thread = kernel.start(args)
        if kernel.mode == COMPILED and thread is not None:
            thread.join()
    entry = kernel.entry(p)
    return entry(*args) if entry is not None else _transient.transient_step(*args)


__all__ = ["AUTO", "COMPILED", "KERNEL", "MODES", "PLAIN", "WORK", "CompiledStep", "Kernel", "accelerations_at",
           "await_loading", "compile_step", "compiled_ready", "failure", "mode", "normal_accelerations", "search_steps",
           "states_at", "transient_step", "use"]
