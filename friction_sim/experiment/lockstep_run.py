"""Playing a schedule into a slider in lockstep: the scheduler participant.

In lockstep (:mod:`friction_sim.core.runtime.lockstep`) the experiment's driver
is a participant of the slider: every command the slider takes goes out on
``stamped_command`` stamped with the time it applies, and each such message
promises that nothing earlier follows, so the slider never runs past what the
driver has said.  What cannot travel stamped (a parameter set on the slider, a
target or drive force for the controller, an operator's service calls) is done
while a promise holds the slider exactly at its time, once every sample up to
it has been answered; then the next promise lets it go on.  So each entry of
the schedule acts at exactly its ``t``, and the run gives the same numbers
every time, as fast as the nodes compute.
"""

from __future__ import annotations

import functools
from collections import defaultdict
from collections.abc import Callable, Sequence
from typing import Any

from friction_sim.core.model.commands import COMMANDS, CONTROLLER, PARAMETERS, SLIDER, Command
from friction_sim.core.runtime.lockstep import to_ns
from friction_sim.experiment.job import ExperimentSpec, OperatorAction
from friction_sim.io.messages import message_class, stamp_ns
from friction_sim.io.stamped import CONTROL_ANSWER, STAMPED_COMMAND, STAMPED_DEPTH, STAMPED_TYPE, stamped_message


class ScheduleParticipant:
    """The driver's side of lockstep (see the module)."""

    def __init__(self, spec: ExperimentSpec, driver: Any, spin_until: Callable[[Callable[[], bool], float, str], None],
                 timeout: float, *, attached: bool) -> None:
        self.spec, self.driver, self.spin_until, self.timeout = spec, driver, spin_until, timeout
        kind = message_class(STAMPED_TYPE)
        self.publisher = driver.create_publisher(kind, STAMPED_COMMAND, STAMPED_DEPTH)
        self.answered_ns = -1
        # (the samples it compares with are the attached plant's, as it records them; in this
        # process the slider's gate says what is answered: a subscription costs a wake-up)
        if attached and spec.controller:
            driver.create_subscription(kind, CONTROL_ANSWER, self._answer, STAMPED_DEPTH)

    def _answer(self, msg: Any) -> None:
        self.answered_ns = max(self.answered_ns, stamp_ns(msg.header.stamp))

    def connected(self) -> bool:
        """Whether the slider listens to the driver's stamped commands."""
        return bool(self.publisher.get_subscription_count() >= 1)

    def promise(self, t_ns: int, commands: Sequence[Command] = ()) -> None:
        """Commands that apply at ``t_ns``; nothing earlier follows."""
        self.publisher.publish(stamped_message(t_ns, commands))

    def reach(self, plant: Any, t_ns: int) -> None:
        """Wait until the slider stands at ``t_ns`` with every sample up to it answered; an
        ExperimentError once its time has not moved for ``timeout`` s of wall time (a long
        stretch of the schedule may take long: only a slider that stopped is a failure)."""
        while True:
            seen = plant.now_ns()
            self.spin_until(functools.partial(self._moved_or_there, plant, t_ns, seen), self.timeout,
                            f"lockstep: the slider stood at t = {seen / 1e9:.9f} s for {self.timeout:g} s of wall "
                            f"time on its way to {t_ns / 1e9:.9f} s (see its log: a participant did not answer)")
            if self._there(plant, t_ns):
                return

    def finish(self, plant: Any) -> None:
        """At the end of a run attached to a slider in another process: wait until it has sent its
        state again (it does, every REPEAT s, while it waits for what comes after the end), so what it
        sent with its last state, on other topics, has come too (DDS keeps no order between topics:
        the last mean velocity could still be on its way), and until every sample recorded is answered."""
        seen = plant.resent

        def done() -> bool:
            return bool(plant.resent > seen) and (not self.spec.controller or self.answered_ns >= plant.sample_ns())

        self.spin_until(done, self.timeout, f"lockstep: the slider did not send its state again within "
                        f"{self.timeout:g} s of wall time at the end of the run (see its log)")

    def _moved_or_there(self, plant: Any, t_ns: int, seen: int) -> bool:
        """Whether the slider is there, or has moved since it stood at ``seen`` (then look again)."""
        now = plant.now_ns()
        return now != seen if now < t_ns else self._there(plant, t_ns)

    def _there(self, plant: Any, t_ns: int) -> bool:
        """Whether the slider stands at ``t_ns`` (or on) with every sample up to it answered."""
        if plant.now_ns() < t_ns:
            return False
        if hasattr(plant, "answered"):  # (in this process: the slider's gate says it)
            return bool(plant.answered())
        return not self.spec.controller or self.answered_ns >= plant.sample_ns()

def timeline(spec: ExperimentSpec) -> list[tuple[int, list[Command], list[OperatorAction]]]:
    """The schedule's and the operator's times [ns, from the start], each with what happens then, and the end."""
    commands: dict[int, list[Command]] = defaultdict(list)
    actions: dict[int, list[OperatorAction]] = defaultdict(list)
    for command in sorted(spec.schedule, key=lambda c: c.t):
        commands[to_ns(command.t)].append(command)
    for action in sorted(spec.operator, key=lambda a: a.t):
        actions[to_ns(action.t)].append(action)
    end = to_ns(spec.duration)
    times = sorted({*commands, *actions, end})
    return [(t, commands.get(t, []), actions.get(t, [])) for t in times if t <= end]


def for_slider(command: Command) -> bool:
    """A topic command the slider takes (sent stamped)."""
    return command.name in COMMANDS and SLIDER in COMMANDS[command.name].consumers


def for_controller(commands: Sequence[Command]) -> dict[str, float]:
    """What the controller takes of ``commands`` (set as its parameters while the slider stands)."""
    return {field: float(value) for command in commands if command.name in COMMANDS
            and CONTROLLER in COMMANDS[command.name].consumers for field, value in command.values.items()}


def plant_sets(commands: Sequence[Command]) -> list[Command]:
    """The slider parameter sets among ``commands``."""
    return [command for command in commands if command.name == PARAMETERS]


__all__ = ["ScheduleParticipant", "for_controller", "for_slider", "plant_sets", "timeline"]

