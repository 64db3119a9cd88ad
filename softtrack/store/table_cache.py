"""Consolidated copies of the runs' tables in the catalog directory, so that a query over
every run's ``eval_metrics`` reads one file instead of ten thousand.

``<runs dir>/.softtrack-catalog/tables/<table>.parquet`` holds the rows of every file of that
table, each row with the file it came from (``__softtrack_file``, its absolute path) and that
file's stamp when it was copied (``__softtrack_stamp``: modification time, size, inode). A
query (:mod:`softtrack.store.query`) takes a file's rows from the copy only while the file
still has that stamp; the rows of new or changed files are read from the files themselves,
and the copy is then rewritten (a temporary file renamed over the old one, under the
catalog's lock; skipped where the directory is read-only or another process holds the lock).
``<table>.verified`` records the copy's own stamp as its writer left it: a copy changed
behind softtrack's back is ignored and rewritten. Like the catalog, the copies are a cache:
deleting them loses nothing.

Only tables whose files are small on average (at most :data:`CACHE_MEAN_FILE_BYTES`) are
copied: the per-run summaries (``eval_metrics``, ``eval_random``, ``train_episodes``,
``eval_moment_peaks``), whose files are mostly Parquet metadata, so that one copy reads in a
fraction of the time of their thousands of files; not ``validation`` or the per-step tables.
"""

from __future__ import annotations

import fcntl
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import duckdb

from softtrack.store.atomic import temp_name
from softtrack.store.catalog_format import CATALOG_DIR, file_stamp

__all__ = [
    "CACHE_MEAN_FILE_BYTES",
    "FILE_COLUMN",
    "MAP_FILE",
    "MAP_RUN_ID",
    "MAP_STAMP",
    "STAMP_COLUMN",
    "CachedTable",
    "TableFile",
    "create_file_map",
]

#: Tables whose files are larger on average are read from the files every time.
CACHE_MEAN_FILE_BYTES = 64 * 2**10
FILE_COLUMN = "__softtrack_file"
STAMP_COLUMN = "__softtrack_stamp"
#: Columns of a file map (:func:`file_map`): a file, its stamp now, its run's id.
MAP_FILE, MAP_STAMP, MAP_RUN_ID = (
    "__softtrack_map_file",
    "__softtrack_map_stamp",
    "__softtrack_run_id",
)
_LOCK = "lock"


@dataclass(frozen=True)
class TableFile:
    """One run's file of a table: absolute path, stamp now, schema id, the run's id."""

    path: str
    stamp: str
    schema: str
    run_id: str


def create_file_map(con: duckdb.DuckDBPyConnection, name: str, files: Sequence[TableFile]) -> None:
    """Table ``name`` in ``con``: the files (:data:`MAP_FILE`, :data:`MAP_STAMP`,
    :data:`MAP_RUN_ID`), for the joins of :meth:`CachedTable.source_sql` and the views.
    (Built from lists by DuckDB itself: an Arrow table built from Python lists would import
    pandas, half a second.)"""
    con.execute(
        f"CREATE TABLE {name} AS SELECT unnest($1::VARCHAR[]) AS {MAP_FILE}, "
        f"unnest($2::VARCHAR[]) AS {MAP_STAMP}, unnest($3::VARCHAR[]) AS {MAP_RUN_ID}",
        [[f.path for f in files], [f.stamp for f in files], [f.run_id for f in files]],
    )


