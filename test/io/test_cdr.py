"""Fixed-layout encoding (cdr.FixedLayout): byte for byte what rosbags'
serializer writes, for any frame, time and value; refused for types whose
bytes depend on more than a stamp and numbers."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from friction_sim.core.model.events import Mode, SliderState
from friction_sim.core.model.records import PeriodSummary
from friction_sim.io import cdr
from friction_sim.io import messages as M
from friction_sim.io.reader import read_recording
from friction_sim.io.recorder import Recorder
from friction_sim.io.sinks import StatesRecord

#: Values a float64 field may hold, awkward ones included.
ODD = [0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1.7976931348623157e308, -1e-300, math.inf, -math.inf,
       math.nan, 1.0 / 3.0, -0.7]
FRAMES = ["slideway", "", "a", "abc", "abcd", "x" * 37, "rail/ü∂", "/feeder1/slideway"]


def state_make(frame_id: str) -> Any:
    def make(ns: int, values: Sequence[float]) -> Sequence[Any]:
        x, v, friction, normal = values
        return M.state_messages(SliderState(ns / 1e9, x, v, 0.0, friction, normal, 0.0, Mode.STUCK), frame_id)

    return make


def random_states(rng: np.random.Generator, n: int) -> list[SliderState]:
    """States at random times up to the end of ROS time, with normal and odd values."""
    times = np.concatenate([[0.0, 1e-9, 0.9999999995, 2147483647.0, 2147483647.999999], rng.uniform(0, 2**31 - 1, n)])
    result = []
    for t in times:
        values = [float(v) if rng.random() < 0.7 else ODD[int(rng.integers(len(ODD)))] for v in rng.normal(0, 10, 4)]
        result.append(SliderState(float(t), values[0], values[1], 0.3, values[2], values[3], 1.0, Mode.FORWARD))
    return result


@pytest.mark.parametrize("frame_id", FRAMES)
def test_state_messages_encode_as_rosbags_serializes_them(frame_id: str) -> None:
    layouts = cdr.fixed_layouts(state_make(frame_id), 4)
    assert layouts is not None and [layout.type_name for layout in layouts] == [
        "geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/TwistStamped", "geometry_msgs/msg/WrenchStamped"]
    states = random_states(np.random.default_rng(len(frame_id)), 300)
    ns = np.array([M.seconds_to_ns(s.t) for s in states], dtype=np.int64)
    values = np.array([(s.x, s.v, s.friction_force, s.normal_force) for s in states], dtype=np.float64)
    encoded = [layout.encode(ns, values) for layout in layouts]
    for k, state in enumerate(states):
        expected = [cdr.serialize(msg) for msg in M.state_messages(state, frame_id)]
        assert [rows[k].tobytes() for rows in encoded] == expected, (frame_id, state)
        assert [layout.encode_one(int(ns[k]), values[k].tolist()) for layout in layouts] == expected


def test_mean_velocity_encodes_as_rosbags_serializes_it() -> None:
    def make(ns: int, values: Sequence[float]) -> Sequence[Any]:
        return [M.mean_velocity_message(PeriodSummary(0, ns / 1e9, values[0], 1, 0.0), "rail")]

    layouts = cdr.fixed_layouts(make, 1)
    assert layouts is not None
    for t, mean in [(0.02, 1.5e-3), (1e6 + 0.02, -0.0), (123.456789123, math.nan), (7.0, 5e-324)]:
        period = PeriodSummary(n=3, t=t, mean_velocity=mean, window_periods=2, stick_fraction=0.5)
        expected = cdr.serialize(M.mean_velocity_message(period, "rail"))
        assert layouts[0].encode_one(M.seconds_to_ns(t), [mean]) == expected


def test_types_whose_bytes_depend_on_more_are_not_fixed_layout() -> None:
    from diagnostic_msgs.msg import DiagnosticStatus
    from std_msgs.msg import Float64, String

    assert cdr.fixed_layouts(lambda ns, v: [String(data=repr(v[0]))], 1) is None, "no stamp, variable length"
    assert cdr.fixed_layouts(lambda ns, v: [Float64(data=v[0])], 1) is None, "no stamp"
    stamped = state_make("slideway")
    assert cdr.fixed_layouts(lambda ns, v: stamped(ns, [abs(x) for x in v]), 4) is None, "a value changed on the way"
    assert cdr.fixed_layouts(lambda ns, v: [*stamped(ns, v), DiagnosticStatus(message=f"{ns}")], 4) is None


def test_a_recording_holds_exactly_the_bytes_rosbags_writes(tmp_path: Path) -> None:
    """Through the whole writer (many states per pass, several frames, each
    topic's messages in order): every state message in the file equals
    rosbags' serialization of the message the node publishes."""
    states = random_states(np.random.default_rng(3), 3000)
    states.sort(key=lambda s: s.t)
    path = tmp_path / "bytes.mcap"
    with Recorder(path, metadata={"mass": 1.0}) as recorder:
        for first in range(0, len(states), 250):
            recorder.write(StatesRecord(tuple(states[first:first + 250]), FRAMES[(first // 250) % len(FRAMES)]))
    assert recorder.stats.dropped == 0
    recording = read_recording(path, require_friction_sim=False)
    for topic_index, topic in enumerate(M.STATE_TOPICS):
        raws = recording.messages_on(topic)
        assert len(raws) == len(states)
        for k, (raw, state) in enumerate(zip(raws, states)):
            frame_id = FRAMES[(k // 250) % len(FRAMES)]
            assert raw.log_time == M.seconds_to_ns(state.t)
            assert raw.data == cdr.serialize(M.state_messages(state, frame_id)[topic_index]), (topic, k)


@settings(max_examples=200, deadline=None)
@given(level=st.integers(0, 127), texts=st.lists(st.text(max_size=12), min_size=3, max_size=3),
       values=st.lists(st.tuples(st.text(max_size=9), st.text(max_size=9)), max_size=6))
def test_a_diagnostic_status_is_serialized_as_rosbags_serializes_it(level: int, texts: list[str],
                                                                    values: list[tuple[str, str]]) -> None:
    """The recording's direct serialization of a status (its events) gives rosbags' bytes for any
    strings (lengths and UTF-8 widths move every alignment) and any number of key-value pairs."""
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

    texts = [text.replace("\x00", "") for text in texts]  # (a ROS string holds no NUL)
    values = [(key.replace("\x00", ""), value.replace("\x00", "")) for key, value in values]
    name, message, hardware_id = texts
    msg = DiagnosticStatus(level=bytes([level]), name=name, message=message, hardware_id=hardware_id,
                           values=[KeyValue(key=key, value=value) for key, value in values])
    assert cdr.diagnostic_status(level, name, message, hardware_id, values) == cdr.serialize(msg)


def test_an_event_is_recorded_as_its_status_message() -> None:
    """What the recording writes for an event is the serialization of :func:`event_message`'s status."""
    from friction_sim.core.model.events import Event, EventKind

    for event in (Event(0.031, EventKind.LANDING, 4e-4, 3.9, Mode.FLIGHT, Mode.STUCK, v_before=0.021,
                        vz_before=-0.08), Event(0.01, EventKind.STICK, 1e-5, 3.0, Mode.FORWARD, Mode.STUCK)):
        name, message, values = M.event_fields(event)
        assert cdr.diagnostic_status(0, name, message, "", values) == cdr.serialize(M.event_message(event))
