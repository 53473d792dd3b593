"""Benchmark of MCAP recording (issue 10, item 12: the writer; item 13: reading).

Writing, measured in one run on this machine (separate functions, called
from main; the figures are medians of ``--repeat`` runs, and ratios are
against baselines measured in the same run):

  (w1) baselines: the old writer path, one message at a time (rclpy messages
       filled, serialized by rosbags, written with mcap's Writer), and raw
       mcap ``Writer.add_message`` calls with bytes serialized beforehand;
  (w2) the Recorder fed as the node feeds it (``deliver_tick``: a tick's states
       in one ``StatesRecord``, then its events and period means), from
       ticks made beforehand at real_time_factor 100 and the default log_rate
       1000 Hz, as fast as the Recorder takes them: state samples recorded per
       second (each = pose, velocity, friction_force), with the producer
       waiting whenever the writer is behind (no drops);
  (w3) a node-like paced run: a 1 kHz loop ticks RealtimeSlider at
       real_time_factor 100 on the wall clock and hands each tick to the
       Recorder: what a tick costs the producer (median, p99), how long it
       waited, and the real-time factor achieved;
  (c)  file size per simulated minute at 1 kHz, and reading/verify times.

Prints figures only: a benchmark never passes or fails on timing.  The
machine is shared: figures vary from run to run.

Run: make bench   (or .venv/bin/python bench/recording.py [--quick])
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import numpy as np

from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.core.model.records import Tick
from friction_sim.core.runtime.realtime import RealtimeSlider
from friction_sim.core.runtime.simulation import random_schedule
from friction_sim.experiment.offline import record_offline
from friction_sim.experiment.verify import verify
from friction_sim.io import cdr
from friction_sim.io.messages import STATE_TOPICS, fill_state_messages, seconds_to_ns, state_messages
from friction_sim.io.reader import read_recording
from friction_sim.io.recorder import Recorder
from friction_sim.io.sinks import deliver_tick

RTF = 100.0
LOG_RATE = 1000.0
TICK_NS = 1_000_000  # the node ticks at 1 kHz


def percentile(samples: list[float], q: float) -> float:
    return float(np.percentile(np.array(samples), q))


def median_of(runs: int, measure: Callable[[], float]) -> float:
    return statistics.median(measure() for _ in range(runs))


def node_ticks(wall_seconds: float) -> list[Tick]:
    """The ticks the slider node hands its sinks in ``wall_seconds`` at RTF 100, 1 kHz."""
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=0, real_time_factor=RTF, log_rate=LOG_RATE)
    return [rt.tick(k * TICK_NS) for k in range(1, round(wall_seconds * 1e9 / TICK_NS) + 1)]


# -- (w1) baselines ---------------------------------------------------------------------------


def _mcap_writer(stream: Any) -> tuple[Any, list[int]]:
    """mcap's own Writer as the baselines use it (4 MB zstd chunks, every index)
    and one channel per state topic."""
    from mcap.writer import CompressionType, IndexType, Writer

    writer = Writer(stream, chunk_size=4 * 1024 * 1024, compression=CompressionType.ZSTD, index_types=IndexType.ALL)
    writer.start(profile="ros2", library="bench")
    schema = writer.register_schema("geometry_msgs/msg/PoseStamped", "ros2msg", b"")
    return writer, [writer.register_channel(topic, "cdr", schema) for topic in STATE_TOPICS]


def old_path(folder: Path, ticks: list[Tick]) -> float:
    """States per second through the old writer path: per state, fill the three
    rclpy messages and for each call rosbags' serializer and mcap's add_message."""
    with (folder / "old.mcap").open("wb") as stream:
        writer, channels = _mcap_writer(stream)
        templates = state_messages(ticks[0].state)
        started = time.perf_counter()
        n = 0
        for tick in ticks:
            for state in tick.samples:
                fill_state_messages(state, "slideway", *templates)
                ns = seconds_to_ns(state.t)
                for channel, msg in zip(channels, templates):
                    writer.add_message(channel, ns, cdr.serialize(msg), ns, n)
                n += 1
        writer.finish()
        return n / (time.perf_counter() - started)


def raw_mcap(folder: Path, ticks: list[Tick]) -> float:
    """States per second that mcap's Writer alone takes (3 add_message calls per
    state, bytes serialized beforehand): the floor of any per-message path."""
    data = [cdr.serialize(msg) for msg in state_messages(ticks[0].state)]
    n = sum(len(tick.samples) for tick in ticks)
    with (folder / "raw.mcap").open("wb") as stream:
        writer, channels = _mcap_writer(stream)
        started = time.perf_counter()
        for k in range(n):
            for channel, payload in zip(channels, data):
                writer.add_message(channel, k, payload, k, k)
        writer.finish()
        return n / (time.perf_counter() - started)


# -- (w2) the Recorder, fed as fast as it takes it --------------------------------------------


def recorder_run(folder: Path, ticks: list[Tick]) -> dict[str, Any]:
    """Feed ``ticks`` to a Recorder with deliver_tick as fast as it takes them
    (until the file is finished); wall time and this process's CPU time."""
    n = sum(len(tick.samples) for tick in ticks)
    costs = []
    started, cpu = time.perf_counter(), time.process_time()
    with Recorder(folder / "fed.mcap", metadata={"bench": 1}) as recorder:
        for tick in ticks:
            begun = time.perf_counter()
            deliver_tick([recorder], tick, "slideway")
            costs.append(time.perf_counter() - begun)
    wall, cpu = time.perf_counter() - started, time.process_time() - cpu
    stats = recorder.stats
    return {"rate": n / wall, "cpu": cpu / n, "tick": statistics.median(costs), "p99": percentile(costs, 99),
            "waits": stats.waits, "waited": stats.waited, "dropped": stats.dropped, "messages": stats.messages}


