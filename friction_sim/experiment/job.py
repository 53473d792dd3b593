"""What an experiment is and what it yields, without ROS.

:class:`ExperimentSpec` is everything :func:`friction_sim.experiment.runner.run_experiment`
needs: the plant, its initial inputs, a schedule of
:class:`~friction_sim.core.model.commands.Command` records and the node settings.
:class:`ExperimentResult` holds the time series a run yields (each a compact
:class:`Series`), :class:`Status` the live view for a status line.

The runner writes a *scenario metadata record* into the recording
(:func:`scenario_metadata`): the experiment's name, duration, initial target,
the schedule as JSON and the simulation time it started at, plus the scenario
file's text for humans.  :func:`read_scenario_metadata` reads it back, so a
report is rebuilt from the recording alone without parsing the scenario file.
This module imports neither rclpy nor the message packages: the scenario
parser and the report depend on it, not on the runner.
"""

from __future__ import annotations

import json
import os
import tempfile
from array import array
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Generic, NamedTuple, TypeVar, cast, overload

from friction_sim.core.model import spec as settings
from friction_sim.core.model.commands import Command
from friction_sim.core.model.params import Inputs, SliderParams

#: Name of the MCAP metadata record that describes an experiment's scenario.
SCENARIO_METADATA = "friction_sim_scenario"
#: A row of a :class:`Series`: a tuple of floats, time first.
Row = TypeVar("Row", bound=tuple[float, ...])
#: Values per block of a :class:`Series` (64 KiB of doubles, whole rows of it).
SERIES_BLOCK = 8192


@dataclass(frozen=True)
class OperatorAction:
    """What an operator does at simulation time ``t`` (relative to the start),
    beside the schedule: ``send`` publishes a command as it is, one the slider
    refuses (its refusal is recorded on rejected_commands); ``calls`` calls the
    slider's simulation-control services (pause, step, resume, reset) in order.
    Neither changes the inputs the report's segments are made of."""

    t: float
    send: Command | None = None
    calls: tuple[str, ...] = ()


@dataclass(frozen=True)
class ExperimentSpec:
    """Everything an experiment needs (see ``run_experiment``).

    ``schedule`` holds the commands to publish, at simulation times relative
    to the experiment's start; ``log_path`` records the run (the slider's
    recording) to that MCAP file; ``notes`` are extra text entries of the
    scenario metadata record (the scenario file's text, say); ``operator``
    holds what an operator does beside the schedule (:class:`OperatorAction`).
    """

    duration: float
    schedule: Sequence[Command] = ()
    plant: SliderParams = SliderParams()
    inputs: Inputs = Inputs()
    controller: bool = False
    controller_parameters: dict[str, Any] = field(default_factory=dict)
    slider_parameters: dict[str, Any] = field(default_factory=dict)
    real_time_factor: float = float(settings.REAL_TIME_FACTOR.default)
    log_path: Path | None = None
    log_rate: float = float(settings.LOG_RATE.default)
    name: str = "experiment"
    notes: dict[str, str] = field(default_factory=dict)
    operator: Sequence[OperatorAction] = ()
    #: Lockstep: the slider advances only when this driver and the controller have answered.
    lockstep: bool = False

    @property
    def initial_target(self) -> float | None:
        """The target the controller starts with (None: open loop, or it stands by)."""
        if not self.controller or "target_speed" not in self.controller_parameters:
            return None
        return float(self.controller_parameters["target_speed"])


