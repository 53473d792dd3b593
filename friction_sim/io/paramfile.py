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
    try:
        document = yaml.safe_load(Path(path).read_text()) or {}
    except (OSError, yaml.YAMLError) as error:
        raise FrictionSimError(f"cannot read parameters file {path}: {error}") from error
    if not isinstance(document, dict):
        raise FrictionSimError(f"{path}: not a ROS 2 parameters file (expected '/**:' or '{node_name}:' sections)")
    values: dict[str, Any] = {}
    for key in ("/**", node_name, f"/{node_name}"):
        section = document.get(key)
        if isinstance(section, dict):
            values.update(section.get("ros__parameters") or {})
    return values
