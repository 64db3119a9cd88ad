"""The catalog of a runs directory: every run's row in one file, so reads need not open every run.

The run directories stay the source of truth; the catalog is a cache beside them that any
command may delete, rebuild or ignore without losing anything::

    <runs dir>/.softtrack-catalog/catalog.parquet   one row per run (softtrack.store.catalog_rows)
    <runs dir>/.softtrack-catalog/entries/<dir>.json  a run's newer row, written by its writer
    <runs dir>/.softtrack-catalog/lock                 flock: one compaction at a time

**Writers** (``run.json`` and table writes in :mod:`softtrack.store`) call :func:`note_run`,
which writes the run's row atomically to ``entries/<dir>.json``: a small file of its own, so
a hundred SLURM jobs finishing together never contend for, or corrupt, a shared file.

**Readers** (:func:`read_catalog`) stat every run directory (the directory, ``run.json`` and
``tables/``: :func:`run_stamp`) and take each run's row from
its entry or the catalog file if the stamp still matches, reading the run again otherwise
(added, changed or replaced behind softtrack's back); rows of deleted directories go. When
anything changed, the reader writes the merged catalog (a temporary file renamed over the old
one, under the lock, skipped if another process holds it) and removes the entries it merged.

When nothing changed and the catalog file is the one its writer left (:data:`_VERIFIED`), a
reader takes the stamps from it with DuckDB and leaves the rows in the file
(:meth:`CatalogSnapshot.columns`, :attr:`CatalogSnapshot.file`): no Arrow, no NumPy, a
fraction of a second at 10,000 runs.

A missing, corrupt or hand-edited catalog (its rows no longer match the digest stored in it)
is rebuilt from the directories; one written by a newer softtrack is left alone and the
answer comes from the directories; so does every answer on a read-only file system. Each case
adds one line to :attr:`CatalogSnapshot.notices`, which the command line prints.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

from softtrack.store.atomic import TEMP_MARK as _TEMP_MARK
from softtrack.store.atomic import atomic_write_text, is_temp_file, temp_name
from softtrack.store.catalog_format import CATALOG_DIR, ROW_COLUMNS, file_stamp, row_schema

if TYPE_CHECKING:
    import duckdb
    import numpy as np
    import pyarrow as pa

__all__ = [
    "FORMAT_VERSION",
    "CatalogSnapshot",
    "catalog_path",
    "note_run",
    "read_catalog",
]

#: Layout version of the catalog file and entries; a newer one is never overwritten.
#: (1: an Arrow IPC file, ``catalog.arrow``; 2: Parquet, which DuckDB reads without Arrow.)
FORMAT_VERSION = 2
_FILE = "catalog.parquet"
_OLDER_FILE = "catalog.arrow"  # format 1, converted to Parquet by the first reader
_ENTRIES = "entries"
_LOCK = "lock"
#: ``mtime_ns.size.inode`` of the catalog file as its writer left it: while the file still
#: matches, its digest need not be computed again (a hand edit changes the stamp).
_VERIFIED = "verified"
#: A row read from a file changed less than this long ago is not trusted to stay current
#: (a second change within the file system's clock tick would keep the stamp): it is stored
#: without a stamp, so it is read again next time.
_RACY_S = 2.0
_META_VERSION = b"softtrack_catalog_version"
_META_DIGEST = b"softtrack_catalog_digest"
_META_SCHEMAS = b"softtrack_catalog_schemas"
_META_TABLES = b"softtrack_catalog_tables"
#: A digest of every directory's stamp when the file was written (:func:`_stamps_digest`):
#: a reader whose directories give the same digest needs none of the file's rows.
_META_STAMPS = b"softtrack_catalog_stamps"
_META_ROWS = b"softtrack_catalog_rows"
#: Layout version of ``entries/<dir>.json`` (a row of :data:`ROW_COLUMNS`).
_ENTRY_VERSION = 1


def catalog_path(root: Path) -> Path:
    """``<root>/.softtrack-catalog/catalog.parquet``."""
    return root / CATALOG_DIR / _FILE


@cache
def _duckdb() -> duckdb.DuckDBPyConnection:
    """The process's DuckDB connection for reading catalog files (DuckDB's default one, which
    ``duckdb.extract_statements`` opens anyway: a second database costs 30 ms)."""
    import duckdb

    return duckdb.default_connection()


@dataclass
class CatalogSnapshot:
    """Every run of a runs directory as the catalog gives it now.

    Attributes:
        root: the runs directory.
        schemas: ``{schema id: schema text}`` for the ids in the ``tables`` cells.
        table_names: every table name the ``tables`` cells name, sorted.
        n_rows: the number of rows (run directories).
        notices: one line each about the catalog itself (built, rebuilt, not writable).
        reread: runs read again from their directories in this call.
        file: the catalog file that holds exactly these rows, where they were left there
            (nothing changed); ``None`` where they are in memory.
    """

    root: Path
    schemas: dict[str, str]
    table_names: list[str]
    n_rows: int
    notices: list[str] = field(default_factory=list)
    reread: int = 0
    file: Path | None = None
    _table: pa.Table | None = None

    @property
    def table(self) -> pa.Table:
        """One row per run directory, sorted by ``dir`` (:func:`row_schema`); read from
        :attr:`file` with Arrow at the first use."""
        if self._table is None:
            assert self.file is not None
            self._table = _read_rows(self.file)
        return self._table

    def columns(self, names: Sequence[str] | None = None, start: int = 0) -> dict[str, list[Any]]:
        """Columns ``names`` (default: all, :data:`ROW_COLUMNS`) from row ``start`` on, as
        lists; read with DuckDB where the rows are still in :attr:`file`."""
        wanted = [name for name, _ in ROW_COLUMNS] if names is None else list(names)
        if self._table is not None or self.file is None:
            return self.table.select(wanted).slice(start).to_pydict()
        select = ", ".join(f'"{name}"' for name in wanted)
        rows = (
            _duckdb()
            .cursor()
            .execute(f"SELECT {select} FROM read_parquet(?) OFFSET {int(start)}", [str(self.file)])
            .fetchall()
        )
        if not rows:
            return {name: [] for name in wanted}
        return {
            name: list(values) for name, values in zip(wanted, zip(*rows, strict=True), strict=True)
        }

    def unreadable(self) -> list[tuple[str, str]]:
        """``(dir, reason)`` of the directories whose ``run.json`` cannot be read."""
        if self._table is not None or self.file is None:
            columns = self.columns(["dir", "unreadable"])
            pairs = zip(columns["dir"], columns["unreadable"], strict=True)
            return [(name, reason) for name, reason in pairs if reason is not None]
        sql = 'SELECT "dir", "unreadable" FROM read_parquet(?) WHERE "unreadable" IS NOT NULL'
        return [
            (str(d), str(r))
            for d, r in _duckdb().cursor().execute(sql, [str(self.file)]).fetchall()
        ]

    def rows(self, start: int = 0) -> list[dict[str, Any]]:
        """The rows from index ``start`` on, as dicts."""
        columns = self.columns(start=start)
        return [
            dict(zip(columns, values, strict=True))
            for values in zip(*columns.values(), strict=True)
        ]


def _read_rows(path: Path) -> pa.Table:
    """A catalog file's rows with its metadata (``ParquetFile``: ``pq.read_table`` would load
    pyarrow's dataset layer, 0.4 s; format 1's Arrow IPC file by its name)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    if path.name == _OLDER_FILE:
        with pa.memory_map(str(path)) as source:
            return pa.ipc.open_file(source).read_all()
    return pq.ParquetFile(str(path)).read(use_threads=False)


