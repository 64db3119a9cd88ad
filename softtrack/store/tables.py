"""Parquet tables of a run, written crash-safely.

Design: a table is **one ordinary Parquet file** (``tables/<name>.parquet``), readable by any
tool (``pandas.read_parquet``, DuckDB, Polars). :func:`append_rows` reads the current file,
appends the new rows and *atomically replaces the whole file* (temporary file + fsync +
rename, :mod:`softtrack.store.atomic`). A process killed at any moment — including SIGKILL in
the middle of an append — therefore leaves the table exactly as it was after the last
completed append; at worst a temporary ``.<name>.tmp-<hex>.parquet`` is left beside it, which
:func:`read_table` never opens and :func:`list_tables` skips.

Why not one part file per append? Part directories need compaction to stay fast to read, and
compaction needs its own crash-safety protocol; whole-file replacement is simpler and is
cheap for the tables of a run: ``train_episodes`` has one row per finished episode
(≈2 000 rows for 1e7 steps of 5 000-step episodes), and an append of a 10 000-row table costs
a few milliseconds. The cost grows linearly with the table, so append in batches (e.g. every
few episodes) and write large per-step tables (trajectories) once with :func:`write_table`.

Tables have a single writer (the run's training or evaluation process); concurrent readers
are always safe.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from softtrack.store.atomic import (
    atomic_path,
    fsync_dir,
    fsync_file,
    remove_stale_temp_files,
    temp_name,
)
from softtrack.store.catalog import note_run
from softtrack.store.table_index import list_tables
from softtrack.store.table_reading import (
    TableError,
    TableNotFoundError,
    read_arrow,
    read_table,
)

__all__ = [
    "TRAIN_EPISODES_COLUMNS",
    "TableError",
    "TableNotFoundError",
    "append_rows",
    "element_peaks_frame",
    "list_tables",
    "read_arrow",
    "read_table",
    "write_table",
    "write_tables",
]

#: Columns of ``tables/train_episodes.parquet``: the run id, the episode index (0-based, in
#: completion order over all envs), the global env step at the episode's end, the undiscounted
#: return, the length in control steps, and the wall-clock seconds since training started.
#: An independent run's rows have one more column, ``arm`` (int 0 or 1): its rows are arm 0's
#: episodes, then arm 1's, and ``episode`` and ``global_step`` count per arm (the arm's episodes
#: and env steps). A centralized run's table has no ``arm`` column; readers treat an absent,
#: null or negative ``arm`` as "the centralized policy". Rows with ``truncated`` true are
#: episodes a stop cut short at the checkpoint training resumed from (partial return); the
#: column is absent or null for whole episodes.
TRAIN_EPISODES_COLUMNS = ("run_id", "episode", "global_step", "return", "length", "wall_time")


def _to_arrow(data: pd.DataFrame | pa.Table | Sequence[Mapping[str, Any]]) -> pa.Table:
    if isinstance(data, pa.Table):
        return data
    if isinstance(data, pd.DataFrame):
        return pa.Table.from_pandas(data, preserve_index=False)
    rows = list(data)
    columns: dict[str, list[Any]] = {}
    for row in rows:  # union of keys, in first-seen order; missing values become null
        for key in row:
            columns.setdefault(str(key), [])
    for key, values in columns.items():
        values.extend(_plain(row.get(key)) for row in rows)
    return pa.table(columns)


def _plain(value: Any) -> Any:
    """numpy scalars → Python scalars (pyarrow infers types from Python objects)."""
    item = getattr(value, "item", None)
    if item is not None and getattr(value, "shape", None) == ():
        return item()
    return value


def _write_parquet(table: pa.Table, path: Path) -> None:
    """Write with zstd, each column in the encoding that compresses it best: floats
    byte-stream-split, integers delta-packed (step counters shrink to almost nothing),
    strings dictionary-encoded; any reader (pandas, DuckDB, Polars) reads them."""
    encodings: dict[str, str] = {}
    dictionary = []
    for field in table.schema:
        if pa.types.is_floating(field.type):
            encodings[field.name] = "BYTE_STREAM_SPLIT"
        elif pa.types.is_integer(field.type):
            encodings[field.name] = "DELTA_BINARY_PACKED"
        elif not pa.types.is_nested(field.type):
            dictionary.append(field.name)
    pq.write_table(
        table,
        path,
        compression="zstd",
        use_dictionary=dictionary,
        column_encoding=encodings or None,
    )


def _write(path: Path, table: pa.Table) -> None:
    """Replace ``path`` atomically, first sweeping temporaries of dead earlier writers."""
    remove_stale_temp_files(path)
    with atomic_path(path) as tmp:
        _write_parquet(table, tmp)
    _note_runs([path])


def _note_runs(paths: Iterable[Path]) -> None:
    """Tell the catalog (:mod:`softtrack.store.catalog`) about the runs whose
    ``tables/`` these files are in."""
    for run_path in {p.parent.parent for p in paths if p.parent.name == "tables"}:
        if (run_path / "run.json").is_file():
            note_run(run_path)


def write_tables(tables: Mapping[Path, pd.DataFrame | pa.Table | None]) -> None:
    """Write (or, for ``None``, delete) several tables as one change: every new file is
    written to a temporary sibling first, and only when all are written are they renamed over
    the old ones; an error or a signal before that leaves every table as it was (and no
    temporary file behind).

    Args:
        tables: ``{path: new content}`` (a DataFrame, its index dropped, or an Arrow table),
            ``None`` to remove the table.

    Raises:
        TableError: a path is a directory (or another non-file): nothing is written.
    """
    for path in tables:
        if (path.exists() or path.is_symlink()) and not path.is_file():
            raise TableError(
                f"{path}: not a file, so the table cannot be written there; move it away "
                "and run the command again (no table was changed)"
            )
    written: list[tuple[Path, Path]] = []
    try:
        for path, data in tables.items():
            if data is None:
                continue
            remove_stale_temp_files(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = temp_name(path)
            written.append((tmp, path))
            _write_parquet(_to_arrow(data), tmp)
            fsync_file(tmp)
        for tmp, path in written:
            os.replace(tmp, path)
        for path, data in tables.items():
            if data is None:
                path.unlink(missing_ok=True)
        for directory in {path.parent for _, path in written}:
            fsync_dir(directory)
    except BaseException:
        for tmp, _ in written:
            tmp.unlink(missing_ok=True)
        raise
    _note_runs(tables)


def write_table(
    path: str | os.PathLike[str], data: pd.DataFrame | pa.Table | Sequence[Mapping[str, Any]]
) -> None:
    """Write (or replace) a whole table atomically.

    Args:
        path: the ``.parquet`` file.
        data: a DataFrame (its index is dropped), an Arrow table, or a list of row dicts.
    """
    _write(Path(path), _to_arrow(data))


def append_rows(path: str | os.PathLike[str], rows: Iterable[Mapping[str, Any]]) -> int:
    """Append ``rows`` (dicts: column → value) to the table at ``path``; create it if missing.

    The table is replaced atomically (see the module docstring), so a crash leaves either the
    old or the new content. Columns missing from some rows are null; a column whose type
    widens (int → float) is promoted. Returns the number of rows now in the table.

    Raises:
        TableError: the existing file is unreadable or the new rows do not fit its schema.
    """
    path = Path(path)
    rows = list(rows)
    if not rows:
        return _count(path)
    new = _to_arrow(rows)
    if path.exists():
        old = read_arrow(path)
        try:
            table = pa.concat_tables([old, new], promote_options="permissive")
        except (pa.ArrowInvalid, pa.ArrowTypeError) as exc:
            raise TableError(f"{path}: new rows do not match the table's columns ({exc})") from exc
    else:
        table = new
    _write(path, table)
    return table.num_rows


def _count(path: Path) -> int:
    if not path.exists():
        return 0
    return pq.ParquetFile(path).metadata.num_rows


def element_peaks_frame(run_id: str, trajectory: str, peaks: np.ndarray) -> pd.DataFrame:
    """Rows (run_id, trajectory, arm, direction, element, peak_abs_moment) from peaks of shape
    (A arms, 2 directions, n_elem elements), N·m, stored as float32."""
    n_arms, n_dirs, n_elem = peaks.shape
    return pd.DataFrame(
        {
            "run_id": run_id,
            "trajectory": trajectory,
            "arm": np.repeat(np.arange(n_arms, dtype=np.int32), n_dirs * n_elem),
            "direction": np.tile(np.repeat(np.arange(n_dirs, dtype=np.int32), n_elem), n_arms),
            "element": np.tile(np.arange(n_elem, dtype=np.int32), n_arms * n_dirs),
            "peak_abs_moment": peaks.reshape(-1).astype(np.float32),
        }
    )
