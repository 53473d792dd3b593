"""The controller node's parameters: its own sets, and the plant node's it takes and follows.

:class:`OwnParameters` answers a set of the node's own parameters: rclpy's
refusals (ranges, types, read-only) are counted like any refusal; the
cross-field rules are checked on a copy of the controller as it is now, and
the change takes effect whole or not at all; each set taken is answered with
the law's output.

:class:`PlantParameters` takes the plant from ``plant_node`` at start-up
through its parameter services (:data:`~friction_sim.ros.controller_plant.ADOPTED`,
and whether it runs in lockstep) and afterwards follows the changes of some of them on
``/parameter_events`` (:data:`~friction_sim.ros.controller_plant.FOLLOWED`), each
through this node's own parameter of the same name, so it is validated like any set.
"""

from __future__ import annotations

import time
from typing import Any, Protocol

from rcl_interfaces.msg import ParameterEvent, SetParametersResult
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

from friction_sim.core.control.law import MeanSpeedController
from friction_sim.core.model import spec
from friction_sim.core.runtime.controller import RealtimeController, plant_words, taken_words
from friction_sim.errors import ParameterError
from friction_sim.io.messages import parameter_event_values
from friction_sim.ros.controller_lockstep import LOCKSTEP_READ
from friction_sim.ros.controller_plant import ADOPTED, FOLLOWED, PARAMETERS, named, own_parameters

#: Wall time [s] the plant node has to answer at start-up.
PLANT_TIMEOUT = 5.0


class ParameterHost(Protocol):
    """What the parameters need of the controller node (:class:`~friction_sim.ros.controller.ControllerNode`)."""

    @property
    def runtime(self) -> RealtimeController: ...
    @property
    def control(self) -> MeanSpeedController: ...
    @property
    def callback_lock(self) -> Any: ...
    @property
    def in_lockstep(self) -> bool: ...
    def get_logger(self) -> Any: ...
    def get_parameter(self, name: str) -> Any: ...
    def set_parameters_atomically(self, parameter_list: list[Parameter]) -> SetParametersResult: ...

    def internal_error(self, where: str, error: BaseException) -> None: ...
    def publish_output(self) -> None: ...
    def publish_diagnostics(self) -> None: ...
    def settle(self, message: str, warn: bool = False) -> None: ...
    def start_lockstep(self, delay: float, accelerometer_rate: float) -> None: ...


class OwnParameters:
    """The handlers of a set of the node's own parameters (see the module doc);
    the node registers them with rclpy."""

    def __init__(self, host: ParameterHost) -> None:
        self._host = host

    def refused(self, name: str, value: Any, why: str) -> None:
        """rclpy refused a parameter value before our callbacks (range, type,
        read-only, undeclared): counted like any refusal (the watch has warned)."""
        with self._host.callback_lock:
            self._host.runtime.refuse(f"parameter {why}")

    def on_set(self, changes: list[Parameter]) -> SetParametersResult:
        """:meth:`_check_and_take`; an unexpected error in it refuses the set."""
        host = self._host
        with host.callback_lock:
            try:
                return self._check_and_take(changes)
            except Exception as error:  # noqa: BLE001 - answer the caller, report, go on
                host.internal_error("parameter set", error)
                return SetParametersResult(successful=False,
                                           reason=f"internal error: {host.runtime.last_internal_error}")

    def _check_and_take(self, changes: list[Parameter]) -> SetParametersResult:
        """Cross-field rules, checked on a copy of the controller as it is now
        (drive force and frequency follow the topics): the change takes effect
        whole, or it is refused and nothing changes."""
        host = self._host
        values = {p.name: p.value for p in changes}
        current = {name: host.get_parameter(name).value for name in PARAMETERS}
        try:
            candidate = host.runtime.with_parameters(values, current)
        except ParameterError as error:
            host.get_logger().warning(f"parameter {error}; value kept")  # one per set: a service call each
            return SetParametersResult(successful=False, reason=str(error))
        host.runtime.adopt(candidate, values, current)
        return SetParametersResult(successful=True)

    def after_set(self, changes: list[Parameter]) -> None:
        """A set was taken: the law's output answers it."""
        self._host.publish_output()


