"""A node under fuzzing: its process, the hostile client, and the model of what
it must do, with the invariants checked after each step and each example.

After every step: the process is alive and printed no traceback; everything
it published is finite (pose stamps never go back); a parameter set was
answered as the model says (refusals with a one-line reason naming a
parameter of the set when fields disagree), and ``get_parameters`` answers
what was set.  After every example: it still publishes; its diagnostics
report the inputs the model has in force (and, for values no topic changed
since, the value ``get_parameters`` answers), and count every refusal.

The slider's contact forces follow the plant in force (the general model:
R = 0 and no friction while z > 0, z never below the track).  Parameters
change the plant, not the state: a slider an earlier example threw off for
good (a lifting force above its weight) is relaunched, and the recording of
each slider must be whole and verify.
"""

from __future__ import annotations

import itertools
import math
import re
import time
import uuid
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, TwistStamped, WrenchStamped
from std_msgs.msg import Float64

from friction_sim.core.meanspeed.predict import predict
from friction_sim.core.meanspeed.urelation import u_map
from friction_sim.core.model import spec
from friction_sim.core.model.commands import COMMANDS, CONTROLLER, SLIDER, consumed_by, unused_input
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.physics.plant import is_kostek
from friction_sim.errors import ParameterError
from friction_sim.io.messages import message_class

from fuzz_harness import BIN, FuzzClient, NodeProcess, diagnostics_after, one_line
from fuzz_models import ControllerModel, Count, ParameterModel, SliderModel
from fuzz_strategies import USE_SIM_TIME, Burst, Params, Step, Topic, Wait
from ros_harness import stamp_ns

#: Let a message published now reach the node's reader before the next input
#: (a bound for local delivery on a loaded machine, not a timing assertion).
DELIVERY = 0.02


def _fields(topic: str, values: dict[str, Any]) -> dict[str, float]:
    """The command fields a message carries (from the command table)."""
    entry = COMMANDS[topic]
    return {field: values[path] for field, path in zip(entry.fields, entry.message_fields)}


#: How the slider's diagnostics mark the input the actuator in force does not use (issue 28).
_UNUSED = re.compile(r" \(unused: actuator [a-z]+\)$")


def _number(text: str) -> float:
    """A diagnostics value as a number (an input marked unused: its value)."""
    return float(_UNUSED.sub("", text))


def check_prediction(values: dict[str, str], params: SliderParams | None = None, inputs: Inputs | None = None) -> None:
    """The slider's diagnostics agree with themselves: predicted_U is U(phi, amplitude_ratio)
    for the paper's model below lift-off; for any other plant (given ``params`` and
    ``inputs`` in force) it is the general mean speed's U of that plant."""
    if not {"phi", "amplitude_ratio", "predicted_U"} <= values.keys():
        return
    phi, ratio, u = (_number(values[k]) for k in ("phi", "amplitude_ratio", "predicted_U"))
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


#: The fuzzed nodes publish diagnostics ten times a second (a node parameter,
#: 1 s by default): each example waits for fresh diagnostics, so this sets the
#: pace of the fuzzing, not what is checked.
DIAGNOSTICS_PERIOD = 0.1
#: How long the counts of a node's diagnostics must stand still after a burst.
QUIET = 0.9

#: The fuzzed slider records at 100 Hz: at the largest real-time factors the
#: recording then holds the simulation back less, so the suite's timing bounds
#: on command delivery hold on a loaded machine (the recording is still checked whole).
LOG_RATE = 100.0


