"""The population engine: the single slider's physics, compiled with Numba.

Every function of :mod:`friction_sim.core.physics` (and the exact angle
helpers of :mod:`friction_sim.core.model.params`) is registered with Numba as
it is (``register_jitable``: called from Python it stays the plain function
the single slider runs), and one loop over sliders calls them compiled: each
slider is advanced event by event to its own end by the single slider's
stepper (:mod:`~friction_sim.core.physics.stepper`), in the order
:meth:`~friction_sim.core.engine.single.Slider.advance_to` takes (period starts
before an event at the same phase, then the samples, then the event and the
step after it), in parallel over cores (``prange``).  There are no rounds: a
bouncer never holds up the others.  The functions are the same, and Numba
calls the same libm as CPython (and never fuses a multiply-add), so a
slider's window is the single slider's bit for bit; only its samples, which
the single slider evaluates at an array of times with numpy's sin, may differ
in their last bits.

Like the single slider it keeps a memo of worked-out steps by segment start
(``seg[:START]``: a periodic motion repeats them bit for bit), held its own
way: the single slider's is a dict, this one a table of ``MEMO`` slots a
thread reuses slider after slider (a dict in compiled code would cost more
than the step it saves).  With ``shortcut`` it looks for a repeat of the
state at a period start, bit for bit, up to ``RING`` periods back: from there
every later period start follows by adding the last repeat's increments, and
the window is filled in without stepping through it.

A resonant slider whose exciter starts off its steady state (:data:`INITIAL`:
from rest, or after a step of drive level or frequency at t = 0) runs the
exciter's transient as the single slider does after ``set_inputs`` at t = 0:
the stepper's transient functions (the exciter after the change, each
segment's transient force and look-ahead, the cut where it ends, the segment
from the same motion) and the transient's root search, compiled, the very
functions the single slider runs.  Under the transient no step is kept in the
memo and no state repeats (its force differs from period to period): the
shortcut waits until it has settled.

Importing this module imports Numba, which the nodes never do: compiling
happens on a population's first run (tens of seconds), after that from the
on-disk cache (:func:`cache_directory`), under a key that changes with every
source file the compiled code depends on.
"""

from __future__ import annotations

import hashlib
import inspect
import os
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba
import numpy as np
from numba.extending import register_jitable

from friction_sim.core.model import dimensionless as _dimensionless
from friction_sim.core.model import params as _params
from friction_sim.core.model import spec
from friction_sim.core.model.dimensionless import TWO_PI
from friction_sim.core.physics import exciter as _exciter
from friction_sim.core.physics import numerics as _numerics
from friction_sim.core.physics import plant as _plant
from friction_sim.core.physics import roots as _roots
from friction_sim.core.physics import segment as _segment
from friction_sim.core.physics import stepper as _stepper
from friction_sim.core.physics import transient as _transient
from friction_sim.core.physics.exciter import Slideway, eigenvalue, steady_response, steady_slideway
from friction_sim.core.physics.plant import Plant, excitation, kostek_applies, plant
from friction_sim.core.physics.roots import NEVER
from friction_sim.core.physics.segment import START, STUCK, Segment, Step, evaluate
from friction_sim.core.physics.stepper import (
    MAX_EVENTS_AT_ONE_INSTANT,
    Anchor,
    advance,
    continued,
    exciter_changed,
    moved,
    offset,
    period_start,
    schedule,
    settled_at,
    step_of,
    to_cycle,
    transient_end,
    transient_window,
)
from friction_sim.core.physics.transient import transient_evaluate, transient_step

#: Numba's run-time settings (untyped: set and read by name).
_CONFIG: Any = numba.config

