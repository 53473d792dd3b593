"""Where the slider node's run goes besides its topics, and what it says
about itself: the recorder and the live view it opens from its parameters
(and what it says of the recording once finished), the health line of its
diagnostics, and the answer to a control call.

Kept apart from :mod:`friction_sim.ros.slider` (the node's wiring and tick)
so each stays short; nothing here holds state.
"""

from __future__ import annotations

import functools
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus

from friction_sim.core.meanspeed.urelation import NO_PREDICTION
from friction_sim.core.model.commands import COMMANDS, PAUSE, RESET, RESUME, STEP, Outcome
from friction_sim.core.model.events import SliderState
from friction_sim.core.model.records import Acceleration
from friction_sim.io.cdr import fixed_layouts
from friction_sim.io.messages import (
    ACCELEROMETER,
    ACCELEROMETER_DEPTH,
    SIM_CONTROL,
    imu_message,
    message_class,
    seconds_to_ns,
    stamp_ns,
    time_msg,
)
from friction_sim.io.recordwriter import imu_row_builder
from friction_sim.io.sinks import MessageRecord, deliver
from friction_sim.ros.run import EXIT_RECORDING_FAILED

#: What the slider keeps of the namespace's other topics, with the depth of its queues.
WATCHED_DEPTH = 10


def control_text(outcome: Outcome, state: SliderState) -> str:
    """The answer to an accepted call: what was done, and where the slider is now."""
    where = f"t = {state.t:.9f} s, x = {state.x:.9g} m, v = {state.v:.9g} m/s"
    if outcome.name == STEP:
        return f"stepped {outcome.values['duration']:.9g} s: {where}"
    return {PAUSE: "paused at ", RESUME: "resumed at ", RESET: "reset to rest at x = 0: "}[outcome.name] + where


#: How many times a diagnostics report makes the prediction again when the plant changed meanwhile.
PREDICTION_TRIES = 3


def consistent_report(rt: Any, lock: Any, now_ns: Callable[[], int]) -> dict[str, Any]:
    """The runtime's diagnostics with the prediction of the plant they report.
    The prediction is made outside ``lock`` (it may simulate, up to ~0.4 s);
    a command taken meanwhile changes the plant, and then it is made again, at
    most PREDICTION_TRIES times (a flood may change it every tick): after that
    the report says there is no prediction (NaN) rather than pair the new
    plant with the old plant's figures."""
    for _ in range(PREDICTION_TRIES):
        with lock:
            params, inputs = rt.slider.params, rt.slider.inputs
        prediction = rt.prediction(params, inputs)
        with lock:
            if rt.slider.params is params and rt.slider.inputs is inputs:
                return rt.diagnostics(now_ns(), prediction)
    with lock:
        return rt.diagnostics(now_ns(), NO_PREDICTION)


class AccelerometerPublisher:
    """The accelerometer topic's publisher: each sample of a tick as sensor_msgs/Imu at its own
    simulation time.  A thousand a second, so the messages of a tick are serialized at once
    into the Imu's fixed layout (the bytes rosbags serializes, as the recording writes them)
    and published as such: building and converting an rclpy Imu costs more than the publish.

    With no reader on the topic a publish is work for no one.  In real time such samples are
    gone (a reader that comes later reads from then on).  In lockstep a controller that starts
    reading later must still get the readings of the windows it has yet to answer (the topic is
    transient local for it): so the samples newer than the last sample answered are held, at
    most :data:`ACCELEROMETER_DEPTH`, and published, in order, as soon as a reader is there
    (:meth:`flush`; the slider's loop calls it while it waits).  Each sample goes out once.
    The sinks (the recording, the live view) get the samples from the tick, not from here."""

    def __init__(self, publisher: Any, frame_id: str, noise: float) -> None:
        self._publisher = publisher
        self._msg = imu_message(Acceleration(0.0, 0.0, 0.0, 0.0), frame_id, noise)
        layouts = fixed_layouts(imu_row_builder(frame_id, noise), 3)
        #: The Imu's fixed layout (None: publish messages one by one).
        self._layout = layouts[0] if layouts else None
        self._held: deque[Acceleration] = deque(maxlen=ACCELEROMETER_DEPTH)

    def publish(self, samples: Sequence[Acceleration], *, hold_after_ns: int | None) -> None:
        """Publish ``samples`` if someone reads the topic; else hold those newer than
        ``hold_after_ns`` (lockstep: the last sample answered; None: hold none)."""
        if not samples:
            return
        if self._publisher.get_subscription_count():
            self._send_held()
            self._send(samples)
        elif hold_after_ns is not None:
            self._held.extend(samples)
            self.forget_through(hold_after_ns)

    def flush(self, hold_after_ns: int) -> None:
        """Publish the held samples newer than ``hold_after_ns`` once a reader is there."""
        self.forget_through(hold_after_ns)
        if self._held and self._publisher.get_subscription_count():
            self._send_held()

    def forget_through(self, t_ns: int) -> None:
        """Drop the held samples stamped at or before ``t_ns`` (their windows are answered)."""
        held = self._held
        while held and seconds_to_ns(held[0].t) <= t_ns:
            held.popleft()

    def _send_held(self) -> None:
        self._send(self._held)
        self._held.clear()

    def _send(self, samples: Iterable[Acceleration]) -> None:
        if self._layout is not None:
            samples = list(samples)
            if not samples:
                return
            stamps = np.array([seconds_to_ns(sample.t) for sample in samples], dtype=np.int64)
            if stamps.min() >= 0:  # (the layout holds no stamp before time 0)
                values = np.array([(sample.x, sample.y, sample.z) for sample in samples], dtype=np.float64)
                publish = self._publisher.publish
                for row in self._layout.encode(stamps, values):
                    publish(row.tobytes())
                return
        msg = self._msg
        stamp, acceleration, publish = msg.header.stamp, msg.linear_acceleration, self._publisher.publish
        for sample in samples:
            time_msg(seconds_to_ns(sample.t), stamp)
            acceleration.x, acceleration.y, acceleration.z = sample.x, sample.y, sample.z
            publish(msg)


