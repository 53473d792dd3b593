"""Measured operating points for ``friction-sim calibrate``: the CSV and the fixed settings.

A measurements file is a CSV with a header row.  Each row is one operating
point: the settings that vary between points, in the sweeps' vocabulary (any
field of the model, ``core/model/spec.py``'s PLANT and INPUTS, or a derived
key: ``throw_number``, ``amplitude_ratio``, ``drive_ratio``;
:data:`friction_sim.experiment.sweep.DERIVED`), then ``mean_speed`` [m/s], the
speed timed over a length of track, and optionally ``std`` [m/s], its standard
deviation (:data:`MEAN_SPEED` and :data:`SPEED_STD` bound both).  Blank lines
and lines starting with ``#`` are skipped; the file is read as UTF-8 with or
without a byte order mark (Excel's "CSV UTF-8" writes one).  For example::

    drive_level,excitation_frequency,mean_speed,std
    0.4,50,0.00102,0.00003
    0.6,50,0.00231,0.00004

The settings that do not vary (the part's mass, the track's slope, the
exciter's data) come from a YAML mapping in the same vocabulary, or a ROS 2
parameters file (``/**: ros__parameters:``, as ``slider --params`` reads), and
from ``--set name=value`` flags; what is given nowhere takes its default.  A
name that is no setting is refused with the closest one.

Everything is checked before any fitting: a bad file is refused with its
path, the line and the reason, as scenarios are (:class:`MeasurementsError`).
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from friction_sim.core.model import spec
from friction_sim.errors import FrictionSimError, ParameterError
from friction_sim.experiment.calibration_fit import closest
from friction_sim.experiment.sweep import DERIVED, FIELDS, KEYS, setting_of
from friction_sim.io.paramfile import is_parameters_file, node_parameters, read_yaml_mapping

#: The measured quantity and its optional standard deviation.
SPEED, STD = "mean_speed", "std"
#: Their ranges: no feeder conveys at a kilometre a second, and a deviation below a picometre a
#: second is no timing's (nor one that the residuals, divided by it, survive in floating point).
MEAN_SPEED = spec.Setting(SPEED, 0.0, "m/s", "measured mean speed", -1e3, 1e3)
SPEED_STD = spec.Setting(STD, 1e-5, "m/s", "standard deviation of a measured mean speed", 1e-12, 1e3)
#: Encoding of a CSV: UTF-8, its byte order mark skipped (Excel's "CSV UTF-8" writes one).
ENCODING = "utf-8-sig"


class MeasurementsError(FrictionSimError):
    """A measurements file or fixed setting that cannot be used, with where and why."""


@dataclass(frozen=True)
class Measurements:
    """The operating points: ``settings`` name -> one value per point (numbers,
    or text for a text setting), the measured ``speed`` [m/s] and its ``std``
    (None: not given), from ``source`` (for messages)."""

    settings: dict[str, np.ndarray]
    speed: np.ndarray
    std: np.ndarray | None
    source: str

    @property
    def count(self) -> int:
        return int(self.speed.size)


def read_measurements(path: Path) -> Measurements:
    """The points of a measurements CSV, each value checked against its setting's range."""
    where = str(path)
    columns = read_table(path, "operating point", _check_header, _setting)
    speed = np.asarray(columns.pop(SPEED), dtype=float)
    std = np.asarray(columns.pop(STD), dtype=float) if STD in columns else None
    settings = {name: np.asarray(values) if name in FIELDS and FIELDS[name].kind is str else
                np.asarray(values, dtype=float) for name, values in columns.items()}
    return Measurements(settings, speed, std, where)


def read_csv_rows(path: Path, row: str) -> tuple[int, list[str], list[tuple[int, list[str]]]]:
    """(the header's line, its names, the body's (line, cells)) of a CSV of one
    ``row`` per line: blank lines and ``#`` lines skipped, UTF-8 with or without
    a byte order mark; a file that cannot be read, or has no rows, refused."""
    where = str(path)
    try:
        with Path(path).open(newline="", encoding=ENCODING) as stream:
            lines = list(csv.reader(stream))
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise MeasurementsError(f"{where}: cannot read: {error}") from None
    rows = [(number, cells) for number, cells in enumerate(lines, start=1)
            if any(cell.strip() for cell in cells) and not cells[0].lstrip().startswith("#")]
    if not rows:
        raise MeasurementsError(f"{where}: empty (expected a header row and one row per {row})")
    (header_line, header), body = rows[0], rows[1:]
    return header_line, [name.strip() for name in header], body