#: Period starts remembered per slider for the periodic shortcut (longest repeat looked for).
RING = 8
#: Slots of the memo of worked-out steps per slider (by a hash of the segment start;
#: a periodic motion has a handful of starts, a bouncer's rarely repeat).
MEMO = 512
#: Event kinds (the count columns).
KINDS = 5
#: The columns of the per-slider inputs, in the order of ``plant``'s arguments.
COLUMNS = ("mass", "mu", "gravity", "static_ratio", "excitation_angle", "excitation_phase", "track_inclination",
           "restitution", "drive_force", "excitation_amplitude", "excitation_frequency", "external_force_x",
           "external_force_z", "natural_frequency", "damping_ratio", "full_drive_acceleration", "drive_level")
#: The inputs whose steady state a resonant slider's exciter starts from at t = 0 (the last columns of
#: the per-slider values: equal to the slider's own, it starts in its steady state, with no transient).
INITIAL = spec.EXCITER_START
#: The result codes of one slider (``status``).
DONE, NO_PROGRESS = 0, 1

#: The modules whose plain functions the compiled code calls: the physics, written once.
PHYSICS = (_numerics, _roots, _exciter, _plant, _segment, _stepper, _transient)


def _register() -> None:
    """Make every function of the physics modules (and the exact angle helpers of
    the parameters) callable from compiled code, as it is: a new function of the
    physics needs no entry anywhere (those that take dataclasses, such as
    plant_of, are registered too, and simply never called from compiled code)."""
    functions: list[Callable[..., Any]] = [value for module in PHYSICS for value in vars(module).values()
                                           if inspect.isfunction(value) and value.__module__ == module.__name__]
    for function in (*functions, _params.sin_degrees, _params.cos_degrees):
        register_jitable(function)


_register()


def _sources() -> list[Path]:
    """The files whose code the compiled engine is made of."""
    modules = (_params, _dimensionless, *PHYSICS)
    return [Path(module.__file__) for module in modules if module.__file__] + [Path(__file__)]


