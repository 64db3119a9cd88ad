"""What a catalog row holds and how a reader knows it is current: the row's columns
(:data:`ROW_COLUMNS`), the stamps of a run directory and of a file, and the catalog's folder
name. Shared by the catalog (:mod:`softtrack.store.catalog`), the row reader
(:mod:`softtrack.store.catalog_rows`) and the table readers, below all of them."""

from __future__ import annotations

import os
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pyarrow as pa

__all__ = ["CATALOG_DIR", "ROW_COLUMNS", "file_stamp", "row_schema", "run_stamp"]

#: The catalog's folder in a runs directory.
CATALOG_DIR = ".softtrack-catalog"


#: The catalog's columns and their Arrow types, in order. ``tables`` is JSON: ``[[table, path relative to the run,
#: schema id or null, error or null, file stamp], ...]``, one item per Parquet file (``schema id``:
#: :func:`~softtrack.store.catalog_rows.schema_id` of the Arrow schema's text, equal for
#: files DuckDB can read as one; ``error``: why the file is not readable Parquet). ``stamp``
#: is :func:`run_stamp`'s value, or null to read the run again.
ROW_COLUMNS: tuple[tuple[str, str], ...] = (
    ("dir", "string"),
    ("unreadable", "string"),
    ("run_id", "string"),
    ("name", "string"),
    ("algo", "string"),
    ("controller", "string"),
    ("seed", "int64"),
    ("status", "string"),
    ("total_timesteps", "int64"),
    ("arm_total_timesteps", "int64"),
    ("global_step", "int64"),
    ("steps_per_second", "float64"),
    ("spec_hash", "string"),
    ("git_commit", "string"),
    ("git_dirty", "bool"),
    ("created", "string"),
    ("started", "string"),
    ("ended", "string"),
    ("heartbeat", "string"),
    ("host", "string"),
    ("cpu", "string"),
    ("pid", "int64"),
    ("sweep", "string"),
    ("error", "string"),
    ("traceback", "string"),
    ("read_only", "bool"),
    ("train_seconds", "float64"),
    ("final_stage_fraction", "float64"),
    ("heartbeat_interval", "float64"),
    ("final_return", "float64"),
    ("final_return_episodes", "int64"),
    ("last_step", "int64"),
    ("tables", "string"),
    ("stamp", "string"),
)


@cache
def row_schema() -> pa.Schema:
    """:data:`ROW_COLUMNS` as an Arrow schema (pyarrow is imported only where rows change)."""
    import pyarrow as pa

    types = {
        "string": pa.string(),
        "int64": pa.int64(),
        "float64": pa.float64(),
        "bool": pa.bool_(),
    }
    return pa.schema([(name, types[kind]) for name, kind in ROW_COLUMNS])


def file_stamp(path: str) -> str:
    """``mtime_ns.size.inode`` of a file or directory, ``-`` if it cannot be stat-ed."""
    try:
        st = os.stat(path)
    except OSError:
        return "-"
    return f"{st.st_mtime_ns}.{st.st_size}.{st.st_ino}"


def run_stamp(run_path: Path | str) -> str | None:
    """What changes whenever softtrack, or anyone replacing files, changes a run: the
    modification time, size and inode of the run directory (a file renamed into it:
    ``run.json``, ``spec.yaml``, ``model.zip``), its ``run.json`` (an edit in place) and its
    ``tables/`` directory (a table replaced or added). ``None`` when the run directory is
    gone. (Plain strings and ``os.stat``: at 100,000 runs every microsecond here is a tenth
    of a second.) A table rewritten in place is caught where it is read: ``softtrack query``
    compares each file it reads with its own stamp."""
    path = os.fspath(run_path)
    directory = file_stamp(path)
    if directory == "-":
        return None
    return f"{directory}|{file_stamp(path + '/run.json')}|{file_stamp(path + '/tables')}"
