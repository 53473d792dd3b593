"""What rosbag2 stores about a message type: its name, full definition, hash and QoS.

A recording opens in ``ros2 bag info``/``ros2 bag play`` and Foxglove only if
every schema and channel carries what rosbag2's MCAP storage plugin (Jazzy)
writes:

* the type name ``pkg/msg/Type``;
* the full ``ros2msg`` definition: the type's ``.msg`` text with every
  dependency appended (80 ``=``, ``MSG: pkg/Type``, its text; sorted, depth
  first, each once), read from the installed ``share/<pkg>/msg``;
* the RIHS01 type hash from the installed type description
  (``share/<pkg>/msg/<Type>.json``);
* the publisher's QoS as the YAML rosbag2 writes (``offered_qos_profiles``).

Nothing here imports rclpy: only the files the message packages install.
"""

from __future__ import annotations

import importlib
import json
import re
import sys
from functools import cache
from pathlib import Path
from typing import Any

import yaml

from friction_sim.errors import RecordingError
from friction_sim.io.messages import TYPE_NAME, message_class

#: RMW_DURATION_INFINITE as rosbag2 serialises it (what the RMW reports for
#: a publisher's default deadline, lifespan and liveliness lease duration).
_INFINITE = {"sec": 9223372036, "nsec": 854775807}

# rosbag2_storage_mcap's message_definition_cache.cpp, verbatim.
_MSG_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVES = frozenset({
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
    "int32", "uint32", "int64", "uint64", "string",
})
_SEPARATOR = "=" * 80 + "\n"
_IDL_TO_MSG = {
    "boolean": "bool", "octet": "byte", "char": "char", "float": "float32", "double": "float64",
    "int8": "int8", "uint8": "uint8", "int16": "int16", "uint16": "uint16", "int32": "int32",
    "uint32": "uint32", "int64": "int64", "uint64": "uint64", "string": "string",
}


def message_type_name(msg_class: type) -> str:
    """``pkg/msg/Type`` of a message class: a generated ROS 2 class (named
    after its module) or a rosbags dataclass (which carries ``__msgtype__``)."""
    name = _type_names.get(msg_class)
    if name is None:
        declared = getattr(msg_class, "__msgtype__", None)
        if isinstance(declared, str):
            name = declared
        else:
            name = f"{msg_class.__module__.split('.', 1)[0]}/msg/{msg_class.__name__}"
        _type_names[msg_class] = name
    return name


_type_names: dict[type, str] = {}  # a class's type name, looked up once (per message written)


@cache
def normalized(type_name: str) -> str:
    """``pkg/msg/Type`` for ``pkg/msg/Type`` or ``pkg/Type``; RecordingError otherwise."""
    match = TYPE_NAME.match(type_name)
    if match is None:
        raise RecordingError(f"not a ROS 2 message type name: {type_name!r}")
    return f"{match.group(1)}/msg/{match.group(3)}"


@cache
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
    """An installed ``share/<package>/msg/<name><suffix>``, or None."""
    share = share_directory(package)
    if share is None:
        return None
    path = share / "msg" / f"{name}{suffix}"
    return path if path.is_file() else None


