"""Recording a run to one MCAP file that the ROS 2 tools open as a bag.

The file is laid out the way rosbag2's MCAP storage plugin (Jazzy) writes
it, so ``ros2 bag info run.mcap``, ``ros2 bag play run.mcap`` and Foxglove
read it as they read a recorded bag:

* profile ``ros2``; one schema per message type, named ``pkg/msg/Type``,
  encoding ``ros2msg``, whose data is the type's full ``.msg`` text with every
  dependency appended as rosbag2 does it (a line of 80 ``=``, then
  ``MSG: pkg/Type``, then that type's text; dependencies in sorted order,
  depth first, each once), read from the installed ``share/<pkg>/msg``;
* message encoding ``cdr`` (``rclpy.serialization.serialize_message``);
* channel metadata ``offered_qos_profiles`` (the YAML rosbag2 Jazzy writes,
  for the node's publishers: reliable, volatile, keep last 10) and
  ``topic_type_hash`` (RIHS01, from the installed type description
  ``share/<pkg>/msg/<Type>.json``);
* chunked, zstd-compressed, with message indexes, statistics and summary;
* a metadata record ``friction_sim`` with the run's parameters, written first;
  and when the file is finished, a complete ``rosbag2`` metadata record
  (``serialized_metadata``, bag metadata version 9) as rosbag2 writes on
  close.  A file that was never finished has no ``rosbag2`` record at all
  rather than a partial one.

Log times are simulation time in whole nanoseconds.

:class:`Recorder` is shaped like ``mcap_ros2.writer.Writer`` (a context
manager with an idempotent :meth:`~Recorder.finish`, channels and schemas
registered on the first message of a topic), but :meth:`~Recorder.write` only
puts the message on a bounded queue: a background thread serializes,
compresses and writes, so a 1 kHz tick thread never waits for the disk.
If that thread falls behind, messages are dropped and counted, never queued
without bound and never blocking the caller.

Durability: the writer thread ends the current chunk (``Writer.flush()``:
the chunk and its message indexes are written whole) and flushes the file
object every ``flush_interval`` (0.25 s) of wall time, so a writer killed
with SIGKILL loses about that much plus the writer's backlog (normally a
message or two); the promise is at most a second, which leaves room for a
process that the machine stalls for a while.  :mod:`friction_sim.io.replay`
reads such a file up to its last complete record.  Ending on SIGINT or
SIGTERM finishes the file (summary and footer) as long as the process gets
to call :meth:`Recorder.finish` (context manager exit, ``destroy_node``, or
the ``atexit`` hook every open recorder registers).

:meth:`Recorder.record_tick` logs what a
:class:`~friction_sim.core.realtime.RealtimeSlider` tick passed (the exact states
on its uniform log grid, independent of timer jitter, the events and the
period means); the slider node and :func:`record_offline`, which runs the
same realtime loop without a clock, both record through it.
"""

from __future__ import annotations

import atexit
import importlib
import json
import logging
import math
import os
import queue
import re
import sys
import threading
import time
import weakref
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import yaml

from friction_sim.core.slider import Event, Slider
from friction_sim.errors import ParameterError, RecordingError
from friction_sim.io.messages import (
    command_message, event_message, fill_state_messages, mean_velocity_message, ns_to_seconds,
    parameters_message, rejection_message, seconds_to_ns, value_text,
)
from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.realtime import CommandOutcome, PeriodSummary, RealtimeSlider, Tick

_log = logging.getLogger("friction_sim.io.recording")

#: Name of the MCAP metadata record that marks a friction_sim recording.
METADATA_NAME = "friction_sim"
#: Name of the metadata record written on finish with the recorder's counts.
SUMMARY_METADATA_NAME = "friction_sim_summary"
#: Value of the "format" key of the friction_sim metadata record.
FORMAT = "friction_sim-recording/1"
#: rosbag2 bag metadata version written in the ``rosbag2`` record (Jazzy).
ROSBAG2_METADATA_VERSION = 9
ROS_DISTRO = "jazzy"
PLANT_FIELDS = ("mass", "mu", "gravity")
INPUT_FIELDS = ("drive_force", "excitation_amplitude", "excitation_frequency", "external_force_x", "external_force_z")

#: RMW_DURATION_INFINITE as rosbag2 serialises it (what the RMW reports for
#: a publisher's default deadline, lifespan and liveliness lease duration).
_INFINITE = {"sec": 9223372036, "nsec": 854775807}


# --------------------------------------------------------------------------
# Type support: names, full message definitions, type hashes, QoS.
# --------------------------------------------------------------------------


