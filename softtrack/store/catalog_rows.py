"""One run directory's row of the catalog (:mod:`softtrack.store.catalog`), read from its files.

A row holds what the read commands need without opening the run again: the scalar fields of
``run.json``, the derived figures that ``softtrack runs`` and the ``runs`` view show (training
clock, final-stage return, the spec's final-stage fraction and heartbeat interval) and, per
table file, its path and schema, so ``softtrack query`` builds its views without reading a
single Parquet footer. A directory whose ``run.json`` is missing or unreadable (but that holds
a ``spec.yaml``) gets a row too, with only ``dir`` and ``unreadable`` (the reason) set.

The row's ``stamp`` (:func:`~softtrack.store.catalog_format.run_stamp`) is taken *before*
the files are read, so a change made while reading leaves a stamp that no longer matches and
the row is read again next time.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from softtrack.file_kinds import describe_path
from softtrack.store.atomic import is_temp_file
from softtrack.store.catalog_format import ROW_COLUMNS, run_stamp
from softtrack.store.errors import RunStoreError
from softtrack.store.run_records import read_run_record
from softtrack.store.status import (
    final_stage_fraction,
    final_stage_return,
    heartbeat_interval,
    training_seconds,
)
from softtrack.store.table_index import table_files, table_item
from softtrack.store.table_reading import TableError, read_table

__all__ = ["RunRow", "run_row"]

_INFO_FIELDS = (
    "run_id",
    "name",
    "algo",
    "controller",
    "seed",
    "status",
    "total_timesteps",
    "arm_total_timesteps",
    "global_step",
    "steps_per_second",
    "spec_hash",
    "git_commit",
    "git_dirty",
    "created",
    "started",
    "ended",
    "heartbeat",
    "host",
    "cpu",
    "pid",
    "error",
    "traceback",
)


def _tables_json(run_path: Path, schemas: dict[str, str]) -> str:
    """The ``tables`` cell of a run; adds each file's schema text to ``schemas`` by id."""
    items = [table_item(name, path, run_path, schemas) for name, path in table_files(run_path)]
    return json.dumps(items, ensure_ascii=False)


@dataclass(frozen=True)
class RunRow:
    """A run's catalog row (:data:`~softtrack.store.catalog_format.ROW_COLUMNS` keys) and the
    schema texts its ``tables`` cell names by id."""

    row: dict[str, Any]
    schemas: dict[str, str]


def run_row(run_path: Path) -> RunRow | None:
    """The catalog row of one directory of a runs directory
    (:data:`~softtrack.store.catalog_format.ROW_COLUMNS`), or ``None`` when it holds no run (no
    ``run.json``, no ``spec.yaml``; a temporary or a file)."""
    if is_temp_file(run_path) or not run_path.is_dir():
        return None
    stamp = run_stamp(run_path)
    row: dict[str, Any] = dict.fromkeys(name for name, _ in ROW_COLUMNS)
    row.update(dir=run_path.name, stamp=stamp)
    schemas: dict[str, str] = {}
    if not (run_path / "run.json").is_file():
        kind = describe_path(run_path / "run.json")
        if kind == "missing" and not (run_path / "spec.yaml").is_file():
            return None
        row["unreadable"] = f"run.json is {kind}" + ("" if kind == "missing" else ", not a file")
        return RunRow(row, schemas)
    try:
        record = read_run_record(run_path)
    except RunStoreError as exc:
        row["unreadable"] = str(exc).split(": ", 1)[-1]
        return RunRow(row, schemas)
    info = record.info
    row.update({name: getattr(info, name) for name in _INFO_FIELDS})
    sweep = (info.notes or {}).get("sweep")
    row["sweep"] = None if sweep is None else str(sweep)
    row["read_only"] = record.read_only
    raw = record.raw_spec()
    fraction = final_stage_fraction(raw)
    row["final_stage_fraction"] = fraction
    row["heartbeat_interval"] = heartbeat_interval(raw)
    try:
        train = read_table(record.table_path("train_episodes"), missing_ok=True)
        final, episodes, last_step = final_stage_return(record, fraction, train)
        row["train_seconds"] = training_seconds(train)
    except (TableError, KeyError, ValueError, TypeError):
        final, episodes, last_step = None, 0, 0
    row.update(final_return=final, final_return_episodes=episodes, last_step=last_step)
    row["tables"] = _tables_json(run_path, schemas)
    return RunRow(row, schemas)
