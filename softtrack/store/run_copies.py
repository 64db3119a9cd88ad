"""Results of shipped runs go into a copy: a run marked read-only (``notes.read_only``, as
``softtrack export`` marks the runs of ``models/``) is copied into the runs directory, without
its evaluation tables, and commands that store results write there
(:func:`writable_run`); the shipped files are only read."""

from __future__ import annotations

import filecmp
import os
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path

from softtrack.store.atomic import atomic_dir, is_temp_file
from softtrack.store.provenance import portable_path
from softtrack.store.runs import RunRecord, RunStore, RunStoreError, resolve_runs_dir

__all__ = ["copy_run", "writable_run"]

#: The model files of a run, relative to nothing (absolute paths inside the run).
ModelFiles = Callable[[RunRecord], Sequence[Path]]


def copy_run(
    record: RunRecord,
    models: Sequence[Path],
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    keep_evaluation: bool = False,
) -> Path:
    """Copy the finished run ``record`` (e.g. the shipped ``models/td3-sbx-1e7-seed0``) into
    the runs directory under its own id, without its evaluation tables, so that evaluating the
    copy (with ``write=True``) makes its tables, and every report of it, show this machine's
    evaluation. The source is only read; ``models`` are its model files (each must exist).

    The copy holds everything but checkpoints, replay buffers, the run lock and
    ``tables/eval_*.parquet`` (training episodes and validation stay: they cannot be measured
    again). A copy already there with the same model files is reused, its evaluation tables
    removed likewise (kept with ``keep_evaluation``: a copy that holds this machine's results
    already). The copy is writable (no ``notes.read_only``) and names its source in
    ``notes.copy_of``.

    Returns:
        The copy's directory, ``<runs_dir>/<run id>``.

    Raises:
        RunStoreError: the run has no model, or the runs directory already holds another run
            under that id, or holds the source itself.
    """
    root = resolve_runs_dir(runs_dir)
    dest = root / record.run_id
    if dest.exists() and dest.resolve() == record.path.resolve():
        raise RunStoreError(
            f"{dest}: the runs directory holds the run to copy itself; give "
            "another --runs-dir (the source is never written)"
        )
    relative = [Path(p).relative_to(record.path) for p in models]
    missing = [m for m in relative if not (record.path / m).is_file()]
    if missing:
        raise RunStoreError(
            f"{record.path / missing[0]}: run {record.run_id} has no trained model to copy"
        )
    if dest.exists():
        same = (dest / "run.json").is_file() and all(
            (dest / m).is_file() and filecmp.cmp(record.path / m, dest / m, shallow=False)
            for m in relative
        )
        if not same:
            raise RunStoreError(
                f"{dest} already holds another run named {record.run_id}; "
                "remove it or give another --runs-dir"
            )
        if keep_evaluation:
            return dest
    else:
        with atomic_dir(dest, fsync=False) as tmp:
            shutil.copytree(record.path, tmp, ignore=_not_copied, dirs_exist_ok=True)
        notes = {k: v for k, v in record.info.notes.items() if k != "read_only"}
        RunStore(root).update_run(
            record.run_id, notes={**notes, "copy_of": portable_path(record.path)}
        )
    for table in (dest / "tables").glob("eval_*.parquet"):
        table.unlink()
    return dest


def _not_copied(directory: str, names: list[str]) -> set[str]:
    in_tables = Path(directory).name == "tables"
    return {
        n
        for n in names
        if n in ("checkpoints", "run.lock", "replay_buffer.pkl")
        or is_temp_file(n)
        or (in_tables and n.startswith("eval_") and n.endswith(".parquet"))
    }


def writable_run(
    record: RunRecord,
    models_of: ModelFiles,
    runs_dir: str | os.PathLike[str] | None = None,
    *,
    in_place: bool = False,
    on_copied: Callable[[RunRecord, RunRecord], None] | None = None,
) -> RunRecord:
    """The run a command that stores results writes into: ``record`` itself, or, for a
    shipped run (``notes.read_only``) unless ``in_place``, its copy in the runs directory
    (:func:`copy_run` of the files ``models_of(record)``, reused by later commands, so results
    accumulate there). ``on_copied(shipped, copy)`` is called when a copy is used.

    Raises:
        RunStoreError: the runs directory is the shipped run's own directory.
    """
    if in_place or not record.read_only:
        return record
    root = resolve_runs_dir(runs_dir)
    if root.resolve() == record.path.parent.resolve():
        raise RunStoreError(
            f"{record.path} is a shipped run (read-only) and --runs-dir is its own directory; "
            "give a --runs-dir for this machine's results (default runs/), or --in-place to "
            "write into the shipped run"
        )
    copied = copy_run(record, models_of(record), runs_dir=root, keep_evaluation=True)
    copy = RunStore(root).get_run(copied.name)
    if on_copied is not None:
        on_copied(record, copy)
    return copy