def message_type_name(msg_class: type) -> str:
    """``pkg/msg/Type`` of a generated ROS 2 message class."""
    package = msg_class.__module__.split(".", 1)[0]
    return f"{package}/msg/{msg_class.__name__}"


def message_class(type_name: str) -> type:
    """The message class for ``pkg/msg/Type`` (or ``pkg/Type``), imported by name."""
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise RecordingError(f"not a ROS 2 message type name: {type_name!r}")
    package, _, name = match.groups()
    try:
        module = importlib.import_module(f"{package}.msg")
        return getattr(module, name)
    except (ImportError, AttributeError):
        raise RecordingError(f"message type {package}/msg/{name} is not installed") from None


_TYPE_NAME = re.compile(r"^([a-zA-Z][a-zA-Z0-9_]*)/((?:msg|srv)/)?([a-zA-Z][a-zA-Z0-9_]*)$")
# rosbag2_storage_mcap's message_definition_cache.cpp, verbatim.
_MSG_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVES = frozenset({
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
    "int32", "uint32", "int64", "uint64", "string",
})
_SEPARATOR = "=" * 80 + "\n"


@lru_cache(maxsize=None)
def share_directory(package: str) -> Path | None:
    """``share/<package>`` of an installed ROS package, or None.

    In a sourced ROS install ament_index finds it (AMENT_PREFIX_PATH).  The
    PyPI wheels install ``share/`` next to ``lib/`` in the environment's
    prefix without setting AMENT_PREFIX_PATH, so failing that, look in the
    prefixes above the package's Python module, then in ``sys.prefix``.
    """
    try:
        from ament_index_python.packages import get_package_share_directory

        return Path(get_package_share_directory(package))
    except Exception:  # noqa: BLE001 - not sourced, or not an ament package
        pass
    candidates: list[Path] = []
    try:
        module = importlib.import_module(package)
        if module.__file__ is not None:
            candidates.extend(Path(module.__file__).resolve().parents)
    except ImportError:
        pass
    candidates.extend([Path(sys.prefix), Path(sys.base_prefix)])
    for prefix in candidates:
        share = prefix / "share" / package
        if share.is_dir():
            return share
    return None


def _interface_file(package: str, name: str, suffix: str) -> Path | None:
    share = share_directory(package)
    if share is None:
        return None
    path = share / "msg" / f"{name}{suffix}"
    return path if path.is_file() else None


@lru_cache(maxsize=None)
def _msg_text(type_name: str) -> tuple[str, bool]:
    """(.msg text of one type, whether it came from the installed file)."""
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise RecordingError(f"not a ROS 2 message type name: {type_name!r}")
    package, _, name = match.groups()
    path = _interface_file(package, name, ".msg")
    if path is not None:
        return path.read_bytes().decode("utf-8"), True
    return _generated_msg_text(message_class(type_name)), False


def message_definition(type_name: str) -> str:
    """The full ``ros2msg`` text of a type as rosbag2's MCAP plugin stores it.

    The type's own ``.msg`` text; then, for each dependency (field types
    that are not primitives, found with rosbag2's regular expression, in
    sorted order, depth first, each type once): ``"\\n"``, 80 ``=``, a newline,
    ``MSG: pkg/Type`` (as the field names it), a newline, and its text.
    """
    return _message_definition(_normalized(type_name))


def _normalized(type_name: str) -> str:
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise RecordingError(f"not a ROS 2 message type name: {type_name!r}")
    return f"{match.group(1)}/msg/{match.group(3)}"


@lru_cache(maxsize=None)
def _message_definition(type_name: str) -> str:
    seen: set[str] = set()

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            raise RecordingError(f"message definition of {type_name} nests too deeply")
        text, _ = _msg_text(_normalized(name))
        package = name.split("/", 1)[0]
        result = text
        for dependency in _dependencies(text, package):
            if dependency not in seen:
                seen.add(dependency)
                result += "\n" + _SEPARATOR + f"MSG: {dependency}\n" + append(dependency, depth - 1)
        return result

    return append(type_name, 50)


def _dependencies(text: str, package: str) -> list[str]:
    found = set()
    for match in _MSG_FIELD_TYPE.finditer(text):
        kind = match.group(1)
        if kind in _PRIMITIVES:
            continue
        found.add(kind if "/" in kind else f"{package}/{kind}")
    return sorted(found)


