"""Timing helper shared by the benchmarks (a leading underscore: ``make bench``
runs every ``bench/*.py`` but this one, which measures nothing by itself)."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import Any


def median_time(function: Callable[[], Any], repeats: int) -> float:
    """Median wall time [s] of ``repeats`` calls of ``function`` (the machine is shared and noisy)."""
    samples = []
    for _ in range(repeats):
        started = time.perf_counter()
        function()
        samples.append(time.perf_counter() - started)
    return statistics.median(samples)
