"""Benchmark of MCAP recording (issue: MCAP logging and replay).

Measures, in one run on this machine:
  (a) what recording costs the 1 kHz tick thread: the time of one
      ``Recorder.on_states`` call (a queue put), and of a whole logged tick
      of :class:`RealtimeSlider` (advance the core through the grid point, take
      the exact state, queue it with the tick's events), median and 99th
      percentile;
  (b) what it costs the writer thread: wall time per simulated second at a
      1 kHz log rate (``record_offline``, which feeds the same writer as fast
      as it can), i.e. the share of one core a real-time run needs;
  (c) the file size per minute of simulated time at 1 kHz (constant inputs,
      and random commands every ~50 periods);
  (d) how long ``--verify`` and reading take for that minute.
Prints figures only: a benchmark never passes or fails on timing.

Run: make bench   (or .venv/bin/python bench/recording.py [--quick])
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import numpy as np

from friction_sim.core.params import Inputs, SliderParams
from friction_sim.core.realtime import RealtimeSlider
from friction_sim.core.simulation import random_schedule
from friction_sim.core.slider import Slider
from friction_sim.io.offline import record_offline
from friction_sim.io.reader import read_recording
from friction_sim.io.recorder import Recorder
from friction_sim.io.sinks import deliver_tick
from friction_sim.io.verify import verify


def percentile(samples: list[float], q: float) -> float:
    return float(np.percentile(np.array(samples), q))


def tick_thread_costs(folder: Path, steps: int) -> None:
    slider = Slider(SliderParams(), Inputs(), event_log_size=1000)
    with Recorder(folder / "tick.mcap", metadata={"bench": 1}) as recorder:
        puts = []
        state = slider.state()
        for _ in range(steps):
            started = time.perf_counter()
            recorder.on_states([state], "slideway")
            puts.append(time.perf_counter() - started)
            time.sleep(0.0002)  # let the writer keep up, as a 1 kHz loop would
        rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, log_rate=1000.0)
        grid = []
        for k in range(1, steps + 1):
            started = time.perf_counter()
            deliver_tick([recorder], rt.tick(k * 1_000_000), "slideway")
            grid.append(time.perf_counter() - started)
            time.sleep(0.0002)
        dropped = recorder.dropped
    print(f"(a) tick thread: on_states {statistics.median(puts) * 1e6:.1f} us median, "
          f"{percentile(puts, 99) * 1e6:.1f} us p99; logged tick (advance + state + queue) "
          f"{statistics.median(grid) * 1e6:.1f} us median, {percentile(grid, 99) * 1e6:.1f} us p99; "
          f"{dropped} dropped")


def minute(folder: Path, seconds: float) -> None:
    cases = {
        "constant inputs": [],
        "random commands": random_schedule(np.random.default_rng(1), seconds, mean_periods=50.0),
    }
    for name, schedule in cases.items():
        path = folder / f"{name.split()[0]}.mcap"
        started = time.perf_counter()
        stats = record_offline(path, schedule=schedule, duration=seconds, log_rate=1000.0)
        wall = time.perf_counter() - started
        size = path.stat().st_size
        started = time.perf_counter()
        recording = read_recording(path)
        read = time.perf_counter() - started
        started = time.perf_counter()
        result = verify(recording)
        checked = time.perf_counter() - started
        per_minute = size * 60.0 / seconds / 1e6
        print(f"    {name}: {stats.messages} messages, {size / 1e6:.2f} MB for {seconds:g} s "
              f"= {per_minute:.2f} MB per simulated minute ({size / stats.messages:.1f} B/message)")
        print(f"(b) writer: {wall / seconds * 1e3:.1f} ms of wall time per simulated second "
              f"(~{100 * wall / seconds:.1f}% of a core in real time, producer included)")
        print(f"(d) read {read:.2f} s, verify {checked:.2f} s ({'passed' if result.passed else 'FAILED'}, "
              f"rel dx {result.rel_dx:.1e}, rel dv {result.rel_dv:.1e})")


# -- (r) reading a long recording: memory and rate (item 13) ------------------------------------

_READ_CHILD = r"""
import resource, sys, time
from pathlib import Path
task, path = sys.argv[1], Path(sys.argv[2])
started = time.perf_counter()
if task == "verify":
    from friction_sim.io.reader import read_recording
    from friction_sim.io.verify import verify
    recording = read_recording(path)
    note = "passed" if verify(recording).passed else "FAILED"
    messages = recording.message_count
elif task == "report":
    from friction_sim.experiment.report import build_report, run_data_from_recording
    from friction_sim.io.reader import read_recording
    note = f"{len(build_report(run_data_from_recording(path)))} rows"
    messages = read_recording(path).message_count
elif task == "stream":
    from friction_sim.io.reader import read_recording
    messages = sum(len(block) for block in read_recording(path).iter_chunks())
    note = "every message, chunk by chunk"
else:  # baseline: mcap's own streaming reader, record by record (make_reader's seeking one took 5.6 GiB here)
    from mcap.records import Message
    from mcap.stream_reader import StreamReader
    with path.open("rb") as stream:
        messages = sum(1 for record in StreamReader(stream).records if isinstance(record, Message))
    note = "mcap StreamReader().records"
wall = time.perf_counter() - started
print(messages, wall, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, note)
"""


def reading(folder: Path, seconds: float) -> None:
    """(r) verify, report and plain reading of a recording of ``seconds`` simulated
    seconds at 1 kHz, each in a child process: peak RSS (the child's own
    ru_maxrss) and messages read per second of wall time; baseline: mcap's
    own reader in the same run."""
    import subprocess

    from friction_sim.core.commands import Command

    path = folder / "long.mcap"
    schedule = [Command(seconds * k / 4, "drive_force", {"drive_force": 0.7 + 0.05 * k}) for k in (1, 2, 3)]
    started = time.perf_counter()
    stats = record_offline(path, schedule=schedule, duration=seconds, log_rate=1000.0)
    print(f"(r) a {seconds:g} s recording: {stats.messages} messages, {path.stat().st_size / 1e6:.0f} MB, "
          f"made in {time.perf_counter() - started:.0f} s")
    rates = {}
    for task in ("mcap", "stream", "verify", "report"):
        done = subprocess.run([sys.executable, "-c", _READ_CHILD, task, str(path)], capture_output=True, text=True,
                              check=False)
        if done.returncode != 0:
            print(f"    {task}: failed: {done.stderr.strip().splitlines()[-1:]}")
            continue
        messages, wall, peak, note = done.stdout.split(maxsplit=3)
        rates[task] = int(messages) / float(wall)
        ratio = f", {rates[task] / rates['mcap']:.2f}x mcap's rate" if "mcap" in rates and task != "mcap" else ""
        print(f"    {task:>6}: {float(wall):6.1f} s, peak RSS {int(peak) / 2**20:5.0f} MiB, "
              f"{rates[task]:,.0f} messages/s{ratio} ({note.strip()})")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="10 s instead of a minute")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        tick_thread_costs(Path(folder), 2000 if args.quick else 5000)
        print("(c) file size at 1 kHz:")
        minute(Path(folder), 10.0 if args.quick else 60.0)
        reading(Path(folder), 300.0 if args.quick else 3600.0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