def definitions_from_files(type_name: str) -> bool:
    """Whether the type and all its dependencies were read from installed .msg files
    (False: some text was generated from the message class's fields)."""
    names = [_normalized(type_name)]
    names += [_normalized(line[5:]) for line in message_definition(type_name).split("\n") if line.startswith("MSG: ")]
    return all(_msg_text(name)[1] for name in names)


_IDL_TO_MSG = {
    "boolean": "bool", "octet": "byte", "char": "char", "float": "float32", "double": "float64",
    "int8": "int8", "uint8": "uint8", "int16": "int16", "uint16": "uint16", "int32": "int32",
    "uint32": "uint32", "int64": "int64", "uint64": "uint64", "string": "string",
}


def _generated_msg_text(msg_class: type) -> str:
    """A .msg text from a message class's fields, for types whose .msg file is
    not installed (constants and comments are lost; field types are exact)."""
    lines = []
    for name, kind in msg_class.get_fields_and_field_types().items():
        suffix = ""
        sequence = re.match(r"^sequence<(.+?)(?:, (\d+))?>$", kind)
        array = re.match(r"^(.+)\[(\d+)\]$", kind)
        if sequence:
            kind, bound = sequence.group(1), sequence.group(2)
            suffix = f"[<={bound}]" if bound else "[]"
        elif array:
            kind, suffix = array.group(1), f"[{array.group(2)}]"
        bounded = re.match(r"^string<(\d+)>$", kind)
        if bounded:
            kind = f"string<={bounded.group(1)}"
        lines.append(f"{_IDL_TO_MSG.get(kind, kind)}{suffix} {name}")
    return "\n".join(lines) + "\n"


@lru_cache(maxsize=None)
def type_hash(type_name: str) -> str:
    """RIHS01 hash of a type, from its installed type description
    (``share/<pkg>/msg/<Type>.json``); "" if that file is not installed."""
    normalized = _normalized(type_name)
    package, _, name = normalized.split("/")
    path = _interface_file(package, name, ".json")
    if path is None:
        return ""
    try:
        hashes = json.loads(path.read_text())["type_hashes"]
    except (OSError, ValueError, KeyError):
        return ""
    for entry in hashes:
        if entry.get("type_name") == normalized:
            return str(entry.get("hash_string", ""))
    return ""


def offered_qos_profiles(
    *, reliability: str = "reliable", durability: str = "volatile", history: str = "keep_last", depth: int = 10,
) -> list[dict[str, Any]]:
    """One publisher's QoS as rosbag2 (Jazzy, metadata version 9) records it:
    policies by name, durations as {sec, nsec}; a default (unspecified)
    deadline, lifespan and lease duration are infinite, as the RMW reports
    them for a discovered publisher."""
    return [{
        "history": history, "depth": depth, "reliability": reliability, "durability": durability,
        "deadline": dict(_INFINITE), "lifespan": dict(_INFINITE), "liveliness": "automatic",
        "liveliness_lease_duration": dict(_INFINITE), "avoid_ros_namespace_conventions": False,
    }]


class _PlainDumper(yaml.SafeDumper):
    """Block-style YAML without anchors and aliases (yaml-cpp writes none)."""

    def ignore_aliases(self, data: Any) -> bool:
        return True


def _yaml(value: Any) -> str:
    return yaml.dump(value, Dumper=_PlainDumper, sort_keys=False, default_flow_style=False)


def qos_yaml(profiles: list[dict[str, Any]]) -> str:
    """The ``offered_qos_profiles`` channel metadata string (block YAML, as
    yaml-cpp dumps it in rosbag2)."""
    return _yaml(profiles).rstrip("\n")


#: The QoS of every friction_sim publisher (depth 10, reliable, volatile).
DEFAULT_QOS = offered_qos_profiles()


# --------------------------------------------------------------------------
# Exact CDR length.
# --------------------------------------------------------------------------

_PRIMITIVE_SIZES = {
    "boolean": 1, "octet": 1, "char": 1, "uint8": 1, "int8": 1, "int16": 2, "uint16": 2, "wchar": 2,
    "int32": 4, "uint32": 4, "float": 4, "int64": 8, "uint64": 8, "double": 8, "long double": 16,
}


def _align(position: int, size: int) -> int:
    return position + (-position % size)


def _cdr_end(msg: Any, position: int) -> int:
    """Where the CDR (XCDR1) encoding of ``msg`` starting at body offset
    ``position`` ends."""
    from rosidl_parser import definition as d

    for name, kind in zip(msg.get_fields_and_field_types(), msg.SLOT_TYPES):
        position = _cdr_field_end(kind, getattr(msg, name), position, d)
    return position


