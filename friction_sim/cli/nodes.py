"""``friction-sim slider``, ``controller`` and ``feeder``: the nodes, run from the command line.

As ``ros2 run friction_sim slider`` (and ``controller``) would, with
``--params FILE``, ``--log FILE`` and ``--foxglove [PORT]`` turned into ROS
arguments and everything after ``--ros-args`` passed through; ``feeder`` runs
both nodes in one process.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from friction_sim.cli.options import Verb, add_foxglove
from friction_sim.errors import FrictionSimError


def add_slider_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``slider`` options."""
    parser.add_argument("--params", type=Path, help="ROS 2 parameters file, e.g. config/slider.yaml")
    parser.add_argument("--log", type=Path, metavar="FILE.mcap", help="record the run to an MCAP file")
    add_foxglove(parser)
    parser.set_defaults(ros_args=[])


def add_controller_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``controller`` options."""
    parser.add_argument("--params", type=Path, help="ROS 2 parameters file, e.g. config/controller.yaml")
    parser.set_defaults(ros_args=[])


def add_feeder_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``feeder`` options."""
    parser.add_argument("--slider-params", type=Path, help="parameters file for the slider")
    parser.add_argument("--controller-params", type=Path, help="parameters file for the controller")
    parser.add_argument("--log", type=Path, metavar="FILE.mcap", help="record the run to an MCAP file (the slider's "
                        "log_path)")
    add_foxglove(parser)
    parser.set_defaults(ros_args=[])


def slider(args: argparse.Namespace) -> int:
    """``slider``: run the real-time slider node."""
    from friction_sim.ros.slider import main as slider_main

    return slider_main(ros_args("friction-sim-slider", args))


def controller(args: argparse.Namespace) -> int:
    """``controller``: run the mean-speed controller node."""
    from friction_sim.ros.controller import main as controller_main

    return controller_main(ros_args("friction-sim-controller", args))


def feeder(args: argparse.Namespace) -> int:
    """``feeder``: slider and controller in one process."""
    from friction_sim.ros.feeder import main as feeder_main

    return feeder_main(ros_args("friction-sim-feeder", args), args.slider_params, args.controller_params)


def ros_args(prog: str, args: argparse.Namespace) -> list[str]:
    """The rclpy argument list: --params FILE becomes --ros-args --params-file FILE,
    --log FILE sets log_path, and anything after --ros-args on our command line is passed through."""
    ros: list[str] = []
    if getattr(args, "log", None) is not None:
        ros += ["-p", f"log_path:={args.log}"]
    if getattr(args, "foxglove", None) is not None:
        ros += ["-p", f"foxglove_port:={args.foxglove}"]
    if getattr(args, "params", None) is not None:
        if not args.params.is_file():
            raise FrictionSimError(f"--params: no such file: {args.params}")
        ros += ["--params-file", str(args.params)]
    ros += args.ros_args
    return [prog, "--ros-args", *ros] if ros else [prog]


VERBS = (
    Verb("slider", "run the real-time slider node (as `ros2 run friction_sim slider`)", add_slider_arguments, slider),
    Verb("controller", "run the mean-speed controller node (as `ros2 run friction_sim controller`)",
         add_controller_arguments, controller),
    Verb("feeder", "run slider and controller in one process (one executor)", add_feeder_arguments, feeder),
)

__all__ = ["VERBS", "controller", "feeder", "ros_args", "slider"]