def throughput(folder: Path, wall_seconds: float, repeat: int) -> None:
    ticks = node_ticks(wall_seconds)
    n = sum(len(tick.samples) for tick in ticks)
    events = sum(len(tick.events) for tick in ticks)
    print(f"(w) {len(ticks)} ticks of the node at real_time_factor {RTF:g}, log_rate {LOG_RATE:g} Hz: "
          f"{n} states, {events} events; median of {repeat} runs")
    old = median_of(repeat, lambda: old_path(folder, ticks))
    raw = median_of(repeat, lambda: raw_mcap(folder, ticks))
    runs = [recorder_run(folder, ticks) for _ in range(repeat)]
    rate = statistics.median(run["rate"] for run in runs)
    print(f"(w1) old path (rclpy fill + rosbags serialize + mcap add_message): {old:,.0f} states/s; "
          f"raw mcap add_message (bytes ready): {raw:,.0f} states/s")
    cpu = statistics.median(run["cpu"] for run in runs)
    print(f"(w2) Recorder fed by deliver_tick: {rate:,.0f} states/s recorded (every state and event, "
          f"{runs[0]['messages']:,} messages, {max(run['dropped'] for run in runs)} dropped) "
          f"= {rate / old:.1f}x the old path, {rate / raw:.1f}x raw mcap writes; CPU {cpu * 1e6:.2f} us per state "
          f"(both threads: {1 / cpu:,.0f} states per CPU-second); producer per tick of 100 states "
          f"{statistics.median(run['tick'] for run in runs) * 1e6:.0f} us median, "
          f"{statistics.median(run['p99'] for run in runs) * 1e6:.0f} us p99 (waits for the writer included: "
          f"{statistics.median(run['waits'] for run in runs):.0f} waits, "
          f"{statistics.median(run['waited'] for run in runs):.2f} s)")


# -- (w3) a node-like paced run ---------------------------------------------------------------