def _cdr_field_end(kind: Any, value: Any, position: int, d: Any) -> int:
    if isinstance(kind, d.BasicType):
        size = _PRIMITIVE_SIZES[kind.typename]
        return _align(position, size) + size
    if isinstance(kind, (d.UnboundedString, d.BoundedString)):
        return _align(position, 4) + 4 + len(value.encode("utf-8")) + 1
    if isinstance(kind, d.NamespacedType):
        return _cdr_end(value, position)
    if isinstance(kind, d.AbstractSequence):
        position = _align(position, 4) + 4
    elif not isinstance(kind, d.Array):
        raise TypeError(f"no CDR size for {kind!r}")
    element = kind.value_type
    if isinstance(element, d.BasicType):
        count = len(value)
        size = _PRIMITIVE_SIZES[element.typename]
        return _align(position, size) + size * count if count else position
    for item in value:
        position = _cdr_field_end(element, item, position, d)
    return position


@lru_cache(maxsize=None)
def _has_sequences(msg_class: type) -> bool:
    from rosidl_parser import definition as d

    def nested(kind: Any) -> bool:
        if isinstance(kind, d.AbstractSequence):
            return True
        if isinstance(kind, d.Array):
            return nested(kind.value_type)
        if isinstance(kind, d.NamespacedType):
            return _has_sequences(message_class("/".join([*kind.namespaces, kind.name])))
        return False

    return any(nested(kind) for kind in msg_class.SLOT_TYPES)


class _Serializer:
    """``rclpy.serialization.serialize_message``, cut to the exact CDR length.

    rmw_fastrtps reports the *estimated* serialized size as the length
    (rmw_serialize), which for some types with empty sequences of 8-byte
    elements (rcl_interfaces/ParameterValue) is longer than the encoding:
    the surplus bytes are uninitialised memory that a strict reader (rosbags)
    rejects.  Types with sequences get their exact length computed from the
    message; the cut is checked once per type by deserializing it.
    """

    def __init__(self) -> None:
        self._checked: set[type] = set()
        self._warned: set[type] = set()

    def __call__(self, msg: Any) -> bytes:
        from rclpy.serialization import serialize_message

        data = serialize_message(msg)
        cls = type(msg)
        if not _has_sequences(cls):
            return data
        exact = 4 + _cdr_end(msg, 0)
        if len(data) <= exact:
            return data
        if cls not in self._checked:  # until one cut message has read back equal
            from rclpy.serialization import deserialize_message

            if deserialize_message(data[:exact], cls) != msg:  # (or NaN in it: then check the next one)
                if cls not in self._warned:
                    self._warned.add(cls)
                    _log.warning("exact CDR length check failed for %s; writing rmw's length", cls.__name__)
                return data
            self._checked.add(cls)
        return data[:exact]


# --------------------------------------------------------------------------
# The recorder.
# --------------------------------------------------------------------------


@dataclass
class RecordingStats:
    """What a recorder wrote: per-topic counts, log-time range [ns], messages
    dropped because the writer fell behind (or arrived after finish)."""

    path: Path
    messages: int = 0
    dropped: int = 0
    per_topic: dict[str, int] = field(default_factory=dict)
    first_ns: int | None = None
    last_ns: int | None = None
    chunks_flushed: int = 0
    last_flush: float | None = None  # time.monotonic() of the last flush
    bytes: int = 0
    error: str | None = None

    @property
    def duration(self) -> float:
        """Seconds between the first and the last log time."""
        if self.first_ns is None or self.last_ns is None:
            return 0.0
        return ns_to_seconds(self.last_ns - self.first_ns)


_STOP = object()
_open_recorders: "weakref.WeakSet[Recorder]" = weakref.WeakSet()


@atexit.register
def _finish_open_recorders() -> None:
    for recorder in list(_open_recorders):
        try:
            recorder.finish()
        except Exception:  # noqa: BLE001 - at exit, report and go on
            _log.exception("could not finish recording %s", recorder.path)


