"""The catalog of a runs directory: every run's row in one file, so reads need not open every run.

The run directories stay the source of truth; the catalog is a cache beside them that any
command may delete, rebuild or ignore without losing anything::

    <runs dir>/.softtrack-catalog/catalog.arrow     one row per run (softtrack.store.catalog_rows)
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
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from softtrack.store.atomic import TEMP_MARK as _TEMP_MARK
from softtrack.store.atomic import atomic_write_text, is_temp_file, temp_name

__all__ = [
    "CATALOG_DIR",
    "FORMAT_VERSION",
    "ROW_SCHEMA",
    "CatalogSnapshot",
    "catalog_path",
    "file_stamp",
    "note_run",
    "read_catalog",
    "run_stamp",
]

CATALOG_DIR = ".softtrack-catalog"
#: Layout version of the catalog file and entries; a newer one is never overwritten.
FORMAT_VERSION = 1
_FILE = "catalog.arrow"
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


#: The catalog's columns, in order. ``tables`` is JSON: ``[[table, path relative to the run,
#: schema id or null, error or null, file stamp], ...]``, one item per Parquet file (``schema id``:
#: :func:`~softtrack.store.catalog_rows.schema_id` of the Arrow schema's text, equal for
#: files DuckDB can read as one; ``error``: why the file is not readable Parquet). ``stamp``
#: is :func:`run_stamp`'s value, or null to read the run again.
ROW_SCHEMA = pa.schema(
    [
        ("dir", pa.string()),
        ("unreadable", pa.string()),
        ("run_id", pa.string()),
        ("name", pa.string()),
        ("algo", pa.string()),
        ("controller", pa.string()),
        ("seed", pa.int64()),
        ("status", pa.string()),
        ("total_timesteps", pa.int64()),
        ("arm_total_timesteps", pa.int64()),
        ("global_step", pa.int64()),
        ("steps_per_second", pa.float64()),
        ("spec_hash", pa.string()),
        ("git_commit", pa.string()),
        ("git_dirty", pa.bool_()),
        ("created", pa.string()),
        ("started", pa.string()),
        ("ended", pa.string()),
        ("heartbeat", pa.string()),
        ("host", pa.string()),
        ("cpu", pa.string()),
        ("pid", pa.int64()),
        ("sweep", pa.string()),
        ("error", pa.string()),
        ("traceback", pa.string()),
        ("read_only", pa.bool_()),
        ("train_seconds", pa.float64()),
        ("final_stage_fraction", pa.float64()),
        ("heartbeat_interval", pa.float64()),
        ("final_return", pa.float64()),
        ("final_return_episodes", pa.int64()),
        ("last_step", pa.int64()),
        ("tables", pa.string()),
        ("stamp", pa.string()),
    ]
)


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


def catalog_path(root: Path) -> Path:
    """``<root>/.softtrack-catalog/catalog.arrow``."""
    return root / CATALOG_DIR / _FILE


@dataclass
class CatalogSnapshot:
    """Every run of a runs directory as the catalog gives it now.

    Attributes:
        root: the runs directory.
        table: one row per run directory, sorted by ``dir``
            (:data:`ROW_SCHEMA`).
        schemas: ``{schema id: schema text}`` for the ids in the ``tables`` cells.
        table_names: every table name the ``tables`` cells name, sorted.
        notices: one line each about the catalog itself (built, rebuilt, not writable).
        reread: runs read again from their directories in this call.
    """

    root: Path
    table: pa.Table
    schemas: dict[str, str]
    table_names: list[str]
    notices: list[str] = field(default_factory=list)
    reread: int = 0

    def rows(self, start: int = 0) -> list[dict[str, Any]]:
        """The rows from index ``start`` on, as dicts."""
        return self.table.slice(start).to_pylist()


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
    body = {"format_version": FORMAT_VERSION, "row": found.row, "schemas": found.schemas}
    text = json.dumps(body, ensure_ascii=False, sort_keys=True)
    digest = _digest_text(text)
    atomic_write_text(entries / f"{run_path.name}.json", json.dumps({"digest": digest, **body}))


def _digest_text(text: str) -> str:
    return hashlib.blake2b(text.encode("utf-8"), digest_size=16).hexdigest()


def _read_head_version(root: Path) -> int | None:
    try:
        with pa.memory_map(str(catalog_path(root))) as source:
            meta = pa.ipc.open_file(source).schema.metadata or {}
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
    """``{dir name: stamp}`` of every directory of ``root`` that may hold a run."""
    stamps: dict[str, str] = {}
    with os.scandir(root) as it:
        for entry in it:
            name = entry.name
            if name == CATALOG_DIR or (name.startswith(".") and _TEMP_MARK in name):
                continue
            try:
                if not entry.is_dir():
                    continue
            except OSError:
                continue
            stamp = run_stamp(entry.path)
            if stamp is not None:
                stamps[name] = stamp
    return stamps


_NUMPY_TYPES = {pa.int64(): np.int64, pa.float64(): np.float64}


def _table_digest(table: pa.Table) -> str:
    """A digest of the table's values, not of how Arrow lays them out (whether a column
    without nulls has a validity bitmap, what a null slot holds). Read from the buffers with
    NumPy: pyarrow's compute functions would import pandas, a second on every command."""
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
            values = np.frombuffer(buffers[0], dtype=_NUMPY_TYPES[column.type])[start : start + n]
            digest.update(np.where(valid, values, 0).tobytes())
    return digest.hexdigest()


