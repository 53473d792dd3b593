"""The bounded queue between a recorder's producers and its writer thread.

:class:`~friction_sim.io.recorder.Recorder` owns the file; this queue owns the
back-pressure between the threads that hand it records (a node's tick, its
parameter service) and the one thread that writes them:

* a producer that finds the queue full waits for the writer (``block=True``),
  for as long as the writer makes progress and no longer: not once the
  recording has failed, is finishing, or the writer thread has ended;
  :attr:`RecordQueue.wait_seconds` and :attr:`RecordQueue.waits` say how long
  and how often (a real-time caller rebases its clock on them);
* with ``block=False`` what does not fit is dropped and counted
  (:attr:`RecordQueue.dropped`);
* once the recording has failed, later records are counted no-ops
  (:attr:`RecordQueue.unrecorded`) that never block;
* the writer takes everything queued at once, letting a batch gather for
  :data:`GATHER` after its first record, so it builds the state topics many
  at a time.

No record is lost silently: every message handed over is queued, or counted
as dropped or unrecorded.  Sizes count messages (a state makes three).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path

from friction_sim.io.recordwriter import Item

_log = logging.getLogger("friction_sim.io.recorder")

#: Messages a command or parameter change may queue beyond the capacity before
#: it waits (a flood brings at most the subscriptions' depth per topic and tick).
URGENT_HEADROOM = 4096
#: Wall time [s] the writer lets records gather after the first of a batch (unless the queue is
#: half full): a batch then holds a tick's worth many times over, written in one numpy pass.
GATHER = 0.02


class RecordQueue:
    """Records waiting for the writer thread, bounded to ``capacity`` messages.

    ``block``: a producer that finds the queue full waits for the writer (else
    the record is dropped and counted).  ``writer_alive`` says whether the
    writer thread still runs (a producer never waits for a writer that is
    gone).  ``path`` names the file in the warning about dropped messages.
    """

    def __init__(self, capacity: int, *, block: bool, path: Path, writer_alive: Callable[[], bool]) -> None:
        #: Messages the queue holds before a producer waits (or drops).
        self.capacity = int(capacity)
        self._block = block
        self._path = path
        self._writer_alive = writer_alive
        self._lock = threading.Lock()
        self._not_empty = threading.Condition(self._lock)
        self._not_full = threading.Condition(self._lock)
        self._items: deque[tuple[Item, int]] = deque()  # (record, messages it makes)
        self._pending = 0  # messages queued
        self._taken = 0  # messages the writer took from the queue
        self._stopping = False
        self._failed = False
        self._dropped = 0
        self._unrecorded = 0
        self._wait_ns = 0
        self._waits = 0
        self._warned_behind = False

    # -- the counts ---------------------------------------------------------------

    @property
    def dropped(self) -> int:
        """Messages the queue dropped: it was full and the producer does not
        wait, or they were handed over while (or after) the recording finished."""
        return self._dropped

    @property
    def unrecorded(self) -> int:
        """Messages not recorded because the recording had failed (:meth:`fail`)."""
        return self._unrecorded

    @property
    def wait_seconds(self) -> float:
        """Wall time [s] producers have waited for the writer so far."""
        return self._wait_ns / 1e9

    @property
    def waits(self) -> int:
        """How many times a producer waited for the writer."""
        return self._waits

    @property
    def failed(self) -> bool:
        """Whether the recording stopped on an error (see :meth:`fail`)."""
        return self._failed

    # -- the producers' side --------------------------------------------------------

    def put(self, item: Item, size: int, *, urgent: bool = False) -> bool:
        """Queue ``item`` (``size`` messages); False if it was not queued (counted).

        An ``urgent`` item (a command, a parameter change: few, and handled on
        the node's parameter-service thread too) may use :data:`URGENT_HEADROOM`
        messages beyond the capacity before it waits, so a node whose states
        keep the queue full still answers a parameter set at once."""
        with self._lock:
            if self._failed:
                self._unrecorded += size
                return False
            if self._stopping:
                self._dropped += size
                return False
            capacity = self.capacity + (URGENT_HEADROOM if urgent else 0)
            if self._pending and self._pending + size > capacity:
                if self._block:
                    if not self._wait_for_room(size, capacity):
                        if self._failed:
                            self._unrecorded += size
                        else:
                            self._dropped += size
                        return False
                else:
                    self._dropped += size
                    warn, self._warned_behind = not self._warned_behind, True
                    if warn:
                        _log.warning("recording %s: the writer falls behind; dropping messages (counted in the "
                                     "file)", self._path)
                    return False
            self._items.append((item, size))
            self._pending += size
            if len(self._items) == 1 or self.capacity // 2 <= self._pending < self.capacity // 2 + size:
                self._not_empty.notify()  # the first of a batch, or half full: not every call (a futex wake costs)
            return True

    def _wait_for_room(self, size: int, capacity: int) -> bool:
        """Wait (lock held) until ``size`` messages fit in ``capacity``; False if
        they never will: the recording failed or is finishing, or the writer is gone."""
        started = time.monotonic_ns()
        self._waits += 1
        try:
            while True:
                if self._failed or self._stopping or not self._writer_alive():
                    return False
                if not (self._pending and self._pending + size > capacity):
                    return True
                self._not_full.wait(0.1)  # woken by the writer's progress; the timeout only re-checks it lives
        finally:
            self._wait_ns += time.monotonic_ns() - started

    # -- the writer's side ----------------------------------------------------------

    def take(self, next_flush: float) -> tuple[list[Item], bool]:
        """The writer's next batch: everything queued, in order, once something
        is queued (after letting a batch gather) or at ``next_flush`` (monotonic
        time [s]) at the latest; and whether the writer should stop (finishing,
        and nothing left to write)."""
        with self._lock:
            while not self._items and not self._stopping:
                timeout = next_flush - time.monotonic()
                if timeout <= 0.0:
                    break
                self._not_empty.wait(timeout)
            if self._items and not self._stopping and self._pending < self.capacity // 2:
                self._not_empty.wait(GATHER)  # gather: a numpy pass, a wake-up and a GIL hand-over a batch
            batch = [item for item, _ in self._items]
            self._taken += self._pending
            self._items.clear()
            self._pending = 0
            self._not_full.notify_all()
            return batch, self._stopping and not batch

    def fail(self, written: int) -> None:
        """The recording failed with ``written`` messages in the file (or
        refused by the writer): count what is queued, or was taken but is not in
        the file, as unrecorded, and refuse what comes later (counted)."""
        with self._lock:
            self._failed = True
            # Queued, or taken but not in the file: a batch half written, the chunk that was being built.
            self._unrecorded += self._pending + self._taken - written
            self._items.clear()
            self._pending = 0
            self._not_full.notify_all()

    # -- finishing -------------------------------------------------------------------

    def stop(self) -> None:
        """Take no more records (counted as dropped); wake the writer to write
        what is queued and end, and any producer waiting for room."""
        with self._lock:
            self._stopping = True
            self._not_empty.notify_all()
            self._not_full.notify_all()

    def discard(self) -> None:
        """Count what a writer that ended early left in the queue (dropped, or
        unrecorded after a failure) and empty it: not lost silently."""
        with self._lock:
            if self._failed:
                self._unrecorded += self._pending
            else:
                self._dropped += self._pending
            self._items.clear()
            self._pending = 0


__all__ = ["GATHER", "URGENT_HEADROOM", "RecordQueue"]