class Recorder:
    """Writes ROS 2 messages to one MCAP file from a background thread.

    >>> with Recorder("run.mcap", metadata={"mass": 1.0}) as rec:   # doctest: +SKIP
    ...     rec.write("drive_force", Float64(data=0.7), 1_000_000)

    :meth:`write` and the ``record_*`` methods are thread-safe and cheap
    (one non-blocking queue put); they never block unless the recorder was
    made with ``block_when_full=True`` (offline producers that must not lose
    anything).  A message passed to :meth:`write` is serialized later, on
    the writer thread: do not change it afterwards (the ``record_*``
    methods take immutable records and build the messages on that thread).

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
        from mcap.writer import CompressionType, IndexType, Writer

        self.path = Path(path)
        if not flush_interval > 0.0:
            raise ParameterError("flush_interval", flush_interval, "must be > 0 s")
        self.flush_interval = float(flush_interval)
        self._fsync = fsync
        self._block = block_when_full
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=queue_size)
        self._qos_profiles = qos_profiles if qos_profiles is not None else DEFAULT_QOS
        self._qos_yaml = qos_yaml(self._qos_profiles)
        self.stats = RecordingStats(self.path)
        self._dropped = 0
        self._dropped_lock = threading.Lock()
        self._finish_lock = threading.Lock()
        self._finished = False
        self._failure: BaseException | None = None
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str]] = {}  # topic -> (channel id, type name)
        self._sequence: dict[int, int] = {}
        self._templates: dict[str, Any] = {}
        self._serialize = _Serializer()
        self._bad_items: set[tuple[Any, ...]] = set()
        try:
            self._stream = open(self.path, "wb")  # noqa: SIM115 - closed in finish()
        except OSError as error:
            raise RecordingError(
                f"cannot write recording {self.path}: {error.strerror or error}") from None
        try:
            self._writer = Writer(
                self._stream, chunk_size=chunk_size, compression=CompressionType.ZSTD,
                index_types=IndexType.ALL, use_chunking=True, use_statistics=True,
                use_summary_offsets=True, repeat_channels=True, repeat_schemas=True, enable_crcs=True,
            )
            self._writer.start(profile="ros2", library=_library())
            if metadata is not None:
                self._writer.add_metadata(metadata_name, {str(k): value_text(v) for k, v in metadata.items()})
            self._flush()
        except OSError as error:
            self._stream.close()
            raise RecordingError(f"cannot write recording {self.path}: {error.strerror or error}") from None
        self._thread = threading.Thread(target=self._run, name="mcap_writer", daemon=True)
        self._thread.start()
        _open_recorders.add(self)

    # -- the caller's side ------------------------------------------------------

    def write(self, topic: str, msg: Any, log_time_ns: int) -> bool:
        """Queue ``msg`` for ``topic`` at ``log_time_ns`` (simulation time, ns).
        False if it was dropped (queue full, or the recorder is finished)."""
        return self._put(("msg", topic, msg, log_time_ns))

    def record_state(self, state: Any, frame_id: str = "slideway") -> bool:
        """Queue a :class:`~friction_sim.core.SliderState` as pose, velocity and
        friction_force at its own time."""
        return self._put(("state", state, frame_id, None))

    def record_event(self, event: Event) -> bool:
        """Queue a stick/slip event on ``events``."""
        return self._put(("event", event, None, None))

    def record_period(self, period: PeriodSummary, frame_id: str = "slideway") -> bool:
        """Queue a period's mean velocity on ``mean_velocity``."""
        return self._put(("period", period, frame_id, None))

    def record_tick(self, tick: Tick, frame_id: str = "slideway") -> None:
        """Queue what a :class:`~friction_sim.core.realtime.RealtimeSlider` tick
        passed: the exact states on the log grid, the events, the period means."""
        for state in tick.samples:
            self.record_state(state, frame_id)
        for event in tick.events:
            self.record_event(event)
        for period in tick.periods:
            self.record_period(period, frame_id)

    def record_command(self, outcome: CommandOutcome, frame_id: str = "") -> bool:
        """Queue a handled command: accepted on its own topic, refused on
        ``rejected_commands``, at the simulation time it was handled."""
        return self._put(("command", outcome, frame_id, None))

    def record_parameters(self, values: Mapping[str, Any], t: float, *, changed: bool = False) -> bool:
        """Queue parameter values on ``parameters`` (new at start, or changed)."""
        return self._put(("parameters", dict(values), t, changed))

    def add_metadata(self, name: str, data: Mapping[str, Any]) -> bool:
        """Queue an MCAP metadata record (values written as text)."""
        return self._put(("metadata", name, {str(k): value_text(v) for k, v in data.items()}, None))

    @property
    def dropped(self) -> int:
        """Messages dropped so far (the writer fell behind, or after finish)."""
        return self._dropped

    @property
    def finished(self) -> bool:
        return self._finished

    def _put(self, item: tuple[Any, ...]) -> bool:
        if self._finished or self._failure is not None:
            self._count_drop()
            return False
        try:
            if self._block:
                while True:
                    try:
                        self._queue.put(item, timeout=0.5)
                        break
                    except queue.Full:
                        if not self._thread.is_alive():
                            raise
            else:
                self._queue.put_nowait(item)
        except queue.Full:
            self._count_drop()
            return False
        return True

    def _count_drop(self) -> None:
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
            failure = self._failure
            try:
                if failure is None:
                    self.stats.dropped = self._dropped
                    self._writer.add_metadata(SUMMARY_METADATA_NAME, {
                        "messages": str(self.stats.messages), "dropped": str(self._dropped),
                    })
                    self._writer.add_metadata("rosbag2", {"serialized_metadata": self._rosbag2_metadata()})
                    self._writer.finish()
                    self._stream.flush()
                    if self._fsync:
                        os.fsync(self._stream.fileno())
            except OSError as error:
                failure = error
            finally:
                self.stats.bytes = self._stream.tell() if not self._stream.closed else self.stats.bytes
                self._stream.close()
            self.stats.dropped = self._dropped
            if failure is not None:
                self.stats.error = str(failure)
                raise RecordingError(f"recording {self.path} failed: {_one_line(failure)}")
            return self.stats

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, kind: Any, value: Any, traceback: Any) -> None:
        try:
            self.finish()
        except RecordingError:
            if kind is None:
                raise

    # -- the writer thread -----------------------------------------------------------

    def _run(self) -> None:
        next_flush = time.monotonic() + self.flush_interval
        dirty = False
        try:
            while True:
                try:
                    item = self._queue.get(timeout=max(0.0, next_flush - time.monotonic()))
                except queue.Empty:
                    item = None
                if item is _STOP:
                    return
                if item is not None:
                    self._handle_safely(item)
                    dirty = True
                    for _ in range(256):  # drain a batch, then let other threads run
                        try:
                            item = self._queue.get_nowait()
                        except queue.Empty:
                            break
                        if item is _STOP:
                            return
                        self._handle_safely(item)
                if time.monotonic() >= next_flush:
                    if dirty:
                        self._flush()
                        dirty = False
                    next_flush = time.monotonic() + self.flush_interval
                time.sleep(0)
        except BaseException as error:  # noqa: BLE001 - reported by finish()
            self._failure = error
            _log.error("recording %s failed: %s", self.path, _one_line(error))
            while True:  # keep draining so that blocked producers and finish() go on
                try:
                    if self._queue.get(timeout=0.1) is _STOP:
                        return
                except queue.Empty:
                    if self._finished:
                        return

    def _handle_safely(self, item: tuple[Any, ...]) -> None:
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
        flush = getattr(self._writer, "flush", None)
        if flush is not None:  # mcap >= 1.2
            flush()
        else:
            self._writer._Writer__finalize_chunk()  # type: ignore[attr-defined]
            self._writer._Writer__flush()  # type: ignore[attr-defined]
            self._stream.flush()
        if self._fsync:
            os.fsync(self._stream.fileno())
        self.stats.chunks_flushed += 1
        self.stats.last_flush = time.monotonic()

    def _handle(self, item: tuple[Any, ...]) -> None:
        kind, a, b, c = item
        if kind == "msg":
            self._add(a, b, c)
        elif kind == "state":
            pose, twist, wrench = self._state_templates()
            fill_state_messages(a, b, pose, twist, wrench)
            ns = seconds_to_ns(a.t)
            self._add("pose", pose, ns)
            self._add("velocity", twist, ns)
            self._add("friction_force", wrench, ns)
        elif kind == "event":
            self._add("events", event_message(a), seconds_to_ns(a.t))
        elif kind == "period":
            self._add("mean_velocity", mean_velocity_message(a, b), seconds_to_ns(a.t))
        elif kind == "command":
            ns = seconds_to_ns(a.t)
            if a.accepted:
                self._add(a.topic, command_message(a, b), ns)
            else:
                self._add("rejected_commands", rejection_message(a), ns)
        elif kind == "parameters":
            self._add("parameters", parameters_message(a, b, changed=c), seconds_to_ns(b))
        elif kind == "metadata":
            self._writer.add_metadata(a, b)

    def _state_templates(self) -> tuple[Any, Any, Any]:
        templates = self._templates.get("state")
        if templates is None:
            from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped

            templates = self._templates["state"] = (PoseStamped(), TwistStamped(), WrenchStamped())
        return templates

    def _add(self, topic: str, msg: Any, log_time_ns: int) -> None:
        log_time_ns = int(log_time_ns)
        if log_time_ns < 0:
            self._count_drop()
            return
        channel = self._channels.get(topic)
        type_name = message_type_name(type(msg))
        if channel is None:
            channel = self._channels[topic] = (self._register(topic, type_name), type_name)
        elif channel[1] != type_name:
            raise RecordingError(f"topic {topic!r} has type {channel[1]}, not {type_name}")
        channel_id = channel[0]
        sequence = self._sequence.get(channel_id, 0)
        self._sequence[channel_id] = sequence + 1
        self._writer.add_message(channel_id, log_time_ns, self._serialize(msg), log_time_ns, sequence)
        stats = self.stats
        stats.messages += 1
        stats.per_topic[topic] = stats.per_topic.get(topic, 0) + 1
        if stats.first_ns is None or log_time_ns < stats.first_ns:
            stats.first_ns = log_time_ns
        if stats.last_ns is None or log_time_ns > stats.last_ns:
            stats.last_ns = log_time_ns

    def _register(self, topic: str, type_name: str) -> int:
        schema_id = self._schemas.get(type_name)
        if schema_id is None:
            schema_id = self._schemas[type_name] = self._writer.register_schema(
                name=type_name, encoding="ros2msg", data=message_definition(type_name).encode("utf-8"))
        return self._writer.register_channel(
            topic=topic, message_encoding="cdr", schema_id=schema_id,
            metadata={"offered_qos_profiles": self._qos_yaml, "topic_type_hash": type_hash(type_name)},
        )

    def _rosbag2_metadata(self) -> str:
        """rosbag2's BagMetadata (version 9) for this file, complete, as YAML."""
        stats = self.stats
        start = stats.first_ns or 0
        duration = (stats.last_ns - start) if stats.last_ns is not None else 0
        name = self.path.name
        info = {
            "version": ROSBAG2_METADATA_VERSION,
            "storage_identifier": "mcap",
            "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": stats.messages,
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": topic, "type": type_name, "serialization_format": "cdr",
                        "offered_qos_profiles": self._qos_profiles,
                        "type_description_hash": type_hash(type_name),
                    },
                    "message_count": stats.per_topic.get(topic, 0),
                }
                for topic, (_, type_name) in self._channels.items()
            ],
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [name],
            "files": [{
                "path": name, "starting_time": {"nanoseconds_since_epoch": start},
                "duration": {"nanoseconds": duration}, "message_count": stats.messages,
            }],
            "custom_data": None,
            "ros_distro": ROS_DISTRO,
        }
        return _yaml(info)


