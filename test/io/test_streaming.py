"""Reading a long recording streams it: verify, report and the figure hold
one chunk at a time, never the file (issue 10, item 13).

The bound is judged against the recording's own payload: loading the file
whole keeps every message's bytes at once, so its peak is at least the sum
of their lengths; streaming stays a small fraction of it."""

from __future__ import annotations

import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from friction_sim.core.model.commands import Command
from friction_sim.experiment.offline import record_offline
from friction_sim.experiment.report import PICTURE_POINTS, build_report, run_data_from_recording
from friction_sim.experiment.verify import verify
from friction_sim.io.reader import read_recording
from friction_sim.io.series import Thinner

from recording_helpers import copy_recording


@pytest.fixture(scope="module")
def long_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """20 s at 1 kHz (about 63,000 messages) with a few commands, in 64 KiB chunks."""
    folder = tmp_path_factory.mktemp("long")
    schedule = [Command(5.0, "excitation_amplitude", {"excitation_amplitude": 6.0}),
                Command(11.0, "drive_force", {"drive_force": 0.8}),
                Command(15.0, "excitation_frequency", {"excitation_frequency": 40.0})]
    record_offline(folder / "made.mcap", schedule=schedule, duration=20.0)
    return copy_recording(folder / "made.mcap", folder / "long.mcap", chunk_size=64 * 1024)


def payload(path: Path) -> int:
    """The sum of the serialized messages' lengths (read with mcap alone)."""
    from mcap.reader import make_reader

    with path.open("rb") as stream:
        return sum(len(message.data) for _, _, message in make_reader(stream).iter_messages())


def peak_bytes(work: Callable[[], Any]) -> tuple[Any, int]:
    """(what ``work`` returns, the peak of Python allocations while it ran)."""
    tracemalloc.start()
    try:
        result = work()
        return result, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_verify_and_report_hold_a_small_fraction_of_the_file(long_recording: Path) -> None:
    total = payload(long_recording)
    assert total > 4_000_000 and read_recording(long_recording).chunks > 60
    verify(read_recording(long_recording))  # once untraced: the message types are built and cached
    result, verify_peak = peak_bytes(lambda: verify(read_recording(long_recording)))
    assert result.passed and result.samples == 20_001 and result.commands == 3
    rows, report_peak = peak_bytes(lambda: build_report(run_data_from_recording(long_recording)))
    assert len(rows) == 4
    assert verify_peak < total / 8, (verify_peak, total)
    assert report_peak < total / 8, (report_peak, total)


def test_the_streamed_report_equals_the_report_of_every_sample(long_recording: Path) -> None:
    from friction_sim.io.messages import stamp_ns

    streamed = run_data_from_recording(long_recording)
    recording = read_recording(long_recording)
    every = [(stamp_ns(m.header.stamp) / 1e9, m.twist.linear.x) for _, m in recording.decoded("mean_velocity")]
    events = [(t / 1e9, m.name) for t, m in recording.decoded("events")]
    assert len(streamed.mean_velocity) <= PICTURE_POINTS + 3 * 4 and len(streamed.events) < len(events) // 10
    from dataclasses import replace

    full = replace(streamed, mean_velocity=every, events=events)
    assert build_report(streamed) == build_report(full)
    for tolerance in (0.001, 0.05):  # another band: read again for it
        again = run_data_from_recording(long_recording, tolerance=tolerance)
        assert build_report(again) == build_report(replace(full, tolerance=tolerance))


def test_the_thinned_curve_keeps_every_extreme() -> None:
    rng = np.random.default_rng(3)
    values = rng.normal(size=(10_007, 2))
    times = np.arange(values.shape[0], dtype=np.int64)
    thinner = Thinner(values.shape[0], 2, points=200)
    for start in range(0, values.shape[0], 333):  # fed in uneven blocks, as chunks come
        thinner.add(times[start:start + 333], values[start:start + 333])
    kept_t, kept = thinner.result()
    assert kept_t.size <= 4 * 200 // 2 + 8 and np.all(np.diff(kept_t) > 0)
    assert np.array_equal(kept, values[kept_t])
    step = thinner.step
    for start in range(0, values.shape[0], step):  # each run's smallest and largest value is there
        run = values[start:start + step]
        inside = kept[(kept_t >= start) & (kept_t < start + step)]
        assert np.array_equal(inside.min(axis=0), run.min(axis=0))
        assert np.array_equal(inside.max(axis=0), run.max(axis=0))
    short = Thinner(50, 2, points=200)
    short.add(times[:50], values[:50])
    assert np.array_equal(short.result()[0], times[:50]), "a short series is kept whole"