# ---- writers ---------------------------------------------------------------------------------
def note_run(run_path: Path) -> None:
    """Record a run's current row in the catalog (``entries/<dir>.json``), after a write to
    the run. Never raises: the catalog is a cache, and readers find a change it missed."""
    try:
        _write_entry(run_path)
    except Exception:
        pass


def _write_entry(run_path: Path) -> None:
    from softtrack.store.catalog_rows import run_row  # the spec models: writers have them

    run_path = Path(run_path)
    entries = run_path.parent / CATALOG_DIR / _ENTRIES
    head = _read_head_version(run_path.parent)
    if head is not None and head > FORMAT_VERSION:
        return
    found = run_row(run_path)
    if found is None:
        return
    entries.mkdir(parents=True, exist_ok=True)
    body = {"format_version": _ENTRY_VERSION, "row": found.row, "schemas": found.schemas}
    text = json.dumps(body, ensure_ascii=False, sort_keys=True)
    digest = _digest_text(text)
    atomic_write_text(entries / f"{run_path.name}.json", json.dumps({"digest": digest, **body}))


def _digest_text(text: str) -> str:
    return hashlib.blake2b(text.encode("utf-8"), digest_size=16).hexdigest()


def _read_head_version(root: Path) -> int | None:
    """The format version of ``root``'s catalog file, ``None`` where there is none readable."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        meta = pq.read_metadata(str(catalog_path(root))).metadata or {}
    except (OSError, pa.ArrowException):
        return None
    try:
        return int(meta.get(_META_VERSION, b"0"))
    except ValueError:
        return None


# ---- readers ---------------------------------------------------------------------------------
@dataclass
class _Entry:
    row: dict[str, Any]
    schemas: dict[str, str]
    path: Path
    identity: tuple[int, int, int]


def _identity(st: os.stat_result) -> tuple[int, int, int]:
    return st.st_mtime_ns, st.st_size, st.st_ino


def _current_stamps(root: Path) -> dict[str, str]:
    """``{dir name: stamp}`` of every directory of ``root`` that may hold a run
    (:func:`run_stamp`, inlined: 30,000 calls at 10,000 runs)."""
    stamps: dict[str, str] = {}
    stat = os.stat
    with os.scandir(root) as it:
        for entry in it:
            name = entry.name
            if name == CATALOG_DIR or (name.startswith(".") and _TEMP_MARK in name):
                continue
            try:
                if not entry.is_dir():
                    continue
                st = stat(entry.path)
            except OSError:
                continue
            path = entry.path
            parts = [f"{st.st_mtime_ns}.{st.st_size}.{st.st_ino}"]
            for inside in ("/run.json", "/tables"):
                try:
                    st = stat(path + inside)
                    parts.append(f"{st.st_mtime_ns}.{st.st_size}.{st.st_ino}")
                except OSError:
                    parts.append("-")
            stamps[name] = "|".join(parts)
    return stamps


def _table_digest(table: pa.Table) -> str:
    """A digest of the table's values, not of how Arrow lays them out (whether a column
    without nulls has a validity bitmap, what a null slot holds). Read from the buffers with
    NumPy: pyarrow's compute functions would import pandas, a second on every command."""
    import numpy as np
    import pyarrow as pa

    numpy_types = {pa.int64(): np.int64, pa.float64(): np.float64}
    digest = hashlib.blake2b(digest_size=16)
    for name in table.column_names:
        column = table.column(name).combine_chunks()
        n, start = len(column), column.offset
        validity, *buffers = column.buffers()
        valid = _bits(validity, start, n) if validity is not None else np.ones(n, dtype=bool)
        digest.update(name.encode("utf-8"))
        digest.update(np.packbits(valid).tobytes())
        if pa.types.is_string(column.type):
            offsets = np.frombuffer(buffers[0], dtype=np.int32)[start : start + n + 1]
            digest.update(np.where(valid, np.diff(offsets), 0).tobytes())
            if buffers[1] is not None and n:
                chars = np.frombuffer(buffers[1], dtype=np.uint8)[offsets[0] : offsets[-1]]
                digest.update(chars[np.repeat(valid, np.diff(offsets))].tobytes())
        elif pa.types.is_boolean(column.type):
            digest.update(np.packbits(_bits(buffers[0], start, n) & valid).tobytes())
        else:
            values = np.frombuffer(buffers[0], dtype=numpy_types[column.type])[start : start + n]
            digest.update(np.where(valid, values, 0).tobytes())
    return digest.hexdigest()


