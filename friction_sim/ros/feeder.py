"""Slider and controller in one process, on one executor: ``friction-sim feeder``.

For users without ROS 2 tooling: the pair behaves exactly as the two nodes
started separately in the same namespace, talking over the same topics.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from rclpy.node import Node
from rclpy.parameter import Parameter

from friction_sim.io.paramfile import read_params_file
from friction_sim.ros.controller import ControllerNode
from friction_sim.ros.run import FEEDER_EXIT_CODES, run_node
from friction_sim.ros.slider import SliderNode


def _overrides(path: Path | None, node_name: str) -> list[Parameter]:
    """Parameters for ``node_name`` from a ROS 2 params file (``/**`` or the node's own key)."""
    if path is None:
        return []
    return [Parameter(name, value=value) for name, value in read_params_file(path, node_name).items()]


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

    return run_node(make, args, prog="feeder", help_text=(
        "Slider and controller in one process, on one executor, talking over the same topics as the two "
        "nodes started separately (see slider --help and controller --help).\n\n" + FEEDER_EXIT_CODES))
