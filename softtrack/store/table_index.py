"""A run's table files and their schemas, as the catalog (:mod:`softtrack.store.catalog`)
records them: light (pyarrow's Parquet footer reader only), so ``softtrack query`` can read
again the schema of a file changed since the catalog saw it."""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from softtrack.store.atomic import is_temp_file
from softtrack.store.catalog_format import file_stamp

__all__ = ["list_tables", "schema_id", "table_files", "table_item"]


def list_tables(tables_dir: str | os.PathLike[str]) -> dict[str, Path]:
    """The tables in a directory: ``{name: path}`` for each ``<name>.parquet``, sorted by name,
    skipping temporary files."""
    tables_dir = Path(tables_dir)
    if not tables_dir.is_dir():
        return {}
    return {
        p.name[: -len(".parquet")]: p
        for p in sorted(tables_dir.iterdir())
        if p.name.endswith(".parquet") and not is_temp_file(p) and not p.name.startswith(".")
    }


def table_files(run_path: Path) -> list[tuple[str, Path]]:
    """``(table name, Parquet file)`` of a run; a table stored as a directory gives its part
    files (hidden ``.``/``_`` ones and temporaries skipped)."""
    found: list[tuple[str, Path]] = []
    for name, path in list_tables(run_path / "tables").items():
        if path.is_dir():
            parts = sorted(
                p
                for p in path.rglob("*.parquet")
                if p.is_file()
                and not is_temp_file(p)
                and not any(part.startswith((".", "_")) for part in p.relative_to(path).parts)
            )
            found.extend((name, p) for p in parts)
        elif path.is_file():
            found.append((name, path))
    return found


def schema_id(text: str) -> str:
    """A short name for a schema's text (the catalog stores each distinct schema once)."""
    return hashlib.blake2b(text.encode("utf-8"), digest_size=8).hexdigest()


def table_item(name: str, path: Path, run_path: Path, schemas: dict[str, str]) -> list[str | None]:
    """One item of a ``tables`` cell: ``[table, path relative to the run, schema id or None,
    error or None, file stamp]``; adds the file's schema text to ``schemas`` by id."""
    rel = str(path.relative_to(run_path))
    import pyarrow as pa  # here: a query that reads no run's files loads no Arrow
    import pyarrow.parquet as pq

    stamp = file_stamp(str(path))  # before reading: a change meanwhile shows as stale
    try:
        schema = pq.read_schema(path).remove_metadata()
    except (pa.ArrowException, OSError) as exc:
        first = " ".join(str(exc).split("\n")[0].split()) or type(exc).__name__
        return [name, rel, None, first, stamp]
    text = ", ".join(f"{json.dumps(field.name)}: {field.type}" for field in schema)
    key = schema_id(text)
    schemas[key] = text
    return [name, rel, key, None, stamp]
