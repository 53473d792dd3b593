"""The controller's side of lockstep without ROS: which sample to answer, and when.

For the closed loop to be the same every run, each mean_velocity sample must be
answered once, in order, with exactly the accelerometer readings stamped up to
the sample's time, however the two topics' messages interleave on arrival.
"""

from __future__ import annotations

import math

from friction_sim.core.runtime.answers import AnswerQueue

MS = 1_000_000


def _queue(rate: float = 1000.0, diagnostics_ns: int = 100 * MS) -> AnswerQueue:
    return AnswerQueue(delay_ns=5 * MS, accelerometer_rate=rate, diagnostics_ns=diagnostics_ns)


def test_a_sample_is_new_once_a_repeat_after_its_answer_and_older_ones_are_old() -> None:
    queue = _queue(rate=0.0)
    assert not queue.waiting
    assert queue.sample(20 * MS, 1e-4) == "new"
    assert queue.sample(20 * MS, 1e-4) == "old", "published again while still queued: ignored"
    assert queue.next_ready(needs_accelerometer=True) == (20 * MS, 1e-4, [])
    assert not queue.waiting
    answer = {"excitation_amplitude": 4.5}
    queue.answered(20 * MS, answer)
    answer["excitation_amplitude"] = 0.0
    assert queue.sample(20 * MS, 1e-4) == "repeat"
    assert queue.last_ns == 20 * MS and queue.last_answer == {"excitation_amplitude": 4.5}, "a copy is kept"
    assert queue.sample(20 * MS - 1, 1e-4) == "old"
    assert queue.sample(0, 0.0) == "old"
    assert not queue.waiting, "neither a repeat nor an old sample is queued"
    assert queue.sample(40 * MS, 2e-4) == "new" and queue.waiting


def test_samples_are_answered_oldest_first() -> None:
    queue = _queue(rate=0.0)
    for stamp, speed in ((20 * MS, 1.0), (40 * MS, 2.0), (60 * MS, 3.0)):
        assert queue.sample(stamp, speed) == "new"
    assert [queue.next_ready(False) for _ in range(4)] == [(20 * MS, 1.0, []), (40 * MS, 2.0, []),
                                                           (60 * MS, 3.0, []), None]


def test_a_sample_waits_for_the_accelerometer_reading_at_its_time() -> None:
    """At 1 kHz the sample of 0.02 s needs the reading stamped 0.02 s: it is handed
    out with the readings up to that time; the later ones are kept for the next sample."""
    queue = _queue()
    assert queue.sample(20 * MS, 1e-4) == "new"
    for k in range(20):
        queue.acceleration(k * MS, 10.0 + k)
    assert queue.next_ready(needs_accelerometer=True) is None
    assert queue.waiting, "still queued"
    queue.acceleration(20 * MS, 30.0)
    queue.acceleration(21 * MS, 31.0)
    queue.acceleration(22 * MS, 32.0)
    ready = queue.next_ready(needs_accelerometer=True)
    assert ready == (20 * MS, 1e-4, [(k * MS, 10.0 + k) for k in range(21)])
    assert queue.sample(40 * MS, 2e-4) == "new"
    assert queue.next_ready(needs_accelerometer=True) is None, "a reading of 22 ms is not the one of 40 ms"
    for k in range(23, 41):
        queue.acceleration(k * MS, 10.0 + k)
    ready = queue.next_ready(needs_accelerometer=True)
    assert ready == (40 * MS, 2e-4, [(k * MS, 10.0 + k) for k in range(21, 41)])


def test_a_sample_between_grid_points_waits_for_the_last_one_before_it() -> None:
    queue = _queue()
    assert queue.sample(20 * MS + 500_000, 1e-4) == "new"  # 20.5 ms: the last grid point is 20 ms
    for k in range(20):
        queue.acceleration(k * MS, float(k))
    assert queue.next_ready(True) is None
    queue.acceleration(20 * MS, 20.0)
    ready = queue.next_ready(True)
    assert ready is not None and ready[2][-1] == (20 * MS, 20.0) and len(ready[2]) == 21