def _bits(buffer: pa.Buffer, start: int, n: int) -> np.ndarray:
    """Bits ``start`` to ``start + n`` of an Arrow bitmap, (n,) bool."""
    import numpy as np

    bits = np.unpackbits(np.frombuffer(buffer, dtype=np.uint8), bitorder="little")
    return bits[start : start + n].astype(bool)


@dataclass
class _Base:
    """The catalog file's rows as found: their ``dir`` and ``stamp`` columns, and the rows
    themselves where they were read with Arrow (``table``) rather than left in ``file``."""

    dirs: list[str]
    stamps: list[str | None]
    schemas: dict[str, str]
    problem: str | None
    newer: bool = False
    table_names: list[str] = field(default_factory=list)
    stale_metadata: bool = False  # readable, but to be written again in the current layout
    table: pa.Table | None = None
    file: Path | None = None
    current: int | None = None  # the file's number of rows, where its stamps are all current


def _stamps_digest(stamps: dict[str, str]) -> str:
    """A digest of ``{dir name: stamp}`` (every directory of a runs directory)."""
    text = "\n".join(f"{name}\t{stamp}" for name, stamp in sorted(stamps.items()))
    return hashlib.blake2b(text.encode("utf-8"), digest_size=16).hexdigest()


def _problem(problem: str, *, newer: bool = False) -> _Base:
    return _Base([], [], {}, problem, newer=newer)


