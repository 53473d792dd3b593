"""A node under fuzzing: what the slider's and the controller's rigs share
(test/ros/fuzz_slider_rig.py, test/ros/fuzz_controller_rig.py): the node's
process, the hostile client, the model of what it must do, and the
invariants checked after each step and each example.

After every step: the process is alive and printed no traceback; everything
it published is finite (pose stamps never go back); a parameter set was
answered as the model says (refusals with a one-line reason naming a
parameter of the set when fields disagree), and ``get_parameters`` answers
what was set.  After every example: it still publishes; its diagnostics
report the inputs the model has in force (and, for values no topic changed
since, the value ``get_parameters`` answers), and count every refusal.
"""

from __future__ import annotations

import itertools
import re
import time
import uuid
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from friction_sim.core.model.commands import COMMANDS

from fuzz_harness import FuzzClient, NodeProcess, one_line
from fuzz_models import Count, ParameterModel, SliderModel
from fuzz_strategies import Params, Step, Topic, Wait

#: Let a message published now reach the node's reader before the next input
#: (a bound for local delivery on a loaded machine, not a timing assertion).
DELIVERY = 0.02


def command_fields(topic: str, values: dict[str, Any]) -> dict[str, float]:
    """The command fields a message carries (from the command table)."""
    entry = COMMANDS[topic]
    return {field: values[path] for field, path in zip(entry.fields, entry.message_fields)}


#: How the slider's diagnostics mark the input the actuator in force does not use (issue 28).
_UNUSED = re.compile(r" \(unused: actuator [a-z]+\)$")


def reading(text: str) -> float:
    """A diagnostics value as a number (an input marked unused: its value)."""
    return float(_UNUSED.sub("", text))


#: The fuzzed nodes publish diagnostics ten times a second (a node parameter,
#: 1 s by default): each example waits for fresh diagnostics, so this sets the
#: pace of the fuzzing, not what is checked.
DIAGNOSTICS_PERIOD = 0.1
#: How long the counts of a node's diagnostics must stand still after a burst.
QUIET = 0.9