@dataclass(frozen=True)
class Status:
    """A live view of a running experiment (for the status line).

    ``amplitude`` is the excitation the plant acts on: Pa [N] for the force
    actuator; for the resonant one (``drive_level`` not None) the slideway's
    normal acceleration amplitude in steady state [m/s^2] at that drive level
    and frequency, its Pa being no input of that plant."""

    t: float
    duration: float
    target: float | None
    mean_speed: float
    amplitude: float
    drive_force: float
    frequency: float
    drive_level: float | None = None

    def line(self) -> str:
        """One line for a terminal: time, target, mean speed and the inputs in force."""
        target = "open loop" if self.target is None else f"{self.target * 1e3:.3f} mm/s"
        excitation = (f"Pa {self.amplitude:6.3f} N" if self.drive_level is None else
                      f"drive {self.drive_level:5.3f} | slideway {self.amplitude:6.3f} m/s^2")
        return (f"t {self.t:6.2f}/{self.duration:g} s | target {target:>12} | mean speed "
                f"{self.mean_speed * 1e3:8.4f} mm/s | {excitation} | Fd {self.drive_force:6.3f} N "
                f"| f {self.frequency:g} Hz")


class Series(Sequence[Row], Generic[Row]):
    """A time series that only grows: rows of ``width`` floats, time first,
    kept packed in ``array('d')`` blocks of :data:`SERIES_BLOCK` values.

    Why not a list of tuples: an experiment's series get a row per
    mean-velocity sample (50 a simulated second), and a tuple of two Python
    floats costs about 110 bytes where its values are 16.  Why blocks, not
    one array: a full block stays where it is, so an hour's megabytes grow
    without reallocations that copy them and leave a hole in the heap as
    large as all before.  It reads as the list did: a sequence of tuples of
    floats (``series[-1][1]``, ``for t, v in series``, ``len``,
    ``reversed``), the same values (doubles either way).  One thread
    appends (the controller's listener runs on its own); a reader on another
    sees whole rows, every row up to some recent one.

    Full blocks beyond the newest :data:`RESIDENT_BLOCKS` go to a temporary
    file of the series' own (unnamed: the system removes it with the last
    reference), read back when asked for: an hour's series no longer grow
    the process (1.6 kB a simulated second, 6 % of the soak's memory over
    the hour).  Where the file cannot be written the blocks stay in memory.
    """

    __slots__ = ("_blocks", "_per_block", "_spill", "width")

    def __init__(self, width: int, rows: Iterable[Row] = ()) -> None:
        if not 1 <= width <= SERIES_BLOCK:
            raise ValueError(f"a series has rows of 1 to {SERIES_BLOCK} values, not {width}")
        self.width = width
        self._per_block = SERIES_BLOCK // width * width  # values a block holds: whole rows
        # Replaced, never changed but for its last block's growth: a reader's reference stays whole.
        self._blocks: list[array[float] | _Spilled] = [array("d")]
        self._spill: _SpillFile | None = None  # (made with the first block spilled)
        self.extend(rows)

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickled as its rows (a spilled block's file stays with this process)."""
        return (Series, (self.width, list(self)))

    def append(self, row: Row) -> None:
        """Add ``row`` (``width`` numbers) at the end; a ValueError (nothing added) for another width."""
        values = array("d", row)  # (converted whole first: a bad value adds nothing)
        if len(values) != self.width:
            raise ValueError(f"a row of {len(values)} values in a series of {self.width}")
        self._add(values)

    def extend(self, rows: Iterable[Row]) -> None:
        """Add ``rows`` at the end: all of them, or none if one is not ``width`` numbers (an error)."""
        values: array[float] = array("d")
        for row in rows:
            if len(row) != self.width:
                raise ValueError(f"a row of {len(row)} values in a series of {self.width}")
            values.extend(row)
        self._add(values)

    def _add(self, values: array[float]) -> None:
        """Append whole rows: fill the last block, then start new ones (each extend is one C call,
        atomic under the GIL, and ends on a row's end)."""
        at = 0
        while at < len(values):
            last = self._blocks[-1]
            assert isinstance(last, array), "the last block is in memory"
            if len(last) == self._per_block:
                last = array("d")
                self._blocks = [*self._spilled(self._blocks), last]
            end = at + self._per_block - len(last)
            last.extend(values[at:end])
            at = end

    def _spilled(self, blocks: list[array[float] | _Spilled]) -> list[array[float] | _Spilled]:
        """``blocks`` (all full) with the one :data:`RESIDENT_BLOCKS` from the newest written to the file."""
        index = len(blocks) - RESIDENT_BLOCKS
        block = blocks[index] if index >= 0 else None
        if not isinstance(block, array):
            return blocks
        if self._spill is None:
            self._spill = _SpillFile.make()
        spilled = self._spill.put(block) if self._spill is not None else None
        if spilled is None:
            return blocks
        return [*blocks[:index], spilled, *blocks[index + 1:]]

    def _values(self, block: array[float] | _Spilled) -> array[float]:
        """A block's values (read back from the file if it was spilled)."""
        if isinstance(block, array):
            return block
        assert self._spill is not None, "a spilled block has its file"
        return self._spill.get(block)

    def column(self, index: int) -> array[float]:
        """Field ``index`` of every row (0: the times), as a new array."""
        if not 0 <= index < self.width:
            raise IndexError(f"column {index} of a series of {self.width}")
        values: array[float] = array("d")
        for block in self._blocks:
            values.extend(self._values(block)[index::self.width])
        return values

    def since(self, start: float) -> Series[Row]:
        """The rows at ``t >= start``, their times made relative to ``start`` (``t - start``)."""
        return Series(self.width, (cast(Row, (row[0] - start, *row[1:])) for row in self if row[0] >= start))

    @property
    def nbytes(self) -> int:
        """Bytes its values take (8 a value, in memory or spilled; the last block's spare room not counted)."""
        return sum(block.values if isinstance(block, _Spilled) else len(block) for block in self._blocks) * 8

    def __len__(self) -> int:
        blocks = self._blocks
        return ((len(blocks) - 1) * self._per_block + len(blocks[-1])) // self.width

    @overload
    def __getitem__(self, index: int) -> Row: ...

    @overload
    def __getitem__(self, index: slice) -> Series[Row]: ...

    def __getitem__(self, index: int | slice) -> Row | Series[Row]:
        if isinstance(index, slice):
            return Series(self.width, (self[k] for k in range(len(self))[index]))
        blocks = self._blocks  # (one look: another thread may append meanwhile; n from the same blocks)
        n = ((len(blocks) - 1) * self._per_block + len(blocks[-1])) // self.width
        at = index + n if index < 0 else index
        if not 0 <= at < n:
            raise IndexError(f"row {index} of a series of {n}")
        block, offset = divmod(at * self.width, self._per_block)
        return cast(Row, tuple(self._values(blocks[block])[offset:offset + self.width]))

    def __iter__(self) -> Iterator[Row]:
        for block in self._blocks:
            values = iter(self._values(block))
            yield from cast(Iterator[Row], zip(*[values] * self.width))

    def __eq__(self, other: object) -> bool:
        """Equal to a series of the same rows, or to a list or tuple of them (what it replaced)."""
        if isinstance(other, (Series, list, tuple)):
            return len(other) == len(self) and all(tuple(theirs) == ours for theirs, ours in zip(other, self))
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]  # mutable, like the list it replaced

    def __repr__(self) -> str:
        return f"Series(width={self.width}, {len(self)} rows)"