def _height_problem(msg: PoseStamped) -> str | None:
    """z is the height above the track: never below it."""
    z = msg.pose.position.z
    return f"position.z = {z!r} m: below the track" if z < 0.0 else None


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
        if self.model.topic(step.topic, _fields(step.topic, dict(step.values))):
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
            for field, value in _fields(m.topic, dict(m.values)).items():
                sent.setdefault(field, set()).add(value)
        self.client.flood(messages, step.repeat)
        total = len(messages) * step.repeat
        self.model.rejected.add(0, total)
        self.ticked()
        values = self.quiet_diagnostics()
        for field, candidates in sent.items():
            now = _number(values[field])
            assert now == before[field] or now in candidates, \
                f"after a burst {field} = {now!r}: neither the value before ({before[field]!r}) nor one sent"
            if now != before[field]:
                self.by_topic.add(field)
        self.model.inputs = self.model.inputs.replace(**{f: _number(values[f]) for f in spec.INPUTS})
        self._synced_ns = round(_number(values["sim_time"]) * 1e9)  # the burst was handled by then
        self.ticked()
        return values

    def fresh_diagnostics(self) -> dict[str, str]:
        """Computed after a tick that took every command so far (its sim_time is later)."""
        self.ticked()
        assert self.client.last_pose_ns is not None
        after = self.client.last_pose_ns / 1e9

        def newer(arrival: float, values: dict[str, str], msg: Any) -> bool:
            return "sim_time" in values and _number(values["sim_time"]) >= after - 1e-9

        values = diagnostics_after(self.client, newer, 5.0)
        # A refusal the node has not counted yet (rclpy's own refusals reach its count a
        # moment after the set returns), or a command a loaded machine delivered later than
        # the ticks waited for: wait for the node's count and inputs in force, not for a time
        # (5 s at most, then compare() says what is missing).
        deadline = time.monotonic() + 5.0
        while (int(values["commands_rejected"]) < self.model.rejected.low or not self._in_force(values)
               or int(values["commands_accepted"]) < self.model.taken) and time.monotonic() < deadline:
            seen = _number(values["sim_time"])
            values = diagnostics_after(
                self.client, lambda arrival, later, msg, seen=seen: _number(later.get("sim_time", "-1")) > seen, 5.0)
        # Computed after every input was taken: the states stamped later show the plant in force (one
        # that arrives later may be older: a backlog of messages is taken topic by topic).
        self._synced_ns = round(_number(values["sim_time"]) * 1e9)
        return values

    def _disagreements(self, values: dict[str, str]) -> list[str]:
        """What the diagnostics report differently from what the model has in force."""
        return [f"diagnostics {key} = {values[key]}, but {expected!r} is in force"
                for key, expected in self.model.in_force().items()
                if key in values and (values[key] if isinstance(expected, str) else _number(values[key])) != expected]

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
            got = values[key] if isinstance(answered[key], str) else _number(values[key])
            assert got == answered[key], \
                f"get_parameters {key} = {answered[key]!r}, but the simulation has {values[key]} in force"
        actuator = model.params.actuator
        for field in ("excitation_amplitude", "drive_level"):  # only the input the actuator uses is shown as acting
            marked = values[field].endswith(f" (unused: actuator {actuator})")
            assert marked == (field == unused_input(actuator)), f"diagnostics {field} = {values[field]} ({actuator})"
        for key in ("sim_time", "real_time_factor", "tick_rate", "drive_force", "excitation_amplitude",
                    "excitation_frequency", "phi", "amplitude_ratio"):
            if key in values:
                assert math.isfinite(_number(values[key])), f"diagnostics {key} = {values[key]}"
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
            assert _number(values[key]) in candidates, \
                f"after a burst {key} = {values[key]}: neither the value before ({before[key]!r}) nor one sent"
        self.model.rejected.add(0, len(messages) * step.repeat)
        self.model.samples.add(0, len(messages) * step.repeat)
        self.model.drive_force = _number(values["drive_force"])
        self.model.frequency = _number(values["excitation_frequency"])
        if _number(values["target_speed"]) not in (before["target_speed"], 0.0):
            self.model.active = True  # a target arrived
        self.model.target = _number(values["target_speed"])
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
            assert _number(values[key]) == expected, f"diagnostics {key} = {values[key]}, but {expected!r} is in force"
        accepted = int(values["commands_accepted"])
        assert accepted == model.accepted, f"diagnostics count {accepted} accepted commands; {model.accepted} were"
        self.check_refusals(values)
        assert values.get("internal_errors", "0") == "0", \
            f"{values['internal_errors']} internal errors, the last: {values.get('last_internal_error')}"
        for key in ("excitation_amplitude", "applied_ratio", "integral", "phi", "u_target"):
            assert math.isfinite(_number(values[key])), f"diagnostics {key} = {values[key]}"
        assert not math.isinf(_number(values["measured_mean_speed"])), values["measured_mean_speed"]
        amplitude, limit = _number(values["excitation_amplitude"]), model.amplitude_limit()
        assert 0.0 <= amplitude <= limit * (1 + 1e-12), f"Pa = {amplitude!r} N outside [0, {limit!r}]"
        answered = self.client.get(["target_speed", "drive_force", "excitation_frequency"])
        for key, value in answered.items():
            if value == model.values[key] and key not in self.by_topic():
                assert _number(values[key]) == value, \
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


__all__ = ["ControllerRig", "Rig", "SliderRig", "check_prediction", "stop_cleanly"]
