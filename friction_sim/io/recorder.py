"""Recording a run to one MCAP file that the ROS 2 tools open as a bag.

The file is laid out the way rosbag2's MCAP storage plugin (Jazzy) writes
it, so ``ros2 bag info run.mcap``, ``ros2 bag play run.mcap`` and Foxglove
read it as they read a recorded bag:

* profile ``ros2``; one schema per message type, named ``pkg/msg/Type``,
  encoding ``ros2msg``, whose data is the full definition rosbag2 stores
  (:func:`~friction_sim.io.typesupport.message_definition`);
* message encoding ``cdr`` (:func:`friction_sim.io.cdr.serialize`);
* channel metadata ``offered_qos_profiles`` (the YAML rosbag2 Jazzy writes,
  for the node's publishers: reliable, volatile, keep last 10) and
  ``topic_type_hash`` (RIHS01);
* chunked, zstd-compressed, with message indexes, statistics and summary;
* a metadata record ``friction_sim`` with the run's parameters, written first;
  and when the file is finished, a complete ``rosbag2`` metadata record
  (``serialized_metadata``, bag metadata version 9) as rosbag2 writes on
  close.  A file that was never finished has no ``rosbag2`` record at all
  rather than a partial one.

Log times are simulation time in whole nanoseconds.

:class:`Recorder` is a :class:`~friction_sim.io.sinks.Sink`: the slider node
and :func:`friction_sim.io.offline.record_offline` hand it what a run
produces.  Its methods only put a record on a bounded queue: a background
thread builds the messages, serializes, compresses and writes, so a 1 kHz
tick thread never waits for the disk.  If that thread falls behind, records
are dropped and counted, never queued without bound and never blocking the
caller.

Durability: the writer thread ends the current chunk (``Writer.flush()``:
the chunk and its message indexes are written whole) and flushes the file
object every ``flush_interval`` (0.25 s) of wall time, so a writer killed
with SIGKILL loses about that much plus the writer's backlog (normally a
message or two); the promise is at most a second, which leaves room for a
process that the machine stalls for a while.  :mod:`friction_sim.io.reader`
reads such a file up to its last complete record.  Ending on SIGINT or
SIGTERM finishes the file (summary and footer) as long as the process gets
to call :meth:`Recorder.finish` (context manager exit, ``destroy_node``, or
the ``atexit`` hook every open recorder registers).
"""

from __future__ import annotations

import atexit
import logging
import os
import queue
import threading
import time
import weakref
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import IO, Any

from friction_sim.core import spec
from friction_sim.core.commands import Outcome
from friction_sim.core.events import Event, SliderState
from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.realtime import PeriodSummary
from friction_sim.errors import ParameterError, RecordingError
from friction_sim.io.bagfile import BagFile, RecordingStats
from friction_sim.io.messages import (
    STATE_TOPICS,
    command_message,
    event_message,
    fill_state_messages,
    mean_velocity_message,
    parameters_message,
    rejection_message,
    seconds_to_ns,
    state_messages,
    value_text,
)
from friction_sim.io.typesupport import (
    DEFAULT_QOS,
)

_log = logging.getLogger("friction_sim.io.recorder")

#: Name of the MCAP metadata record that marks a friction_sim recording.
METADATA_NAME = "friction_sim"
#: Name of the metadata record written on finish with the recorder's counts.
SUMMARY_METADATA_NAME = "friction_sim_summary"
#: Value of the "format" key of the friction_sim metadata record.
FORMAT = "friction_sim-recording/1"
#: The plant and input fields a recording starts from (what ``--verify`` rebuilds).
PLANT_FIELDS = tuple(spec.PLANT)
INPUT_FIELDS = tuple(spec.INPUTS)


def plant_parameters(params: SliderParams, inputs: Inputs) -> dict[str, float]:
    """The physical parameters and inputs a run starts with, by field name
    (what ``--verify`` rebuilds the simulation from)."""
    values = {name: float(getattr(params, name)) for name in PLANT_FIELDS}
    values.update({name: float(getattr(inputs, name)) for name in INPUT_FIELDS})
    return values


def recording_metadata(params: SliderParams, inputs: Inputs, *, log_rate: float, frame_id: str = "slideway",
                       **extra: Any) -> dict[str, str]:
    """The ``friction_sim`` metadata record: the format, the log rate, the frame
    and the parameters at start (full precision), plus ``extra``."""
    data = {"format": FORMAT, "log_rate": repr(float(log_rate)), "frame_id": frame_id}
    data.update({name: repr(float(value)) for name, value in plant_parameters(params, inputs).items()})
    data.update({name: value_text(value) for name, value in extra.items()})
    return data