def test_the_sample_at_zero_waits_for_the_reading_at_zero() -> None:
    queue = _queue()
    queue.sample(0, 0.0)
    assert queue.next_ready(True) is None
    queue.acceleration(0, 10.0)
    assert queue.next_ready(True) == (0, 0.0, [(0, 10.0)])


def test_without_the_inner_loop_or_the_accelerometer_a_sample_is_ready_at_once() -> None:
    """Not needed (no inner loop) or not there (rate 0): nothing to wait for; the
    readings up to the sample's time are still taken off the queue."""
    queue = _queue()
    queue.acceleration(10 * MS, 1.0)
    queue.acceleration(30 * MS, 3.0)
    queue.sample(20 * MS, 1e-4)
    assert queue.next_ready(needs_accelerometer=False) == (20 * MS, 1e-4, [(10 * MS, 1.0)])
    off = _queue(rate=0.0)
    off.sample(20 * MS, 1e-4)
    assert off.next_ready(needs_accelerometer=True) == (20 * MS, 1e-4, [])


# The slider stamps a period ending at 1/30 s and the accelerometer reading k = 10 (10/300 s,
# the same float) both 33_333_333 ns: the reading lies a fraction of a ns past the stamp's
# float, and must still be waited for, or whether it is fed with this sample or the next
# would depend on which topic's message arrives first.
def test_a_reading_stamped_at_the_sample_own_nanosecond_is_waited_for() -> None:
    stamp = round(1 / 30 * 1e9)  # the slider's stamp of the period ending at 1/30 s
    reading_10 = round(10 / 300 * 1e9)  # the slider's stamp of the accelerometer reading k = 10
    assert stamp == reading_10 == 33_333_333
    queue = _queue(rate=300.0)
    queue.sample(stamp, 1e-4)
    for k in range(10):
        queue.acceleration(round(k / 300 * 1e9), float(k))
    assert queue.next_ready(True) is None  # reading k = 10, stamped 33_333_333 ns, has not come
    queue.acceleration(reading_10, 10.0)
    ready = queue.next_ready(True)
    assert ready is not None and [t for t, _ in ready[2]][-1] == reading_10


def test_diagnostics_are_due_once_per_period_crossed() -> None:
    """Every 100 ms of simulation time, at the first sample at or past each multiple;
    a jump over several multiples gives one report, and the next is due at the next multiple."""
    queue = _queue(diagnostics_ns=100 * MS)
    due = [t for t in range(0, 1001 * MS, 20 * MS) if queue.diagnostics_due(t)]
    assert due == [k * 100 * MS for k in range(11)]
    queue = _queue(diagnostics_ns=100 * MS)
    assert queue.diagnostics_due(30 * MS), "the first sample reports"
    assert not queue.diagnostics_due(99 * MS)
    assert queue.diagnostics_due(350 * MS), "crossed 100, 200 and 300 ms: one report"
    assert not queue.diagnostics_due(380 * MS)
    assert not queue.diagnostics_due(400 * MS - 1)
    assert queue.diagnostics_due(400 * MS)
    assert not queue.diagnostics_due(400 * MS), "once per period, not per call"


def test_values_report_the_last_sample_answered_and_those_waiting() -> None:
    queue = _queue()
    values = queue.values()
    assert values["lockstep"] is True and values["actuation_delay"] == 0.005
    assert math.isnan(values["lockstep_last_answered"]) and values["lockstep_samples_waiting"] == 0
    queue.sample(20 * MS, 1e-4)
    queue.sample(40 * MS, 1e-4)
    assert queue.next_ready(needs_accelerometer=False) is not None
    queue.answered(20 * MS, {"drive_level": 0.7})
    values = queue.values()
    assert values["lockstep_last_answered"] == 0.02 and values["lockstep_samples_waiting"] == 1
