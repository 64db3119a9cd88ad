"""Reading a run's Parquet tables (:mod:`softtrack.store.tables` writes them): one file per
table, its schema checked against what softtrack writes before the rows are read, so a table
written by another program or damaged is one line naming the file and the fix."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

__all__ = [
    "KEY_COLUMNS",
    "TEXT_COLUMNS",
    "TableError",
    "TableNotFoundError",
    "check_schema",
    "read_arrow",
    "read_table",
]


#: Columns softtrack writes as text; every other column of its tables holds numbers or flags.
TEXT_COLUMNS = frozenset(
    {"run_id", "trajectory", "cpu", "candidate", "perturbation", "setting", "baseline"}
)
#: Per table (its file name), the columns its readers rely on: a file without them is not a
#: softtrack table of that name.
KEY_COLUMNS: dict[str, tuple[str, ...]] = {
    "train_episodes": ("global_step", "return"),
    "validation": ("global_step", "arm", "rmse_3d"),
    "confirmation": ("arm", "rmse_3d"),
    "eval_metrics": ("trajectory", "arm", "rmse_3d"),
    "eval_random": ("episode", "arm", "rmse_3d"),
    "eval_trajectories": ("trajectory", "step", "arm"),
    "eval_moments": ("trajectory", "step", "arm"),
    "eval_moment_peaks": ("trajectory", "arm"),
    "eval_snapshots": ("trajectory", "arm"),
    "eval_robustness": ("trajectory", "arm", "rmse_3d"),
}


class TableError(Exception):
    """A table cannot be read or written; the message names the file."""


class TableNotFoundError(TableError, FileNotFoundError):
    """The table file does not exist."""


def _fix(path: Path) -> str:
    """What to do about a damaged table ``path``."""
    if path.stem.startswith("eval_") and path.parent.name == "tables":
        run = path.parent.parent
        return f"move it away and run `softtrack evaluate {run}` to measure it again"
    return "restore it from a copy of the run (it cannot be measured again)"


def check_schema(path: Path, schema: pa.Schema, columns: Sequence[str] | None = None) -> None:
    """Raise :class:`TableError` (one line naming the file and the fix) when ``schema`` is not
    that of the softtrack table ``path`` names: a key column missing (:data:`KEY_COLUMNS`), a
    requested column missing, or a column holding text where softtrack writes numbers (or
    numbers where it writes text)."""
    names = set(schema.names)
    known = path.stem in KEY_COLUMNS  # the types are checked in softtrack's own tables only
    wanted = set(columns) if columns else set(KEY_COLUMNS.get(path.stem, ()))
    missing = sorted(wanted - names)
    if missing:
        raise TableError(
            f"{path}: no column {', '.join(map(repr, missing))} (not a softtrack "
            f"{path.stem} table, or written by another program); {_fix(path)}"
        )
    for field in schema:
        if not known or (columns and field.name not in wanted):
            continue
        textual = pa.types.is_string(field.type) or pa.types.is_large_string(field.type)
        if pa.types.is_dictionary(field.type):
            textual = pa.types.is_string(field.type.value_type)
        if field.name.startswith("__") or pa.types.is_null(field.type):
            continue
        if textual and field.name not in TEXT_COLUMNS:
            problem = "holds text where softtrack stores numbers"
        elif not textual and field.name in TEXT_COLUMNS:
            problem = f"holds {field.type} where softtrack stores text"
        else:
            continue
        raise TableError(f"{path}: column {field.name!r} {problem}; {_fix(path)}")


def read_arrow(path: str | os.PathLike[str], columns: Sequence[str] | None = None) -> pa.Table:
    """Read a table as Arrow (see :func:`read_table`)."""
    path = Path(path)
    if not path.exists():
        raise TableNotFoundError(f"{path}: no such table")
    if not path.is_file():
        raise TableError(f"{path}: not a file (a table is one Parquet file); {_fix(path)}")
    try:
        schema = pq.read_schema(path)
    except (pa.ArrowInvalid, OSError) as exc:
        raise TableError(f"{path}: unreadable Parquet table ({exc}); {_fix(path)}") from exc
    check_schema(path, schema, columns)
    try:
        return pq.read_table(path, columns=list(columns) if columns else None)
    except (pa.ArrowInvalid, OSError) as exc:
        raise TableError(f"{path}: unreadable Parquet table ({exc}); {_fix(path)}") from exc


def read_table(
    path: str | os.PathLike[str],
    columns: Sequence[str] | None = None,
    *,
    missing_ok: bool = False,
) -> pd.DataFrame:
    """Read a table into a DataFrame.

    Temporary files of interrupted writers (``.<name>.tmp-*``) sit beside the table under
    other names and are never read. The file's schema is checked first (:func:`check_schema`):
    a table with another program's columns or types is one line, not a traceback later.

    Args:
        columns: read only these columns.
        missing_ok: return an empty DataFrame (with ``columns``, if given) instead of raising
            when the table does not exist.

    Raises:
        TableNotFoundError: the table does not exist (and ``missing_ok`` is false).
        TableError: the file is not readable Parquet, not a file, or not the table its name
            says (:func:`check_schema`).
    """
    try:
        return read_arrow(path, columns).to_pandas()
    except TableNotFoundError:
        if missing_ok:
            return pd.DataFrame({c: [] for c in columns or ()})
        raise
