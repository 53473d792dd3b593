"""The slider under fuzzing (see test/ros/fuzz_rigs.py for what every rig checks).

The slider's contact forces follow the plant in force (the general model:
R = 0 and no friction while z > 0, z never below the track).  Parameters
change the plant, not the state: a slider an earlier example threw off for
good (a lifting force above its weight) is relaunched, and the recording of
each slider must be whole and verify.  Its diagnostics agree with
themselves (:func:`check_prediction`).
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped

from friction_sim.core.meanspeed.predict import predict
from friction_sim.core.meanspeed.urelation import u_map
from friction_sim.core.model import spec
from friction_sim.core.model.commands import COMMANDS, SLIDER, consumed_by, unused_input
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import is_kostek
from friction_sim.errors import ParameterError
from friction_sim.io.messages import message_class

from fuzz_harness import BIN, FuzzClient, diagnostics_after
from fuzz_models import SliderModel
from fuzz_rigs import DELIVERY, DIAGNOSTICS_PERIOD, Rig, command_fields, reading
from fuzz_strategies import USE_SIM_TIME, Burst, Params, Topic
from ros_harness import stamp_ns

#: The fuzzed slider records at 100 Hz: at the largest real-time factors the
#: recording then holds the simulation back less, so the suite's timing bounds
#: on command delivery hold on a loaded machine (the recording is still checked whole).
LOG_RATE = 100.0


def _height_problem(msg: PoseStamped) -> str | None:
    """z is the height above the track: never below it."""
    z = msg.pose.position.z
    return f"position.z = {z!r} m: below the track" if z < 0.0 else None


def check_prediction(values: dict[str, str], params: SliderParams | None = None, inputs: Inputs | None = None) -> None:
    """The slider's diagnostics agree with themselves: predicted_U is U(phi, amplitude_ratio)
    for the paper's model below lift-off; for any other plant (given ``params`` and
    ``inputs`` in force) it is the general mean speed's U of that plant."""
    if not {"phi", "amplitude_ratio", "predicted_U"} <= values.keys():
        return
    phi, ratio, u = (reading(values[k]) for k in ("phi", "amplitude_ratio", "predicted_U"))
    if params is not None and inputs is not None and not (
            is_kostek(params) and inputs.excitation_amplitude < params.weight - inputs.external_force_z):
        try:
            general = predict(params, inputs).u
        except Exception:  # noqa: BLE001 - the node reports nan when there is no prediction
            general = math.nan
        assert u == general or (math.isnan(u) and math.isnan(general)), \
            f"diagnostics predicted_U = {u!r}, but the general mean speed of {params}, {inputs} gives {general!r}"
        return
    try:
        expected = float(u_map(phi, ratio))
    except ParameterError as error:
        raise AssertionError(f"diagnostics phi = {phi!r}, amplitude_ratio = {ratio!r} have no U ({error}), "
                             f"but predicted_U = {u!r}") from None
    assert expected == u or (math.isfinite(u) and abs(expected - u) <= 1e-12 * abs(expected)), \
        f"diagnostics predicted_U = {u!r}, but U(phi = {phi!r}, amplitude_ratio = {ratio!r}) = {expected!r}"


