"""A slider in lockstep and its controller in one process take their turns through a link, not DDS.

The link (:mod:`friction_sim.ros.lockstep_link`) must change nothing but the
transport: the same scenario gives the same recording linked or through the
topics, and anyone listening on ``control_answer`` still hears every answer.
"""

from __future__ import annotations

import dataclasses
import threading
import time
import uuid
from pathlib import Path
from typing import Any

import pytest

from friction_sim.experiment import runner
from friction_sim.experiment.scenario import load_scenario
from friction_sim.io.digest import differences, recording_digest
from friction_sim.ros import lockstep_link
from friction_sim.ros.lockstep_link import TurnTopics

ROOT = Path(__file__).resolve().parents[2]
#: The link's own attach (the tests below wrap it, each time afresh).
ATTACH = lockstep_link.attach
TOPICS = TurnTopics("/a/mean_velocity", "/a/control_answer", "/a/accelerometer")


class _Answers:
    """A controller's side that keeps what it is handed."""

    def __init__(self) -> None:
        self.handed: list[tuple[list[tuple[int, float]], list[tuple[int, float]]]] = []

    def deliver(self, samples: Any, readings: Any) -> None:
        self.handed.append((list(samples), list(readings)))


class _Context:
    """Stands for an rclpy context: the link compares contexts by identity."""


def test_a_controller_links_only_to_a_slider_of_its_context_with_the_same_topics() -> None:
    context, other = _Context(), _Context()
    wakes: list[int] = []
    link = lockstep_link.offer(context, TOPICS, lambda: wakes.append(1))
    assert link is not None
    try:
        assert lockstep_link.offer(context, TOPICS, lambda: None) is None  # a name clash: left to DDS
        remapped = dataclasses.replace(TOPICS, answers="/b/control_answer")
        assert not lockstep_link.linkable(context, remapped)
        assert lockstep_link.attach(context, remapped, _Answers()) is None
        assert lockstep_link.attach(other, TOPICS, _Answers()) is None
        assert lockstep_link.linkable(context, TOPICS)
        first = _Answers()
        assert lockstep_link.attach(context, TOPICS, first) is link and link.controller is first
        assert link.generation == 1
        assert not lockstep_link.linkable(context, TOPICS)
        assert lockstep_link.attach(context, TOPICS, _Answers()) is None  # one controller per slider
        lockstep_link.detach(link, _Answers())  # not the one linked: nothing changes
        assert link.controller is first
        lockstep_link.detach(link, first)
        assert link.controller is None
        second = _Answers()
        assert lockstep_link.attach(context, TOPICS, second) is link and link.generation == 2
    finally:
        lockstep_link.withdraw(link)
    assert link.controller is None
    assert not lockstep_link.linkable(context, TOPICS)
    assert lockstep_link.offer(context, TOPICS, lambda: None) is not None  # offered anew once withdrawn
    lockstep_link.withdraw(lockstep_link.attach(context, TOPICS, _Answers()) or link)


def test_an_answer_wakes_the_slider_only_from_another_thread() -> None:
    wakes: list[int] = []
    link = lockstep_link.Link(_Context(), TOPICS, lambda: wakes.append(1))
    link.slider_thread = threading.current_thread()
    link.answer("in the slider's thread")
    assert wakes == [] and list(link.answers) == ["in the slider's thread"]
    helper = threading.Thread(target=link.answer, args=("from another",))
    helper.start()
    helper.join()
    assert wakes == [1] and list(link.answers) == ["in the slider's thread", "from another"]


def _run(out: Path, namespace: str) -> dict[str, str]:
    spec = dataclasses.replace(load_scenario(ROOT / "config/acceptance_7_resonant_steps.yaml").spec(),
                               log_path=out, lockstep=True)
    runner.run_experiment(spec, namespace=namespace)
    return recording_digest(out)


def _counting_attach(monkeypatch: pytest.MonkeyPatch, allow: bool) -> list[bool]:
    """Record each attach of a controller (whether it linked); with ``allow`` false none links."""
    linked: list[bool] = []

    def counted(context: Any, topics: TurnTopics, answers: Any, name: str = "") -> Any:
        link = ATTACH(context, topics, answers, name) if allow else None
        linked.append(link is not None)
        return link

    monkeypatch.setattr(lockstep_link, "attach", counted)
    return linked


def _listen(namespace: str) -> tuple[list[int], list[int], Any]:
    """A node of this process listening on ``control_answer`` and ``mean_velocity`` (as ``ros2 topic
    echo`` would), spun in a thread: the stamps it heard on each, and how to stop it."""
    import rclpy
    from geometry_msgs.msg import TwistStamped
    from rclpy.executors import SingleThreadedExecutor

    from friction_sim.io.messages import message_class, stamp_ns
    from friction_sim.io.stamped import STAMPED_DEPTH, STAMPED_TYPE

    node = rclpy.create_node("answer_listener", namespace=namespace)
    heard: list[int] = []
    node.create_subscription(message_class(STAMPED_TYPE), "control_answer",
                             lambda msg: heard.append(stamp_ns(msg.header.stamp)), STAMPED_DEPTH)
    samples: list[int] = []
    node.create_subscription(TwistStamped, "mean_velocity", lambda msg: samples.append(stamp_ns(msg.header.stamp)),
                             STAMPED_DEPTH)
    executor, stop = SingleThreadedExecutor(), threading.Event()
    executor.add_node(node)
    spinner = threading.Thread(target=lambda: [executor.spin_once(timeout_sec=0.05) for _ in iter(stop.is_set, True)],
                               daemon=True)
    spinner.start()

    def close() -> None:
        stop.set()
        spinner.join()
        executor.shutdown()
        node.destroy_node()

    return heard, samples, close


def test_linked_or_through_the_topics_a_run_records_the_same_and_listeners_hear_every_answer(
        ros: None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """acceptance_7 (resonant, inner loop on the accelerometer): linked in process, then with
    the link refused (every turn over DDS, as between processes), then linked with a listener
    on control_answer and mean_velocity: three identical recordings, and the listener hears every
    answer and sample from the moment it matched their publisher (discovery is asynchronous, as for
    any DDS listener) to the end."""
    namespace = f"/link_{uuid.uuid4().hex[:8]}"  # (the same for all three: the recordings name it)
    linked = _counting_attach(monkeypatch, allow=True)
    first = _run(tmp_path / "linked.mcap", namespace)
    assert linked == [True]
    unlinked = _counting_attach(monkeypatch, allow=False)
    second = _run(tmp_path / "topics.mcap", namespace)
    assert unlinked == [False]
    assert differences(first, second) == []

    linked = _counting_attach(monkeypatch, allow=True)
    heard, published, close = _listen(namespace)
    try:
        third = _run(tmp_path / "heard.mcap", namespace)
        # every period's end at 50 Hz but the run's own end (t = 3 s: the run stops there, unanswered)
        samples = [round(k / 50.0 * 1e9) for k in range(1, 150)]
        deadline = time.monotonic() + 30.0
        while (samples[-1] not in heard or samples[-1] not in published) and time.monotonic() < deadline:
            time.sleep(0.01)  # poll interval of a wait for the listener to have the last answer and sample
    finally:
        close()
    assert linked == [True]
    assert differences(first, third) == []
    assert heard and sorted(set(heard)) == [stamp for stamp in samples if stamp >= min(heard)]
    assert published and sorted(set(published)) == [stamp for stamp in samples if stamp >= min(published)]