def _load_base(root: Path, stamps: dict[str, str] | None) -> _Base:
    """The catalog file as found; with ``stamps`` (no entries to merge) and a verified file
    whose directories' digest equals theirs, without its rows (``_Base.current``)."""
    path = catalog_path(root)
    if not path.is_file():
        older = root / CATALOG_DIR / _OLDER_FILE
        if not path.exists() and older.is_file():
            return _load_full(root, older)
        return _problem("missing" if not path.exists() else "not a file")
    if _verified(root):
        light = _load_light(path, stamps)
        if light is not None:
            return light
    return _load_full(root, path)


def _load_light(path: Path, stamps: dict[str, str] | None) -> _Base | None:
    """The ``dir`` and ``stamp`` columns of a verified catalog file, read with DuckDB, or
    none of them where ``stamps`` digest to the file's; ``None`` where only a full read can
    tell what is wrong with it."""
    import duckdb

    con = _duckdb().cursor()
    try:
        meta = dict(
            con.execute("SELECT key, value FROM parquet_kv_metadata(?)", [str(path)]).fetchall()
        )
        version = int(meta.get(_META_VERSION, b"0"))
        if version > FORMAT_VERSION:
            return _problem(f"written by a newer softtrack (format {version})", newer=True)
        if version != FORMAT_VERSION or _META_TABLES not in meta:
            return None
        schemas = json.loads(meta.get(_META_SCHEMAS, b"{}"))
        names = json.loads(meta[_META_TABLES])
        digest_now = None if stamps is None else _stamps_digest(stamps)
        if digest_now is not None and meta.get(_META_STAMPS, b"").decode() == digest_now:
            n_rows = int(meta[_META_ROWS])
            return _Base([], [], schemas, None, table_names=names, file=path, current=n_rows)
        rows = con.execute('SELECT "dir", "stamp" FROM read_parquet(?)', [str(path)]).fetchall()
    except (duckdb.Error, ValueError):
        return None
    finally:
        con.close()
    dirs = [row[0] for row in rows]
    row_stamps = [row[1] for row in rows]
    # rows all current but the digest not (written before it was kept): to be written again
    stale = stamps is not None and all(
        stamps.get(name) == stamp for name, stamp in zip(dirs, row_stamps, strict=True)
    )
    return _Base(
        dirs, row_stamps, schemas, None, table_names=names, file=path, stale_metadata=stale
    )