def cache_directory() -> Path:
    """Where compiled code is kept: ``$NUMBA_CACHE_DIR``, else the user's cache
    (``$XDG_CACHE_HOME``, else ~/.cache), under friction_sim/numba/<key>, where
    the key hashes every source the code depends on, where it lies, and the Numba
    version (Numba itself only notices a change of this file, not of the physics
    it calls; and it takes a file of another modification time for a changed one:
    two checkouts of the same sources sharing a directory recompiled in turn).
    A package installed read-only (a colcon install, a system prefix) compiles
    into the user's cache; where that cannot be written, into the temporary
    directory."""
    digest = hashlib.sha256(numba.__version__.encode())
    for source in _sources():
        digest.update(str(source.resolve()).encode())
        digest.update(source.read_bytes())
    base = os.environ.get("NUMBA_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "friction_sim", "numba")
    for root in (Path(base), Path(tempfile.gettempdir()) / f"friction_sim-numba-{os.getuid()}"):
        directory = root / digest.hexdigest()[:16]
        try:
            directory.mkdir(parents=True, exist_ok=True)
            probe = directory / f".probe-{os.getpid()}"
            probe.touch()
            probe.unlink()
            return directory
        except OSError:
            continue
    raise OSError(f"no writable cache directory for compiled code (tried {base} and the temporary directory)")


#: Where this process keeps and finds the compiled engine (see :func:`cache_directory`).
CACHE_DIR = cache_directory()
_CONFIG.CACHE_DIR = str(CACHE_DIR)


# -- one slider ------------------------------------------------------------------------------------


@numba.njit(cache=True)
def _memo_slot(key: tuple[int, float, float, float, float, int, bool]) -> int:
    """The memo slot of a segment start (``seg[:START]``): a hash of it (equal starts, equal slots)."""
    bits = np.array([key[1], key[2], key[3]]).view(np.uint64)
    mixed = (bits[0] * np.uint64(0x9E3779B97F4A7C15)) ^ (bits[1] * np.uint64(0xC2B2AE3D27D4EB4F)) ^ bits[2]
    mixed ^= np.uint64(key[0] + 4 * key[5] + 16)
    mixed ^= mixed >> np.uint64(29)
    return int(mixed % np.uint64(MEMO))


#: The state record of a slider at rest at t = 0, phase 0, x = 0 (the start of every slider).
_REST = Segment(STUCK, 0.0, 0.0, 0.0, 0.0, 0, False, 0.0, 0.0, 0.0, 0.0, 0, 0.0, 0.0, 0)


@numba.njit(cache=True)
def _transient_start(p: Plant, seg: Segment, way: Slideway, way_t0: float, mass: float, until: float,
                     frequency: float, work: np.ndarray) -> tuple[Step, complex, float]:
    """(step, c, look_until) of ``seg``, which starts under the exciter's transient, as the
    single slider's ``_start`` works them out: its transient force and its next step,
    sought up to ``look_until`` (:func:`~friction_sim.core.physics.stepper.transient_window`,
    :func:`~friction_sim.core.physics.transient.transient_step`; never kept in the memo)."""
    c, horizon = transient_window(way, way_t0, mass, until, seg.t0, frequency)
    return (transient_step(p, c, way.lam, horizon, seg.mode, seg.phase0, seg.v0, seg.vz0, seg.z0, seg.closing,
                           seg.grounded, work), c, seg.t0 + horizon)


@numba.njit(cache=True)
def _run_one(values: np.ndarray, impulsive: bool, resonant: bool, can_slip: bool, settle: int, end: int,
             times: np.ndarray, shortcut: bool, window: np.ndarray, counts: np.ndarray, samples: np.ndarray,
             sample_modes: np.ndarray, memo_keys: Any, memo_steps: Any, memo_owner: np.ndarray, owner: int,
             work: np.ndarray) -> int:
    """Advance one slider from rest at t = 0, phase 0, x = 0 to the start of period
    ``end`` (and past the last sample time) with the single slider's stepper
    (:mod:`~friction_sim.core.physics.stepper`); write x, stuck and flight time at
    period starts ``settle`` and ``end`` into ``window`` (2, 3), the event counts
    between them into ``counts`` (5,), and the state (x, v, z, vz) at ``times`` into
    ``samples`` (K, 4) and ``sample_modes``.  The memo of worked-out steps
    (``memo_*``, by segment start ``seg[:START]``, as the single slider keeps one)
    is a thread's, reused slider after slider: a slot is this slider's where
    ``memo_owner`` holds ``owner``.

    A resonant slider whose exciter starts from the steady state of other inputs
    (the :data:`INITIAL` columns: a start from rest, a step of drive or frequency
    at t = 0) runs the exciter's transient as the single slider does after
    ``set_inputs`` at t = 0: the same stepper functions, its segments cut where
    the single slider cuts them, its root search counting into ``work``."""
    mass, mu, gravity, static_ratio, angle = values[0], values[1], values[2], values[3], values[4]
    psi, inclination, restitution, drive, amplitude = values[5], values[6], values[7], values[8], values[9]
    frequency, force_x, force_z = values[10], values[11], values[12]
    amplitude, lag = excitation(mass, resonant, amplitude, frequency, values[13], values[14], values[15], values[16])
    kostek = not resonant and kostek_applies(angle, inclination, static_ratio, amplitude, mass * gravity, force_z)
    p = plant(mass, mu, gravity, static_ratio, angle, psi, inclination, restitution, impulsive, drive, amplitude,
              frequency, force_x, force_z, lag, kostek, kostek and can_slip)
    anchor = Anchor(0.0, 0, 0.0, frequency, p.omega)  # (a segment's offset s0 is then its time t0)
    seg = _REST
    # the exciter's transient: the slideway, when it started, when it settles (-inf: never there)
    lam = 0j
    way, way_t0, until = steady_slideway(0.0, 0.0, 0.0, lam), 0.0, -NEVER
    if resonant and (values[17] != values[16] or values[18] != frequency):
        lam = eigenvalue(values[13], values[14])
        start, lag0 = steady_response(values[17], values[15], values[18], values[13], values[14])
        steady, lag1 = steady_response(values[16], values[15], frequency, values[13], values[14])
        way, delay = exciter_changed(steady_slideway(start, lag0, TWO_PI * values[18], lam), 0.0, 0.0, steady, lag1,
                                     TWO_PI * frequency, lam, mass, p)
        if delay > 0.0:
            until = delay
    total = np.zeros(KINDS, np.int64)
    step, c, look_until = _transient_start(p, seg, way, way_t0, mass, until, frequency, work) if seg.t0 < until else (
        step_of(p, seg), 0j, NEVER)
    ring_keys = [seg[:START]] * RING
    ring_n = np.full(RING, -1, np.int64)
    ring_whole = np.zeros(RING, np.int64)
    ring_values = np.zeros((RING, 3))
    ring_counts = np.zeros((RING, KINDS), np.int64)
    got = np.zeros(2, np.bool_)
    mark_n = settle if not shortcut else 0
    mark_s = offset(anchor, mark_n, 0.0)
    k_samples = times.size
    k = 0
    while True:
        next_s, next_t = schedule(anchor, seg, step)
        # under the transient the segment may be cut first (the single slider's Slider.advance_to)
        cut_t, cut = transient_end(seg, c, look_until, next_t) if c != 0j else (next_t, False)
        ends = next_s != NEVER or cut
        # period starts that come first (by phase: a mark and an event may round to one t; before a cut by time)
        while mark_n <= end and mark_s <= next_s and not (cut and anchor.t + mark_s >= cut_t):
            tau = to_cycle(mark_n, seg.cycles, seg.phase0, anchor.omega)
            x, stuck_at, flight_at = period_start(seg, tau, moved(p, seg, c, lam, tau))
            for side in range(2):
                if mark_n == (settle if side == 0 else end):
                    window[side, 0], window[side, 1], window[side, 2] = x, stuck_at, flight_at
                    counts[side * KINDS:(side + 1) * KINDS] = total
                    got[side] = True
            periodic = False
            if shortcut and c == 0j:  # (under the transient no state repeats: its force differs)
                slot = mark_n % RING
                key, whole = seg[:START], mark_n - seg.cycles
                period = 0
                eligible = next_s != NEVER and k >= k_samples  # (samples are taken event by event)
                for back in range(RING, 0, -1):  # the smallest repeat wins
                    old = (mark_n - back) % RING
                    if (eligible and mark_n - back >= 0 and ring_n[old] == mark_n - back and ring_keys[old] == key
                            and ring_whole[old] == whole):
                        period = back
                if period > 0:
                    base = mark_n - period
                    first = base % RING
                    for side in range(2):
                        target = settle if side == 0 else end
                        if not got[side]:
                            q, r = divmod(target - base, period)
                            at = (base + r) % RING
                            window[side, 0] = ring_values[at, 0] + q * (x - ring_values[first, 0])
                            window[side, 1] = ring_values[at, 1] + q * (stuck_at - ring_values[first, 1])
                            window[side, 2] = ring_values[at, 2] + q * (flight_at - ring_values[first, 2])
                            for kind in range(KINDS):
                                counts[side * KINDS + kind] = (ring_counts[at, kind]
                                                               + q * (total[kind] - ring_counts[first, kind]))
                            got[side] = True
                    periodic = True
                ring_keys[slot], ring_n[slot], ring_whole[slot] = key, mark_n, whole
                ring_values[slot, 0], ring_values[slot, 1], ring_values[slot, 2] = x, stuck_at, flight_at
                ring_counts[slot] = total
            if periodic:
                mark_n = end + 1
            elif shortcut and ends and mark_n < end:
                mark_n += 1
            else:
                mark_n = settle if mark_n < settle else (end if mark_n < end else end + 1)
            mark_s = offset(anchor, mark_n, 0.0) if mark_n <= end else NEVER
        # samples before the event (or the cut)
        limit = cut_t if cut else next_s
        while k < k_samples and times[k] < limit:
            tau = times[k] - seg.t0
            if c != 0j:
                x, v, _, _, _, _, z, vz = transient_evaluate(p, seg, c, lam, tau)
            else:
                x, v, _, _, _, _, z, vz = evaluate(p, seg, tau)
            samples[k, 0], samples[k, 1], samples[k, 2], samples[k, 3] = x, v, z, vz
            sample_modes[k] = seg.mode
            k += 1
        if mark_n > end and k >= k_samples:
            return DONE
        if cut:  # a new segment from the same motion; the transient dropped once it has settled
            seg = continued(p, seg, c, lam, cut_t, anchor.t)
            way, way_t0, until = settled_at(way, way_t0, until, cut_t)
        elif next_s == NEVER:  # an endless segment: every later period start is in it
            continue
        else:  # the event, and the step of the segment it starts
            after = advance(seg, step, next_s, next_t)
            if after.at_instant > MAX_EVENTS_AT_ONE_INSTANT:
                return NO_PROGRESS
            total[step.kind] += 1
            seg = after
        if seg.t0 < until:  # under the transient: its own step, never kept
            step, c, look_until = _transient_start(p, seg, way, way_t0, mass, until, frequency, work)
            continue
        c = 0j
        key = seg[:START]
        slot = _memo_slot(key)
        if memo_owner[slot] == owner and memo_keys[slot] == key:
            step = memo_steps[slot]
        else:
            step = step_of(p, seg)
            memo_steps[slot], memo_keys[slot], memo_owner[slot] = step, key, owner


@numba.njit(parallel=True, cache=True)
def _run_all(values: np.ndarray, impulsive: np.ndarray, resonant: np.ndarray, can_slip: np.ndarray, settle: int,
             end: int, times: np.ndarray, shortcut: bool, window: np.ndarray, counts: np.ndarray, samples: np.ndarray,
             sample_modes: np.ndarray, status: np.ndarray, blocks: int) -> None:
    """Every slider, in ``blocks`` blocks of neighbours handed to the cores (more
    blocks than cores, so a block of bouncers does not leave a core idle at the
    end); each block allocates its memo once."""
    n = values.shape[0]
    for block in numba.prange(blocks):
        first, stop = block * n // blocks, (block + 1) * n // blocks
        memo_keys = [_REST[:START]] * MEMO
        memo_owner = np.full(MEMO, -1, np.int64)
        memo_steps = [step_of(plant(1.0, 0.1, 10.0, 1.0, 90.0, 0.0, 0.0, 0.0, True, 0.7, 5.0, 50.0, 0.0, 0.0, 0.0,
                                    True, True), _REST)] * MEMO
        work = np.zeros(1, np.int64)
        for i in range(first, stop):
            status[i] = _run_one(values[i], impulsive[i], resonant[i], can_slip[i], settle, end, times, shortcut,
                                 window[i], counts[i], samples[i], sample_modes[i], memo_keys, memo_steps, memo_owner,
                                 i, work)


@numba.njit(cache=True)
def _margins(values: np.ndarray, resonant: np.ndarray, margins: np.ndarray) -> None:
    """slip_margin of every slider of Kostek's model (the others slip or not by their general onsets)."""
    for i in range(values.shape[0]):
        row = values[i]
        weight = row[0] * row[2]
        if not resonant[i] and kostek_applies(row[4], row[6], row[3], row[9], weight, row[12]):
            margins[i] = _plant.slip_margin(abs(row[8] + row[11]), weight - row[12] - row[9], row[1])
        else:
            margins[i] = 1

_LOCK = threading.Lock()
#: Compile time [s] on the development machine (2 cores: 40 s idle, 53 s loaded, with the
#: exciter's transient compiled in), for the progress line's estimate.
COMPILE_SECONDS = 45


def cached() -> bool:
    """Whether the compiled engine is in the cache already (else its first run compiles it)."""
    return any(CACHE_DIR.rglob("*._run_all-*.nbi"))  # (Numba files them one folder down)


def prepare(progress: Callable[[str], None] | None = None) -> float:
    """Load the compiled engine, compiling it first if the cache does not hold it
    (saying so on ``progress``); the seconds it took.  A sweep calls it once before
    it hands chunks to local workers, so they load the cache instead of compiling
    side by side."""
    started = time.perf_counter()
    run({name: np.ones(1) for name in COLUMNS} | {"landing_friction": np.array(["none"]),
                                                  "actuator": np.array(["force"])}, lambda i: True, 0, 1,
        np.zeros(1), False, 1, progress)
    return time.perf_counter() - started


def run(columns: dict[str, np.ndarray], exact_can_slip: Callable[[int], bool], settle: int, count: int,
        times: np.ndarray | None, shortcut: bool, threads: int | None,
        progress: Callable[[str], None] | None,
        initial: dict[str, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None,
                                                               np.ndarray | None]:
    """Run a validated population (``columns``: every field, one value per slider):
    (window (N, 2, 3): x, stuck and flight time at the period starts ``settle``
    and ``settle + count``; counts (N, 2, 5): the events before each; samples
    (N, K, 4) of x, v, z, vz at ``times`` and their modes, or None).
    ``exact_can_slip(i)``: can_ever_slip of slider i, asked for the few that
    :func:`~friction_sim.core.physics.plant.slip_margin` cannot tell; ``threads``:
    cores to use (None: all); ``progress`` hears when the engine compiles; ``initial``:
    the inputs of :data:`INITIAL` whose steady state a resonant slider's exciter starts
    from (one value per slider; a field not given: the slider's own, steady)."""
    n = len(columns["mass"])
    initial = initial or {}
    stacked = [columns[name] for name in COLUMNS] + [initial.get(name, columns[name]) for name in INITIAL]
    values = np.ascontiguousarray(np.stack([np.asarray(column, dtype=np.float64) for column in stacked], axis=1))
    impulsive = np.asarray(columns["landing_friction"] == "impulsive", dtype=np.bool_)
    resonant = np.asarray(columns["actuator"] == "resonant", dtype=np.bool_)
    sample_times = np.zeros(0) if times is None else np.ascontiguousarray(times, dtype=np.float64)
    k = sample_times.size
    window = np.zeros((n, 2, 3))
    counts = np.zeros((n, 2 * KINDS), np.int64)
    samples = np.zeros((n, k, 4))
    modes = np.zeros((n, k), np.int8)
    status = np.zeros(n, np.int64)
    margins = np.zeros(n, np.int64)
    with _LOCK:  # (Numba's default thread pool takes one caller at a time)
        compiling = not cached()
        if progress is not None and compiling:
            progress(f"compiling the population engine (first use of this version on this machine, about "
                     f"{COMPILE_SECONDS} s; cached in {CACHE_DIR})")
        started = time.perf_counter()
        numba.set_num_threads(max(1, min(threads or _CONFIG.NUMBA_NUM_THREADS, _CONFIG.NUMBA_NUM_THREADS)))
        _margins(values, resonant, margins)
        can_slip = margins > 0
        for i in np.flatnonzero(margins == 0):
            can_slip[i] = exact_can_slip(int(i))
        blocks = min(n, 16 * _CONFIG.NUMBA_NUM_THREADS)
        _run_all(values, impulsive, resonant, can_slip, settle, settle + count, sample_times, shortcut, window,
                 counts, samples, modes, status, blocks)
        if progress is not None and compiling:
            progress(f"population engine compiled in {time.perf_counter() - started:.0f} s")
    stalled = np.flatnonzero(status == NO_PROGRESS)
    if stalled.size:
        from friction_sim.errors import SimulationFault

        raise SimulationFault(f"the general model made no progress: more than {MAX_EVENTS_AT_ONE_INSTANT} events at "
                              f"one instant for slider {int(stalled[0])}")
    return window, counts.reshape(n, 2, KINDS), (samples if times is not None else None), (
        modes if times is not None else None)


__all__ = ["COLUMNS", "INITIAL", "RING", "cache_directory", "cached", "prepare", "run"]
