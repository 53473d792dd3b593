"""Slider and controller in one process, on one executor: ``friction-sim feeder``.

For users without ROS 2 tooling: the pair behaves exactly as the two nodes
started separately in the same namespace, talking over the same topics.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

from rclpy.node import Node

from friction_sim.errors import FrictionSimError
from friction_sim.nodes.common import run_node
from friction_sim.nodes.controller import ControllerNode
from friction_sim.nodes.slider import SliderNode


def _overrides(path: Path | None, node_name: str) -> list:  # type: ignore[type-arg]
    """Parameters for ``node_name`` from a ROS 2 params file (``/**`` or the node's own key)."""
    if path is None:
        return []
    import yaml
    from rclpy.parameter import Parameter

    try:
        document = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError) as error:
        raise FrictionSimError(f"cannot read parameters file {path}: {error}") from error
    if not isinstance(document, dict):
        raise FrictionSimError(f"{path}: not a ROS 2 parameters file (expected '/**:' or '{node_name}:' sections)")
    values: dict = {}
    for key, section in document.items():
        if key in ("/**", node_name, f"/{node_name}") and isinstance(section, dict):
            values.update(section.get("ros__parameters", {}) or {})
    return [Parameter(name, value=value) for name, value in values.items()]


def main(args: Sequence[str] | None = None, slider_params: Path | None = None,
         controller_params: Path | None = None) -> int:
    """Run both nodes until Ctrl-C / SIGTERM; exit code as for the single nodes."""

    def make() -> list[Node]:
        slider_overrides = _overrides(slider_params, "slider")
        controller_overrides = _overrides(controller_params, "controller")
        slider = SliderNode(parameter_overrides=slider_overrides)
        try:
            return [slider, ControllerNode(parameter_overrides=controller_overrides)]
        except BaseException:
            slider.destroy_node()  # its tick thread and recorder must not outlive the failure
            raise

    return run_node(make, args, prog="feeder")
