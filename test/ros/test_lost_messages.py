"""A message rclpy takes but cannot convert to a Python object (its error
"Unable to convert call argument '0' to Python object", seen twice in CI on a
loaded machine) is counted and lost; the node, and an experiment's driver, go
on.  Any other error still surfaces."""

from __future__ import annotations

from typing import Any

import pytest

from friction_sim.ros import driving, run
from friction_sim.ros.intake import LostMessages, take_with_info

FAILURE = RuntimeError("Unable to convert call argument '0' to Python object (#define PYBIND11_DETAILED_ERROR_MESSAGES "
                       "or compile in debug mode for details)")


class _Handle:
    """A subscription handle whose takes answer ``script`` in order (an exception is raised)."""

    def __init__(self, script: list[Any]) -> None:
        self.script = script

    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None

    def take_message(self, msg_type: Any, raw: bool) -> Any:
        item = self.script.pop(0)
        if isinstance(item, BaseException):
            raise item
        return item


class _Subscription:
    def __init__(self, script: list[Any]) -> None:
        self.handle, self.msg_type, self.raw = _Handle(script), object, False


def test_a_take_that_cannot_convert_is_counted_and_the_next_message_taken() -> None:
    before = LostMessages.count
    taken = take_with_info(_Subscription([FAILURE, ("message", {"received_timestamp": 1}), None]), 10)  # type: ignore[arg-type]
    assert taken == [("message", {"received_timestamp": 1})]
    assert LostMessages.count == before + 1 and "Unable to convert" in LostMessages.last
    with pytest.raises(RuntimeError, match="something else"):
        take_with_info(_Subscription([RuntimeError("something else")]), 10)  # type: ignore[arg-type]


class _Executor:
    def __init__(self, script: list[BaseException | None]) -> None:
        self.script, self.turns = script, 0

    def spin_once(self, timeout_sec: float) -> None:
        self.turns += 1
        item = self.script.pop(0) if self.script else None
        if item is not None:
            raise item

    def spin(self) -> None:
        self.spin_once(0.0)


def test_the_driver_and_the_node_spin_on_past_a_lost_message(ros: None) -> None:
    before = LostMessages.count
    driver = _Executor([FAILURE])
    driving.spin_once(driver, 0.01)  # the experiment driver's turn
    assert LostMessages.count == before + 1
    with pytest.raises(RuntimeError, match="other"):
        driving.spin_once(_Executor([RuntimeError("other")]), 0.01)
    node = _Executor([FAILURE, FAILURE, None])
    flag = run._InterruptFlag()  # noqa: SLF001 - a node's spin, as run_node does it
    try:
        run._spin(node, flag)  # type: ignore[arg-type]  # noqa: SLF001
    finally:
        flag.restore()
    assert node.turns == 3 and LostMessages.count == before + 3
