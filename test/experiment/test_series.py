"""An experiment's sampled series (:class:`~friction_sim.experiment.job.Series`):
read as the lists of (t, value) tuples they replaced, kept as packed doubles.
No ROS: the runner fills them from its callbacks (test_acceptance runs it)."""

from __future__ import annotations

import math
import pickle
import threading
import tracemalloc
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from friction_sim.experiment.job import RESIDENT_BLOCKS, SERIES_BLOCK, ExperimentResult, Series


class Held:
    """Bytes allocated inside a :func:`traced` block and still held at its end."""

    bytes = 0


@contextmanager
def traced() -> Iterator[Held]:
    """Count what the block leaves allocated (tracemalloc; left running if it already was)."""
    started = not tracemalloc.is_tracing()
    if started:
        tracemalloc.start()
    held = Held()
    before = tracemalloc.get_traced_memory()[0]
    try:
        yield held
    finally:
        held.bytes = tracemalloc.get_traced_memory()[0] - before
        if started:
            tracemalloc.stop()


def test_a_sample_costs_its_doubles_not_python_objects() -> None:
    """A (t, v) row holds 16 bytes (and the array's spare room, a sixteenth),
    where a tuple of two Python floats in a list held ~110: an hour's 180,000
    mean-velocity samples grew a run by ~20 MB.  Counted by tracemalloc, so the
    same on any machine."""
    result = ExperimentResult()
    rows = 20_000
    with traced() as grown:
        for k in range(rows):
            result.mean_velocity.append((0.02 * k, 1e-4 + k * 1e-9))
            result.amplitude.append((0.02 * k + 1e-3, 2.5))
            result.drive.append((0.02 * k, 0.5, 50.0, math.nan))
    per_row = grown.bytes / rows
    assert per_row < 1.2 * 8 * (2 + 2 + 4), f"{per_row:.1f} bytes per sample of the three series"
    assert result.mean_velocity.nbytes == rows * 16 and result.drive.nbytes == rows * 32


def test_it_reads_as_the_list_of_tuples_it_replaced() -> None:
    rows = [(0.02 * k, math.sin(k)) for k in range(10)]
    series: Series[tuple[float, float]] = Series(2, rows)
    assert list(series) == rows and series == rows and len(series) == 10 and bool(series)
    assert series[0] == rows[0] and series[-1] == rows[-1] and series[-1][1] == rows[-1][1]
    assert list(reversed(series)) == rows[::-1] and series[2:5] == rows[2:5] and series[::-3] == rows[::-3]
    assert [v for t, v in series if t > 0.1] == [v for t, v in rows if t > 0.1]
    assert rows[3] in series and series.index(rows[4]) == 4
    assert list(series.column(0)) == [t for t, _ in rows] and list(series.column(1)) == [v for _, v in rows]
    assert not Series(2) and Series(2) == [] and Series(2) != rows
    with pytest.raises(IndexError):
        series[10]
    with pytest.raises(IndexError):
        series[-11]
    restored = pickle.loads(pickle.dumps(series))
    assert restored == series and restored.width == 2


def test_rows_across_its_blocks_read_as_one_sequence() -> None:
    """A width that does not divide the block: each block holds whole rows."""
    rows = [(float(k), -float(k), k / 7.0) for k in range(3 * SERIES_BLOCK + 5)]
    series: Series[tuple[float, float, float]] = Series(3)
    for row in rows[:SERIES_BLOCK]:
        series.append(row)
    series.extend(rows[SERIES_BLOCK:])
    assert len(series) == len(rows) and list(series) == rows and series == rows
    assert [series[k] for k in range(0, len(rows), 997)] == rows[::997] and series[-1] == rows[-1]
    assert list(series.column(2)) == [x for _, _, x in rows] and series.nbytes == 8 * 3 * len(rows)
    assert list(reversed(series))[:3] == rows[:-4:-1]


