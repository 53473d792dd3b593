"""The controller under fuzzing, without a plant node: the client is its
plant (see test/ros/fuzz_rigs.py for what every rig checks)."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistStamped
from std_msgs.msg import Float64

from friction_sim.core.model import spec
from friction_sim.core.model.commands import CONTROLLER, consumed_by
from friction_sim.io.messages import message_class

from fuzz_harness import BIN, FuzzClient, diagnostics_after
from fuzz_models import ControllerModel, Count
from fuzz_rigs import DELIVERY, DIAGNOSTICS_PERIOD, Rig, reading
from fuzz_strategies import USE_SIM_TIME, Burst, Params, Topic


class ControllerRig(Rig):
    """The controller console script in its own process, without a plant node
    (plant_node ''): the client is its plant."""

    label = "controller"
    first_output = "excitation_amplitude"
    model: ControllerModel

    def __init__(self, log_dir: Path) -> None:
        self._epoch = time.monotonic()
        super().__init__(log_dir)

    def argv(self) -> list[str]:
        return [str(BIN / "controller"), "--ros-args", "-r", f"__ns:={self.namespace}", "-p", "plant_node:=''",
                "-p", f"diagnostics_period:={DIAGNOSTICS_PERIOD}"]

    def make_client(self) -> FuzzClient:
        inputs: dict[str, type] = {entry.name: message_class(entry.message_type)
                                   for entry in consumed_by(CONTROLLER)}
        inputs["mean_velocity"] = TwistStamped
        return FuzzClient(self.namespace, "controller", inputs,
                          {"excitation_amplitude": Float64, "diagnostics": DiagnosticArray},
                          checks={"excitation_amplitude": self._amplitude_problem})

    def _amplitude_problem(self, msg: Float64) -> str | None:
        limit = self.model.largest_limit
        if not 0.0 <= msg.data <= limit * (1 + 1e-12):
            return f"Pa = {msg.data!r} N outside [0, {limit!r}] (max_amplitude_ratio m g of any model in force)"
        return None

    def new_model(self) -> ControllerModel:
        return ControllerModel({"diagnostics_period": DIAGNOSTICS_PERIOD})

    def healthy(self) -> bool:
        """Its diagnostics (every DIAGNOSTICS_PERIOD) still come."""
        recent = self.client.diagnostics and time.monotonic() - self.client.diagnostics[-1][0] < 2.5
        return bool(recent) or self.client.wait_for("diagnostics", 1, 5.0)

    def handled(self) -> None:
        """Wait until the node has handled what was published so far: its one
        executor thread takes waiting messages before a service request."""
        self.client.spin_for(DELIVERY)
        self.client.get(["active"])

    def topic(self, step: Topic) -> None:
        values = dict(step.values)
        if step.topic == "mean_velocity":
            self.model.sample(values["twist.linear.x"])
            stamp = values.pop("header.stamp")
            if stamp is None:  # a plausible plant: real time since the start
                stamp = divmod(int((time.monotonic() - self._epoch) * 1e9), 1_000_000_000)
            values["header.stamp.sec"], values["header.stamp.nanosec"] = stamp
        else:
            self.model.topic(step.topic, values["data"])
        self.client.publish(step.topic, self.client.message(step.topic, values))
        self.handled()

    def params(self, step: Params) -> set[str]:
        names = super().params(step)
        self.handled()
        return names

    def burst(self, step: Burst) -> dict[str, str]:
        """Publish a flood; the inputs in force after it are read from the diagnostics."""
        messages = []
        before = self.model.in_force()
        sent: dict[str, set[float]] = {key: {value} for key, value in before.items()}
        sent["target_speed"].add(0.0)  # a drive force of the other sign zeroes the target
        for m in step.messages:
            values = dict(m.values)
            if m.topic in sent:
                sent[m.topic].add(values["data"])
            if m.topic == "mean_velocity":
                stamp = values.pop("header.stamp") or (1, 0)
                values["header.stamp.sec"], values["header.stamp.nanosec"] = stamp
            messages.append((m.topic, self.client.message(m.topic, values)))
        self.client.flood(messages, step.repeat)
        self.handled()
        # What got through a full queue is unknown: take the inputs in force from the diagnostics.
        values = self.quiet_diagnostics()
        for key, candidates in sent.items():
            assert reading(values[key]) in candidates, \
                f"after a burst {key} = {values[key]}: neither the value before ({before[key]!r}) nor one sent"
        self.model.rejected.add(0, len(messages) * step.repeat)
        self.model.samples.add(0, len(messages) * step.repeat)
        self.model.drive_force = reading(values["drive_force"])
        self.model.frequency = reading(values["excitation_frequency"])
        if reading(values["target_speed"]) not in (before["target_speed"], 0.0):
            self.model.active = True  # a target arrived
        self.model.target = reading(values["target_speed"])
        self.model.accepted = int(values["commands_accepted"])
        return values

    def _newer(self) -> Any:
        """A test for diagnostics computed after the node handled everything so
        far (call it after :meth:`handled`): stamped (wall clock) after now."""
        since, now = time.time(), time.monotonic()
        arrivals: list[float] = []

        def newer(arrival: float, values: dict[str, str], msg: Any) -> bool:
            if not self.model.values[USE_SIM_TIME]:
                return bool(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 >= since)
            # On simulated time the stamp says nothing: the second one to arrive after now.
            if arrival > now and arrival not in arrivals:
                arrivals.append(arrival)
            return len(arrivals) >= 2 and arrival == arrivals[1]

        return newer

    def adopt_counts(self, values: dict[str, str]) -> None:
        self.model.accepted = int(values["commands_accepted"])
        samples = int(values["samples_rejected"])
        others = int(values["commands_rejected"]) - samples  # the samples are among commands_rejected
        self.model.samples = Count(samples, samples)
        self.model.rejected = Count(others, others)

    def check_refusals(self, values: dict[str, str]) -> None:
        """Refused inputs: ``commands_rejected`` counts all of them (commands,
        parameter values, samples), ``samples_rejected`` the samples among them."""
        model, rejected = self.model, int(values["commands_rejected"])
        samples = int(values["samples_rejected"])
        assert model.samples.holds(samples), \
            f"diagnostics count {samples} refused samples; {model.samples.low}..{model.samples.high} were refused"
        expected = Count(model.rejected.low + samples, model.rejected.high + samples)
        assert expected.holds(rejected), \
            f"diagnostics count {rejected} refused inputs; {expected.low}..{expected.high} were refused"

    def fresh_diagnostics(self) -> dict[str, str]:
        self.handled()
        return diagnostics_after(self.client, self._newer(), 5.0)

    def compare(self, values: dict[str, str]) -> None:
        model = self.model
        for key, expected in model.in_force().items():
            assert reading(values[key]) == expected, f"diagnostics {key} = {values[key]}, but {expected!r} is in force"
        accepted = int(values["commands_accepted"])
        assert accepted == model.accepted, f"diagnostics count {accepted} accepted commands; {model.accepted} were"
        self.check_refusals(values)
        assert values.get("internal_errors", "0") == "0", \
            f"{values['internal_errors']} internal errors, the last: {values.get('last_internal_error')}"
        for key in ("excitation_amplitude", "applied_ratio", "integral", "phi", "u_target"):
            assert math.isfinite(reading(values[key])), f"diagnostics {key} = {values[key]}"
        assert not math.isinf(reading(values["measured_mean_speed"])), values["measured_mean_speed"]
        amplitude, limit = reading(values["excitation_amplitude"]), model.amplitude_limit()
        assert 0.0 <= amplitude <= limit * (1 + 1e-12), f"Pa = {amplitude!r} N outside [0, {limit!r}]"
        answered = self.client.get(["target_speed", "drive_force", "excitation_frequency"])
        for key, value in answered.items():
            if value == model.values[key] and key not in self.by_topic():
                assert reading(values[key]) == value, \
                    f"get_parameters {key} = {value!r}, but the law has {values[key]} in force"

    def by_topic(self) -> set[str]:
        """The law's inputs that differ from their parameters (a topic changed them)."""
        return {k for k, v in self.model.in_force().items() if v != self.model.values[k]}

    def reset(self, full: bool) -> None:
        defaults = [(name, s.default) for name, s in spec.CONTROLLER_NODE.items()
                    if name != "plant_node" and not s.start_only]
        self.reset_parameters([*defaults, ("plant_node", ""), (USE_SIM_TIME, False)])
        self.handled()
        counts = self.model.rejected, self.model.samples, self.model.accepted
        self.model = self.new_model()
        self.model.rejected, self.model.samples, self.model.accepted = counts


__all__ = ["ControllerRig"]
