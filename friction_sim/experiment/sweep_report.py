"""Maps from a sweep's results: what ``friction-sim sweep-report`` draws and tabulates.

The results of ``friction-sim sweep`` (one row per point) are grouped into
cells of two chosen input columns ``x`` and ``y`` within *slices*: one slice
per combination of the other design keys of the sweep (its grid and points
keys, read from the file's metadata), or of the columns named with
``slices``.  The points of one cell are the parts of that combination (the
Monte Carlo samples, when the sweep has ``random:`` keys): a cell holds their
mean and standard deviation of the chosen value (mean speed by default), the
share of them that do not move (U == 0 exactly: stuck for the whole window)
and the share that fly (flight_fraction > 0).  A column with more distinct
values than ``bins`` (a random one) is binned into ``bins`` equal intervals,
each cell at its interval's centre.

:func:`optimum_table` is the Markdown table of the best cell per slice.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from friction_sim.errors import FrictionSimError
from friction_sim.experiment.sweep_run import META, OUTPUTS
from friction_sim.io.parquet import Columns, read_table

MAX_SLICES = 12
DEFAULT_BINS = 40


class SweepReportError(FrictionSimError):
    """A report that cannot be made from these results (a missing column, too many slices)."""


@dataclass(frozen=True)
class SliceMap:
    """One slice: its key values and the cell arrays (rows: y, columns: x; NaN: no point)."""

    key: dict[str, Any]
    mean: np.ndarray
    spread: np.ndarray
    count: np.ndarray
    still: np.ndarray
    flying: np.ndarray

    @property
    def label(self) -> str:
        """The slice as ``name = value, ...`` ('' for the only slice)."""
        return ", ".join(f"{name} = {_fmt(value)}" for name, value in self.key.items())


@dataclass(frozen=True)
class SweepMaps:
    """Every slice's map over the same x and y cells."""

    source: Path
    x: str
    y: str
    value: str
    x_values: np.ndarray
    y_values: np.ndarray
    slices: tuple[SliceMap, ...]
    parts: int  # the most points in one cell (1: no spread to show)
    metadata: dict[str, str]


def _fmt(value: Any) -> str:
    return f"{value:.6g}" if isinstance(value, (float, np.floating)) else str(value)


def load_results(path: Path, names: Sequence[str]) -> tuple[Columns, dict[str, str]]:
    """The named columns of a sweep's results, refusing a file that lacks one."""
    from friction_sim.io.parquet import read_metadata

    meta = read_metadata(path)
    if META + "sweep" not in meta:
        raise SweepReportError(f"{path}: not the results of friction-sim sweep (no sweep in its metadata)")
    available = set(json.loads(meta[META + "columns"])["inputs"]) | set(OUTPUTS)
    missing = [name for name in names if name not in available]
    if missing:
        raise SweepReportError(f"{path}: no column {missing[0]!r}; inputs and outputs: "
                               f"{', '.join(sorted(available - {'point'}))}")
    return read_table(path, list(dict.fromkeys(names)))


def _codes(values: np.ndarray, bins: int) -> tuple[np.ndarray, np.ndarray]:
    """Cell index of every value and the cells' values (binned when too many distinct)."""
    distinct, codes = np.unique(values, return_inverse=True)
    if distinct.size <= bins or distinct.dtype.kind not in "fiu":
        return codes.reshape(-1), distinct
    edges = np.linspace(float(distinct[0]), float(distinct[-1]), bins + 1)
    codes = np.clip(np.searchsorted(edges, values, side="right") - 1, 0, bins - 1)
    return codes, 0.5 * (edges[:-1] + edges[1:])


def build_maps(path: Path, x: str, y: str, *, value: str = "mean_velocity", slices: Sequence[str] | None = None,
               bins: int = DEFAULT_BINS) -> SweepMaps:
    """Group the results at ``path`` into maps of ``value`` over (x, y), per slice."""
    if x == y:
        raise SweepReportError(f"--x and --y are both {x!r}: choose two parameters")
    from friction_sim.io.parquet import read_metadata

    meta = read_metadata(path)
    if slices is None:
        design = json.loads(meta.get(META + "columns", "{}")).get("design", [])
        slices = [key for key in design if key not in (x, y)]
    for name in slices:
        if name in (x, y):
            raise SweepReportError(f"--slice {name}: it is already the {'x' if name == x else 'y'} axis")
    columns, meta = load_results(path, [x, y, value, *slices, "U", "flight_fraction"])
    if columns[value].dtype.kind not in "fiu":
        raise SweepReportError(f"--value {value}: not a numeric column")
    x_codes, x_values = _codes(columns[x], bins)
    y_codes, y_values = _codes(columns[y], bins)
    slice_codes = np.zeros(x_codes.size, dtype=np.int64)
    if slices:
        keys = np.stack([np.unique(columns[s], return_inverse=True)[1].reshape(-1) for s in slices])
        slice_codes = np.unique(keys, axis=1, return_inverse=True)[1].reshape(-1)
    count = int(slice_codes.max()) + 1 if slice_codes.size else 0
    if count > MAX_SLICES:
        raise SweepReportError(f"{count} slices ({', '.join(slices)}): at most {MAX_SLICES}; name the slice "
                               "columns with --slice, or report a smaller sweep")
    shape = (y_values.size, x_values.size)
    cell = (y_codes * x_values.size + x_codes).astype(np.int64)
    values = columns[value].astype(float)
    maps = []
    for k in range(count):
        rows = slice_codes == k
        first = int(np.argmax(rows))
        maps.append(_slice_map({s: _item(columns[s][first]) for s in slices},
                               cell[rows], values[rows], columns["U"][rows], columns["flight_fraction"][rows],
                               shape))
    parts = max(int(np.nanmax(m.count)) for m in maps) if maps else 0
    return SweepMaps(Path(path), x, y, value, x_values, y_values, tuple(maps), parts, meta)


