"""CDR encoding and decoding of recorded messages with rosbags' typestore (no rclpy).

The recorder gets messages built from the generated ROS 2 classes (the
message packages; the node publishes the same objects) or, when a recording
is copied, the rosbags dataclasses :func:`deserialize` returns.  rosbags'
generated serializers read fields by attribute, so they take a generated
ROS 2 object directly when its field values are what rosbags expects (the
1 kHz state types: only floats, ints and strings).  Types with ``byte``
fields (rclpy gives ``b"\\x01"``, rosbags wants an int) or primitive
sequences (rosbags wants numpy arrays) are first converted to rosbags
dataclasses.  Padding bytes are zero (rclpy's serializer leaves them
uninitialised); everything else equals rclpy's encoding.

Types missing from the Jazzy store are registered from the rosbag2-style
definition text (:func:`friction_sim.io.typesupport.message_definition`).

:class:`FixedLayout` encodes many messages of a fixed-layout type at once
(the state topics at 1 kHz and far faster than real time): the bytes of a
template that rosbags serialized, with the stamp and the numbers written in
at offsets found by serializing probes, and checked byte for byte against
rosbags before use.
"""

from __future__ import annotations

import dataclasses
import math
import struct
import threading
from collections.abc import Callable, Sequence
from functools import cache, lru_cache
from typing import Any

import numpy as np

from friction_sim.core.model.spec import NS_PER_S
from friction_sim.io.typesupport import message_definition, message_type_name, normalized

# rosbags node types (rosbags.typesys.msg.Nodetype): a primitive, a message, an array, a sequence.
_BASE, _NAME, _ARRAY, _SEQUENCE = 1, 2, 3, 4
_DTYPES = {
    "bool": np.bool_, "byte": np.uint8, "char": np.uint8, "uint8": np.uint8, "int8": np.int8,
    "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32,
    "int64": np.int64, "uint64": np.uint64, "float32": np.float32, "float64": np.float64,
}
_lock = threading.Lock()