def read_table(path: Path, row: str, check_header: Callable[[str, int, list[str]], None],
               setting: Callable[[str], spec.Setting]) -> dict[str, list[Any]]:
    """A CSV's columns by name (see :func:`read_csv_rows`), the header checked by
    ``check_header`` and every cell by its column's ``setting``; a bad file is
    refused with its path, the line and the reason."""
    where = str(path)
    header_line, names, body = read_csv_rows(path, row)
    check_header(where, header_line, names)
    columns: dict[str, list[Any]] = {name: [] for name in names}
    for line, cells in body:
        if len(cells) != len(names):
            raise MeasurementsError(f"{where}: line {line}: {len(cells)} values, the header has {len(names)}")
        for name, cell in zip(names, cells):
            columns[name].append(checked_cell(where, line, name, cell.strip(), setting(name)))
    if not body:
        raise MeasurementsError(f"{where}: no {row}s (only the header)")
    return columns


def _check_header(where: str, line: int, names: list[str]) -> None:
    unknown = [name for name in names if name not in (*KEYS, SPEED, STD)]
    if unknown:
        raise MeasurementsError(f"{where}: line {line}: unknown column '{unknown[0]}' (columns: the model's settings, "
                                f"{', '.join(DERIVED)}, {SPEED} [m/s] and optionally {STD} [m/s])"
                                + closest(unknown[0], (*KEYS, SPEED, STD)))
    repeated = next((name for name in names if names.count(name) > 1), None)
    if repeated:
        raise MeasurementsError(f"{where}: line {line}: column '{repeated}' given twice")
    if SPEED not in names:
        raise MeasurementsError(f"{where}: line {line}: no '{SPEED}' column (the measured mean speed [m/s])")
    targets = [DERIVED[name][0] if name in DERIVED else name for name in names if name not in (SPEED, STD)]
    twice = next((name for name in targets if targets.count(name) > 1), None)
    if twice:
        raise MeasurementsError(f"{where}: line {line}: {twice} is set by two columns")


def _setting(name: str) -> spec.Setting:
    return setting_of(name) if name in KEYS else {SPEED: MEAN_SPEED, STD: SPEED_STD}[name]


def checked_cell(where: str, line: int, name: str, cell: str, setting: spec.Setting) -> Any:
    """One cell, checked: a finite number in its setting's range (a text setting: one of its choices)."""
    if setting.kind is str:
        try:
            return setting.check(cell)
        except ParameterError as error:
            raise MeasurementsError(f"{where}: line {line}: {error}") from None
    try:
        value = float(cell)
    except ValueError:
        raise MeasurementsError(f"{where}: line {line}: {name} = {cell!r} is not a number") from None
    try:  # (inf and NaN too: the setting's check refuses them with its range)
        setting.check(value)
    except ParameterError as error:
        raise MeasurementsError(f"{where}: line {line}: {error}") from None
    return value


def read_fixed(path: Path | None, flags: list[str]) -> dict[str, Any]:
    """The fixed settings: a YAML mapping or a ROS 2 parameters file (its ``/**``
    or ``slider`` section), then ``name=value`` flags; each checked.  A name
    that is no setting is refused with the closest one, in a mapping and in a
    flag (a parameters file's other node parameters are the node's: left out)."""
    values: dict[str, Any] = {}
    if path is not None:
        values.update(_checked(str(path), _fixed_file(path)))
    for flag in flags:
        name, sep, text = (part.strip() for part in flag.partition("="))
        if not sep or not name:
            raise MeasurementsError(f"--set {flag!r}: expected name=value")
        if name not in KEYS:
            raise MeasurementsError(f"--set {name}={text}: no such setting{closest(name, KEYS)}")
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError:
            raise MeasurementsError(f"--set {name}={text}: not a value") from None
        values.update(_checked(f"--set {name}={text}", {name: value}))
    return values


def _checked(where: str, values: dict[str, Any]) -> dict[str, Any]:
    """Each value checked by its setting; the first bad one refused, saying where it came from."""
    try:
        return {name: setting_of(name).check(value) for name, value in values.items()}
    except ParameterError as error:
        raise MeasurementsError(f"{where}: {error}") from None


def _fixed_file(path: Path) -> dict[str, Any]:
    """A plain mapping of settings, or a ROS 2 parameters file (read once, by the one reader of those)."""
    document = read_yaml_mapping(path, "a mapping of settings (or a ROS 2 parameters file)")
    if is_parameters_file(document, "slider"):  # the node's other parameters are not the model's
        return {name: value for name, value in node_parameters(document, "slider").items() if name in KEYS}
    unknown = next((str(name) for name in document if name not in KEYS), None)
    if unknown is not None:
        raise MeasurementsError(f"{path}: {unknown}: no such setting{closest(unknown, KEYS)}")
    return document


__all__ = ["ENCODING", "MEAN_SPEED", "SPEED", "SPEED_STD", "STD", "Measurements", "MeasurementsError", "checked_cell",
           "read_csv_rows", "read_fixed", "read_measurements", "read_table"]