#: Full blocks of a :class:`Series` kept in memory, the newest (what a status line and a
#: controller's report read); older ones go to the series' file.
RESIDENT_BLOCKS = 2


class _Spilled(NamedTuple):
    """A full block of a :class:`Series` in its file: where, and how many values (its ``len``)."""

    offset: int
    values: int


class _SpillFile:
    """A series' unnamed temporary file of spilled blocks: written by the appending thread
    (``pwrite`` at its end), read by any (``pread``: no shared position)."""

    def __init__(self, stream: IO[bytes]) -> None:
        self._stream = stream
        self._end = 0

    @classmethod
    def make(cls) -> _SpillFile | None:
        """A new file, or None where none can be made (the blocks then stay in memory)."""
        try:
            return cls(tempfile.TemporaryFile(prefix="friction_sim-series-"))
        except OSError:
            return None

    def put(self, block: array[float]) -> _Spilled | None:
        """Write ``block`` at the end; where it lies, or None if it could not be written whole."""
        data = block.tobytes()
        try:
            written = os.pwrite(self._stream.fileno(), data, self._end)
        except OSError:
            return None
        if written != len(data):
            return None
        spilled = _Spilled(self._end, len(block))
        self._end += len(data)
        return spilled

    def get(self, block: _Spilled) -> array[float]:
        """The values of a spilled block."""
        values: array[float] = array("d")
        values.frombytes(os.pread(self._stream.fileno(), 8 * block.values, block.offset))
        return values


