"""Running sweeps: the numbers are the scalar core's, whatever the executor,
the number of workers or the chunk size; parts are written once each, an
interrupted sweep resumes where it stopped, another sweep's files are never mixed in."""

from __future__ import annotations

import json
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import pytest

from friction_sim import __version__
from friction_sim.cli.progress import TerminalProgress
from friction_sim.core.engine.single import Slider
from friction_sim.core.meanspeed.urelation import u_map
from friction_sim.core.model.params import Inputs, SliderParams
from friction_sim.errors import FrictionSimError
from friction_sim.experiment.sweep import FIELDS, Sweep, parse_sweep
from friction_sim.experiment.sweep_run import (
    DaskExecutor,
    SerialExecutor,
    SweepProgress,
    SweepRunError,
    parts_dir,
    run_chunk,
    run_sweep,
)
from friction_sim.io.parquet import ChunkExistsError, read_table, write_table

#: The mechanics below do not depend on the engine: the exact scalar loop keeps them fast and stable.
ENGINE = "scalar"

MIXED = """\
name: mixed
settle_periods: 3
periods: 4
chunk_size: 3
seed: 5
fixed: {drive_force: 0.2}
grid:
  throw_number: [0.4, 0.9, 1.6, 3.0]
  excitation_angle: [30, 90]
samples: 3
random:
  mu: {distribution: uniform, low: 0.1, high: 0.5}
  track_inclination: {distribution: normal, mean: 0, std: 3}
  restitution: {distribution: choice, values: [0.0, 0.3]}
"""


def scalar_mean_velocity(columns: dict[str, np.ndarray], i: int, settle: int, periods: int) -> tuple[float, float]:
    """Point ``i`` by the scalar core directly: x at the period starts, and the time off the track."""
    values = {name: (str(columns[name][i]) if FIELDS[name].kind is str else float(columns[name][i]))
              for name in FIELDS}
    params = SliderParams(**{k: v for k, v in values.items() if k in SliderParams.__dataclass_fields__})
    inputs = Inputs(**{k: v for k, v in values.items() if k in Inputs.__dataclass_fields__})
    slider = Slider(params, inputs, cycle_log_size=None)
    f = inputs.excitation_frequency
    slider.advance_to((settle + periods + 0.5) / f)
    marks = {mark.n: mark for mark in slider.cycle_marks}
    start, end = marks[settle], marks[settle + periods]
    return (end.x - start.x) * f / periods, (end.flight_time - start.flight_time) * f / periods


def run(sweep: Sweep, tmp_path: Path, name: str, executor: object = None, **kwargs: object) -> dict[str, np.ndarray]:
    output = tmp_path / f"{name}.parquet"
    with (executor or SerialExecutor()) as ex:  # type: ignore[attr-defined]
        run_sweep(sweep, ex, output=output, engine=str(kwargs.pop("engine", ENGINE)), **kwargs)  # type: ignore[arg-type]
    return read_table(output)[0]


def test_every_row_is_the_scalar_cores_number(tmp_path: Path) -> None:
    sweep = parse_sweep(MIXED)
    columns = run(sweep, tmp_path, "mixed")
    assert np.array_equal(columns["point"], np.arange(sweep.size))
    regimes = set()
    for i in range(sweep.size):
        v, flight = scalar_mean_velocity(columns, i, 3, 4)
        assert columns["mean_velocity"][i] == pytest.approx(v, rel=1e-12, abs=1e-15), i
        assert columns["flight_fraction"][i] == pytest.approx(flight, rel=1e-12, abs=1e-12), i
        regimes.add(("flies" if flight > 0 else "contact", "moves" if v != 0 else "still"))
    assert {("flies", "moves"), ("contact", "moves"), ("contact", "still")} <= regimes
    assert np.allclose(columns["U"], columns["mean_velocity"] * columns["excitation_frequency"]
                       / (columns["gravity"] * columns["mu"]), rtol=1e-14)


def test_the_kostek_case_gives_the_exact_u(tmp_path: Path) -> None:
    sweep = parse_sweep("settle_periods: 4\nperiods: 5\nchunk_size: 7\ngrid:\n"
                        "  drive_ratio: [-0.6, 0.0, 0.3, 0.7, 0.95]\n  amplitude_ratio: [0.1, 0.4, 0.8, 0.95]\n")
    columns = run(sweep, tmp_path, "kostek")
    expected = u_map(columns["drive_ratio"], columns["amplitude_ratio"])
    assert np.allclose(columns["U"], expected, rtol=1e-9, atol=1e-12)
    assert np.sum(columns["U"] == 0.0) >= 3 and np.sum(columns["U"] != 0.0) >= 10


RESONANT = """\
settle_periods: 2
periods: 6
chunk_size: 2
fixed: {actuator: resonant, natural_frequency: 52, damping_ratio: 0.05, full_drive_acceleration: 15}
grid:
  drive_level: [0.4, 0.9]
  excitation_angle: [30, 90]
"""