def _load_full(root: Path, path: Path) -> _Base:
    """The catalog file read with Arrow, its layout and (unless verified) its digest checked."""
    import pyarrow as pa

    try:
        table = _read_rows(path)
        meta = table.schema.metadata or {}
        version = int(meta.get(_META_VERSION, b"0"))
    except (OSError, pa.ArrowException, ValueError) as exc:
        return _problem(f"unreadable ({_first_line(exc)})")
    if version > FORMAT_VERSION:
        return _problem(f"written by a newer softtrack (format {version})", newer=True)
    expected = 1 if path.name == _OLDER_FILE else FORMAT_VERSION
    if version != expected or table.schema.remove_metadata() != row_schema():
        return _problem(f"of an older layout (format {version})")
    if not _verified(root, path) and meta.get(_META_DIGEST, b"").decode() != _table_digest(table):
        return _problem("edited outside softtrack (its digest does not match)")
    try:
        schemas = json.loads(meta.get(_META_SCHEMAS, b"{}"))
        names = json.loads(meta[_META_TABLES]) if _META_TABLES in meta else None
    except ValueError:
        return _problem("edited outside softtrack (unreadable metadata)")
    table = table.replace_schema_metadata(None)
    dirs = table.column("dir").to_pylist()
    stamps = table.column("stamp").to_pylist()
    if names is None or path.name == _OLDER_FILE:  # to be written again in this layout
        names = names or _used_schemas(table.column("tables").to_pylist(), schemas)[1]
        return _Base(
            dirs, stamps, schemas, None, table_names=names, stale_metadata=True, table=table
        )
    return _Base(dirs, stamps, schemas, None, table_names=names, table=table)


def _verified(root: Path, path: Path | None = None) -> bool:
    """Whether the catalog file (``path``, default :func:`catalog_path`) is the one its
    writer verified (:data:`_VERIFIED`)."""
    try:
        recorded = (root / CATALOG_DIR / _VERIFIED).read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError):
        return False
    return recorded == file_stamp(str(catalog_path(root) if path is None else path))


def _load_entries(root: Path) -> tuple[dict[str, _Entry], list[_Entry]]:
    """The valid entries by directory name, and every entry file seen (valid or not: each
    is obsolete once the catalog file holds rows at least as new)."""
    directory = root / CATALOG_DIR / _ENTRIES
    found: dict[str, _Entry] = {}
    seen: list[_Entry] = []
    try:
        names = os.listdir(directory)
    except OSError:
        return found, seen
    for name in names:
        if not name.endswith(".json") or is_temp_file(name):
            continue
        path = directory / name
        try:
            st = path.stat()
            seen.append(_Entry({}, {}, path, _identity(st)))
            data = json.loads(path.read_text(encoding="utf-8"))
            digest = data.pop("digest")
            if _digest_text(json.dumps(data, ensure_ascii=False, sort_keys=True)) != digest:
                continue
            if data["format_version"] != _ENTRY_VERSION:
                continue
            row, schemas = data["row"], data["schemas"]
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            continue  # unreadable or edited: the run is read from its directory instead
        found[name[: -len(".json")]] = _Entry(row, schemas, path, _identity(st))
    return found, seen


def _remove_entries(entries: list[_Entry]) -> None:
    """Remove the entry files not rewritten since they were read."""
    for entry in entries:
        try:
            if _identity(entry.path.stat()) == entry.identity:
                entry.path.unlink()
        except OSError:
            pass


def _first_line(exc: BaseException) -> str:
    return " ".join(str(exc).split("\n")[0].split()) or type(exc).__name__


def _settled(stamp: str | None, now_ns: int) -> str | None:
    """``stamp`` if none of its times is within :data:`_RACY_S` of now, else ``None``."""
    if stamp is None:
        return None
    for part in stamp.split("|"):
        mtime = part.split(".", 1)[0]
        if mtime.isdigit() and now_ns - int(mtime) < _RACY_S * 1e9:
            return None
    return stamp