Item = tuple[Any, ...]
_STOP: Item = ("stop",)
_open_recorders: weakref.WeakSet[Recorder] = weakref.WeakSet()


@atexit.register
def _finish_open_recorders() -> None:
    """Finish every recorder still open when the interpreter exits."""
    for recorder in list(_open_recorders):
        try:
            recorder.finish()
        except Exception:  # noqa: BLE001 - at exit, report and go on
            _log.exception("could not finish recording %s", recorder.path)


class Recorder:
    """Writes ROS 2 messages to one MCAP file from a background thread; a Sink.

    >>> with Recorder("run.mcap", metadata={"mass": 1.0}) as rec:   # doctest: +SKIP
    ...     rec.write("drive_force", Float64(data=0.7), 1_000_000)

    :meth:`write`, :meth:`add_metadata` and the sink methods (``on_*``) are
    thread-safe and cheap (one non-blocking queue put); they never block
    unless the recorder was made with ``block_when_full=True`` (offline
    producers that must not lose anything).  A message passed to
    :meth:`write` is serialized later, on the writer thread: do not change it
    afterwards (the sink methods take immutable records and build the
    messages on that thread).

    ``metadata`` becomes the ``friction_sim`` MCAP metadata record, written
    first.  ``flush_interval`` [s of wall time] bounds what a SIGKILL can
    lose.  Errors opening the file raise :class:`RecordingError`; a failure
    of the writer thread (disk full) is raised by :meth:`finish`.
    """

    def __init__(
        self, path: str | os.PathLike[str], metadata: Mapping[str, Any] | None = None, *,
        metadata_name: str = METADATA_NAME, queue_size: int = 65536, block_when_full: bool = False,
        flush_interval: float = 0.25, chunk_size: int = 4 * 1024 * 1024, fsync: bool = False,
        qos_profiles: list[dict[str, Any]] | None = None,
    ) -> None:
        self.path = Path(path)
        if not flush_interval > 0.0:
            raise ParameterError("flush_interval", flush_interval, "must be > 0 s")
        self.flush_interval = float(flush_interval)
        self._fsync = fsync
        self._block = block_when_full
        self._queue: queue.Queue[Item] = queue.Queue(maxsize=queue_size)
        self.stats = RecordingStats(self.path)
        self._dropped = 0
        self._dropped_lock = threading.Lock()
        self._finish_lock = threading.Lock()
        self._finished = False
        self._failure: BaseException | None = None
        self._bad_items: set[tuple[Any, ...]] = set()
        self._queue_front: Item | None = None  # taken from the queue, not handled yet
        self._templates: tuple[Any, Any, Any] | None = None  # pose, twist, wrench, refilled per state
        self._stream = self._open()
        self._file = self._start(qos_profiles if qos_profiles is not None else DEFAULT_QOS, chunk_size,
                                 metadata_name, metadata)
        self._thread = threading.Thread(target=self._run, name="mcap_writer", daemon=True)
        self._thread.start()
        _open_recorders.add(self)

    def _open(self) -> IO[bytes]:
        """The output file, opened for writing (a one-line RecordingError if it cannot be)."""
        try:
            return open(self.path, "wb")
        except OSError as error:
            raise RecordingError(f"cannot write recording {self.path}: {error.strerror or error}") from None

    def _start(self, qos_profiles: list[dict[str, Any]], chunk_size: int, metadata_name: str,
               metadata: Mapping[str, Any] | None) -> BagFile:
        """Write the header and the metadata record, and flush them."""
        try:
            mcap = BagFile(self._stream, qos_profiles, chunk_size, self.stats)
            mcap.writer.start(profile="ros2", library=_library())
            if metadata is not None:
                mcap.writer.add_metadata(metadata_name, {str(k): value_text(v) for k, v in metadata.items()})
            self._file = mcap
            self._flush()
        except OSError as error:
            self._stream.close()
            raise RecordingError(f"cannot write recording {self.path}: {error.strerror or error}") from None
        return mcap

    # -- the caller's side: the sink -----------------------------------------------

    def on_states(self, states: Sequence[SliderState], frame_id: str) -> None:
        """Queue exact states as pose, velocity and friction_force at their own times."""
        for state in states:
            self._put(("state", state, frame_id))

    def on_event(self, event: Event) -> None:
        """Queue a stick/slip event on ``events``."""
        self._put(("event", event))

    def on_period(self, period: PeriodSummary, frame_id: str) -> None:
        """Queue a period's mean velocity on ``mean_velocity``."""
        self._put(("period", period, frame_id))

    def on_command(self, outcome: Outcome, frame_id: str) -> None:
        """Queue a handled command: accepted on its own topic, refused on
        ``rejected_commands``, at the simulation time it was handled."""
        self._put(("command", outcome, frame_id))

    def on_parameters(self, values: Mapping[str, Any], t: float, *, changed: bool) -> None:
        """Queue parameter values on ``parameters`` (new at start, or changed)."""
        self._put(("parameters", dict(values), t, changed))

    def close(self) -> None:
        """Finish the file (see :meth:`finish`)."""
        self.finish()

    # -- the caller's side: messages and metadata ------------------------------------

    def write(self, topic: str, msg: Any, log_time_ns: int) -> bool:
        """Queue ``msg`` for ``topic`` at ``log_time_ns`` (simulation time, ns).
        False if it was dropped (queue full, or the recorder is finished)."""
        return self._put(("msg", topic, msg, log_time_ns))

    def add_metadata(self, name: str, data: Mapping[str, Any]) -> bool:
        """Queue an MCAP metadata record (values written as text)."""
        return self._put(("metadata", name, {str(k): value_text(v) for k, v in data.items()}))

    @property
    def dropped(self) -> int:
        """Records dropped so far (the writer fell behind, or after finish)."""
        return self._dropped

    @property
    def finished(self) -> bool:
        """Whether :meth:`finish` was called."""
        return self._finished

    def _put(self, item: Item) -> bool:
        """Queue ``item``; False (and counted) if it was dropped."""
        if self._finished or self._failure is not None:
            self._count_drop()
            return False
        try:
            if self._block:
                self._put_blocking(item)
            else:
                self._queue.put_nowait(item)
        except queue.Full:
            self._count_drop()
            return False
        return True

    def _put_blocking(self, item: Item) -> None:
        """Wait for room in the queue as long as the writer thread lives."""
        while True:
            try:
                self._queue.put(item, timeout=0.5)
                return
            except queue.Full:
                if not self._thread.is_alive():
                    raise

    def _count_drop(self) -> None:
        """Count one dropped record (and warn on the first)."""
        with self._dropped_lock:
            self._dropped += 1
            first = self._dropped == 1
        if first and not self._finished:
            _log.warning("recording %s: the writer falls behind; dropping messages", self.path)

    # -- finishing ---------------------------------------------------------------

    def finish(self) -> RecordingStats:
        """Write everything queued, the ``rosbag2`` and summary metadata
        records, the summary and the footer, and close the file.  Idempotent
        and thread-safe; raises :class:`RecordingError` (once) if the writer
        thread failed."""
        with self._finish_lock:
            if self._finished:
                return self.stats
            self._finished = True
            _open_recorders.discard(self)
            if self._thread.is_alive():
                self._queue.put(_STOP)  # blocks only while the writer drains a full queue
                self._thread.join()
            failure = self._failure if self._failure is not None else self._close_file()
            self.stats.dropped = self._dropped
            if failure is not None:
                self.stats.error = str(failure)
                raise RecordingError(f"recording {self.path} failed: {_one_line(failure)}")
            return self.stats

    def _close_file(self) -> BaseException | None:
        """Write the closing records and close the file; the I/O error, if any."""
        failure: BaseException | None = None
        try:
            self.stats.dropped = self._dropped
            writer = self._file.writer
            writer.add_metadata(SUMMARY_METADATA_NAME, {
                "messages": str(self.stats.messages), "dropped": str(self._dropped),
            })
            writer.add_metadata("rosbag2", {"serialized_metadata": self._file.rosbag2_metadata(self.path.name)})
            writer.finish()  # type: ignore[no-untyped-call]  # mcap's Writer.finish has no annotations
            self._stream.flush()
            if self._fsync:
                os.fsync(self._stream.fileno())
        except OSError as error:
            failure = error
        finally:
            self.stats.bytes = self._stream.tell() if not self._stream.closed else self.stats.bytes
            self._stream.close()
        return failure

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        try:
            self.finish()
        except RecordingError:
            if kind is None:
                raise

    # -- the writer thread -----------------------------------------------------------

    def _run(self) -> None:
        """The writer thread: write what is queued, flush every flush_interval."""
        try:
            self._write_until_stopped()
        except BaseException as error:  # noqa: BLE001 - reported by finish()
            self._failure = error
            _log.error("recording %s failed: %s", self.path, _one_line(error))
            self._drain()

    def _write_until_stopped(self) -> None:
        """Handle queued items in batches until _STOP; flush when due and something was written."""
        next_flush = time.monotonic() + self.flush_interval
        dirty = False
        while True:
            item, self._queue_front = self._queue_front, None
            if item is None:
                try:
                    item = self._queue.get(timeout=max(0.0, next_flush - time.monotonic()))
                except queue.Empty:
                    item = None
            if item is not None:
                if not self._handle_batch(item):
                    return
                dirty = True
            if time.monotonic() >= next_flush:
                if dirty:
                    self._flush()
                    dirty = False
                next_flush = time.monotonic() + self.flush_interval
            time.sleep(0)

    def _handle_batch(self, item: Item) -> bool:
        """Handle ``item`` and up to 256 more that are queued (then let other
        threads run); False when _STOP came."""
        for _ in range(257):
            if item is _STOP:
                return False
            self._handle_safely(item)
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return True
        self._queue_front = item
        return True

    def _drain(self) -> None:
        """After a failure: keep taking items so that blocked producers and finish() go on."""
        while True:
            try:
                if self._queue.get(timeout=0.1) is _STOP:
                    return
            except queue.Empty:
                if self._finished:
                    return

    def _handle_safely(self, item: Item) -> None:
        """Write one item; a bad item (a topic reused with another type, a
        value no message can hold) is dropped and counted, only I/O errors
        end the recording."""
        try:
            self._handle(item)
        except OSError:
            raise
        except Exception as error:  # noqa: BLE001 - one bad item must not end the recording
            with self._dropped_lock:
                self._dropped += 1
            key = (type(error), str(item[1])[:40] if item[0] == "msg" else item[0])
            if key not in self._bad_items:
                self._bad_items.add(key)
                _log.warning("recording %s: dropped a %s record: %s", self.path, item[0], _one_line(error))

    def _flush(self) -> None:
        """End the open chunk, write it and flush the file object (and fsync)."""
        self._file.writer.flush()  # type: ignore[no-untyped-call]  # mcap's Writer.flush has no annotations
        self._stream.flush()
        if self._fsync:
            os.fsync(self._stream.fileno())
        self.stats.chunks_flushed += 1
        self.stats.last_flush = time.monotonic()

    def _handle(self, item: Item) -> None:
        """Build the messages of one queued record and write them."""
        kind = item[0]
        if kind == "msg":
            self._add(item[1], item[2], item[3])
        elif kind == "metadata":
            self._file.writer.add_metadata(item[1], item[2])
        elif kind == "state":
            self._add_state(item[1], item[2])
        else:
            for topic, msg, log_time_ns in _messages(item):
                self._add(topic, msg, log_time_ns)

    def _add_state(self, state: SliderState, frame_id: str) -> None:
        """Write a state as pose, velocity and friction_force (messages reused: serialized at once)."""
        if self._templates is None:
            self._templates = state_messages(state, frame_id)
        else:
            fill_state_messages(state, frame_id, *self._templates)
        ns = seconds_to_ns(state.t)
        for topic, msg in zip(STATE_TOPICS, self._templates):
            self._add(topic, msg, ns)

    def _add(self, topic: str, msg: Any, log_time_ns: int) -> None:
        """Write one message; a negative log time is dropped and counted."""
        if not self._file.add(topic, msg, log_time_ns):
            self._count_drop()