def test_a_sweep_from_rest_runs_the_exciter_s_start_up(tmp_path: Path) -> None:
    """``initial: rest``: every resonant point's exciter starts at rest, its transient run exactly
    (the compiled engine, the single slider member by member: the same bits); the default,
    ``initial: steady``, is today's start on a running feeder."""
    steady = parse_sweep(RESONANT)
    rest = parse_sweep(RESONANT + "initial: rest\n")
    assert (steady.initial, rest.initial) == ("steady", "rest")
    from_rest = run(rest, tmp_path, "rest", engine="compiled")
    assert np.array_equal(from_rest["mean_velocity"], run(rest, tmp_path, "rest-scalar")["mean_velocity"])
    running = run(steady, tmp_path, "steady", engine="compiled")
    assert np.array_equal(running["mean_velocity"], run(parse_sweep(RESONANT + "initial: steady\n"), tmp_path,
                                                        "steady-explicit", engine="compiled")["mean_velocity"])
    assert not np.array_equal(from_rest["mean_velocity"], running["mean_velocity"])


@pytest.mark.timeout(120)
def test_the_default_engine_equals_the_scalar_loop(tmp_path: Path) -> None:
    sweep = parse_sweep(MIXED)
    default = run(sweep, tmp_path, "compiled", engine="compiled")
    scalar = run(sweep, tmp_path, "scalar", engine="scalar")
    # the compiled engine is the single slider bit for bit, except where its periodic shortcut
    # extrapolates a window: a sum of (settle + periods) repeats, rounding within ~1e-14 (test_batch)
    for name in ("mean_velocity", "flight_fraction", "stick_fraction", "U"):
        assert np.allclose(default[name], scalar[name], rtol=1e-12, atol=1e-15), name


def test_results_do_not_depend_on_workers_or_chunk_size(tmp_path: Path) -> None:
    reference = run(parse_sweep(MIXED), tmp_path, "serial")
    for workers, chunk in ((1, 24), (2, 5)):
        columns = run(parse_sweep(MIXED, chunk_size=chunk), tmp_path, f"dask{workers}_{chunk}",
                      DaskExecutor(workers=workers))
        assert list(columns) == list(reference)
        for name, values in reference.items():
            assert np.array_equal(columns[name], values), (workers, chunk, name)


def test_the_file_says_what_made_it(tmp_path: Path) -> None:
    sweep = parse_sweep(MIXED, "mixed.yaml")
    output = tmp_path / "meta.parquet"
    run_sweep(sweep, SerialExecutor(), output=output, engine=ENGINE)
    columns, meta = read_table(output)
    assert meta["friction_sim.version"] == __version__
    assert meta["friction_sim.sweep"] == MIXED and meta["friction_sim.sweep_file"] == "mixed.yaml"
    assert json.loads(meta["friction_sim.chunking"])["chunks"] == sweep.chunks == 8
    assert meta["friction_sim.periods"] == "4" and meta["friction_sim.settle_periods"] == "3"
    assert {"throw_number", "mu", "landing_friction", "excitation_amplitude", "lift_off_count",
            "landing_count", "stick_fraction"} <= set(columns)
    assert not parts_dir(output).exists()


class Interrupted(Exception):
    """Stands for Ctrl-C or a lost cluster in the middle of a sweep."""


class StopsAfter:
    """An executor that delivers ``count`` chunks, then fails (as a crash would)."""

    description = "stops"

    def __init__(self, count: int) -> None:
        self.count = count

    def run(self, sweep: Sweep, indices: Sequence[int], engine: str) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
        for index in indices[:self.count]:
            yield index, run_chunk(sweep, index, engine)
        raise Interrupted


def test_an_interrupted_sweep_resumes_without_writing_a_chunk_twice(tmp_path: Path) -> None:
    sweep = parse_sweep(MIXED)
    output = tmp_path / "resumed.parquet"
    first: list[int] = []
    with pytest.raises(Interrupted):
        run_sweep(sweep, StopsAfter(3), output=output, engine=ENGINE, on_chunk=first.append)
    assert first == [0, 1, 2] and not output.exists()
    assert sorted(p.name for p in parts_dir(output).glob("chunk-*")) == [f"chunk-00000{i}.parquet" for i in first]
    second: list[int] = []
    outcome = run_sweep(sweep, SerialExecutor(), output=output, engine=ENGINE, on_chunk=second.append)
    assert second == list(range(3, sweep.chunks)) and (outcome.computed, outcome.reused) == (5, 3)
    reference = run(sweep, tmp_path, "straight")
    columns = read_table(output)[0]
    for name, values in reference.items():
        assert np.array_equal(columns[name], values), name
    again = run_sweep(sweep, SerialExecutor(), output=output, engine=ENGINE, on_chunk=second.append)
    assert again.computed == 0 and again.executor == "already complete" and len(second) == 5


