"""Running a sweep: chunks of batch-core calls on Dask, Parquet parts, resume.

A validated :class:`~friction_sim.experiment.sweep.Sweep` is cut into chunks
of ``chunk_size`` points.  Each chunk is one call of
:func:`friction_sim.core.engine.population.run_batch` (:func:`run_chunk`, a plain function
of the sweep and the chunk's index, so any Dask worker with friction_sim
installed can run it: it needs no ROS and no file system shared with the
client).  The client alone writes: each finished chunk becomes one part file
``<output>.parts/chunk-000042.parquet``, written atomically and exclusively (a
second write of the same chunk would fail, see :func:`friction_sim.io.parquet.write_table`).
When every chunk is there, the parts are joined into ``<output>`` with the
metadata (model version, the sweep file's text, the chunking) and the parts
folder is removed.

An interrupted sweep (Ctrl-C, a crash, a lost cluster) resumes from its parts:
the next run of the same file skips the chunks already written.  A parts
folder or an output of a *different* sweep (another file text or chunk size)
is never mixed in: the run is refused unless ``fresh`` replaces it.

Executors: :class:`SerialExecutor` runs the chunks in this process (no Dask);
:class:`DaskExecutor` sends them to a ``dask.distributed`` cluster, a
``LocalCluster`` sized to the machine by default or an existing scheduler.
Dask reruns a chunk whose worker died on another worker; its result still
reaches the client once.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, Protocol

import numpy as np

from friction_sim.core.engine.population import run_batch
from friction_sim.core.model import spec as settings
from friction_sim.core.model.spec import Setting
from friction_sim.core.runtime.progress import Progress
from friction_sim.errors import FrictionSimError, one_line
from friction_sim.experiment.sweep import BLOCK, DERIVED, FIELDS, Sweep, materialize
from friction_sim.io.parquet import Columns, combine, read_metadata, write_table

#: The output columns after the inputs: per point, over the averaging window.
OUTPUTS = ("mean_velocity", "U", "flight_fraction", "stick_fraction")
META = "friction_sim."
Chunk = tuple[int, Columns]


class SweepRunError(FrictionSimError):
    """A sweep that cannot run or finish here (a clashing output, a failed chunk, no cluster)."""


def model_version() -> str:
    """The version of friction_sim that computed the results."""
    from friction_sim import __version__

    return str(__version__)


def run_chunk(sweep: Sweep, index: int, engine: str = "compiled", threads: int | None = None) -> Columns:
    """Chunk ``index`` of ``sweep``: its points' input columns and the population
    engine's outputs (one row per point), on ``threads`` cores (None: all; a Dask
    worker process is one core).  Runs on a Dask worker: needs no ROS."""
    start, stop = sweep.chunk_range(index)
    columns = materialize(sweep, start, stop)
    values = {name: columns[name].astype(str) if FIELDS[name].kind is str else columns[name] for name in FIELDS}
    try:
        result = run_batch(values, settle_periods=sweep.settle_periods, periods=sweep.periods, engine=engine,
                           threads=threads, initial=settings.INITIAL_INPUTS[sweep.initial])
    except FrictionSimError as error:  # one picklable error type, whatever the core raised, with the chunk named
        raise SweepRunError(f"chunk {index} (points {start}..{stop - 1}): {one_line(error)}") from None
    columns["mean_velocity"] = np.asarray(result.mean_velocity, dtype=float)
    columns["U"] = np.asarray(result.u, dtype=float)
    columns["flight_fraction"] = np.asarray(result.flight_fraction, dtype=float)
    columns["stick_fraction"] = np.asarray(result.stick_fraction, dtype=float)
    for kind, counts in result.event_counts.items():
        columns[f"{kind}_count"] = np.asarray(counts, dtype=np.int64)
    return columns


class Executor(Protocol):
    """Runs chunks and yields ``(index, columns)`` as each finishes (any order)."""

    description: str

    def run(self, sweep: Sweep, indices: Sequence[int], engine: str) -> Iterator[Chunk]:
        """The chunks ``indices`` of ``sweep``, each once, as they finish."""
        ...


class SerialExecutor:
    """Every chunk in this process, in order (no Dask): the reference."""

    description = "in this process"

    def run(self, sweep: Sweep, indices: Sequence[int], engine: str) -> Iterator[Chunk]:
        """The chunks, one after the other."""
        for index in indices:
            yield index, run_chunk(sweep, index, engine)

    def __enter__(self) -> SerialExecutor:
        return self

    def __exit__(self, *exc: object) -> None:
        return None


def _load_compiled_engine() -> None:
    """Run on each Dask worker: one tiny population, which loads the compiled
    kernels from the cache (or compiles them)."""
    run_batch({"drive_force": [0.7]}, settle_periods=1, periods=1, threads=1)


class DaskExecutor:
    """Chunks as tasks of a ``dask.distributed`` cluster: a ``LocalCluster`` of
    ``workers`` single-threaded worker processes (default: one per core) or,
    with ``scheduler`` (``tcp://HOST:8786``), an existing cluster.  Use it as a
    context manager: it connects (and starts the local cluster) on entry."""

    def __init__(self, scheduler: str | None = None, workers: int | None = None, *,
                 connect_timeout: float = 20.0) -> None:
        self.scheduler = scheduler
        self.workers = workers if workers is not None else (os.cpu_count() or 1)
        self.connect_timeout = connect_timeout
        self.client: Any = None
        self.cluster: Any = None
        self.description = ""
        self._engine_loaded = False

    def __enter__(self) -> DaskExecutor:
        try:
            from distributed import Client, LocalCluster
        except ImportError as error:
            raise SweepRunError(f"sweeps need dask.distributed: pip install -r requirements.txt ({error})") \
                from error
        try:
            if self.scheduler:
                self.client = Client(self.scheduler, timeout=f"{self.connect_timeout}s")
                count = len(self.client.scheduler_info().get("workers", {}))
                self.description = f"Dask cluster {self.scheduler} ({count} workers)"
            else:
                self.cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                            host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                            # A worker's failure reaches us as its task's exception; its own
                                            # log only adds shutdown races (a heartbeat to a scheduler that
                                            # has just closed, logged with a traceback).
                                            silence_logs=logging.CRITICAL)
                self.client = Client(self.cluster)
                self.description = f"local Dask cluster, {self.workers} worker process(es)"
        except OSError as error:  # distributed raises OSError (TimeoutError) when no scheduler answers
            self.__exit__(None, None, None)
            raise SweepRunError(f"--scheduler {self.scheduler}: no Dask scheduler answered: {error}") from error
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        self.client = self.cluster = None
        self._engine_loaded = False

    def load_engine(self) -> None:
        """Load the compiled engine in every worker now, all at once (about a
        second each from the cache), so that no chunk pays for it and a
        worker without a usable engine fails here, once.  Done before the
        first compiled chunk; idempotent."""
        if self._engine_loaded:
            return
        try:
            self.client.run(_load_compiled_engine)
        except FrictionSimError:
            raise
        except Exception as error:  # a worker without friction_sim, or one that died
            raise SweepRunError(f"the cluster's workers cannot load the compiled engine: "
                                f"{one_line(error, with_type=True)}") from error
        self._engine_loaded = True

    def run(self, sweep: Sweep, indices: Sequence[int], engine: str) -> Iterator[Chunk]:
        """Submit every chunk; yield each result as it arrives (each once)."""
        from distributed import as_completed

        if engine == "compiled":
            self.load_engine()

        futures = {self.client.submit(run_chunk, sweep, index, engine, 1, key=f"friction-sim-{sweep.identity}-{index}",
                                      pure=False): index for index in indices}
        try:
            for future in as_completed(list(futures)):
                index = futures.pop(future)
                try:
                    columns = future.result()
                except FrictionSimError:
                    raise
                except Exception as error:  # a worker's failure (no friction_sim there, killed too often)
                    raise SweepRunError(f"chunk {index} failed on the cluster: {one_line(error, with_type=True)}") \
                        from error
                yield index, columns
                future.release()
        finally:
            for future in futures:  # cancelled on error or interrupt: nothing left running for us
                future.cancel()


@dataclass(frozen=True)
class SweepOutcome:
    """What a run did: the output file, the points, the chunks computed now and
    those reused from an earlier run, and the wall time."""

    output: Path
    points: int
    chunks: int
    computed: int
    reused: int
    seconds: float
    executor: str


class SweepProgress:
    """A sweep's bar, ``name [#####.....]  12/40 chunks  24000/80000 points  3.1 s  ETA 7 s``,
    on a progress line (:class:`~friction_sim.core.runtime.progress.Progress`: the
    command line's, which redraws it on a terminal)."""

    def __init__(self, name: str, chunks: int, points: int, line: Progress) -> None:
        self.name, self.chunks, self.points, self.line = name, chunks, points, line
        self.start = time.monotonic()
        self.done_chunks = self.done_points = self.new_points = 0

    def restart(self) -> None:
        """Count the time from now (the cluster is up, the work starts)."""
        self.start = time.monotonic()

    def note(self, message: str) -> None:
        """A line of its own (the engine compiling, say)."""
        self.line.note(f"{self.name}: {message}")

    def advance(self, points: int, *, new: bool = True) -> None:
        """One more chunk of ``points`` done (``new``: computed now, not reused)."""
        self.done_chunks += 1
        self.done_points += points
        self.new_points += points if new else 0
        self.line.show(self.text(time.monotonic() - self.start), final=self.done_chunks == self.chunks)

    def text(self, elapsed: float) -> str:
        """The bar after ``elapsed`` seconds."""
        share = self.done_points / self.points if self.points else 1.0
        bar = "#" * round(30 * share) + "." * (30 - round(30 * share))
        rate = self.new_points / elapsed if elapsed > 0 else 0.0
        left = (self.points - self.done_points) / rate if rate > 0 else float("nan")
        eta = f"ETA {left:.0f} s" if left == left else "ETA ?"
        return (f"{self.name} [{bar}] {self.done_chunks}/{self.chunks} chunks  "
                f"{self.done_points}/{self.points} points  {elapsed:.1f} s  {eta}")

    def close(self) -> None:
        """End the line."""
        self.line.close()


def parts_dir(output: Path) -> Path:
    """The folder of a sweep's part files, beside its output."""
    return output.with_name(output.name + ".parts")


def part_path(output: Path, index: int) -> Path:
    """The part file of chunk ``index``."""
    return parts_dir(output) / f"chunk-{index:06d}.parquet"


def metadata(sweep: Sweep, engine: str) -> dict[str, str]:
    """The file metadata: version, sweep text and file, chunking, window, columns."""
    inputs = ["point", *FIELDS, *(key for key in DERIVED if key in sweep.lines)]
    return {
        META + "version": model_version(),
        META + "sweep": sweep.source,
        META + "sweep_file": sweep.where,
        META + "sweep_identity": sweep.identity,
        META + "chunking": json.dumps({"chunk_size": sweep.chunk_size, "chunks": sweep.chunks,
                                       "points": sweep.size, "random_block": BLOCK}),
        META + "settle_periods": str(sweep.settle_periods),
        META + "periods": str(sweep.periods),
        META + "engine": engine,
        META + "columns": json.dumps({"inputs": inputs, "design": list(sweep.design_keys),
                                      "random": list(sweep.random), "outputs": list(OUTPUTS)}),
    }


def _prepare(sweep: Sweep, output: Path, fresh: bool) -> set[int]:
    """The chunks already written for this sweep (none if fresh); refuses to mix sweeps."""
    parts = parts_dir(output)
    manifest = parts / "manifest.json"
    if fresh and parts.exists():
        shutil.rmtree(parts)
    if parts.exists():
        try:
            identity = json.loads(manifest.read_text()).get("identity")
        except (OSError, ValueError):
            identity = None
        if identity != sweep.identity:
            raise SweepRunError(f"{parts} holds the parts of another sweep (or another chunk size): "
                                "run with --fresh to replace them, or give another --output")
    parts.mkdir(parents=True, exist_ok=True)
    if not manifest.exists():
        manifest.write_text(json.dumps({"identity": sweep.identity, "sweep_file": sweep.where,
                                        "chunks": sweep.chunks, "chunk_size": sweep.chunk_size}))
    return {index for index in range(sweep.chunks) if part_path(output, index).exists()}


def run_sweep(sweep: Sweep, executor: Executor, *, output: Path | None = None, engine: str = "compiled",
              fresh: bool = False, progress: SweepProgress | None = None,
              on_chunk: Callable[[int], None] | None = None) -> SweepOutcome:
    """Run ``sweep`` (resuming from its parts), write ``output`` (default: the
    sweep's), and return what was done.  ``on_chunk(index)`` is called after
    each part is written (tests count the writes with it)."""
    output = Path(output if output is not None else sweep.output)
    started = time.monotonic()
    if output.exists() and not fresh:
        if read_metadata(output).get(META + "sweep_identity") == sweep.identity:
            return SweepOutcome(output, sweep.size, sweep.chunks, 0, sweep.chunks, 0.0, "already complete")
        raise SweepRunError(f"{output} holds the results of another sweep: run with --fresh to replace it, "
                            "or give another --output")
    done = _prepare(sweep, output, fresh)
    if progress is not None:
        progress.restart()
        for index in sorted(done):
            start, stop = sweep.chunk_range(index)
            progress.advance(stop - start, new=False)
    todo = [index for index in range(sweep.chunks) if index not in done]
    if todo and engine == "compiled":  # compile (or load) once here, before workers would each compile
        from friction_sim.core.engine.compiled import prepare

        prepare(progress.note if progress is not None else None)
    meta = metadata(sweep, engine)
    for index, columns in executor.run(sweep, todo, engine):
        start, stop = sweep.chunk_range(index)
        if columns["point"].size != stop - start or int(columns["point"][0]) != start:
            raise SweepRunError(f"chunk {index}: a worker returned points other than {start}..{stop - 1}")
        write_table(part_path(output, index), columns, meta, exclusive=True)
        if on_chunk is not None:
            on_chunk(index)
        if progress is not None:
            progress.advance(stop - start)
    if progress is not None:
        progress.close()
    rows = combine([part_path(output, index) for index in range(sweep.chunks)], output, meta)
    if rows != sweep.size:  # pragma: no cover - every chunk was checked as it was written
        raise SweepRunError(f"{output}: {rows} rows joined, {sweep.size} expected")
    shutil.rmtree(parts_dir(output))
    return SweepOutcome(output, sweep.size, sweep.chunks, len(todo), len(done), time.monotonic() - started,
                        getattr(executor, "description", ""))


def result_columns(columns: Columns) -> list[str]:
    """The output columns present in a results table, in order."""
    return [name for name in columns if name in OUTPUTS or name.endswith("_count")]


def settings_of(name: str) -> Setting | None:
    """The setting behind an input column (a field or a derived key), if any."""
    return FIELDS.get(name) or (DERIVED[name][1] if name in DERIVED else None)


__all__ = [
    "OUTPUTS", "DaskExecutor", "Executor", "SerialExecutor", "SweepProgress", "SweepOutcome", "SweepRunError",
    "metadata", "model_version", "part_path", "parts_dir", "result_columns", "run_chunk", "run_sweep", "settings_of",
]