def read_catalog(
    root: Path, *, progress: Callable[[int, int], None] | None = None, write: bool = True
) -> CatalogSnapshot:
    """Every run of ``root`` from the catalog, brought up to date with the directories (module
    docstring) and written back where anything changed and the directory is writable.

    Args:
        root: an existing runs directory.
        progress: called as ``progress(done, total)`` while runs are read from their files.
        write: ``False``: never write the catalog or remove entries (``softtrack watch``,
            which must leave the store as it found it).
    """
    root = Path(root)
    stamps = _current_stamps(root)
    entries, seen = _load_entries(root)
    base = _load_base(root, None if seen else stamps)
    if base.current is not None:
        return CatalogSnapshot(root, base.schemas, base.table_names, base.current, file=base.file)
    if base.newer:
        entries = {}
    notices: list[str] = []
    base_index = {d: i for i, d in enumerate(base.dirs)}
    keep: list[int] = []
    fresh: list[dict[str, Any]] = []
    schemas = dict(base.schemas)
    stale: list[str] = []
    for name in sorted(stamps):
        stamp = stamps[name]
        entry = entries.get(name)
        if entry is not None and entry.row.get("stamp") == stamp:
            fresh.append(entry.row)
            schemas.update(entry.schemas)
            continue
        index = base_index.get(name)
        if index is not None and base.stamps[index] == stamp:
            keep.append(index)
            continue
        stale.append(name)
    reread = _reread(root, stale, schemas, progress)
    fresh.extend(reread)
    runs_reread = {row["dir"] for row in reread}  # not the directories that hold no run
    present = base.problem is None
    changed = not present or bool(fresh) or len(keep) != len(base.dirs) or base.stale_metadata
    if changed and present and keep and base.table is None:
        kept_rows = _kept_rows(base, keep)
        if kept_rows is None:  # the file was replaced since its stamps were read
            fresh.extend(_reread(root, [base.dirs[i] for i in keep], schemas, progress))
            keep = []
        base.table = kept_rows
    notices.extend(
        _notices(
            root,
            base,
            [n for n in stale if n in runs_reread or n in base_index],
            base_index,
            stamps,
        )
    )
    if not changed:
        if not base.newer and write:
            _remove_entries(seen)  # none was current: the file's rows are
        return CatalogSnapshot(
            root, schemas, base.table_names, len(base.dirs), notices, 0, base.file, base.table
        )
    table = _merged_table(base.table, keep, fresh)
    used, names = _used_schemas(table.column("tables").to_pylist(), schemas)
    snapshot = CatalogSnapshot(root, used, names, table.num_rows, notices, len(reread), None, table)
    digest = _stamps_digest(stamps) if _all_current(table, stamps) else ""
    written = base.newer or not write or _write_back(root, table, used, names, seen, digest)
    only_metadata = present and not fresh and len(keep) == len(base.dirs)
    if not written and not only_metadata:
        notices.append(
            f"catalog of {root} cannot be written (a read-only file system?): "
            "answered from the run directories"
        )
    return snapshot


def _all_current(table: pa.Table, stamps: dict[str, str]) -> bool:
    """Whether every row's stamp is the directory's stamp now (none racy, none missing)."""
    rows = zip(table.column("dir").to_pylist(), table.column("stamp").to_pylist(), strict=True)
    return all(stamp is not None and stamps.get(name) == stamp for name, stamp in rows)


def _kept_rows(base: _Base, keep: list[int]) -> pa.Table | None:
    """The rows of ``base``'s file, read with Arrow; ``None`` where the file no longer holds
    the rows whose stamps were read."""
    assert base.file is not None
    try:
        table = _read_rows(base.file).replace_schema_metadata(None)
    except Exception:
        return None
    same = (
        table.schema == row_schema()
        and table.column("dir").to_pylist() == base.dirs
        and table.column("stamp").to_pylist() == base.stamps
    )
    return table if same else None


def _merged_table(base: pa.Table | None, keep: list[int], fresh: list[dict[str, Any]]) -> pa.Table:
    """The kept rows of ``base`` and the ``fresh`` rows, sorted by ``dir``."""
    import pyarrow as pa

    table = pa.Table.from_pylist(fresh, schema=row_schema())
    if base is not None and keep:
        kept = base.take(pa.array(keep, type=pa.int64()))
        table = pa.concat_tables([kept, table])
    return table.sort_by("dir")