class SliderRig(Rig):
    """The slider console script in its own process."""

    label = "slider"
    first_output = "pose"
    model: SliderModel

    def __init__(self, log_dir: Path) -> None:
        #: The slider records the whole fuzzing run: bad input must never corrupt a recording.
        self.recording = log_dir / "fuzzed.mcap"
        #: The recordings of sliders relaunched because they flew away (see :meth:`relaunch`).
        self.recordings: list[Path] = []
        super().__init__(log_dir)

    def argv(self) -> list[str]:
        return [str(BIN / "slider"), "--ros-args", "-r", f"__ns:={self.namespace}",
                "-p", f"log_path:={self.recording}", "-p", f"log_rate:={LOG_RATE}",
                "-p", f"diagnostics_period:={DIAGNOSTICS_PERIOD}"]

    def make_client(self) -> FuzzClient:
        inputs = {entry.name: message_class(entry.message_type) for entry in consumed_by(SLIDER)}
        outputs = {"pose": PoseStamped, "velocity": TwistStamped, "friction_force": WrenchStamped,
                   "mean_velocity": TwistStamped, "diagnostics": DiagnosticArray}
        return FuzzClient(self.namespace, "slider", inputs, outputs, checks={"pose": _height_problem})

    def new_model(self) -> SliderModel:
        #: Inputs a topic changed since their parameter was last set (the two differ then).
        self.by_topic: set[str] = set()
        #: Contact forces stamped after this simulation time [ns] reflect the model.
        self._synced_ns = self.client.last_pose_ns or 0
        return SliderModel({"log_path": str(self.recording), "log_rate": LOG_RATE,
                            "diagnostics_period": DIAGNOSTICS_PERIOD})

    def publishing(self, count: int = 3) -> bool:
        """``count`` more poses arrive within a bound for the publish rate in force."""
        return self.client.wait_for("pose", count, 5.0 + count / self.model.publish_rate)

    def healthy(self) -> bool:
        return self.publishing(2)

    def ticked(self) -> None:
        """Wait until the node has surely taken what was published so far: it
        takes commands at the start of each tick, so a few ticks after delivery."""
        self.client.spin_for(DELIVERY)
        if not self.publishing(3):
            self.process.check()
            raise AssertionError(f"slider stopped publishing pose; its output ends:\n{self.process.tail()}")

    def topic(self, step: Topic) -> None:
        if self.model.topic(step.topic, command_fields(step.topic, dict(step.values))):
            self.by_topic.update(COMMANDS[step.topic].fields)
        self.client.publish(step.topic, self.client.message(step.topic, step.values))
        self.ticked()

    def params(self, step: Params) -> set[str]:
        names = super().params(step)
        self.by_topic -= names
        return names

    def burst(self, step: Burst) -> dict[str, str]:
        """Publish a flood; the state after it is one of the values sent (or the
        one before).  Returns the diagnostics once it has been handled."""
        before = self.model.in_force()
        sent: dict[str, set[float]] = {}
        messages = [(m.topic, self.client.message(m.topic, m.values)) for m in step.messages]
        for m in step.messages:
            for field, value in command_fields(m.topic, dict(m.values)).items():
                sent.setdefault(field, set()).add(value)
        self.client.flood(messages, step.repeat)
        total = len(messages) * step.repeat
        self.model.rejected.add(0, total)
        self.ticked()
        values = self.quiet_diagnostics()
        for field, candidates in sent.items():
            now = reading(values[field])
            assert now == before[field] or now in candidates, \
                f"after a burst {field} = {now!r}: neither the value before ({before[field]!r}) nor one sent"
            if now != before[field]:
                self.by_topic.add(field)
        self.model.inputs = self.model.inputs.replace(**{f: reading(values[f]) for f in spec.INPUTS})
        self._synced_ns = round(reading(values["sim_time"]) * 1e9)  # the burst was handled by then
        self.ticked()
        return values

    def fresh_diagnostics(self) -> dict[str, str]:
        """Computed after a tick that took every command so far (its sim_time is later)."""
        self.ticked()
        assert self.client.last_pose_ns is not None
        after = self.client.last_pose_ns / 1e9

        def newer(arrival: float, values: dict[str, str], msg: Any) -> bool:
            return "sim_time" in values and reading(values["sim_time"]) >= after - 1e-9

        values = diagnostics_after(self.client, newer, 5.0)
        # A refusal the node has not counted yet (rclpy's own refusals reach its count a
        # moment after the set returns), or a command a loaded machine delivered later than
        # the ticks waited for: wait for the node's count and inputs in force, not for a time
        # (5 s at most, then compare() says what is missing).
        deadline = time.monotonic() + 5.0
        while (int(values["commands_rejected"]) < self.model.rejected.low or not self._in_force(values)
               or int(values["commands_accepted"]) < self.model.taken) and time.monotonic() < deadline:
            seen = reading(values["sim_time"])
            values = diagnostics_after(
                self.client, lambda arrival, later, msg, seen=seen: reading(later.get("sim_time", "-1")) > seen, 5.0)
        # Computed after every input was taken: the states stamped later show the plant in force (one
        # that arrives later may be older: a backlog of messages is taken topic by topic).
        self._synced_ns = round(reading(values["sim_time"]) * 1e9)
        return values

    def _disagreements(self, values: dict[str, str]) -> list[str]:
        """What the diagnostics report differently from what the model has in force."""
        return [f"diagnostics {key} = {values[key]}, but {expected!r} is in force"
                for key, expected in self.model.in_force().items()
                if key in values and (values[key] if isinstance(expected, str) else reading(values[key])) != expected]

    def _in_force(self, values: dict[str, str]) -> bool:
        return not self._disagreements(values)

    def compare(self, values: dict[str, str]) -> None:
        model = self.model
        wrong = self._disagreements(values)
        assert not wrong, wrong[0]
        rejected = int(values["commands_rejected"])
        assert model.rejected.holds(rejected), \
            f"diagnostics count {rejected} refused commands; {model.rejected.low}..{model.rejected.high} were " \
            f"refused; the node's output ends:\n{self.process.tail(40)}"
        shared = [k for k in values if k in model.values and k not in self.by_topic]
        answered = self.client.get(shared)
        for key in shared:
            got = values[key] if isinstance(answered[key], str) else reading(values[key])
            assert got == answered[key], \
                f"get_parameters {key} = {answered[key]!r}, but the simulation has {values[key]} in force"
        actuator = model.params.actuator
        for field in ("excitation_amplitude", "drive_level"):  # only the input the actuator uses is shown as acting
            marked = values[field].endswith(f" (unused: actuator {actuator})")
            assert marked == (field == unused_input(actuator)), f"diagnostics {field} = {values[field]} ({actuator})"
        for key in ("sim_time", "real_time_factor", "tick_rate", "drive_force", "excitation_amplitude",
                    "excitation_frequency", "phi", "amplitude_ratio"):
            if key in values:
                assert math.isfinite(reading(values[key])), f"diagnostics {key} = {values[key]}"
        self.check_contact_forces()
        check_prediction(values, model.params, model.inputs)
        frame = self.client.last["pose"].header.frame_id
        assert frame == model.values["frame_id"], f"pose frame_id {frame!r}, but {model.values['frame_id']!r} is set"

    def check_contact_forces(self) -> None:
        """The plant in force shows in the contact forces published since the
        commands were taken: in contact R = m g cos(alpha) - Fz - Pa sin(theta),
        so max(0, N - Pa) <= R <= max(0, N + Pa) with N = m g cos(alpha) - Fz
        (Fz > 0 lifts), R = 0 only at the instant of a lift-off or landing;
        |F| <= mu_s R; and a state with z > 0 (in flight, which an earlier
        plant may have started) has R = 0 and no friction.  The resonant
        actuator's P is its steady response plus the transient of every change
        before (from a state the rig does not know), so it bounds R only below, by 0."""
        params, inputs = self.model.params, self.model.inputs
        force = params.actuator == "force"
        load, pa = params.normal_weight - inputs.external_force_z, inputs.excitation_amplitude if force else math.inf
        mu_s = params.static_ratio * params.mu
        slack = 1e-9 * (params.weight + abs(inputs.external_force_z) + (pa if force else 0.0))
        low, high = max(0.0, load - pa), max(0.0, load + pa)
        def later() -> list[Any]:
            return [m for m in self.client.since("friction_force", 0) if stamp_ns(m) > self._synced_ns]

        assert self.client.spin_until(lambda: len(later()) >= 3, 5.0 + 3 / self.model.publish_rate), \
            f"no contact forces stamped after {self._synced_ns} ns arrived"
        flying = {stamp_ns(m) for m in self.client.since("pose", 0) if m.pose.position.z > 0.0}
        for msg in later():
            normal, friction = msg.wrench.force.z, msg.wrench.force.x
            if stamp_ns(msg) in flying:
                assert normal == 0.0 and friction == 0.0, \
                    f"in flight (z > 0) at {stamp_ns(msg)} ns, but R = {normal!r} N and friction {friction!r} N"
                continue
            if normal == 0.0 and friction == 0.0:
                continue  # z = 0 at a lift-off or landing instant (or a pose that did not arrive)
            assert low - slack <= normal <= high + slack, \
                f"normal force R = {normal!r} N outside [max(0, N - Pa), max(0, N + Pa)] = [{low!r}, {high!r}] N, " \
                f"N = m g cos(alpha) - Fz, of the plant in force ({params}, {inputs})"
            assert abs(friction) <= mu_s * normal * (1 + 1e-9) + slack + 1e-9 * normal, \
                f"friction {friction!r} N > mu_s R = {mu_s * normal!r} N of the plant in force ({params}, {inputs})"

    def reset(self, full: bool) -> None:
        """Back to the defaults: unload the contact, zero the external force,
        then every parameter, in two sets: an actuator refuses a set of the input
        it does not use (issue 28), so drive_level is set under the resonant one
        and excitation_amplitude with the switch back to the force one."""
        model = self.model
        sets = 2  # the commands reset takes (each set changes the plant or the inputs; the wrench is one)
        if full or model.inputs.external_force_x != 0.0 or model.inputs.external_force_z != 0.0:
            self.reset_parameters([("actuator", "force"), ("excitation_amplitude", 0.0)])
            self.client.publish("external_wrench", self.client.message("external_wrench", {}))
            self.ticked()
            sets += 2
        defaults = {name: s.default for name, s in spec.SLIDER_NODE.items() if not s.start_only}
        amplitude = defaults.pop("excitation_amplitude")
        self.reset_parameters([*{**defaults, "actuator": "resonant"}.items(), (USE_SIM_TIME, False)])
        self.reset_parameters([("actuator", defaults["actuator"]), ("excitation_amplitude", amplitude)])
        self.ticked()
        rejected, taken = model.rejected, model.taken
        self.model = self.new_model()
        self.model.rejected, self.model.taken = rejected, taken + sets
        if self.back_on_the_track(0.5):
            return
        # Parameters change the plant, not the state: a slider that an earlier plant
        # threw far off the track (a lifting force above the weight: it flies away
        # for good) stays in flight.  Its ~/reset puts it back at rest on the track.
        answer = self.client.trigger("reset")
        assert answer.success, answer.message
        if not self.back_on_the_track():
            self.relaunch()

    def back_on_the_track(self, timeout: float = 2.0) -> bool:
        """Whether the slider is on the track again (z = 0) within ``timeout`` s."""
        return self.client.spin_until(
            lambda: "pose" in self.client.last and self.client.last["pose"].pose.position.z == 0.0, timeout)

    def relaunch(self) -> None:
        """A fresh slider in place of one that flies away for good: the old one
        must end cleanly (Ctrl-C, exit code 0) with its recording finished, kept
        for the final check; the new one records to a file of its own."""
        code, said = self.process.interrupt()
        assert code == 0, f"slider exit code {code} after SIGINT; output:\n{said}"
        assert "Traceback" not in self.process.output(), self.process.tail(40)
        self.recordings.append(self.recording)
        self.recording = self.recording.with_name(f"fuzzed-{len(self.recordings)}.mcap")
        # The old node's readers must be gone from the graph first: the client's publishers
        # would count them as matched, and a command sent then would miss the new node.
        gone = self.client.spin_until(
            lambda: all(p.get_subscription_count() == 0 for p in self.client.publishers.values()), 15.0)
        assert gone, "the ended slider's subscriptions are still in the graph after 15 s"
        self.process.argv = self.argv()
        self.process.start()
        self.client.connect(self.first_output)
        # Forget what the old node said: its simulation time was later than the new one's.
        self.client.violations.clear()
        self.client.diagnostics.clear()
        for kept in self.client.recent.values():
            kept.clear()
        self.client.last_pose_ns, self.client.error = None, ""
        assert self.publishing(3), f"the relaunched slider does not publish; its output:\n{self.process.tail()}"
        self.model = self.new_model()
        self.rebaseline()


__all__ = ["SliderRig", "check_prediction"]
