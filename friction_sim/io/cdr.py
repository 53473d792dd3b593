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
"""

from __future__ import annotations

import dataclasses
import threading
from functools import cache, lru_cache
from typing import Any

import numpy as np

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
    store = typestore()
    name = normalized(type_name)
    if name not in store.fielddefs:
        from rosbags.typesys import get_types_from_msg

        with _lock:
            if name not in store.fielddefs:
                store.register(get_types_from_msg(message_definition(name), name))
    return list(store.fielddefs[name][1])


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
    for _, (node, detail) in fields(type_name):
        if node == _BASE and detail[0] in ("byte", "char"):
            return False
        if node in (_ARRAY, _SEQUENCE) and detail[0][0] == _BASE and detail[0][1][0] != "string":
            return False
        element = detail if node == _NAME else detail[0][1] if node in (_ARRAY, _SEQUENCE) else None
        if isinstance(element, str) and not _duck_typed(element):
            return False
    return True


def to_rosbags(msg: Any, type_name: str) -> Any:
    """A generated ROS 2 message as the rosbags dataclass of ``type_name``."""
    values = {name: _value(getattr(msg, name), node, detail) for name, (node, detail) in fields(type_name)}
    return typestore().types[normalized(type_name)](**values)


def _value(value: Any, node: int, detail: Any) -> Any:
    """One field value as rosbags holds it (see :func:`to_rosbags`)."""
    if node == _NAME:
        return to_rosbags(value, detail)
    if node == _BASE:
        return value[0] if isinstance(value, bytes) else value
    (element_node, element), _ = detail
    if element_node == _NAME:
        return [to_rosbags(item, element) for item in value]
    if element[0] == "string":
        return list(value)
    if len(value) and isinstance(value[0], bytes):
        return np.frombuffer(b"".join(value), dtype=np.uint8).copy()
    return np.asarray(value, dtype=_DTYPES[element[0]])


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


__all__ = ["deserialize", "field_names", "fields", "is_message", "serialize", "to_rosbags", "typestore"]
