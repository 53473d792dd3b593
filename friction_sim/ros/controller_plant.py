"""How the controller reads its plant node's parameters: which ones, and as what.

At start-up the controller takes its whole plant from ``plant_node``
(:data:`ADOPTED`) and afterwards follows the changes of some of them on
``/parameter_events`` (:data:`FOLLOWED`); each value becomes this node's own
parameter of the same name (:func:`own_parameters`), so it is validated like
any parameter set.
"""

from __future__ import annotations

from typing import Any

from rclpy.parameter import Parameter

from friction_sim.core.model import spec
from friction_sim.core.runtime.controller import MODEL
from friction_sim.io.messages import node_name

PARAMETERS = spec.CONTROLLER_NODE

#: The plant node's parameters the controller follows as they change (its exciter's data are
#: read once: the inner loop learns how a load moves them).
FOLLOWED = (*(name for name in MODEL if name not in spec.EXCITER), "mean_window_periods", "drive_force",
            "excitation_frequency")
#: The plant node's parameters the controller takes at start-up: its whole plant (model, exciter,
#: window, Fd, f) and the drive level it runs at (where the inner loop starts).
ADOPTED = (*MODEL, "mean_window_periods", "drive_force", "excitation_frequency", "drive_level")


def own_parameters(values: dict[str, Any]) -> list[Parameter]:
    """The plant's parameter values as this node's parameters of the same
    names (a value the plant does not have, None, is left out)."""
    return [Parameter(name, value=typed(PARAMETERS[name], value)) for name, value in values.items()
            if value is not None]


def qualified(node: str, namespace: str) -> str:
    """The fully qualified name of ``node`` as seen from ``namespace`` (an
    absolute name stays; a relative one is resolved in the namespace)."""
    return node if node.startswith("/") else node_name(namespace, node)


def typed(setting: spec.Setting, value: Any) -> Any:
    """A plant parameter's value as this node's parameter of the same name
    takes it (an integer answer for a float parameter is taken as a float)."""
    if setting.kind is str:
        if not isinstance(value, str):
            raise TypeError(f"{setting.name} = {value!r} is not a string")
        return value
    if setting.kind is int:
        return int(value)
    return float(value)


def named(name: str, value: Any) -> Any:
    """A rcl_interfaces/Parameter message from a ParameterValue (for Parameter.from_parameter_msg)."""
    from rcl_interfaces.msg import Parameter as ParameterMsg

    return ParameterMsg(name=name, value=value)


__all__ = ["ADOPTED", "FOLLOWED", "named", "own_parameters", "qualified", "typed"]
