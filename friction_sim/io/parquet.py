"""Parquet tables of columns: sweep results written atomically, read back whole.

A table here is a mapping column name -> 1-D numpy array (numbers, or str for
text columns) plus string metadata, stored in the Parquet schema's key-value
metadata.  Every write goes to a temporary file beside the target first and
is then moved into place in one step, so a reader (or a resumed sweep) never
sees half a file: :func:`write_table` with ``exclusive=True`` also refuses to
replace a file that exists, which is how a sweep proves it never writes a
chunk twice.

pyarrow is imported when a table is read or written, so nothing else in the
package pays for it.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from friction_sim.errors import FrictionSimError

Columns = dict[str, NDArray[Any]]


class ParquetError(FrictionSimError):
    """A results file that cannot be read or written (missing, not Parquet, ours but incomplete)."""


class ChunkExistsError(ParquetError):
    """An exclusive write found its target already there (a chunk would be written twice)."""


def _pyarrow() -> tuple[Any, Any]:
    """pyarrow and pyarrow.parquet, or a one-line refusal naming the missing package."""
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError as error:  # pragma: no cover - pyarrow is a requirement; this is the message if it is not
        # pyarrow 26 refuses NumPy 1.x (Ubuntu 24.04's is 1.26): name the range that works with this NumPy.
        wanted = "pyarrow>=25" if int(np.__version__.split(".")[0]) >= 2 else "pyarrow>=25,<26"
        raise ParquetError(f"Parquet needs pyarrow: pip install '{wanted}' ({error})") from error
    return pyarrow, pyarrow.parquet


def _table(columns: Mapping[str, NDArray[Any]], metadata: Mapping[str, str]) -> Any:
    pa, _ = _pyarrow()
    arrays = [pa.array(np.asarray(values).astype(str) if np.asarray(values).dtype.kind in "OU"
                       else np.asarray(values)) for values in columns.values()]
    table = pa.table(arrays, names=list(columns))
    return table.replace_schema_metadata({k.encode(): v.encode() for k, v in metadata.items()})


def write_table(path: Path, columns: Mapping[str, NDArray[Any]], metadata: Mapping[str, str], *,
                exclusive: bool = False) -> Path:
    """Write ``columns`` and ``metadata`` to ``path`` atomically (temporary file, then a
    rename); with ``exclusive``, raise :class:`ChunkExistsError` if ``path`` exists."""
    _, pq = _pyarrow()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        pq.write_table(_table(columns, metadata), tmp, compression="zstd")
        if exclusive:
            try:
                os.link(tmp, path)  # fails if the target exists: never two writes of one chunk
            except FileExistsError:
                raise ChunkExistsError(f"{path}: already written") from None
        else:
            os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
    return path


def read_metadata(path: Path) -> dict[str, str]:
    """The key-value metadata of a Parquet file (its schema only is read)."""
    _, pq = _pyarrow()
    try:
        schema = pq.read_schema(path)
    except (OSError, ValueError) as error:
        raise ParquetError(f"{path}: not a readable Parquet file: {error}") from error
    raw: dict[bytes, bytes] = schema.metadata or {}
    return {key.decode(): value.decode() for key, value in raw.items()}


def read_table(path: Path, names: Sequence[str] | None = None) -> tuple[Columns, dict[str, str]]:
    """The columns (all, or ``names``) and the metadata of a Parquet file."""
    _, pq = _pyarrow()
    try:
        table = pq.read_table(path, columns=list(names) if names is not None else None)
    except (OSError, ValueError, KeyError) as error:
        raise ParquetError(f"{path}: not a readable Parquet file: {error}") from error
    columns: Columns = {}
    for name in table.column_names:
        values = table.column(name).to_numpy()
        columns[name] = values.astype(str) if values.dtype.kind == "O" else values
    raw: dict[bytes, bytes] = table.schema.metadata or {}
    return columns, {key.decode(): value.decode() for key, value in raw.items()}


def combine(parts: Sequence[Path], path: Path, metadata: Mapping[str, str]) -> int:
    """Concatenate the part files, in order, into one file at ``path`` (atomically),
    with ``metadata``; return the number of rows."""
    pa, pq = _pyarrow()
    tables = [pq.read_table(part) for part in parts]
    table = pa.concat_tables(tables).replace_schema_metadata(
        {k.encode(): v.encode() for k, v in metadata.items()})
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        pq.write_table(table, tmp, compression="zstd")
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
    rows: int = table.num_rows
    return rows


__all__ = ["ChunkExistsError", "Columns", "ParquetError", "combine", "read_metadata", "read_table", "write_table"]