def test_since_makes_times_relative_and_drops_the_rows_before() -> None:
    """What the runner does once the run ends: the same arithmetic (t - start) as the list comprehension did."""
    start = 1234.56789
    rows = [(start - 0.02 + 0.02 * k, 0.5 * k, 50.0, math.nan) for k in range(6)]
    series: Series[tuple[float, float, float, float]] = Series(4, rows)
    shifted = series.since(start)
    expected = [(t - start, level, f, x) for t, level, f, x in rows if t >= start]
    assert len(shifted) == len(expected) == 5
    for ours, theirs in zip(shifted, expected):
        assert ours[:3] == theirs[:3] and math.isnan(ours[3])
    assert len(series) == 6, "the original is left as it was"


def test_a_row_of_another_width_or_not_numbers_adds_nothing() -> None:
    series: Series[tuple[float, float]] = Series(2, [(0.0, 1.0)])
    with pytest.raises(ValueError, match="2"):
        series.append((1.0,))  # type: ignore[arg-type]
    with pytest.raises(TypeError):
        series.append((1.0, None))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="2"):
        series.extend([(1.0, 2.0), (3.0, 4.0, 5.0)])  # type: ignore[list-item]
    assert series == [(0.0, 1.0)]


def test_a_reader_on_another_thread_sees_whole_rows() -> None:
    """The controller's listener appends from its own thread while the driver reads the last row."""
    series: Series[tuple[float, float]] = Series(2)
    done = threading.Event()

    def write() -> None:
        for k in range(200_000):
            series.append((float(k), float(k)))
        done.set()

    writer = threading.Thread(target=write)
    writer.start()
    while not done.is_set():
        if series:
            t, v = series[-1]
            assert t == v
    writer.join()
    assert len(series) == 200_000


def test_an_hours_series_keeps_only_its_newest_blocks_in_memory() -> None:
    """Full blocks beyond the newest RESIDENT_BLOCKS go to the series' file: the memory held stays
    that of a few blocks however long the run, and every row reads back as it was written (in
    order, by index, by column, pickled), while it keeps growing."""
    blocks = 12
    rows = [(0.02 * k, math.sin(k), k / 3.0) for k in range(blocks * (SERIES_BLOCK // 3) + 7)]
    with traced() as grown:
        series: Series[tuple[float, float, float]] = Series(3)
        for row in rows:
            series.append(row)
    assert grown.bytes < (RESIDENT_BLOCKS + 2) * SERIES_BLOCK * 8, f"{grown.bytes} bytes held for {blocks} blocks"
    assert series.nbytes == 8 * 3 * len(rows) and len(series) == len(rows)
    assert list(series) == rows and [series[k] for k in range(0, len(rows), 1013)] == rows[::1013]
    assert series[0] == rows[0] and series[-1] == rows[-1] and list(series.column(1)) == [v for _, v, _ in rows]
    assert pickle.loads(pickle.dumps(series)) == rows
    series.append((1e9, 1.0, 2.0))
    assert series[-1] == (1e9, 1.0, 2.0) and series[:len(rows)] == rows


@pytest.mark.parametrize("failure", ["no file", "a full disk"])
def test_a_series_whose_file_cannot_be_written_keeps_its_blocks_in_memory(
        failure: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """No temporary file (a read-only or missing TMPDIR), or a write that fails (ENOSPC): the
    blocks stay where they are, every row intact, and the series goes on growing."""
    import os
    import tempfile

    def refused(*args: object, **kwargs: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(tempfile if failure == "no file" else os, "TemporaryFile" if failure == "no file"
                        else "pwrite", refused)
    rows = [(float(k), -float(k)) for k in range(6 * (SERIES_BLOCK // 2) + 3)]
    series: Series[tuple[float, float]] = Series(2, rows)
    assert list(series) == rows and series[SERIES_BLOCK // 2] == rows[SERIES_BLOCK // 2]