@cache
def _msg_text(type_name: str) -> tuple[str, bool]:
    """(.msg text of one type, whether it came from the installed file)."""
    package, _, name = normalized(type_name).split("/")
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
    The text is read from the installed .msg files because rosbag2 stores it
    with the comments, which no library's generated text reproduces.
    """
    return _message_definition(normalized(type_name))


@cache
def _message_definition(type_name: str) -> str:
    """:func:`message_definition` of a normalized name (cached)."""
    return _with_dependencies(_msg_text(type_name)[0], type_name)


def _with_dependencies(text: str, type_name: str) -> str:
    """``text`` (of ``type_name``) with every dependency appended, as rosbag2 does."""
    seen: set[str] = set()

    def append(body: str, package: str, depth: int) -> str:
        if depth <= 0:
            raise RecordingError(f"message definition of {type_name} nests too deeply")
        result = body
        for dependency in _dependencies(body, package):
            if dependency not in seen:
                seen.add(dependency)
                dependency_text, _ = _msg_text(normalized(dependency))
                result += "\n" + _SEPARATOR + f"MSG: {dependency}\n" + append(
                    dependency_text, dependency.split("/", 1)[0], depth - 1)
        return result

    return append(text, type_name.split("/", 1)[0], 50)


@cache
def service_definitions(type_name: str) -> tuple[str, str]:
    """The ``ros2msg`` texts of a service's request and response
    (``pkg/srv/Type``): the halves of its installed ``.srv`` file, each with
    its dependencies appended as :func:`message_definition` appends them."""
    match = TYPE_NAME.match(type_name)
    share = share_directory(match.group(1)) if match and match.group(2) == "srv/" else None
    path = share / "srv" / f"{match.group(3)}.srv" if share is not None and match else None
    if path is None or not path.is_file():
        raise RecordingError(f"service type {type_name!r} is not installed (want pkg/srv/Type)")
    request, _, response = _halves(path.read_text("utf-8"))
    return _with_dependencies(request, type_name), _with_dependencies(response, type_name)


def _halves(text: str) -> tuple[str, str, str]:
    """A .srv text split at its ``---`` line: (request, separator, response)."""
    parts = re.split(r"^---[ \t]*\n?", text, maxsplit=1, flags=re.MULTILINE)
    if len(parts) != 2:
        raise RecordingError("a .srv file without its --- line")
    return parts[0], "---", parts[1]


def _dependencies(text: str, package: str) -> list[str]:
    """The non-primitive field types of a .msg text, as ``pkg/Type``, sorted."""
    found = set()
    for match in _MSG_FIELD_TYPE.finditer(text):
        kind = match.group(1)
        if kind not in _PRIMITIVES:
            found.add(kind if "/" in kind else f"{package}/{kind}")
    return sorted(found)


def definitions_from_files(type_name: str) -> bool:
    """Whether the type and all its dependencies were read from installed .msg files
    (False: some text was generated from the message class's fields)."""
    names = [normalized(type_name)]
    names += [normalized(line[5:]) for line in message_definition(type_name).split("\n") if line.startswith("MSG: ")]
    return all(_msg_text(name)[1] for name in names)


def _generated_msg_text(msg_class: type) -> str:
    """A .msg text from a message class's fields, for types whose .msg file is
    not installed (constants and comments are lost; field types are exact)."""
    lines = []
    fields: dict[str, str] = msg_class.get_fields_and_field_types()  # type: ignore[attr-defined]
    for name, kind in fields.items():
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


@cache
def type_hash(type_name: str) -> str:
    """RIHS01 hash of a type, from its installed type description
    (``share/<pkg>/msg/<Type>.json``); "" if that file is not installed."""
    name = normalized(type_name)
    package, _, short = name.split("/")
    path = _interface_file(package, short, ".json")
    if path is None:
        return ""
    try:
        hashes = json.loads(path.read_text())["type_hashes"]
    except (OSError, ValueError, KeyError):
        return ""
    for entry in hashes:
        if entry.get("type_name") == name:
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


def _plain_dumper(base: type[Any]) -> type[Any]:
    """A dumper on ``base`` that writes block-style YAML without anchors and aliases (yaml-cpp writes none)."""

    class PlainDumper(base):  # type: ignore[misc]  # (a class chosen at run time)
        def ignore_aliases(self, data: Any) -> bool:
            """Never write an alias: every repeated value is written out."""
            return True

    return PlainDumper


#: PyYAML's own emitter, and libyaml's where PyYAML was built with it (the same text, five times
#: faster: a recording's rosbag2 metadata, written as it finishes, took 8 ms with the former).
PLAIN_DUMPERS = {"python": _plain_dumper(yaml.SafeDumper),
                 **({"libyaml": _plain_dumper(yaml.CSafeDumper)} if yaml.__with_libyaml__ else {})}
_PLAIN_DUMPER = PLAIN_DUMPERS.get("libyaml", PLAIN_DUMPERS["python"])


def plain_yaml(value: Any, dumper: type[Any] = _PLAIN_DUMPER) -> str:
    """``value`` as block YAML in the order given, without aliases (as yaml-cpp writes it)."""
    return yaml.dump(value, Dumper=dumper, sort_keys=False, default_flow_style=False)


def qos_yaml(profiles: list[dict[str, Any]]) -> str:
    """The ``offered_qos_profiles`` channel metadata string (block YAML, as
    yaml-cpp dumps it in rosbag2)."""
    return plain_yaml(profiles).rstrip("\n")


#: The QoS of every friction_sim publisher (depth 10, reliable, volatile).
DEFAULT_QOS = offered_qos_profiles()


__all__ = [
    "DEFAULT_QOS", "PLAIN_DUMPERS", "definitions_from_files", "message_definition", "message_type_name", "normalized",
    "offered_qos_profiles", "plain_yaml", "qos_yaml", "service_definitions", "share_directory", "type_hash",
]