class Rig:
    """What the slider's and the controller's rigs share."""

    label = "node"
    first_output = ""
    model: ParameterModel

    def __init__(self, log_dir: Path) -> None:
        self.namespace = f"/fz{uuid.uuid4().hex[:8]}"
        self.process = NodeProcess(self.argv(), log_dir, self.label)
        self.client = self.make_client()
        self.client.when_silent = self.process.check
        #: Restarts after the node died or stopped publishing: each is a failure.
        self.restarts: list[str] = []
        self.clean = False
        self.started = False
        self.model = self.new_model()

    # -- to provide -------------------------------------------------------------------

    def argv(self) -> list[str]:
        raise NotImplementedError

    def make_client(self) -> FuzzClient:
        raise NotImplementedError

    def new_model(self) -> ParameterModel:
        raise NotImplementedError

    def healthy(self) -> bool:
        raise NotImplementedError

    def reset(self, full: bool) -> None:
        """Back to the defaults (``full``: from a state the model may not know)."""
        raise NotImplementedError

    def fresh_diagnostics(self) -> dict[str, str]:
        """The first diagnostics computed after the node handled every input so far."""
        raise NotImplementedError

    def compare(self, values: dict[str, str]) -> None:
        """Diagnostics against the model, parameters and each other."""
        raise NotImplementedError

    def settle(self, compare: bool = True, values: dict[str, str] | None = None) -> dict[str, str]:
        """Fresh diagnostics (or ``values``, fresh already), compared with the
        model (``compare``) and taken as its counts."""
        values = values if values is not None else self.fresh_diagnostics()
        if compare:
            self.compare(values)
        self.adopt_counts(values)
        return values

    # -- life cycle ---------------------------------------------------------------------

    def ensure_running(self) -> None:
        """Start the node the first time; restart it (and record that) if it
        died or stopped publishing; bring a node left in an unknown state back to its defaults."""
        if self.started and not (self.process.alive() and self.healthy() and not self.client.error):
            why = ("it died" if not self.process.alive() else
                   f"it reports ERROR: {self.client.error}" if self.client.error else "it stopped publishing")
            self.restarts.append(f"restarted because {why}; its output ended:\n{self.process.tail(15)}")
            if self.process.alive():
                self.process.kill()
            self.started = False
        if not self.started:
            self.process.start()
            self.client.violations.clear()
            self.client.last_pose_ns, self.client.error = None, ""
            self.client.connect(self.first_output)
            self.started, self.clean = True, False
        if not self.clean:
            self.model = self.new_model()
            self.reset(full=True)
            self.rebaseline()

    def rebaseline(self) -> None:
        """Start counting refusals from what the node's diagnostics say now."""
        self.settle(compare=False)
        self.clean = True

    def adopt_counts(self, values: dict[str, str]) -> None:
        """Take the counts of the node's diagnostics as the model's."""
        rejected = int(values["commands_rejected"])
        self.model.rejected = Count(rejected, rejected)
        if isinstance(self.model, SliderModel):
            self.model.taken = int(values["commands_accepted"])

    def check(self) -> None:
        """After every step: alive, no traceback, nothing non-finite published."""
        self.process.check()
        found, self.client.violations[:] = list(self.client.violations), []  # each is reported once
        assert not found, "\n".join(found[:10])

    def run(self, steps: Iterable[Step]) -> None:
        """One example: from the defaults, each step then the invariants; at the end, the diagnostics."""
        self.ensure_running()
        self.clean = False
        latest: dict[str, str] | None = None  # diagnostics after the last step, if it waited for them
        for step in steps:
            latest = None
            if isinstance(step, Topic):
                self.topic(step)
            elif isinstance(step, Params):
                self.params(step)
            elif isinstance(step, Wait):
                self.client.spin_for(step.seconds)
            else:
                latest = self.burst(step)
            self.check()
        self.settle(values=latest)
        self.check()
        self.reset(full=False)
        self.clean = True

    def quiet_diagnostics(self) -> dict[str, str]:
        """Diagnostics once the node has handled a burst: the counts have not
        moved for :data:`QUIET` seconds of diagnostics (a burst still in
        flight would move them)."""
        since = time.monotonic()

        def counts(values: dict[str, str]) -> tuple[str, str]:
            return values["commands_accepted"], values["commands_rejected"]

        def steady() -> bool:
            fresh = [(arrival, counts(values)) for arrival, values, _ in self.client.diagnostics if arrival > since]
            if not fresh:
                return False
            last_arrival, last = fresh[-1]
            unchanged = [arrival for arrival, seen in itertools.takewhile(lambda item: item[1] == last,
                                                                         reversed(fresh))]
            return last_arrival - min(unchanged) > QUIET

        assert self.client.spin_until(steady, 15.0), f"the {self.label}'s diagnostics never settled after a burst"
        return self.client.diagnostics[-1][1]

    def stop(self) -> tuple[int | None, str]:
        self.client.close()
        return self.process.interrupt()

    # -- parameters ------------------------------------------------------------------------

    def params(self, step: Params) -> set[str]:
        """Set parameters as the step says; the names that were set."""
        items = list(step.items)
        if step.kind == "atomic":
            verdicts = [self.model.set(items)]
            groups = [items]
        else:
            verdicts = [self.model.set([item]) for item in items]
            groups = [[item] for item in items]
        results = self.client.set(step.kind, items)
        assert len(results) == len(verdicts), f"{len(results)} results for {len(verdicts)} sets"
        for verdict, result, group in zip(verdicts, results, groups):
            said = "accepted" if result.successful else f"refused ({result.reason})"
            assert result.successful == verdict.successful, \
                f"set {group}: the node {said}, but it must be {'accepted' if verdict.successful else 'refused'}"
            if not result.successful:
                assert one_line(result.reason), f"set {group}: refusal not one line: {result.reason!r}"
            if verdict.cross_field:
                assert any(name in result.reason for name, _ in group), \
                    f"set {group}: the refusal names no parameter that was set: {result.reason!r}"
        self.expect_parameters()
        return {name for verdict, group in zip(verdicts, groups) if verdict.successful for name, _ in group}

    def expect_parameters(self) -> None:
        names = list(self.model.values)
        answered = self.client.get(names)
        for name in names:
            expected, got = self.model.values[name], answered[name]
            assert type(got) is type(expected) and got == expected, \
                f"get_parameters {name} = {got!r}, but {expected!r} was set last"

    def reset_parameters(self, items: list[tuple[str, Any]]) -> None:
        (result,) = self.client.set("atomic", items)
        assert result.successful, f"resetting {items} was refused: {result.reason}"


def stop_cleanly(rig: Rig) -> None:
    """After the run: Ctrl-C ends the node with exit code 0 and at most one line."""
    assert rig.started, f"the {rig.label} never ran"
    rig.check()
    code, said = rig.stop()
    assert code == 0, f"{rig.label} exit code {code} after SIGINT; output:\n{said}"
    assert "Traceback" not in rig.process.output(), rig.process.tail(40)
    assert not rig.process.python_warnings(), f"{rig.label} printed Python warnings"
    assert len(said.strip().splitlines()) <= 1, f"{rig.label} printed more than one line on SIGINT:\n{said}"
    assert not rig.restarts, f"the {rig.label} had to be restarted:\n" + "\n".join(rig.restarts)


__all__ = ["DELIVERY", "DIAGNOSTICS_PERIOD", "QUIET", "Rig", "command_fields", "reading", "stop_cleanly"]