def _pairs() -> Series[tuple[float, float]]:
    """An empty series of (t, value) rows."""
    return Series(2)


def _drive_rows() -> Series[tuple[float, float, float, float]]:
    """An empty series of (t, drive level, drive frequency, per drive) rows."""
    return Series(4)


@dataclass
class ExperimentResult:
    """Time series of one run (simulation time in s relative to its start; speeds in m/s, forces in N).

    ``amplitude`` is the controller's output at the time it decided;
    ``drive`` (resonant actuator) its drive commands then: (t, drive level,
    drive frequency [Hz], the latest window's slideway amplitude per unit drive
    [m/s^2], nan until one is read); ``commands`` are the scheduled commands as
    the driver published them, at the time it did.  The sampled series are
    :class:`Series` (a row per sample, kept as packed doubles: a run of hours
    must not grow by a Python tuple per sample); ``commands`` stays a list (a
    command per schedule entry).
    """

    mean_velocity: Series[tuple[float, float]] = field(default_factory=_pairs)
    amplitude: Series[tuple[float, float]] = field(default_factory=_pairs)
    drive: Series[tuple[float, float, float, float]] = field(default_factory=_drive_rows)
    commands: list[Command] = field(default_factory=list)
    duration: float = 0.0


# -- the scenario metadata record ----------------------------------------------------


@dataclass(frozen=True)
class ScenarioRecord:
    """What a recording's scenario metadata record says (times relative to ``start_ns``)."""

    name: str
    duration: float
    initial_target: float | None
    schedule: tuple[Command, ...]
    start_ns: int | None


def schedule_json(schedule: Sequence[Command]) -> str:
    """A schedule as JSON: a list of ``[t, name, {field: value}]`` (full float precision)."""
    return json.dumps([[command.t, command.name, dict(command.values)] for command in schedule])


def schedule_from_json(text: str) -> tuple[Command, ...]:
    """The schedule :func:`schedule_json` wrote (a ParameterError on an unknown command)."""
    return tuple(Command(float(t), str(name), {str(k): float(v) for k, v in values.items()})
                 for t, name, values in json.loads(text))


def scenario_metadata(spec: ExperimentSpec, start_ns: int) -> dict[str, str]:
    """The scenario metadata record of a run that started at simulation time ``start_ns``."""
    target = spec.initial_target
    return {
        **spec.notes, "name": spec.name, "duration": repr(float(spec.duration)),
        "initial_target": "" if target is None else repr(target), "schedule": schedule_json(spec.schedule),
        "start_ns": str(int(start_ns)),
    }


def read_scenario_metadata(meta: Mapping[str, str]) -> ScenarioRecord | None:
    """The record :func:`scenario_metadata` wrote, or None if ``meta`` has no
    schedule (a recording made before the record carried one)."""
    if "schedule" not in meta or "duration" not in meta:
        return None
    target = meta.get("initial_target", "")
    start = meta.get("start_ns")
    return ScenarioRecord(
        name=meta.get("name", "experiment"), duration=float(meta["duration"]),
        initial_target=float(target) if target else None, schedule=schedule_from_json(meta["schedule"]),
        start_ns=int(start) if start else None,
    )


__all__ = [
    "RESIDENT_BLOCKS", "SCENARIO_METADATA", "SERIES_BLOCK", "ExperimentResult", "ExperimentSpec", "OperatorAction",
    "ScenarioRecord", "Series", "Status", "read_scenario_metadata", "scenario_metadata", "schedule_from_json",
    "schedule_json",
]
