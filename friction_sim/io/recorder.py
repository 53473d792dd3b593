"""Recording a run to one MCAP file that the ROS 2 tools open as a bag.

The file is laid out the way rosbag2's MCAP storage plugin (Jazzy) writes
it, so ``ros2 bag info run.mcap``, ``ros2 bag play run.mcap`` and Foxglove
read it as they read a recorded bag:

* profile ``ros2``; one schema per message type, named ``pkg/msg/Type``,
  encoding ``ros2msg``, whose data is the full definition rosbag2 stores
  (:func:`~friction_sim.io.typesupport.message_definition`);
* message encoding ``cdr`` (:mod:`friction_sim.io.cdr`);
* topics by their fully qualified names, as rosbag2 stores them: ``/pose``,
  ``/events``, or ``/feeder1/pose`` for a node in namespace ``/feeder1``;
* channel metadata ``offered_qos_profiles`` (the YAML rosbag2 Jazzy writes,
  for the node's publishers: reliable, volatile, keep last 10) and
  ``topic_type_hash`` (RIHS01);
* chunked, zstd-compressed, with message indexes, statistics and summary
  (:class:`~friction_sim.io.bagfile.BagFile`);
* a metadata record ``friction_sim`` with the run's parameters, written
  first, and the key ``external_force_z_convention: lifts``: the file's
  ``external_wrench`` force.z and ``external_force_z`` point away from the
  track (> 0 lifts).  Files written before that convention existed have no
  such key; their positive force.z pressed the slider on the track
  (``loads``), and the reader turns it round (:mod:`friction_sim.io.reader`);
  and when the file is finished, a ``friction_sim_summary`` record (messages
  written, messages dropped) and a complete ``rosbag2`` metadata record
  (``serialized_metadata``, bag metadata version 9) as rosbag2 writes on
  close.  A file that was never finished has neither.

Log times are simulation time in whole nanoseconds (so the file holds no
``/clock``: ``ros2 bag play --clock`` publishes it from them).

:class:`Recorder` is a :class:`~friction_sim.io.sinks.Sink`: the slider node
and :func:`friction_sim.experiment.offline.record_offline` hand it what a run
produces.  Its methods only put a record on a bounded queue (one entry per
call: a tick's states go together); a background thread builds the
messages (the state topics many at a time, :class:`~friction_sim.io.cdr.FixedLayout`),
compresses and writes.  The queue and its back-pressure are a
:class:`~friction_sim.io.recordqueue.RecordQueue` (:attr:`Recorder.queue`).
No message is lost silently:

* By default (``block_when_full=True``) a producer that finds the queue
  full waits for the writer, for as long as the writer makes progress and
  no longer: not once the recording has failed or the writer thread has
  ended.  :attr:`RecordQueue.wait_seconds <friction_sim.io.recordqueue.RecordQueue.wait_seconds>`
  and :attr:`~friction_sim.io.recordqueue.RecordQueue.waits` (of :attr:`Recorder.queue`) say
  how long and how often producers waited (a real-time caller rebases its clock).
* With ``block_when_full=False`` records that do not fit are dropped, counted
  and the count is written in the file (``friction_sim_summary``).
* When a write fails (disk full, file too large, I/O error) the recording
  stops: :attr:`Recorder.error` holds one line saying what failed, where,
  and how much the file holds; later records are counted no-ops
  (:attr:`~friction_sim.io.recordqueue.RecordQueue.unrecorded`) that never block; :meth:`Recorder.finish`
  returns the stats with the error, never raises.  The file keeps every
  chunk written before the failure and reads and verifies up to there
  (:mod:`friction_sim.io.reader`).

Durability: the writer thread ends the current chunk (written whole, with
its message indexes) every ``flush_interval`` (0.25 s) of wall time, so a
writer killed with SIGKILL loses about that much plus the writer's backlog;
the promise is at most a second, which leaves room for a process that the
machine stalls for a while.  The file is written unbuffered, so nothing
stays in a Python buffer.  Ending on SIGINT or SIGTERM finishes the file
(summary and footer) as long as the process gets to call
:meth:`Recorder.finish` (context manager exit, ``destroy_node``, or the
``atexit`` hook every open recorder registers).
"""