def _item(value: Any) -> Any:
    return value.item() if isinstance(value, np.generic) else value


def _slice_map(key: dict[str, Any], cell: np.ndarray, values: np.ndarray, u: np.ndarray, flight: np.ndarray,
               shape: tuple[int, int]) -> SliceMap:
    """The cell statistics of one slice."""
    size = shape[0] * shape[1]
    count = np.bincount(cell, minlength=size).astype(float)
    total = np.bincount(cell, weights=values, minlength=size)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = total / count
        square = np.bincount(cell, weights=(values - mean[cell]) ** 2, minlength=size)
        spread = np.sqrt(square / count)
        still = np.bincount(cell, weights=(u == 0.0).astype(float), minlength=size) / count
        flying = np.bincount(cell, weights=(flight > 0.0).astype(float), minlength=size) / count
    return SliceMap(key, mean.reshape(shape), spread.reshape(shape), count.reshape(shape), still.reshape(shape),
                    flying.reshape(shape))


def optimum_table(maps: SweepMaps) -> str:
    """Markdown: per slice, the cell with the largest mean value, its spread,
    parts and the share of them flying, and the no-motion share over the slice."""
    unit = " [m/s]" if maps.value == "mean_velocity" else ""
    head = [*(maps.slices[0].key if maps.slices else {}), f"best {maps.x}", f"best {maps.y}",
            f"{maps.value}{unit}", "spread (std over parts)", "parts", "flying parts", "cells without motion"]
    rows = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for piece in maps.slices:
        if np.all(np.isnan(piece.mean)):
            continue
        iy, ix = np.unravel_index(int(np.nanargmax(piece.mean)), piece.mean.shape)
        present = piece.count > 0
        frozen = int(np.sum(piece.still[present] == 1.0))
        cells = [*(_fmt(v) for v in piece.key.values()), _fmt(maps.x_values[ix]), _fmt(maps.y_values[iy]),
                 f"{piece.mean[iy, ix]:.6g}", f"{piece.spread[iy, ix]:.3g}", str(int(piece.count[iy, ix])),
                 f"{piece.flying[iy, ix]:.0%}", f"{frozen}/{int(np.sum(present))}"]
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def report_text(maps: SweepMaps, picture: Path | None) -> str:
    """The Markdown report: what was mapped, from which sweep, and the optimum table."""
    meta = maps.metadata
    sweep_name = meta.get(META + "sweep_file", "?")
    lines = [f"# Sweep report: {maps.value} over {maps.x} and {maps.y}", "",
             f"Results `{maps.source}` of the sweep `{sweep_name}` (friction_sim {meta.get(META + 'version', '?')}, "
             f"{meta.get(META + 'periods', '?')} periods averaged after {meta.get(META + 'settle_periods', '?')}).",
             f"Cells: {maps.x_values.size} x {maps.y_values.size}; up to {maps.parts} part(s) per cell "
             "(spread: the standard deviation over them); no motion: U = 0 exactly; flying: flight_fraction > 0.",
             ""]
    if picture is not None:
        lines += [f"![{maps.value} map]({picture.name})", ""]
    lines += ["## Optimum per slice", "", optimum_table(maps)]
    return "\n".join(lines)


def finite_range(arrays: Sequence[np.ndarray]) -> tuple[float, float]:
    """The smallest and largest finite value over ``arrays`` (0, 1 if none)."""
    finite = [a[np.isfinite(a)] for a in arrays]
    values = np.concatenate(finite) if finite else np.array([])
    if values.size == 0:
        return 0.0, 1.0
    low, high = float(values.min()), float(values.max())
    return (low, high) if high > low else (low - 0.5 * (abs(low) or 1.0), high + 0.5 * (abs(high) or 1.0))


__all__ = ["DEFAULT_BINS", "MAX_SLICES", "SliceMap", "SweepMaps", "SweepReportError", "build_maps",
           "finite_range", "load_results", "optimum_table", "report_text"]