def test_another_sweeps_files_are_never_mixed_in(tmp_path: Path) -> None:
    output = tmp_path / "clash.parquet"
    with pytest.raises(Interrupted):
        run_sweep(parse_sweep(MIXED), StopsAfter(1), output=output, engine=ENGINE)
    other = parse_sweep(MIXED.replace("seed: 5", "seed: 6"))
    with pytest.raises(SweepRunError, match="holds the parts of another sweep"):
        run_sweep(other, SerialExecutor(), output=output, engine=ENGINE)
    with pytest.raises(SweepRunError, match="another chunk size"):
        run_sweep(parse_sweep(MIXED, chunk_size=4), SerialExecutor(), output=output, engine=ENGINE)
    done = run_sweep(other, SerialExecutor(), output=output, engine=ENGINE, fresh=True)
    assert done.computed == other.chunks and done.reused == 0
    with pytest.raises(SweepRunError, match="holds the results of another sweep"):
        run_sweep(parse_sweep(MIXED), SerialExecutor(), output=output, engine=ENGINE)


def test_a_part_is_never_written_twice(tmp_path: Path) -> None:
    path = tmp_path / "part.parquet"
    write_table(path, {"a": np.arange(3)}, {"k": "v"}, exclusive=True)
    with pytest.raises(ChunkExistsError, match="already written"):
        write_table(path, {"a": np.arange(4)}, {"k": "w"}, exclusive=True)
    columns, meta = read_table(path)
    assert list(columns["a"]) == [0, 1, 2] and meta == {"k": "v"}
    assert [p.name for p in tmp_path.iterdir()] == ["part.parquet"]  # no temporary file left


def test_the_progress_bar_counts_chunks_and_points(tmp_path: Path) -> None:
    import io

    stream = io.StringIO()
    sweep = parse_sweep(MIXED)
    run_sweep(sweep, SerialExecutor(), output=tmp_path / "p.parquet", engine=ENGINE,
              progress=SweepProgress("mixed", sweep.chunks, sweep.size, TerminalProgress(stream, interval=0.0)))
    lines = stream.getvalue().splitlines()
    assert len(lines) == sweep.chunks
    assert lines[-1].startswith("mixed [" + "#" * 30 + "] 8/8 chunks  24/24 points")
    assert "1/8 chunks  3/24 points" in lines[0]


def test_a_failing_chunk_is_named_and_picklable(monkeypatch: pytest.MonkeyPatch) -> None:
    import pickle

    from friction_sim.errors import SimulationFault
    from friction_sim.experiment import sweep_run

    def fails(*args: object, **kwargs: object) -> None:
        raise SimulationFault("more than 1000 events at t = 0.5 s")

    monkeypatch.setattr(sweep_run, "run_batch", fails)
    with pytest.raises(SweepRunError) as caught:
        run_chunk(parse_sweep(MIXED), 2, ENGINE)
    assert str(caught.value) == "chunk 2 (points 6..8): more than 1000 events at t = 0.5 s"
    assert str(pickle.loads(pickle.dumps(caught.value))) == str(caught.value)  # it crosses from a worker intact


RESONANT = """
name: tuning
settle_periods: 10
periods: 20
fixed: {actuator: resonant, excitation_angle: 30, mu: 0.5, drive_force: 0.0, full_drive_acceleration: 20.0}
grid:
  natural_frequency: {from: 46.0, to: 54.0, num: 5}
  damping_ratio: [0.02, 0.1]
  drive_level: [0.5, 1.0]
"""


def test_the_exciter_is_swept_in_steady_state_as_the_single_slider_runs_it(tmp_path: Path) -> None:
    """Issue 21: the exciter's parameters and the drive level are sweep axes (steady state)."""
    columns = run(parse_sweep(RESONANT), tmp_path, "tuning", engine="compiled")
    assert len(columns["mean_velocity"]) == 20 and set(columns["actuator"]) == {"resonant"}
    for i in range(20):
        expected, _ = scalar_mean_velocity(columns, i, 10, 20)
        assert columns["mean_velocity"][i] == pytest.approx(expected, rel=1e-12, abs=1e-18)
    by_level = {level: columns["mean_velocity"][columns["drive_level"] == level] for level in (0.5, 1.0)}
    assert np.all(by_level[1.0] >= by_level[0.5]) and np.any(by_level[1.0] > 0.0)


@pytest.mark.parametrize(("fixed", "axis", "named"), [
    ("actuator: resonant", "throw_number: [0.5, 1.0]", "drive_level"),
    ("actuator: resonant", "excitation_amplitude: [1.0, 2.0]", "drive_level"),
    ("actuator: force", "drive_level: [0.5, 1.0]", "excitation_amplitude"),
])
def test_a_sweep_of_the_input_its_actuator_ignores_is_refused(fixed: str, axis: str, named: str) -> None:
    text = f"periods: 10\nfixed: {{{fixed}}}\ngrid:\n  {axis}\n"
    with pytest.raises(FrictionSimError) as error:
        parse_sweep(text)
    message = str(error.value)
    assert "line 4" in message and axis.split(":")[0] in message and named in message and "\n" not in message