def _library() -> str:
    from importlib.metadata import PackageNotFoundError, version

    def known(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "unknown"

    return f"friction_sim/{known('friction_sim')}; mcap-python/{known('mcap')}"




def _one_line(error: BaseException) -> str:
    text = str(error) or type(error).__name__
    return " ".join(text.split())


# --------------------------------------------------------------------------
# Sampling a slider on the uniform grid.
# --------------------------------------------------------------------------


def plant_parameters(params: SliderParams, inputs: Inputs) -> dict[str, float]:
    """The physical parameters and inputs a run starts with, by field name
    (what ``--verify`` rebuilds the simulation from)."""
    values = {name: getattr(params, name) for name in PLANT_FIELDS}
    values.update({name: getattr(inputs, name) for name in INPUT_FIELDS})
    return values


def recording_metadata(params: SliderParams, inputs: Inputs, *, log_rate: float, frame_id: str = "slideway",
                       **extra: Any) -> dict[str, str]:
    """The ``friction_sim`` metadata record: the format, the log rate, the frame
    and the parameters at start (full precision), plus ``extra``."""
    data = {"format": FORMAT, "log_rate": repr(float(log_rate)), "frame_id": frame_id}
    data.update({name: repr(float(value)) for name, value in plant_parameters(params, inputs).items()})
    data.update({name: value_text(value) for name, value in extra.items()})
    return data


@dataclass(frozen=True)
class _Action:
    t_ns: int
    order: int
    topic: str
    values: dict[str, Any]


def _actions(schedule: Iterable[Any]) -> list[_Action]:
    """Commands of a schedule (simulation.Command or experiment.ScheduledCommand),
    one per topic the node would receive them on, in time order."""
    actions: list[_Action] = []
    for order, command in enumerate(schedule):
        t = float(command.t)
        if not (math.isfinite(t) and t >= 0.0):
            raise ParameterError("t", t, "must be a finite time >= 0 s")
        t_ns = seconds_to_ns(t)
        if hasattr(command, "changes"):
            changes = dict(command.changes)
            plant = {k: changes.pop(k) for k in PLANT_FIELDS if k in changes}
            if plant:
                actions.append(_Action(t_ns, order, "parameters", plant))
            wrench = {k: changes.pop(k) for k in ("external_force_x", "external_force_z") if k in changes}
            for name, value in changes.items():
                actions.append(_Action(t_ns, order, name, {name: value}))
            if wrench:
                actions.append(_Action(t_ns, order, "external_wrench", wrench))
        else:
            topic, value = command.topic, command.value
            if topic == "external_wrench":
                fx, fz = value
                actions.append(_Action(t_ns, order, topic, {"external_force_x": float(fx),
                                                             "external_force_z": float(fz)}))
            elif topic in ("drive_force", "excitation_amplitude", "excitation_frequency"):
                actions.append(_Action(t_ns, order, topic, {topic: float(value)}))
            else:
                raise ParameterError("topic", topic, "is not a slider input (record_offline runs no controller)")
    return sorted(actions, key=lambda a: (a.t_ns, a.order))


def record_offline(
    path: str | os.PathLike[str], params: SliderParams | None = None, inputs: Inputs | None = None,
    schedule: Sequence[Any] = (), duration: float = 1.0, log_rate: float = 1000.0, *,
    frame_id: str = "slideway", mean_window_periods: int = 1, tick_rate: float | None = None,
    metadata: Mapping[str, Any] | None = None,
) -> RecordingStats:
    """Run the exact core for ``duration`` s of simulation time without a
    clock and record what the slider node records.

    ``schedule`` holds :class:`friction_sim.core.simulation.Command` (field changes
    at a time) or :class:`friction_sim.experiment.ScheduledCommand` entries;
    each change reaches the slider as the node would receive it (one command
    per topic; external forces as one external_wrench, the missing
    component kept) and is recorded accepted or refused.  States are logged
    on the grid ``k / log_rate``; the mean velocity comes from the core's
    period marks through :class:`RealtimeSlider`, ticked at ``tick_rate``
    (default ``log_rate``), exactly as in the node.
    """
    params = params if params is not None else SliderParams()
    inputs = inputs if inputs is not None else Inputs()
    duration = float(duration)
    if not (math.isfinite(duration) and duration >= 0.0):
        raise ParameterError("duration", duration, "must be a finite time >= 0 s")
    rate = float(tick_rate if tick_rate is not None else log_rate)
    rt = RealtimeSlider(params, inputs, wall_ns=0, real_time_factor=1.0, publish_rate=rate,
                        mean_window_periods=mean_window_periods, log_rate=log_rate)
    actions = _actions(schedule)
    end_ns = seconds_to_ns(duration)
    extra = dict(metadata or {})
    extra.setdefault("recorded_by", "record_offline")
    extra.setdefault("mean_window_periods", mean_window_periods)
    with Recorder(path, recording_metadata(params, inputs, log_rate=log_rate, frame_id=frame_id, **extra),
                  block_when_full=True) as recorder:
        recorder.record_parameters({**plant_parameters(params, inputs), "log_rate": float(log_rate),
                                    "frame_id": frame_id, "mean_window_periods": mean_window_periods}, 0.0)
        pending = list(reversed(actions))
        k = 0
        while True:  # exactly what the node does, with the clock replaced by a counter
            tick_ns = min(round(k * 1e9 / rate), end_ns)
            while pending and pending[-1].t_ns <= tick_ns:
                action = pending.pop()
                recorder.record_command(_apply(rt, action), frame_id)
            recorder.record_tick(rt.tick(tick_ns), frame_id)
            if tick_ns >= end_ns:
                break
            k += 1
    stats = recorder.stats
    return stats


def _apply(rt: RealtimeSlider, action: _Action) -> CommandOutcome:
    if action.topic == "parameters":
        try:
            params = rt.slider.params.replace(**action.values)
        except ParameterError as error:
            return rt.refuse("parameters", action.values, f"parameters: {error}", action.t_ns)
        return rt.set_params(params, action.t_ns)
    values = dict(action.values)
    if action.topic == "external_wrench":  # a wrench carries both components
        values.setdefault("external_force_x", rt.slider.inputs.external_force_x)
        values.setdefault("external_force_z", rt.slider.inputs.external_force_z)
    return rt.command(action.topic, values, action.t_ns)


__all__ = [
    "DEFAULT_QOS", "FORMAT", "METADATA_NAME", "Recorder", "RecordingStats",
    "message_class", "message_definition", "message_type_name", "offered_qos_profiles",
    "plant_parameters", "qos_yaml", "record_offline", "recording_metadata", "share_directory", "type_hash",
]