def open_recorder(values: dict[str, Any], namespace: str, node: str) -> Any:
    """A Recorder for ``log_path`` (None when it is empty), with the run's
    parameters as the file's metadata, the node's namespace (topics are
    stored fully qualified, as rosbag2 does) and waiting rather than dropping
    when the writer falls behind (the tick thread then holds simulation time)."""
    if not values["log_path"]:
        return None
    from friction_sim.io.recorder import Recorder

    return Recorder(values["log_path"], metadata=recorded(values), namespace=namespace, node=node,
                    block_when_full=True)


def finish_recording(recorder: Any) -> tuple[bool, str]:
    """Finish the slider's recording (never raises: a failure is in its stats): whether it
    failed (the node then exits with EXIT_RECORDING_FAILED), and the line the node logs."""
    stats = recorder.finish()
    simulated = f"{stats.last_ns / 1e9 if stats.last_ns else 0.0:.3f} s simulated"
    if stats.error:
        what = stats.error.split("; ")[0]  # the recorder's one line, without "the run goes on"
        return True, (f"{what}; the {stats.messages} messages written ({simulated}) are readable; "
                      f"exit code {EXIT_RECORDING_FAILED}")
    return False, f"recording finished: {stats.path} ({stats.messages} messages, {simulated}, {stats.dropped} dropped)"


def open_live_view(values: dict[str, Any], namespace: str, node: str, services: list[Any]) -> Any:
    """A LiveView on ``foxglove_port`` (None when it is 0; -1: a port the
    system chooses when the server binds, which the view's ``port`` and ``url``
    then give): the Foxglove SDK's server on ``foxglove_address``, topics
    qualified in the node's namespace, with ``services``.  A port that is
    taken raises LiveViewError naming it (the node does not start)."""
    if not values["foxglove_port"]:
        return None
    from friction_sim.io.live import ADVERTISED, LiveView

    # Advertised at start, so a viewer that connects first can subscribe before the first one comes.
    topics: list[Any] = [*ADVERTISED, SIM_CONTROL, *COMMANDS, ("diagnostics", "diagnostic_msgs/msg/DiagnosticArray")]
    if values["publish_clock"]:
        topics.append(("/clock", "rosgraph_msgs/msg/Clock"))
    if values["accelerometer_rate"]:
        topics.append((ACCELEROMETER, "sensor_msgs/msg/Imu"))
    return LiveView(max(values["foxglove_port"], 0), values["foxglove_address"], namespace=namespace, node=node,
                    advertise=topics, services=services)


