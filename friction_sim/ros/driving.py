"""What a driver of nodes does over ROS, whoever drives: turn its executor
until something holds, and set a node's parameters through its service.

The experiment runner (:mod:`friction_sim.experiment.runner`) drives the
feeder's nodes with these, in this process or attached to nodes in another;
an experiment's failures are :class:`~friction_sim.errors.ExperimentError`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any

from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

from friction_sim.errors import ExperimentError
from friction_sim.ros.intake import LostMessages
from friction_sim.ros.run import NodeFault


def overrides(values: dict[str, Any]) -> list[Parameter]:
    """rclpy parameters (node overrides, or a set) for ``values``."""
    return [Parameter(name, value=value) for name, value in values.items()]


def spin_until(executor: Any, done: Callable[[], bool], seconds: float, failure: str, *, poll: float = 0.01) -> None:
    """Spin ``executor`` until ``done()``; an ExperimentError saying ``failure``
    after ``seconds`` of wall time (math.inf: wait for ever).  ``done()`` is asked
    after each callback and at least every ``poll`` seconds: a condition that no
    callback of the executor's nodes brings about needs the default; one that
    one does (a message, a guard condition) may wait longer between looks."""
    deadline = time.monotonic() + seconds
    while not done():
        if time.monotonic() > deadline:
            raise ExperimentError(failure)
        spin_once(executor, poll)


def spin_once(executor: Any, timeout: float) -> None:
    """One turn of the driver's executor; a message rclpy took but could not
    convert (see :class:`friction_sim.ros.intake.LostMessages`) is lost and
    counted, not the end of the experiment."""
    try:
        executor.spin_once(timeout_sec=timeout)
    except NodeFault as fault:  # a node of this process stopped (it logged why): so does the experiment
        raise ExperimentError(str(fault)) from None
    except RuntimeError as error:
        if not LostMessages.lost(error):
            raise


#: The attribute of a driver node that keeps its parameter clients, one per node it sets.
_CLIENTS = "_friction_sim_parameter_clients"


def parameter_client(driver: Any, executor: Any, node: str) -> AsyncParameterClient:
    """The parameter client of ``node`` in the driver's namespace, once its services answer.
    One per node for the driver's lifetime, kept on the driver node: each holds six service
    clients (~0.85 MB) that rclpy frees only with the node, and a soak sets parameters every
    simulated minute (a client per call grew an hour's run by 50 MB)."""
    clients: dict[str, AsyncParameterClient] = driver.__dict__.setdefault(_CLIENTS, {})
    client = clients.get(node)
    if client is None:
        client = clients[node] = AsyncParameterClient(driver, node)
    spin_until(executor, client.services_are_ready, 10.0,
               f"no node '{node}' answers in {driver.get_namespace()} "
               "(start it first, e.g. friction-sim feeder --ros-args -r __ns:=...)")
    return client


def set_parameters(driver: Any, executor: Any, node: str, values: dict[str, Any]) -> None:
    """Set ``values`` on ``node`` through its parameter service; refusals are ExperimentErrors."""
    future = parameter_client(driver, executor, node).set_parameters(overrides(values))
    spin_until(executor, future.done, math.inf, "")
    check_results(node, values, future.result().results)


def check_results(node: str, values: dict[str, Any], results: Sequence[Any]) -> None:
    """An ExperimentError naming the first of ``values`` that ``node`` refused (rcl_interfaces
    SetParametersResult, one per value), if any."""
    for name, result in zip(values, results, strict=False):
        if not result.successful:
            raise ExperimentError(f"{node} refused {name}: {result.reason}")


def get_parameters(driver: Any, executor: Any, node: str, names: list[str]) -> list[Any]:
    """The values (rcl_interfaces ParameterValue) of ``names`` on ``node``."""
    future = parameter_client(driver, executor, node).get_parameters(names)
    spin_until(executor, future.done, 10.0, f"{node} did not answer for its parameters {', '.join(names)}")
    return list(future.result().values)


__all__ = ["check_results", "get_parameters", "overrides", "parameter_client", "set_parameters", "spin_once",
           "spin_until"]
