"""The heap of a process that runs nodes: a bound on glibc's per-thread arenas, and
the garbage collector kept off what was there before a run.

glibc gives threads that allocate at once arenas of their own, up to eight per
core, and keeps what is freed in each.  A node process has many threads (the
DDS middleware's, the slider's loop, the recorder's writer, an executor's), so
its resident memory grew with what every arena held on to: the demo feeder's
simulated hour (``bench/soak.py``) ended 10-20 % above its first minute,
varying from run to run, and 7 % with two arenas (the rest is the
experiment's own per-period series, which grow by design).  ``MALLOC_ARENA_MAX``
set in the environment has the same effect and takes precedence: a user's
setting is left as it is.

Python's cyclic garbage collector, when it collects its oldest generation,
walks every object the process holds: after start-up (rclpy, numpy, Numba,
the nodes) that is ~80 ms of the GIL, stopped in the middle of a run, and
it comes when allocation counts say so (an experiment in lockstep ran a third
slower for the one it met; a real-time slider fell that far behind its
clock).  :func:`run_heap` freezes what exists when a run starts
(``gc.freeze``): collections during the run walk only what the run made.
Nothing is lost: reference counting frees as always, and what was frozen is
handed back to the collector when the run ends.

Within a run the youngest generation is collected every
:data:`RUN_YOUNG_THRESHOLD` net allocations, not every 700: a run keeps what
it makes (its records on their way, its series), ~10,000 objects in the 3 s
of acceptance case 7, and the collector walked them 14 times, 3-7 ms of the
GIL in a run that takes ~150 ms; its few cycles wait a little longer.
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
import os
from collections.abc import Iterator

#: Net allocations between collections of the youngest generation within a run (Python's default is 700).
RUN_YOUNG_THRESHOLD = 10_000
#: Arenas a node process uses at most (glibc's M_ARENA_MAX; two is what is commonly set for
#: servers with many threads: memory flat, the allocator's locks barely contended here).
ARENAS = 2
#: glibc's mallopt() parameter for the arena bound (malloc.h).
_M_ARENA_MAX = -8


def limit_heap_arenas(arenas: int = ARENAS) -> bool:
    """Bound glibc's arenas to ``arenas`` for this process, before its threads start; whether it
    was set (not on another C library, nor when ``MALLOC_ARENA_MAX`` says otherwise already)."""
    if "MALLOC_ARENA_MAX" in os.environ:
        return False
    with contextlib.suppress(OSError, AttributeError):
        return bool(ctypes.CDLL(None).mallopt(_M_ARENA_MAX, arenas))
    return False


@contextlib.contextmanager
def run_heap() -> Iterator[None]:
    """Within it the garbage collector leaves alone the objects that existed when it began
    (``gc.freeze``); at its end they are the collector's again (``gc.unfreeze``: what a
    run left unreachable is collected later, outside it).  Not nested: the end of an
    inner one would hand back the outer one's objects too (as it hands back the few
    hundred Python 3.12 freezes at start-up: the collector then walks them, as 3.11's
    and 3.13's does).  Within it the youngest generation is collected every
    :data:`RUN_YOUNG_THRESHOLD` net allocations (or as set, if more)."""
    thresholds = gc.get_threshold()
    gc.freeze()
    gc.set_threshold(max(thresholds[0], RUN_YOUNG_THRESHOLD), *thresholds[1:])
    try:
        yield
    finally:
        gc.set_threshold(*thresholds)
        gc.unfreeze()


__all__ = ["ARENAS", "RUN_YOUNG_THRESHOLD", "limit_heap_arenas", "run_heap"]
