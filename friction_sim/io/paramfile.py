"""Reading a ROS 2 parameters file (``--params-file`` format) without ROS.

Both ``friction-sim feeder`` (which builds its nodes in-process) and scenario
files (``plant_params:``) take their values from such files; this is the one
reader of them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from friction_sim.errors import FrictionSimError


def read_params_file(path: Path, node_name: str) -> dict[str, Any]:
    """The ``ros__parameters`` of ``node_name`` in ``path``: the ``/**``
    section, overridden by the node's own (``name`` or ``/name``)."""
    document = read_yaml_mapping(path, f"a ROS 2 parameters file (expected '/**:' or '{node_name}:' sections)",
                                 what="parameters file")
    return node_parameters(document, node_name)


def read_yaml_mapping(path: Path, expected: str, *, what: str = "file") -> dict[str, Any]:
    """The YAML mapping in ``path``; FrictionSimError (one line) if it cannot be
    read or is not a mapping (``expected`` says what it should have been)."""
    try:
        document = yaml.safe_load(Path(path).read_text()) or {}
    except (OSError, yaml.YAMLError) as error:
        raise FrictionSimError(f"cannot read {what} {path}: {error}") from error
    if not isinstance(document, dict):
        raise FrictionSimError(f"{path}: not {expected}")
    return document


def _sections(node_name: str) -> tuple[str, ...]:
    return ("/**", node_name, f"/{node_name}")


def is_parameters_file(document: dict[str, Any], node_name: str) -> bool:
    """Whether a YAML mapping is laid out as a ROS 2 parameters file for ``node_name``."""
    return any(key in document for key in _sections(node_name))


def node_parameters(document: dict[str, Any], node_name: str) -> dict[str, Any]:
    """The ``ros__parameters`` of ``node_name`` in a parameters file's mapping:
    the ``/**`` section, overridden by the node's own."""
    values: dict[str, Any] = {}
    for key in _sections(node_name):
        section = document.get(key)
        if isinstance(section, dict):
            values.update(section.get("ros__parameters") or {})
    return values