def watch_namespace(node: Any, now: Callable[[], float], *, lockstep: bool) -> None:
    """Keep what other nodes put on ``node``'s namespace's ``diagnostics`` (the
    controller's, and the slider's own) and ``target_speed`` for the node's sinks
    (``node.sinks``: a recording, a live view), logged at the simulation time
    ``now()``, so the file and the view show the whole feeder (the shipped layout
    plots the target against the mean speed).  The subscriptions exist whether
    or not anything records, so the number of subscribers of ``target_speed``
    (what ``ros2 topic pub -w`` waits for) is the same in every setup: the
    controller's and this one.  In ``lockstep`` a recording keeps the other
    nodes' diagnostics stamped in the run's simulation time (0 < stamp <= now:
    a controller's answers'), not those of their start-up (stamped 0 or by a
    wall clock, as many as the start-up took): those would differ from run to
    run; the slider records its own as it publishes them."""

    own = node.get_fully_qualified_name()

    def forward(topic: str, msg: Any) -> None:
        if not node.sinks:
            return
        log_time_ns = seconds_to_ns(now())
        linked = getattr(getattr(node, "topics", None), "linked_name", "")
        skipped = (own, linked) if linked else (own,)
        if lockstep and topic == "diagnostics" and (not 0 < stamp_ns(msg.header.stamp) <= log_time_ns or any(
                status.hardware_id in skipped for status in msg.status)):
            return  # (its own: recorded as it publishes them; a linked controller's: through the link)
        deliver(node.sinks, MessageRecord(topic, msg, log_time_ns))

    for topic, kind in (("diagnostics", DiagnosticArray), ("target_speed", message_class("std_msgs/msg/Float64"))):
        node.create_subscription(kind, topic, functools.partial(forward, topic), WATCHED_DEPTH)


def pace_problems(report: dict[str, Any]) -> list[str]:
    """What the wall clock says is wrong with a real-time run: the recorder or the
    computer cannot keep up, the timer ticks late."""
    problems: list[str] = []
    if report.get("recording_waited_in_interval_s", 0.0) > 0.0:
        problems.append(f"the recorder held the simulation back {report['recording_waited_in_interval_s']:.3f} s "
                        f"(achieved real-time factor {report['achieved_real_time_factor']:.3g})")
    if report.get("ticks_behind_in_interval", 0):
        problems.append(f"the simulation cannot keep up with real_time_factor {report['real_time_factor']:g} "
                        f"while recording (achieved {report['achieved_real_time_factor']:.3g})")
    if report["tick_rate"] < 0.8 * report["publish_rate"]:
        problems.append(f"tick rate {report['tick_rate']:.0f} Hz < 80% of {report['publish_rate']:g} Hz")
    if report["late_ticks"]:
        slipped = (f" ({report['stalls']} stalls in all: {report['time_slipped']:.3f} s not simulated, beyond "
                   f"max_catch_up {report['max_catch_up']:g} s)") if report.get("stalls") else ""
        problems.append(f"{report['late_ticks']} late ticks{slipped}")
    return problems


class RecorderHealth:
    """What the slider's recorder (None: not recording) says about itself on
    diagnostics, and how long it made the tick thread wait."""

    def __init__(self, recorder: Any) -> None:
        self.recorder = recorder
        self._waited_ns = 0
        self._reported = 0.0

    def newly_waited_ns(self) -> int:
        """Wall time [ns] the recorder held its producers since the last call."""
        if self.recorder is None:
            return 0
        waited = round(self.recorder.queue.wait_seconds * 1e9)
        new, self._waited_ns = max(0, waited - self._waited_ns), max(waited, self._waited_ns)
        return new

    def report(self) -> dict[str, Any]:
        """The recorder's part of diagnostics: its error (the run goes on
        unrecorded), messages dropped, and how long it held the simulation back."""
        recorder = self.recorder
        if recorder is None:
            return {}
        waited = recorder.queue.wait_seconds
        report = {"recording": str(recorder.path), "recording_error": recorder.error or "",
                  "recording_dropped": recorder.dropped, "recording_waited_s": waited,
                  "recording_waited_in_interval_s": waited - self._reported}
        self._reported = waited
        return report


def recorded(values: dict[str, Any]) -> dict[str, Any]:
    """The parameter values a recording keeps: all but log_path (a file name, not a setting of the run)."""
    return {k: v for k, v in values.items() if k not in ("log_path",)}


def health(report: dict[str, Any], fault: str = "", name_problem: str = "") -> tuple[bytes, str]:
    """ERROR with the reason when the simulation stopped; else OK, or WARN with
    the reasons: the timer falls behind, commands were refused, the node's
    name is taken twice."""
    if fault:
        return DiagnosticStatus.ERROR, fault
    if report.get("recording_error"):
        return DiagnosticStatus.ERROR, report["recording_error"]
    problems = [name_problem] if name_problem else []
    if report.get("live_view_error"):
        problems.append(f"live view: {report['live_view_error']}")
    if not report.get("lockstep"):  # in lockstep the pace is the participants': no wall-clock health
        problems += pace_problems(report)
    if report["commands_rejected_in_interval"]:
        problems.append(f"{report['commands_rejected_in_interval']} commands rejected ({report['last_rejection']})")
    if not problems:
        return DiagnosticStatus.OK, "paused" if report.get("paused") else "running"
    return DiagnosticStatus.WARN, "; ".join(problems)


__all__ = ["PREDICTION_TRIES", "AccelerometerPublisher", "RecorderHealth", "consistent_report", "control_text",
           "finish_recording", "health", "open_live_view", "open_recorder", "recorded", "watch_namespace"]