def _messages(item: Item) -> list[tuple[str, Any, int]]:
    """(topic, message, log time [ns]) of a queued sink record."""
    kind = item[0]
    if kind == "event":
        return [("events", event_message(item[1]), seconds_to_ns(item[1].t))]
    if kind == "period":
        return [("mean_velocity", mean_velocity_message(item[1], item[2]), seconds_to_ns(item[1].t))]
    if kind == "command":
        outcome: Outcome = item[1]
        if outcome.accepted:
            return [(outcome.name, command_message(outcome.command, item[2]), seconds_to_ns(outcome.t))]
        return [("rejected_commands", rejection_message(outcome), seconds_to_ns(outcome.t))]
    if kind == "parameters":
        return [("parameters", parameters_message(item[1], item[2], changed=item[3]), seconds_to_ns(item[2]))]
    raise ValueError(f"unknown record kind {kind!r}")


def _library() -> str:
    """The header's library string: ``friction_sim/<version>; mcap-python/<version>``."""
    from importlib.metadata import PackageNotFoundError, version

    def known(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "unknown"

    return f"friction_sim/{known('friction_sim')}; mcap-python/{known('mcap')}"


def _one_line(error: BaseException) -> str:
    """An error as one line of text."""
    text = str(error) or type(error).__name__
    return " ".join(text.split())


__all__ = [
    "FORMAT", "INPUT_FIELDS", "METADATA_NAME", "PLANT_FIELDS", "SUMMARY_METADATA_NAME", "Recorder",
    "RecordingStats", "plant_parameters", "recording_metadata",
]