@lru_cache(maxsize=1)
def typestore() -> Any:
    """The rosbags typestore of ROS 2 Jazzy (types are added on first use)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def fields(type_name: str) -> list[tuple[str, Any]]:
    """(field name, rosbags field description) of a type, registering it first if needed."""
    return list(_fields(type_name))


@cache
def _fields(type_name: str) -> tuple[tuple[str, Any], ...]:
    """:func:`fields`, cached (a type's fields never change once registered)."""
    store = typestore()
    name = normalized(type_name)
    if name not in store.fielddefs:
        from rosbags.typesys import get_types_from_msg

        with _lock:
            if name not in store.fielddefs:
                store.register(get_types_from_msg(message_definition(name), name))
    return tuple(store.fielddefs[name][1])


def serialize(msg: Any) -> bytes:
    """``msg`` (a generated ROS 2 message or a rosbags dataclass) as CDR
    (little endian, with the 4-byte encapsulation header)."""
    type_name = message_type_name(type(msg))
    if not hasattr(msg, "__msgtype__") and not _duck_typed(type_name):
        msg = to_rosbags(msg, type_name)
    return bytes(typestore().serialize_cdr(msg, type_name))


def deserialize(data: bytes, type_name: str) -> Any:
    """A rosbags dataclass of ``type_name`` decoded from CDR ``data``."""
    fields(type_name)
    return typestore().deserialize_cdr(data, normalized(type_name))


@cache
def _duck_typed(type_name: str) -> bool:
    """Whether rosbags can serialize a generated ROS 2 object of this type as it
    is: no ``byte``/``char`` field and no primitive sequence or array at any depth."""
    for _, (node, detail) in _fields(type_name):
        if node == _BASE and detail[0] in ("byte", "char"):
            return False
        if node in (_ARRAY, _SEQUENCE) and detail[0][0] == _BASE and detail[0][1][0] != "string":
            return False
        element = detail if node == _NAME else detail[0][1] if node in (_ARRAY, _SEQUENCE) else None
        if isinstance(element, str) and not _duck_typed(element):
            return False
    return True


def to_rosbags(msg: Any, type_name: str) -> Any:
    """A generated ROS 2 message as the rosbags dataclass of ``type_name``, to
    serialize (fields that rosbags serializes as they are stay as given)."""
    kind, plan = _conversion(type_name)
    return kind(**{name: _value(getattr(msg, name), node, detail) for name, (node, detail) in plan})


@cache
def _conversion(type_name: str) -> tuple[Any, tuple[tuple[str, Any], ...]]:
    """(rosbags class, fields) of a type: what :func:`to_rosbags` needs, looked up once."""
    plan = _fields(type_name)
    return typestore().types[normalized(type_name)], plan


def _value(value: Any, node: int, detail: Any) -> Any:
    """One field value as rosbags holds it (see :func:`to_rosbags`); a
    message that rosbags serializes as it is (:func:`_duck_typed`) stays."""
    if node == _NAME:
        return value if _duck_typed(detail) else to_rosbags(value, detail)
    if node == _BASE:
        return value[0] if isinstance(value, bytes) else value
    (element_node, element), _ = detail
    if element_node == _NAME:
        return value if _duck_typed(element) else [to_rosbags(item, element) for item in value]
    if element[0] == "string":
        return list(value)
    if len(value) and isinstance(value[0], bytes):
        return np.frombuffer(b"".join(value), dtype=np.uint8).copy()
    return np.asarray(value, dtype=_DTYPES[element[0]])


# -- the stamped-message layout --------------------------------------------------
# The one place that knows where a *Stamped message keeps its stamp and its
# numbers in CDR little-endian: 4 bytes of encapsulation, then std_msgs/Header:
# builtin_interfaces/Time (int32 sec, uint32 nanosec), then frame_id (uint32
# length with its NUL, the bytes), then the body, 8-byte aligned counting from
# byte 4.  (Hand-written: reading a column of stamps or floats from thousands
# of messages at numpy speed is what rosbags' one-message decoder cannot do.)

_STAMP = struct.Struct("<iI")  # builtin_interfaces/Time: int32 sec, uint32 nanosec
LITTLE_ENDIAN_CDR = b"\x00\x01"
STAMP_OFFSET = 4
FRAME_ID_OFFSET = STAMP_OFFSET + _STAMP.size


def stamped_body_offset(data: bytes) -> int | None:
    """Where the body (the first field after the header) of a CDR little-endian
    *Stamped message starts, or None if ``data`` is not one."""
    if len(data) < FRAME_ID_OFFSET + 4 or data[:2] != LITTLE_ENDIAN_CDR:
        return None
    frame_length = int.from_bytes(data[FRAME_ID_OFFSET:FRAME_ID_OFFSET + 4], "little")  # with its NUL
    return STAMP_OFFSET + ((FRAME_ID_OFFSET + 4 - STAMP_OFFSET + frame_length + 7) & ~7)


def header_end(data: bytes) -> int:
    """The end of the header (encapsulation, stamp, frame_id) of a *Stamped message."""
    return FRAME_ID_OFFSET + 4 + int.from_bytes(data[FRAME_ID_OFFSET:FRAME_ID_OFFSET + 4], "little")


def stamps_ns(datas: Sequence[bytes]) -> np.ndarray[Any, np.dtype[np.int64]]:
    """The header stamps [ns] of CDR little-endian *Stamped messages, at numpy speed."""
    if not datas:
        return np.empty(0, np.int64)
    joined = np.frombuffer(b"".join(d[STAMP_OFFSET:FRAME_ID_OFFSET] for d in datas), dtype="<i4").reshape(-1, 2)
    stamps: np.ndarray[Any, np.dtype[np.int64]] = (joined[:, 0].astype(np.int64) * NS_PER_S
                                                   + (joined[:, 1].astype(np.int64) & 0xFFFFFFFF))
    return stamps


# -- many messages at once ---------------------------------------------------------

_F64 = struct.Struct("<d")
#: Two probe times [ns] that are exact in float seconds (t = ns / 1e9 round-trips).
_PROBE_NS = (1_234_500_000_000, 2_345_250_000_000)


@dataclasses.dataclass(frozen=True)
class FixedLayout:
    """Where a stamp and float64 values sit in the CDR of one message type
    whose bytes depend on nothing else (a header with a given frame_id, then
    numbers).  Hand-written format code only in that it writes numbers into
    the bytes rosbags serialized for a template: one rosbags call per
    message costs about 3.7 us, too slow for 300,000 state messages a second.
    Made by :func:`fixed_layouts`, which checks the result against rosbags."""

    type_name: str
    template: bytes
    #: Offset of the header stamp (int32 sec, uint32 nanosec).
    stamp: int
    #: (index of the value, offset of its float64) for each value the message carries.
    values: tuple[tuple[int, int], ...]

    @property
    def size(self) -> int:
        """Bytes of one message (with the 4-byte encapsulation header)."""
        return len(self.template)

    def encode_one(self, ns: int, values: Sequence[float]) -> bytes:
        """The CDR of one message stamped ``ns`` carrying ``values``."""
        data = bytearray(self.template)
        _STAMP.pack_into(data, self.stamp, *divmod(ns, NS_PER_S))
        for index, offset in self.values:
            _F64.pack_into(data, offset, values[index])
        return bytes(data)

    def fields(self, prefix: str, at: int) -> dict[str, tuple[str, int]]:
        """The numbers a message of this layout carries, as fields of a numpy structured type
        (name: (format, byte offset)): its stamp's ``sec`` and ``nanosec`` and each value
        ``value<index>``, named after ``prefix``, the message starting at byte ``at`` of a row."""
        return {f"{prefix}sec": ("<i4", at + self.stamp), f"{prefix}nanosec": ("<u4", at + self.stamp + 4),
                **{f"{prefix}value{index}": ("<f8", at + offset) for index, offset in self.values}}

    def fill(self, rows: np.ndarray[Any, np.dtype[Any]], prefix: str, ns: np.ndarray[Any, np.dtype[np.int64]],
             values: np.ndarray[Any, np.dtype[np.float64]]) -> None:
        """Write into structured ``rows`` (whose type holds :meth:`fields` under ``prefix``) each
        message's stamp ``ns[i]`` (>= 0, seconds within int32) and its ``values[i]``."""
        rows[f"{prefix}sec"], rows[f"{prefix}nanosec"] = np.divmod(ns, NS_PER_S)
        for index, _ in self.values:
            rows[f"{prefix}value{index}"] = values[:, index]

    def encode(self, ns: np.ndarray[Any, np.dtype[np.int64]],
               values: np.ndarray[Any, np.dtype[np.float64]]) -> np.ndarray[Any, np.dtype[np.uint8]]:
        """One message per row (``len(ns)`` rows of :attr:`size` bytes)."""
        rows = np.empty(len(ns), dtype=structured(self.fields("", 0), self.size))
        data = rows.view(np.uint8).reshape(len(ns), self.size)
        data[:] = np.frombuffer(self.template, dtype=np.uint8)
        self.fill(rows, "", ns, values)
        return data


def structured(fields: dict[str, tuple[str, int]], size: int) -> np.dtype[Any]:
    """The numpy structured type of rows of ``size`` bytes holding ``fields`` (name: (format,
    byte offset), little endian, unaligned): a row group is filled in one numpy call per field."""
    return np.dtype({"names": list(fields), "formats": [kind for kind, _ in fields.values()],
                     "offsets": [offset for _, offset in fields.values()], "itemsize": size})


def fixed_layouts(make: Callable[[int, Sequence[float]], Sequence[Any]],
                  n_values: int) -> tuple[FixedLayout, ...] | None:
    """The layouts of the messages ``make(ns, values)`` builds (a group of
    messages stamped ``ns`` that carry ``n_values`` float64 values), or None
    when they are not fixed-layout: found by serializing two probes with
    rosbags, then checked on random values (any difference: None, and the
    caller serializes one message at a time)."""
    markers = [[-7.25e-3 * (j + 1) - 1.0 / 3.0 for j in range(n_values)],
               [3.0e5 + 1.0 / 7.0 + j for j in range(n_values)]]
    probes = [[serialize(msg) for msg in make(ns, values)] for ns, values in zip(_PROBE_NS, markers)]
    if len(probes[0]) != len(probes[1]):
        return None
    layouts = []
    for first, second, msg in zip(*probes, make(_PROBE_NS[0], markers[0])):
        layout = _layout(message_type_name(type(msg)), first, second, markers)
        if layout is None:
            return None
        layouts.append(layout)
    rng = np.random.default_rng(0)
    for ns in (0, 999_999_999, 1_000_000_000, 86_400_123_456_789, 2_147_483_647_000_000_000):
        values = [float(v) for v in rng.normal(0.0, 1e3, n_values)] if ns else [0.0, -0.0, 5e-324][:n_values]
        values += [math.inf] * (n_values - len(values))
        expected = [serialize(msg) for msg in make(ns, values)]
        if [layout.encode_one(ns, values) for layout in layouts] != expected:
            return None
        many = np.array([values], dtype=np.float64)
        if [layout.encode(np.array([ns], dtype=np.int64), many)[0].tobytes() for layout in layouts] != expected:
            return None
    return tuple(layouts)


def _layout(type_name: str, first: bytes, second: bytes, markers: list[list[float]]) -> FixedLayout | None:
    """The layout of one message from its two probes (None if other bytes change)."""
    if len(first) != len(second):
        return None
    stamps = [_STAMP.pack(*divmod(ns, NS_PER_S)) for ns in _PROBE_NS]
    stamp = _unique(first, stamps[0])
    if stamp is None or second[stamp:stamp + 8] != stamps[1]:
        return None
    changing = set(range(stamp, stamp + 8))
    values = []
    for index, (a, b) in enumerate(zip(*markers)):
        offset = first.find(_F64.pack(a))
        while offset >= 0:
            if second[offset:offset + 8] != _F64.pack(b):
                return None
            values.append((index, offset))
            changing.update(range(offset, offset + 8))
            offset = first.find(_F64.pack(a), offset + 8)
    if any(x != y for k, (x, y) in enumerate(zip(first, second)) if k not in changing):
        return None
    return FixedLayout(type_name, first, stamp, tuple(values))


def _unique(data: bytes, pattern: bytes) -> int | None:
    """The one offset of ``pattern`` in ``data`` (None: absent or repeated)."""
    offset = data.find(pattern)
    return offset if offset >= 0 and data.find(pattern, offset + 1) < 0 else None


# -- introspection -----------------------------------------------------------------


def field_names(msg: Any) -> list[str]:
    """The field names of a message (rosbags dataclass or generated ROS 2
    message), in declaration order, without constants."""
    if hasattr(msg, "get_fields_and_field_types"):
        return list(msg.get_fields_and_field_types())
    return [name for name, _ in fields(message_type_name(type(msg)))]


def is_message(value: Any) -> bool:
    """Whether ``value`` is a message (rosbags dataclass or generated ROS 2 class)."""
    return hasattr(value, "get_fields_and_field_types") or (
        dataclasses.is_dataclass(value) and hasattr(value, "__msgtype__"))


# -- diagnostic_msgs/DiagnosticStatus ---------------------------------------------

_U32 = struct.Struct("<I")
#: CDR, little endian (the encapsulation header every message begins with).
_LITTLE_ENDIAN = b"\x00\x01\x00\x00"


def diagnostic_status(level: int, name: str, message: str, hardware_id: str,
                      values: Sequence[tuple[str, str]]) -> bytes:
    """The CDR of a diagnostic_msgs/DiagnosticStatus, byte for byte what rosbags
    serializes.  Hand-written because the recording writes an event of the motion
    as one, twice a period: rosbags' generic serializer took ~40 us a message, this
    ~6 us (a byte, three strings, a sequence of string pairs: CDR aligns each
    string's length to 4 bytes from the end of the encapsulation header)."""
    out = bytearray(_LITTLE_ENDIAN)
    out.append(level)
    for text in (name, message, hardware_id):
        _append_aligned(out, _named(text))
    out += b"\x00" * (-len(out) % 4)
    out += _U32.pack(len(values))
    for key, value in values:
        _append_aligned(out, _named(key))
        _append_aligned(out, _cdr_string(value))
    return bytes(out)


def _append_aligned(out: bytearray, encoded: bytes) -> None:
    """Append an encoded CDR string, its length aligned to 4 (the header's 4 bytes keep the body's alignment)."""
    out += b"\x00" * (-len(out) % 4)
    out += encoded


def _cdr_string(text: str) -> bytes:
    """A CDR string: its length (the NUL included), UTF-8, a NUL."""
    data = text.encode()
    return _U32.pack(len(data) + 1) + data + b"\x00"


#: The names, messages and keys an event's status takes are a few dozen: encoded once each.
_named = lru_cache(maxsize=512)(_cdr_string)


__all__ = [
    "FRAME_ID_OFFSET", "STAMP_OFFSET", "FixedLayout", "deserialize", "diagnostic_status", "field_names",
    "fields", "fixed_layouts", "header_end", "is_message", "serialize", "stamped_body_offset", "stamps_ns",
    "structured", "to_rosbags", "typestore",
]
