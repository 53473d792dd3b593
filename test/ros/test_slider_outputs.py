"""What the slider node says about itself (friction_sim.ros.slider_outputs), without a node."""

from __future__ import annotations

import math
import threading
from typing import Any

from friction_sim.core.meanspeed.predict import predict
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.model.records import Acceleration
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.io.cdr import deserialize
from friction_sim.ros.slider_outputs import PREDICTION_TRIES, AccelerometerPublisher, consistent_report


class ChangingWhilePredicting(RealtimeSlider):
    """A runtime whose drive force a command changes while the first ``changes`` predictions are made
    (as the tick thread does while the diagnostics' prediction simulates outside the lock)."""

    def __init__(self, changes: int) -> None:
        super().__init__(SliderParams(), Inputs(), wall_ns=0)
        self.changes, self.made = changes, 0

    def prediction(self, params: Any = None, inputs: Any = None) -> Any:
        made = super().prediction(params, inputs)
        self.made += 1
        if self.made <= self.changes:
            self.slider.set_inputs(self.slider.inputs.replace(drive_force=self.slider.inputs.drive_force + 0.01))
        return made


def test_a_report_pairs_the_plant_it_shows_with_that_plants_prediction() -> None:
    rt = ChangingWhilePredicting(changes=PREDICTION_TRIES - 1)
    report = consistent_report(rt, threading.Lock(), lambda: 0)
    assert report["drive_force"] == rt.slider.inputs.drive_force
    assert report["predicted_U"] == predict(rt.slider.params, rt.slider.inputs).u
    assert rt.made == PREDICTION_TRIES


def test_a_plant_that_changes_at_every_try_is_reported_without_a_prediction() -> None:
    rt = ChangingWhilePredicting(changes=PREDICTION_TRIES)
    report = consistent_report(rt, threading.Lock(), lambda: 0)
    assert report["drive_force"] == rt.slider.inputs.drive_force
    assert math.isnan(report["predicted_U"]) and math.isnan(report["phi"])
    assert rt.made == PREDICTION_TRIES


class Topic:
    """A stand-in publisher: its readers are counted by the test; it keeps (stamp, x) of each message."""

    def __init__(self) -> None:
        self.readers = 0
        self.sent: list[tuple[int, float]] = []

    def get_subscription_count(self) -> int:
        return self.readers

    def publish(self, msg: Any) -> None:
        if isinstance(msg, bytes):  # (published serialized, as rclpy's publish takes it)
            msg = deserialize(msg, "sensor_msgs/msg/Imu")
        self.sent.append((msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec, msg.linear_acceleration.x))


def readings(first: int, count: int) -> list[Acceleration]:
    """``count`` readings 1 ms apart from ``first`` ms, x = their index."""
    return [Acceleration((first + k) / 1000, float(first + k), 0.0, 9.81) for k in range(count)]


def test_accelerometer_samples_with_no_reader_are_dropped_in_real_time() -> None:
    topic = Topic()
    accelerometer = AccelerometerPublisher(topic, "slideway", 0.0)
    accelerometer.publish(readings(1, 20), hold_after_ns=None)
    topic.readers = 1
    accelerometer.publish(readings(21, 20), hold_after_ns=None)
    assert [x for _, x in topic.sent] == [float(k) for k in range(21, 41)]  # a reader reads from when it came


def test_in_lockstep_a_late_reader_gets_every_sample_of_the_windows_still_to_answer_once_in_order() -> None:
    """With no reader the samples newer than the last answered sample are held; a reader that comes
    gets them (at a flush, or before the next samples), each once, then every sample as it is made."""
    topic = Topic()
    accelerometer = AccelerometerPublisher(topic, "slideway", 0.0)
    accelerometer.publish(readings(1, 20), hold_after_ns=-1)  # the first window: nothing answered yet
    accelerometer.publish(readings(21, 20), hold_after_ns=20_000_000)  # window 1 answered: its samples go
    accelerometer.flush(20_000_000)
    assert topic.sent == []
    topic.readers = 1
    accelerometer.flush(20_000_000)
    accelerometer.flush(20_000_000)
    accelerometer.publish(readings(41, 20), hold_after_ns=40_000_000)
    assert [stamp for stamp, _ in topic.sent] == [k * 1_000_000 for k in range(21, 61)]
    assert [x for _, x in topic.sent] == [float(k) for k in range(21, 61)]