def _bits(buffer: pa.Buffer, start: int, n: int) -> np.ndarray:
    """Bits ``start`` to ``start + n`` of an Arrow bitmap, (n,) bool."""
    bits = np.unpackbits(np.frombuffer(buffer, dtype=np.uint8), bitorder="little")
    return bits[start : start + n].astype(bool)


@dataclass
class _Base:
    table: pa.Table | None
    schemas: dict[str, str]
    problem: str | None
    newer: bool = False
    table_names: list[str] = field(default_factory=list)
    stale_metadata: bool = False  # readable, but to be written again in the current layout


def _load_base(root: Path) -> _Base:
    path = catalog_path(root)
    if not path.is_file():
        return _Base(None, {}, "missing" if not path.exists() else "not a file")
    try:
        with pa.memory_map(str(path)) as source:
            table = pa.ipc.open_file(source).read_all()
        meta = table.schema.metadata or {}
        version = int(meta.get(_META_VERSION, b"0"))
    except (OSError, pa.ArrowException, ValueError) as exc:
        return _Base(None, {}, f"unreadable ({_first_line(exc)})")
    if version > FORMAT_VERSION:
        return _Base(None, {}, f"written by a newer softtrack (format {version})", newer=True)
    if version != FORMAT_VERSION or table.schema.remove_metadata() != ROW_SCHEMA:
        return _Base(None, {}, f"of an older layout (format {version})")
    if not _verified(root) and meta.get(_META_DIGEST, b"").decode() != _table_digest(table):
        return _Base(None, {}, "edited outside softtrack (its digest does not match)")
    try:
        schemas = json.loads(meta.get(_META_SCHEMAS, b"{}"))
        names = json.loads(meta[_META_TABLES]) if _META_TABLES in meta else None
    except ValueError:
        return _Base(None, {}, "edited outside softtrack (unreadable metadata)")
    table = table.replace_schema_metadata(None)
    if names is None:  # written before the catalog listed its tables
        return _Base(
            table, schemas, None, table_names=_used_schemas(table, schemas)[1], stale_metadata=True
        )
    return _Base(table, schemas, None, table_names=names)


def _verified(root: Path) -> bool:
    """Whether the catalog file is the one its writer verified (:data:`_VERIFIED`)."""
    try:
        recorded = (root / CATALOG_DIR / _VERIFIED).read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError):
        return False
    return recorded == file_stamp(str(catalog_path(root)))