class PlantParameters:
    """The plant node's parameters, taken at start-up and followed afterwards (see the module doc)."""

    def __init__(self, host: ParameterHost, client: AsyncParameterClient | None) -> None:
        """``client``: the plant node's parameter client (None: no plant node, settled at once)."""
        self._host = host
        self._client = client
        self._future: Any = None
        self._deadline = time.monotonic() + PLANT_TIMEOUT
        #: True once the model is taken from the plant (or the plant did not answer, or there is none).
        self.settled = client is None

    def poll(self) -> None:
        """Ask the plant node once its services are up; take its answer, or give up after the timeout."""
        if self._client is None:
            return
        if self._future is None and self._client.services_are_ready():
            self._future = self._client.get_parameters([*ADOPTED, *LOCKSTEP_READ])
        if self._future is not None and self._future.done():
            self.adopt(self._future.result())
        elif time.monotonic() > self._deadline:
            self._host.settle(f"plant node '{self._host.get_parameter('plant_node').value}' did not answer "
                              f"within {PLANT_TIMEOUT:g} s: using this node's own mass, mu and gravity", warn=True)

    def adopt(self, response: Any) -> None:
        """Take the plant's whole model, window, drive force and frequency as this
        node's own parameters (validated and applied like any parameter change),
        and its drive level as where the inner loop starts.  A parameter the
        plant node does not declare (an older slider) keeps this node's value."""
        host = self._host
        runtime = host.runtime
        try:
            read = [*ADOPTED, *LOCKSTEP_READ]
            values = dict(zip(read, [Parameter.from_parameter_msg(named(name, value)).value
                                     for name, value in zip(read, response.values, strict=True)]))
            lockstep = {name: values.pop(name) for name in LOCKSTEP_READ}
            level = values.pop("drive_level")  # the resonant plant's level in force: the inner loop starts there
            # Checked here, where it comes in: the inner loop starts from it as from a level in range.
            runtime.plant_drive_level = None if level is None else float(spec.DRIVE_LEVEL.check(level))
            update = own_parameters(values)
        except (TypeError, ValueError) as error:
            host.settle(f"plant parameters unusable ({error}): using this node's own", warn=True)
            return
        result = host.set_parameters_atomically(update)
        if not result.successful:
            host.settle(f"plant parameters unusable ({result.reason}): using this node's own", warn=True)
            return
        if lockstep["lockstep"]:
            host.start_lockstep(lockstep["actuation_delay"], lockstep["accelerometer_rate"] or 0.0)
        runtime.model_source = f"plant node {runtime.plant_node}"
        runtime.taken_from_plant = taken_words({parameter.name: parameter.value for parameter in update}, level)
        host.settle(f"took from {runtime.model_source}: {runtime.taken_from_plant}")

    def on_event(self, msg: ParameterEvent) -> None:
        """The plant node's parameters changed (``ros2 param set /slider
        excitation_frequency 100.0``): the model follows, through this node's
        own parameters (validated like any set), so the law inverts the plant
        in force; what this node cannot take is warned about, and it keeps the
        model it has."""
        host = self._host
        runtime = host.runtime
        if msg.node != runtime.plant_node or not self.settled or host.in_lockstep:
            return  # (in lockstep an event is not ordered with the samples: who changes the plant sets this node)
        new, changed = parameter_event_values(msg)
        event = {**new, **changed}
        values = {name: value for name, value in event.items() if name in FOLLOWED}
        if not values:
            return
        words = ", ".join(f"{name} = {value!r}" for name, value in values.items())
        try:
            result = host.set_parameters_atomically(own_parameters(values))
            reason = "" if result.successful else result.reason
        except (TypeError, ValueError) as error:
            reason = str(error)
        if reason:
            runtime.refuse(f"plant change {words}: {reason}")
            host.get_logger().warning(f"plant {runtime.plant_node} changed {words}, which this controller "
                                      f"cannot take ({reason}); it keeps inverting {plant_words(host.control)}")
        else:
            runtime.plant_changes += 1
            host.get_logger().info(f"plant {runtime.plant_node} changed {words}: the model follows "
                                   f"({plant_words(host.control)})")
        host.publish_diagnostics()


__all__ = ["PLANT_TIMEOUT", "OwnParameters", "ParameterHost", "PlantParameters"]
