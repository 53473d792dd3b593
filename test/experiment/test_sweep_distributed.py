"""A sweep on a real Dask cluster of separate processes: ``dask scheduler`` and
two ``dask worker`` processes started here on 127.0.0.1 (on ports the system
chooses; the scheduler's is read from its scheduler file), as a user starts
them on other machines.  One worker is killed (SIGKILL) while it holds a
chunk: the sweep still completes, every chunk written exactly once, every
number equal to the in-process run."""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from friction_sim.experiment.sweep import parse_sweep
from friction_sim.experiment.sweep_run import DaskExecutor, SerialExecutor, run_sweep
from friction_sim.io.parquet import read_table

SWEEP = """\
name: fault
settle_periods: 200
periods: 1800
chunk_size: 4
fixed: {drive_force: 0.3, mu: 0.2}
grid:
  throw_number: {from: 0.3, to: 3.0, num: 10}
  excitation_angle: [20, 40, 60, 80]
samples: 2
random:
  static_ratio: {distribution: uniform, low: 1.0, high: 1.5}
"""


def environment() -> dict[str, str]:
    """The workers need no ROS; discovery stays local and on a domain of its own all the same."""
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(random.SystemRandom().randint(1, 100))
    env["PYTHONUNBUFFERED"] = "1"
    return env


def dask(*args: str, log: Path) -> subprocess.Popen[bytes]:
    with log.open("wb") as out:
        return subprocess.Popen([sys.executable, "-m", "dask", *args], stdout=out, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, env=environment())


def scheduler_address(scheduler_file: Path, scheduler: subprocess.Popen[bytes], log: Path,
                      timeout: float = 30.0) -> str:
    """The address the scheduler listens on, once it has written its file: it chose the port itself
    (``--port 0``), so no other process can take it between a choice and a bind.  The file is written
    in one ``json.dump``, not atomically: a file that does not parse yet is read again."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if scheduler.poll() is not None:
            raise AssertionError(f"dask scheduler exited with {scheduler.returncode}:\n{log.read_text()}")
        try:
            return str(json.loads(scheduler_file.read_text())["address"])
        except (FileNotFoundError, json.JSONDecodeError, KeyError):
            time.sleep(0.05)  # poll interval: waiting for the scheduler file
    raise AssertionError(f"dask scheduler wrote no {scheduler_file.name} in {timeout} s:\n{log.read_text()}")


@pytest.fixture
def cluster(tmp_path: Path) -> Iterator[tuple[str, dict[str, subprocess.Popen[bytes]]]]:
    """A scheduler and two single-threaded workers without nannies (a killed worker stays dead).
    Every process binds port 0: the scheduler reports its address in the scheduler file, the
    workers find it there and report theirs to it."""
    scheduler_file = tmp_path / "scheduler.json"
    processes = {"scheduler": dask("scheduler", "--host", "127.0.0.1", "--port", "0",
                                   "--scheduler-file", str(scheduler_file),
                                   "--dashboard-address", "127.0.0.1:0", log=tmp_path / "scheduler.log")}
    try:
        address = scheduler_address(scheduler_file, processes["scheduler"], tmp_path / "scheduler.log")
        for name in ("w1", "w2"):
            processes[name] = dask("worker", "--scheduler-file", str(scheduler_file), "--name", name,
                                   "--nthreads", "1", "--no-nanny", "--host", "127.0.0.1",
                                   "--dashboard-address", "127.0.0.1:0", log=tmp_path / f"{name}.log")
        yield address, processes
    finally:
        for name in ("w1", "w2", "scheduler"):  # workers first: they would wait for a scheduler gone
            process = processes.get(name)
            if process is None:
                continue
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
                try:
                    process.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()


def wait_for_workers(executor: DaskExecutor, count: int, timeout: float = 30.0) -> dict[str, str]:
    """Worker name -> address once ``count`` workers have joined."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        workers = executor.client.scheduler_info(n_workers=-1)["workers"]
        if len(workers) >= count:
            return {info["name"]: address for address, info in workers.items()}
        time.sleep(0.1)  # poll interval: waiting for the workers to join
    raise AssertionError(f"fewer than {count} workers joined in {timeout} s")


@pytest.mark.timeout(90)
def test_a_worker_killed_mid_sweep_loses_no_chunk_and_writes_none_twice(
        tmp_path: Path, cluster: tuple[str, dict[str, subprocess.Popen[bytes]]]) -> None:
    address, processes = cluster
    sweep = parse_sweep(SWEEP)
    assert sweep.chunks == 20
    written: list[int] = []
    seen: dict[str, object] = {}
    with DaskExecutor(address, connect_timeout=30.0) as executor:
        names = wait_for_workers(executor, 2)

        def kill_w2_mid_sweep(index: int) -> None:
            written.append(index)
            if len(written) == 3:
                # The chunk just written may be w2's own: until the scheduler hands it the next one
                # (17 are left) it holds none, and killing it then would lose nothing.  Wait for that.
                deadline = time.monotonic() + 30.0
                while not (held := list(executor.client.processing().get(names["w2"], ()))) \
                        and time.monotonic() < deadline:
                    time.sleep(0.01)  # poll interval: waiting for w2 to hold a chunk
                seen["held"] = held
                processes["w2"].send_signal(signal.SIGKILL)
                processes["w2"].wait(timeout=10)

        outcome = run_sweep(sweep, executor, output=tmp_path / "fault.parquet", engine="scalar",
                            on_chunk=kill_w2_mid_sweep)
        survivors = executor.client.scheduler_info(n_workers=-1)["workers"]
        ros_on_workers = executor.client.run(lambda: "rclpy" in sys.modules)
    assert list(ros_on_workers.values()) == [False]  # the chunks ran without ROS
    assert seen["held"], "w2 held no chunk when it was killed: the test did not test a loss"
    print(f"w2 killed after 3 chunks were written, holding {seen['held']}; {sweep.chunks} chunks written once each")
    assert processes["w2"].returncode == -signal.SIGKILL
    assert [info["name"] for info in survivors.values()] == ["w1"]
    assert sorted(written) == list(range(sweep.chunks)) and len(written) == sweep.chunks
    assert outcome.computed == sweep.chunks and outcome.points == sweep.size
    columns = read_table(tmp_path / "fault.parquet")[0]
    assert np.array_equal(columns["point"], np.arange(sweep.size))
    run_sweep(sweep, SerialExecutor(), output=tmp_path / "serial.parquet", engine="scalar")
    reference = read_table(tmp_path / "serial.parquet")[0]
    for name, values in reference.items():
        assert np.array_equal(columns[name], values), name


@pytest.mark.timeout(60)
def test_the_cli_sends_a_sweep_to_a_running_cluster(
        tmp_path: Path, cluster: tuple[str, dict[str, subprocess.Popen[bytes]]]) -> None:
    address, _ = cluster
    path = tmp_path / "fault.yaml"
    path.write_text(SWEEP.replace("periods: 1800", "periods: 20"))
    output = tmp_path / "cli.parquet"
    done = subprocess.run([sys.executable, "-m", "friction_sim", "sweep", str(path), "--scheduler", address,
                           "--output", str(output), "--engine", "scalar"], capture_output=True, text=True,
                          env=environment(), timeout=60, check=False)
    assert done.returncode == 0, done.stderr
    assert f"Dask cluster {address}" in done.stdout and "20 chunk(s) computed" in done.stdout
    assert read_table(output)[0]["point"].size == 80