def _lit(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


def scan_sql(files: Sequence[TableFile]) -> str:
    """A SELECT over ``files`` read from themselves: one ``read_parquet`` per schema, joined
    by name (DuckDB reads one footer per schema to bind, not one per file), with the
    :data:`FILE_COLUMN` of each row."""
    groups: dict[str, list[str]] = {}
    for file in files:
        groups.setdefault(file.schema, []).append(file.path)
    return " UNION ALL BY NAME ".join(
        f"SELECT * FROM read_parquet([{', '.join(_lit(p) for p in paths)}], "
        f"filename = '{FILE_COLUMN}')"
        for paths in groups.values()
    )


def _size(stamp: str) -> int:
    parts = stamp.split(".")
    return int(parts[1]) if len(parts) == 3 and parts[1].isdigit() else 0


class CachedTable:
    """The consolidated copy of one table of a runs directory (module docstring).

    Args:
        root: the runs directory.
        name: the table.
        files: every current file of the table.
    """

    def __init__(self, root: Path, name: str, files: Sequence[TableFile]) -> None:
        self.root = root
        self.name = name
        self.files = list(files)
        self.path = root / CATALOG_DIR / "tables" / f"{name}.parquet"
        #: where the copy is read from: ``path`` or a link to one version of it
        #: (:class:`~softtrack.store.query_snapshot.QuerySnapshot`)
        self.read_path = self.path
        self._verified = self.path.with_suffix(".verified")

    @property
    def cacheable(self) -> bool:
        sizes = [_size(f.stamp) for f in self.files]
        return bool(sizes) and sum(sizes) <= CACHE_MEAN_FILE_BYTES * len(sizes)

    def _copied(self, con: duckdb.DuckDBPyConnection) -> set[tuple[str, str]]:
        """(file, stamp) of every file in a copy its writer verified; empty without one."""
        try:
            verified = self._verified.read_text(encoding="utf-8").strip()
            if verified != file_stamp(str(self.read_path)):
                return set()
            rows = con.execute(
                f"SELECT DISTINCT {FILE_COLUMN}, {STAMP_COLUMN} FROM read_parquet(?)",
                [str(self.read_path)],
            ).fetchall()
        except (OSError, UnicodeDecodeError, duckdb.Error):
            return set()
        return {(str(f), str(s)) for f, s in rows}

    def split(self, con: duckdb.DuckDBPyConnection) -> tuple[list[TableFile], list[TableFile]]:
        """The files whose rows the copy holds as they are now, and the others."""
        copied = self._copied(con) if self.cacheable else set()
        fresh = [f for f in self.files if (f.path, f.stamp) in copied]
        stale = [f for f in self.files if (f.path, f.stamp) not in copied]
        return fresh, stale

    def source_sql(self, fresh: Sequence[TableFile], stale: Sequence[TableFile], files: str) -> str:
        """A SELECT of every current row: the copy's rows of ``fresh`` files (semi-joined on
        file and stamp with ``files``, a :func:`create_file_map` table), the ``stale`` files read from
        themselves; with :data:`FILE_COLUMN`."""
        parts = []
        if fresh:
            parts.append(
                f"SELECT * EXCLUDE ({STAMP_COLUMN}) FROM read_parquet({_lit(str(self.read_path))}) "
                f"AS c SEMI JOIN {files} AS s "
                f"ON c.{FILE_COLUMN} = s.{MAP_FILE} AND c.{STAMP_COLUMN} = s.{MAP_STAMP}"
            )
        if stale:
            parts.append(scan_sql(stale))
        return " UNION ALL BY NAME ".join(f"({p})" for p in parts)

    def refresh(self, fresh: Sequence[TableFile], stale: Sequence[TableFile]) -> bool:
        """Rewrite the copy with every current row (the copy's own rows of ``fresh`` files,
        the ``stale`` files read anew); ``False`` where it cannot be written now."""
        if not self.cacheable or not stale:
            return False
        directory = self.path.parent
        try:
            directory.mkdir(parents=True, exist_ok=True)
            fd = os.open(directory / _LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError:
            return False
        tmp = temp_name(self.path)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            with duckdb.connect(":memory:") as con:
                con.execute("SET enable_progress_bar = false")
                create_file_map(con, "files", self.files)
                rows = self.source_sql(fresh, stale, "files")
                con.execute(
                    f"COPY (SELECT t.*, s.{MAP_STAMP} AS {STAMP_COLUMN} FROM ({rows}) AS t "
                    f"JOIN files AS s ON t.{FILE_COLUMN} = s.{MAP_FILE}) TO {_lit(str(tmp))} "
                    "(FORMAT parquet, COMPRESSION zstd)"
                )
            os.replace(tmp, self.path)
            self._verified.write_text(file_stamp(str(self.path)), encoding="utf-8")
        except (OSError, duckdb.Error):
            tmp.unlink(missing_ok=True)
            return False
        finally:
            os.close(fd)
        return True