def _load_entries(root: Path) -> dict[str, _Entry]:
    directory = root / CATALOG_DIR / _ENTRIES
    found: dict[str, _Entry] = {}
    try:
        names = os.listdir(directory)
    except OSError:
        return found
    for name in names:
        if not name.endswith(".json") or is_temp_file(name):
            continue
        path = directory / name
        try:
            st = path.stat()
            data = json.loads(path.read_text(encoding="utf-8"))
            digest = data.pop("digest")
            if _digest_text(json.dumps(data, ensure_ascii=False, sort_keys=True)) != digest:
                continue
            if data["format_version"] != FORMAT_VERSION:
                continue
            row, schemas = data["row"], data["schemas"]
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            continue  # unreadable or edited: the run is read from its directory instead
        found[name[: -len(".json")]] = _Entry(row, schemas, path, _identity(st))
    return found


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
    root: Path, *, progress: Callable[[int, int], None] | None = None
) -> CatalogSnapshot:
    """Every run of ``root`` from the catalog, brought up to date with the directories (module
    docstring) and written back where anything changed and the directory is writable.

    Args:
        root: an existing runs directory.
        progress: called as ``progress(done, total)`` while runs are read from their files.
    """
    root = Path(root)
    stamps = _current_stamps(root)
    base = _load_base(root)
    entries = {} if base.newer else _load_entries(root)
    notices: list[str] = []
    base_index: dict[str, int] = {}
    base_stamps: list[Any] = []
    if base.table is not None:
        base_stamps = base.table.column("stamp").to_pylist()
        base_index = {d: i for i, d in enumerate(base.table.column("dir").to_pylist())}
    keep: list[int] = []
    fresh: list[dict[str, Any]] = []
    schemas = dict(base.schemas)
    merged: list[_Entry] = []
    stale: list[str] = []
    for name in sorted(stamps):
        stamp = stamps[name]
        entry = entries.get(name)
        if entry is not None and entry.row.get("stamp") == stamp:
            fresh.append(entry.row)
            schemas.update(entry.schemas)
            merged.append(entry)
            continue
        index = base_index.get(name)
        if index is not None and base_stamps[index] == stamp:
            keep.append(index)
            continue
        stale.append(name)
    reread = _reread(root, stale, schemas, progress)
    fresh.extend(reread)
    runs_reread = {row["dir"] for row in reread}  # not the directories that hold no run
    changed = (
        base.table is None or bool(fresh) or len(keep) != len(base_index) or base.stale_metadata
    )
    if base.table is not None and not changed:
        table = base.table
    else:
        table = pa.Table.from_pylist(fresh, schema=ROW_SCHEMA)
        if base.table is not None and keep:
            kept = base.table.take(pa.array(keep, type=pa.int64()))
            table = pa.concat_tables([kept, table])
        table = table.sort_by("dir")
    used, names = _used_schemas(table, schemas) if changed else (schemas, base.table_names)
    snapshot = CatalogSnapshot(root, table, used, names, notices, len(reread))
    notices.extend(
        _notices(
            root,
            base,
            [n for n in stale if n in runs_reread or n in base_index],
            base_index,
            stamps,
            base_stamps,
        )
    )
    if changed and not base.newer and not _write_back(root, table, used, names, merged):
        notices.append(
            f"catalog of {root} cannot be written (a read-only file system?): "
            "answered from the run directories"
        )
    return snapshot


def _notices(
    root: Path,
    base: _Base,
    stale: list[str],
    base_index: dict[str, int],
    stamps: dict[str, str],
    base_stamps: list[Any],
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
        1 for name in stale if name in base_index and base_stamps[base_index[name]] is not None
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


def _used_schemas(table: pa.Table, schemas: dict[str, str]) -> tuple[dict[str, str], list[str]]:
    """The schemas the ``tables`` cells name by id, and the table names they list."""
    used: dict[str, str] = {}
    names: set[str] = set()
    for cell in table.column("tables").to_pylist():
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
    merged: list[_Entry],
) -> bool:
    """Write the catalog and remove the merged entries (those not rewritten meanwhile);
    ``False`` where the directory cannot be written or another process is compacting."""
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
        }
        path = catalog_path(root)
        tmp = temp_name(path)
        try:
            if path.is_dir():
                path.rmdir()  # an empty directory in its place; anything else stays, unwritten
            options = pa.ipc.IpcWriteOptions(compression="zstd")
            with pa.OSFile(str(tmp), "wb") as sink:
                with pa.ipc.new_file(sink, table.schema.with_metadata(meta), options=options) as w:
                    w.write_table(table)
            os.replace(tmp, path)
            (directory / _VERIFIED).write_text(file_stamp(str(path)), encoding="utf-8")
        except OSError:
            tmp.unlink(missing_ok=True)
            return False
        for entry in merged:
            try:
                if _identity(entry.path.stat()) == entry.identity:
                    entry.path.unlink()
            except OSError:
                pass
        return True
    finally:
        os.close(fd)