from __future__ import annotations

import atexit
import contextlib
import functools
import logging
import os
import threading
import time
import weakref
from collections.abc import Mapping
from pathlib import Path
from types import TracebackType
from typing import IO, Any

from friction_sim.core.model import spec
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.errors import ParameterError, RecordingPathError, one_line
from friction_sim.io import cdr
from friction_sim.io.bagfile import BagFile, RecordingStats
from friction_sim.io.messages import TOPIC_TYPES, message_class, node_name, value_text
from friction_sim.io.recordqueue import RecordQueue
from friction_sim.io.recordwriter import Item, Metadata, RecordWriter, qualified_topic
from friction_sim.io.sinks import ClockRecord, CommandRecord, ParametersRecord, Record, record_size
from friction_sim.io.typesupport import DEFAULT_QOS

_log = logging.getLogger("friction_sim.io.recorder")

#: Name of the MCAP metadata record that marks a friction_sim recording.
METADATA_NAME = "friction_sim"
#: Name of the metadata record written on finish with the recorder's counts.
SUMMARY_METADATA_NAME = "friction_sim_summary"
#: Value of the "format" key of the friction_sim metadata record (2: z up, flight, the convention key).
FORMAT = "friction_sim-recording/2"
#: Key of the friction_sim metadata record that says which way ``external_force_z``
#: (``external_wrench`` force.z) points in the file's commands and parameters.
CONVENTION_KEY = "external_force_z_convention"
#: The convention written since issue 11: z away from the track, > 0 lifts the slider.
LIFTS = "lifts"
#: The convention of files without :data:`CONVENTION_KEY`: > 0 pressed the slider on the track.
LOADS = "loads"
#: The plant and input fields a recording starts from (what ``--verify`` rebuilds).
PLANT_FIELDS = tuple(spec.PLANT)
INPUT_FIELDS = tuple(spec.INPUTS)
#: The records that may use the queue's URGENT_HEADROOM: commands and parameter changes.
_URGENT = frozenset({CommandRecord, ParametersRecord})


def plant_parameters(params: SliderParams, inputs: Inputs) -> dict[str, float | str]:
    """The physical parameters and inputs a run starts with, by field name
    (what ``--verify`` rebuilds the simulation from): floats, and text for a
    string setting (``landing_friction``)."""
    values: dict[str, float | str] = {}
    for source, names in ((params, PLANT_FIELDS), (inputs, INPUT_FIELDS)):
        for name in names:
            value = getattr(source, name)
            values[name] = value if isinstance(value, str) else float(value)
    return values


def recording_metadata(params: SliderParams, inputs: Inputs, *, log_rate: float, frame_id: str = "slideway",
                       **extra: Any) -> dict[str, str]:
    """The ``friction_sim`` metadata record: the format, the log rate, the frame
    and the parameters at start (full precision), plus ``extra``."""
    data = {"format": FORMAT, "log_rate": repr(float(log_rate)), "frame_id": frame_id}
    data.update({name: value_text(value) for name, value in plant_parameters(params, inputs).items()})
    data.update({name: value_text(value) for name, value in extra.items()})
    return data


_open_recorders: weakref.WeakSet[Recorder] = weakref.WeakSet()


@atexit.register
def _finish_open_recorders() -> None:
    """Finish every recorder still open when the interpreter exits."""
    for recorder in list(_open_recorders):
        recorder.finish()