def _notices(
    root: Path,
    base: _Base,
    stale: list[str],
    base_index: dict[str, int],
    stamps: dict[str, str],
) -> list[str]:
    """One line about the catalog where it was not simply current: built, rebuilt, left
    alone (a newer softtrack's), or runs added, changed or removed behind softtrack's back
    (not counting rows that were too fresh to trust, :data:`_RACY_S`)."""
    if base.newer:
        return [
            f"catalog of {root} {base.problem}: answered from the run directories; "
            "upgrade softtrack to use it"
        ]
    if base.problem == "missing":
        return [f"catalog of {root} built from {len(stale)} run directories"] if stale else []
    if base.problem is not None:
        return [f"catalog of {root} {base.problem}: rebuilt from {len(stale)} run directories"]
    added = sum(1 for name in stale if name not in base_index)
    changed = sum(
        1 for name in stale if name in base_index and base.stamps[base_index[name]] is not None
    )
    removed = sum(1 for name in base_index if name not in stamps)
    parts = [
        f"{count} {what}"
        for count, what in ((added, "added"), (changed, "changed"), (removed, "removed"))
        if count
    ]
    if not parts:
        return []
    return [
        f"catalog of {root}: run directories {', '.join(parts)} outside softtrack; "
        "read from the directories"
    ]


def _reread(
    root: Path,
    names: list[str],
    schemas: dict[str, str],
    progress: Callable[[int, int], None] | None,
) -> list[dict[str, Any]]:
    if not names:
        return []
    from softtrack.store.catalog_rows import run_row  # the spec models: only when rows changed

    rows: list[dict[str, Any]] = []
    now_ns = time.time_ns()
    for done, name in enumerate(names, 1):
        found = run_row(root / name)
        if found is not None:
            found.row["stamp"] = _settled(found.row["stamp"], now_ns)
            rows.append(found.row)
            schemas.update(found.schemas)
        if progress is not None:
            progress(done, len(names))
    return rows


def _used_schemas(
    cells: list[str | None], schemas: dict[str, str]
) -> tuple[dict[str, str], list[str]]:
    """The schemas the ``tables`` cells name by id, and the table names they list."""
    used: dict[str, str] = {}
    names: set[str] = set()
    for cell in cells:
        for item in json.loads(cell or "[]"):
            names.add(item[0])
            key = item[2]
            if key is not None and key in schemas:
                used[key] = schemas[key]
    return used, sorted(names)


def _write_back(
    root: Path,
    table: pa.Table,
    schemas: dict[str, str],
    names: list[str],
    entries: list[_Entry],
    stamps_digest: str,
) -> bool:
    """Write the catalog and remove the entries read (those not rewritten meanwhile);
    ``False`` where the directory cannot be written or another process is compacting."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    directory = root / CATALOG_DIR
    try:
        directory.mkdir(exist_ok=True)
        fd = os.open(directory / _LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError:
        return False
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return True  # another reader is writing the same merge
        if (_read_head_version(root) or 0) > FORMAT_VERSION:
            return True
        meta = {
            _META_VERSION: str(FORMAT_VERSION).encode(),
            _META_DIGEST: _table_digest(table).encode(),
            _META_SCHEMAS: json.dumps(schemas, sort_keys=True).encode(),
            _META_TABLES: json.dumps(names).encode(),
            _META_STAMPS: stamps_digest.encode(),
            _META_ROWS: str(table.num_rows).encode(),
        }
        path = catalog_path(root)
        tmp = temp_name(path)
        try:
            if path.is_dir():
                path.rmdir()  # an empty directory in its place; anything else stays, unwritten
            pq.write_table(table.replace_schema_metadata(meta), str(tmp), compression="zstd")
            os.replace(tmp, path)
            (directory / _VERIFIED).write_text(file_stamp(str(path)), encoding="utf-8")
        except (OSError, pa.ArrowException):
            tmp.unlink(missing_ok=True)
            return False
        try:
            (directory / _OLDER_FILE).unlink()
        except OSError:
            pass
        _remove_entries(entries)
        return True
    finally:
        os.close(fd)