def paced(folder: Path, wall_seconds: float) -> None:
    """A 1 kHz loop on the wall clock at RTF 100, the recorder as its sink; the
    wall time it waits for the writer passes without simulation time, and the
    GIL switch interval is the node's."""
    sys.setswitchinterval(min(sys.getswitchinterval(), 0.0005))
    rt = RealtimeSlider(SliderParams(), Inputs(), wall_ns=time.monotonic_ns(), real_time_factor=RTF,
                        log_rate=LOG_RATE)
    ticks, puts = [], []
    held = 0
    with Recorder(folder / "paced.mcap", metadata={"bench": 1}) as recorder:
        begin = time.monotonic()
        deadline = begin
        while time.monotonic() - begin < wall_seconds:
            deadline = max(deadline + TICK_NS / 1e9, time.monotonic() - TICK_NS / 1e9)  # no bursts after a stall
            delay = deadline - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            started = time.perf_counter()
            tick = rt.tick(time.monotonic_ns())
            queued = time.perf_counter()
            deliver_tick([recorder], tick, "slideway")
            done = time.perf_counter()
            ticks.append(done - started)
            puts.append(done - queued)
            waited = round(recorder.queue.wait_seconds * 1e9)
            rt.clock.hold(waited - held)
            held = waited
        wall = time.monotonic() - begin
    stats = recorder.stats
    sim = rt.slider.t
    print(f"(w3) paced 1 kHz loop at real_time_factor {RTF:g} for {wall:.1f} s: {len(ticks)} ticks, tick (core + "
          f"recorder) {statistics.median(ticks) * 1e6:.0f} us median, {percentile(ticks, 99) * 1e6:.0f} us p99; "
          f"recorder share {statistics.median(puts) * 1e6:.1f} us median, {percentile(puts, 99) * 1e6:.0f} us p99; "
          f"{stats.waits} waits for the writer ({stats.waited:.3f} s); achieved real-time factor "
          f"{sim / wall:.1f} ({stats.per_topic.get('/pose', 0) / wall:,.0f} states/s recorded, "
          f"{stats.dropped} dropped)")


# -- (c) size, reading and verifying ----------------------------------------------------------


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
        print(f"(c) {name}: {stats.messages} messages, {size / 1e6:.2f} MB for {seconds:g} s "
              f"= {per_minute:.2f} MB per simulated minute ({size / stats.messages:.1f} B/message); "
              f"record_offline {wall / seconds * 1e3:.1f} ms of wall time per simulated second (core included)")
        print(f"    read {read:.2f} s, verify {checked:.2f} s ({'passed' if result.passed else 'FAILED'}, "
              f"rel dx {result.rel_dx:.1e}, rel dv {result.rel_dv:.1e})")


# -- (r) reading a long recording: memory and rate (item 13) ------------------------------------

_READ_CHILD = r"""
import sys, time
from pathlib import Path
task, path = sys.argv[1], Path(sys.argv[2])
started = time.perf_counter()
if task == "verify":
    from friction_sim.io.reader import read_recording
    from friction_sim.experiment.verify import verify
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
# VmHWM, not ru_maxrss: Linux carries ru_maxrss over from the parent through fork and exec
peak = next(int(line.split()[1]) * 1024 for line in open("/proc/self/status") if line.startswith("VmHWM:"))
print(messages, wall, peak, note)
"""


def reading(folder: Path, seconds: float) -> None:
    """(r) verify, report and plain reading of a recording of ``seconds`` simulated
    seconds at 1 kHz, each in a child process: peak RSS (the child's own
    VmHWM) and messages read per second of wall time; baseline: mcap's
    own reader in the same run."""
    import subprocess

    from friction_sim.core.model.commands import Command

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
    parser.add_argument("--quick", action="store_true", help="shorter runs")
    parser.add_argument("--repeat", type=int, default=3, help="runs per throughput figure (median)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        throughput(Path(folder), 1.0 if args.quick else 3.0, args.repeat)
        paced(Path(folder), 2.0 if args.quick else 5.0)
        minute(Path(folder), 10.0 if args.quick else 60.0)
        reading(Path(folder), 300.0 if args.quick else 3600.0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