class Recorder:
    """Writes ROS 2 messages to one MCAP file from a background thread; a Sink.

    >>> with Recorder("run.mcap", metadata={"mass": 1.0}) as rec:   # doctest: +SKIP
    ...     rec.write(MessageRecord("drive_force", Float64(data=0.7), 1_000_000))

    :meth:`write` and :meth:`add_metadata` are thread-safe and cheap (one
    queue put per call).  They wait only when the queue is full and
    ``block_when_full`` is True (see the module docstring).  A record's
    messages are built and serialized later, on the writer thread: do not
    change a message (or a dict of parameters) once written.

    ``metadata`` becomes the ``friction_sim`` MCAP metadata record, written
    first, with ``external_force_z_convention`` (default ``lifts``, the
    convention of this version) added unless ``metadata`` has it; None adds
    no key (a file as written before the key existed: tests of old files).
    ``namespace`` is the node's namespace: relative topic names are
    stored fully qualified in it; ``node`` is the node's fully qualified
    name, which the parameter events name (default: ``slider`` in
    ``namespace``).  ``setting`` names the setting ``path``
    came from, for the error message.  ``queue_size`` counts messages (a
    state is three); ``flush_interval`` [s of wall time] bounds what a
    SIGKILL can lose.  A path that cannot be written raises one
    :class:`~friction_sim.errors.RecordingPathError` (nothing is left open);
    later failures never raise (:attr:`error`).

    The queue between the producers and the writer thread, with its counts
    (waits, unrecorded messages), is :attr:`queue`; the recorder owns the
    file's life: opening it, the writer thread's loop, flushing, finishing
    and failing.
    """

    def __init__(
        self, path: str | os.PathLike[str], metadata: Mapping[str, Any] | None = None, *,
        metadata_name: str = METADATA_NAME, namespace: str = "/", node: str | None = None, setting: str = "log_path",
        queue_size: int = 262_144, block_when_full: bool = True, flush_interval: float = 0.25,
        chunk_size: int = 4 * 1024 * 1024, fsync: bool = False, qos_profiles: list[dict[str, Any]] | None = None,
        external_force_z_convention: str | None = LIFTS,
    ) -> None:
        if not flush_interval > 0.0:
            raise ParameterError("flush_interval", flush_interval, "must be > 0 s")
        if not queue_size >= 1:
            raise ParameterError("queue_size", queue_size, "must be >= 1 message")
        if not (isinstance(namespace, str) and namespace.startswith("/")):
            raise ParameterError("namespace", namespace, "must be an absolute ROS namespace such as / or /feeder1")
        self._given = _checked_path(setting, path)
        self.path = Path(self._given)
        self.namespace = namespace
        self.flush_interval = float(flush_interval)
        self.stats = RecordingStats(self.path)
        #: Why the recording stopped (one line), or None while it works.
        self.error: str | None = None
        self._setting = setting
        self._fsync = fsync
        #: The bounded queue the producers put records on and the writer thread takes them from.
        self.queue = RecordQueue(queue_size, block=block_when_full, path=self.path,
                                 writer_alive=lambda: self._thread.is_alive())
        self._finished = False
        self._finish_lock = threading.Lock()
        self._stream = self._open()
        if metadata is not None and metadata_name == METADATA_NAME and external_force_z_convention is not None:
            metadata = {**metadata, CONVENTION_KEY: metadata.get(CONVENTION_KEY, external_force_z_convention)}
        self._file = self._start(qos_profiles if qos_profiles is not None else DEFAULT_QOS, chunk_size,
                                 metadata_name, metadata)
        self._writer = RecordWriter(self._file, namespace, self.path, node or node_name(namespace))
        _prepare_encoders()
        self._thread = threading.Thread(target=self._run, name="mcap_writer", daemon=True)
        self._thread.start()
        _open_recorders.add(self)

    def _open(self) -> IO[bytes]:
        """The output file, opened unbuffered for writing (RecordingPathError if it cannot be)."""
        try:
            return open(self.path, "wb", buffering=0)
        except OSError as error:
            raise RecordingPathError(self._setting, self._given, f"cannot write there: {_reason(error)}") from None

    def _start(self, qos_profiles: list[dict[str, Any]], chunk_size: int, metadata_name: str,
               metadata: Mapping[str, Any] | None) -> BagFile:
        """Write the header and the metadata record; on failure close and
        remove what was made and raise one RecordingPathError."""
        mcap = BagFile(self._stream, qos_profiles, chunk_size, self.stats)
        try:
            mcap.start(profile="ros2", library=_library())
            if metadata is not None:
                mcap.add_metadata(metadata_name, {str(k): value_text(v) for k, v in metadata.items()})
            if self._fsync:
                os.fsync(self._stream.fileno())
        except OSError as error:
            with contextlib.suppress(OSError):
                self._stream.close()
            if self.path.is_file():  # not a device such as /dev/full
                with contextlib.suppress(OSError):
                    self.path.unlink()
            raise RecordingPathError(self._setting, self._given, f"cannot write there: {_reason(error)}") from None
        return mcap

    # -- the caller's side: the sink, and metadata --------------------------------------

    def write(self, record: Record) -> bool:
        """Queue a sink record (:mod:`friction_sim.io.sinks`): the states as pose,
        velocity and friction_force, each event, period mean, accelerometer sample
        (sensor_msgs/Imu), command (accepted on its own topic, refused on
        ``rejected_commands``) and parameter set at its own simulation time, any
        other message at its log time.  A :class:`~friction_sim.io.sinks.ClockRecord`
        is not recorded: every message's log time is the simulation time already
        (``ros2 bag play --clock`` publishes /clock from them).  False if it was
        not queued (dropped, failed, or finished; counted)."""
        kind = type(record)  # (records are final classes: the type says what each is, cheaper than isinstance)
        if kind is ClockRecord:
            return True
        size = record_size(record)
        return not size or self.queue.put(record, size, urgent=kind in _URGENT)

    def close(self) -> None:
        """Finish the file (see :meth:`finish`)."""
        self.finish()

    def add_metadata(self, name: str, data: Mapping[str, Any]) -> bool:
        """Queue an MCAP metadata record (values written as text)."""
        return self.queue.put(Metadata(name, {str(k): value_text(v) for k, v in data.items()}), 0)

    # -- state ----------------------------------------------------------------------

    @property
    def dropped(self) -> int:
        """Messages dropped so far: the queue was full and the producer does
        not wait, a record no message could hold, or handed over after finish."""
        return self.queue.dropped + self._writer.bad

    @property
    def writer_alive(self) -> bool:
        """Whether the writer thread runs (it ends after finish or a failure)."""
        return self._thread.is_alive()

    @property
    def finished(self) -> bool:
        """Whether :meth:`finish` was called."""
        return self._finished

    # -- finishing ---------------------------------------------------------------

    def finish(self) -> RecordingStats:
        """Write everything queued, the summary and ``rosbag2`` metadata
        records, the summary and the footer, and close the file; return the
        stats (with ``error`` set if the recording failed).  Idempotent and
        thread-safe; never raises for a failed recording."""
        with self._finish_lock:
            if self._finished:
                return self.stats
            self.queue.stop()
            _open_recorders.discard(self)
            self._thread.join()
            self.queue.discard()  # left in the queue by a writer that ended early: counted, not lost silently
            self._finished = True
            self._update_stats()
            return self.stats

    def _update_stats(self) -> None:
        self.stats.dropped = self.dropped
        self.stats.unrecorded = self.queue.unrecorded
        self.stats.waited = self.queue.wait_seconds
        self.stats.waits = self.queue.waits
        self.stats.error = self.error

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        self.finish()

    # -- the writer thread -----------------------------------------------------------

    def _run(self) -> None:
        """The writer thread: write what is queued, flush every flush_interval,
        close the file when stopped; any error ends the recording (:meth:`_fail`)."""
        try:
            self._write_until_stopped()
            self._close_file()
        except BaseException as error:  # noqa: BLE001 - reported once, as self.error
            self._fail(error)

    def _write_until_stopped(self) -> None:
        """Take all that is queued, write it; flush when due and something was written."""
        next_flush = time.monotonic() + self.flush_interval
        dirty = False
        while True:
            batch, stop = self.queue.take(next_flush)
            if stop:
                return
            if batch:
                self._write_batch(batch)
                dirty = True
            if time.monotonic() >= next_flush:
                if dirty:
                    self._flush()
                    dirty = False
                next_flush = time.monotonic() + self.flush_interval

    def _write_batch(self, batch: list[Item]) -> None:
        """Write the records taken from the queue, in order."""
        self._writer.write(batch)

    def _close_file(self) -> None:
        """Write the closing records and close the file."""
        self._file.flush()
        self._file.add_metadata(SUMMARY_METADATA_NAME, {
            "messages": str(self.stats.messages), "dropped": str(self.dropped)})
        self._file.add_metadata("rosbag2", {"serialized_metadata": self._file.rosbag2_metadata(self.path.name)})
        self._file.finish()
        if self._fsync:
            os.fsync(self._stream.fileno())
        self.stats.bytes = self._file.position
        self._stream.close()

    def _fail(self, error: BaseException) -> None:
        """The recording stops: say once what failed and how much the file
        holds, refuse what comes later (counted), close the file."""
        stats = self.stats
        at = f" (t = {stats.last_ns / 1e9:.3f} s)" if stats.last_ns is not None else ""
        message = (f"recording failed: {_reason(error)} writing {self.path} after {stats.messages} messages{at}; "
                   "the run goes on unrecorded")
        self.error = stats.error = message
        self.queue.fail(stats.messages + self._writer.bad)
        stats.bytes = self._file.position
        _log.error("%s", message)
        with contextlib.suppress(OSError):
            self._stream.close()  # unbuffered: nothing left to write, so closing cannot fail again

    def _flush(self) -> None:
        """End the open chunk and write it (and fsync)."""
        self._file.flush()
        if self._fsync:
            os.fsync(self._stream.fileno())
        self.stats.chunks_flushed += 1
        self.stats.last_flush = time.monotonic()


def _checked_path(setting: str, path: str | os.PathLike[str]) -> str:
    """``path`` as text, if it can name a file to write (RecordingPathError if not)."""
    text = os.fsdecode(os.fspath(path))
    if not text:
        raise RecordingPathError(setting, text, "give a file name such as run.mcap")
    if text.endswith(("/", os.sep)) or os.path.isdir(text):
        example = os.path.join(text, "run.mcap")
        raise RecordingPathError(setting, text, f"names a directory, not a file (e.g. {example})")
    return text


def _reason(error: BaseException) -> str:
    """An error's reason as one line: ``[Errno 28] No space left on device`` for an OSError."""
    if isinstance(error, OSError) and error.errno is not None:
        return f"[Errno {error.errno}] {error.strerror or os.strerror(error.errno)}"
    return one_line(error, with_type=True)


def _library() -> str:
    """The header's library string: ``friction_sim/<version>; mcap-python/<version>``."""
    from importlib.metadata import PackageNotFoundError, version

    def known(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "unknown"

    return f"friction_sim/{known('friction_sim')}; mcap-python/{known('mcap')}"


@functools.cache
def _prepare_encoders() -> None:
    """Encode one message of every recorded type once per process, before a
    run starts: the first encoding of a type builds its rosbags encoder (about
    0.1 s with the GIL held), which in the middle of a run stalled the node's
    tick and the controller at the user's first command."""
    for type_name in sorted(set(TOPIC_TYPES.values())):
        cdr.serialize(message_class(type_name)())


__all__ = [
    "CONVENTION_KEY", "FORMAT", "INPUT_FIELDS", "LIFTS", "LOADS", "METADATA_NAME", "PLANT_FIELDS",
    "SUMMARY_METADATA_NAME", "Recorder", "RecordingStats", "plant_parameters", "qualified_topic", "recording_metadata",
]
