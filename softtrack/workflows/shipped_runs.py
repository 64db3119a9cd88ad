"""Shipped runs are only read: copies of them in the runs directory take results
(:mod:`softtrack.store.run_copies`, told which files are a run's policy)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from softtrack.rl.policy import (
    model_paths,
)
from softtrack.store import run_copies
from softtrack.store.runs import RunRecord
from softtrack.store.selection import select_one_run


def _policy_files(record: RunRecord) -> list[Path]:
    return model_paths(record, record.load_spec())


def copy_run(
    source: str | os.PathLike[str],
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    keep_evaluation: bool = False,
) -> Path:
    """Copy a finished run directory into the runs directory without its evaluation tables
    (:func:`softtrack.store.run_copies.copy_run`); returns the copy's directory."""
    record = select_one_run(str(source))
    return run_copies.copy_run(
        record, _policy_files(record), runs_dir=runs_dir, keep_evaluation=keep_evaluation
    )


def writable_run(
    record: RunRecord,
    runs_dir: str | os.PathLike[str] | None = None,
    *,
    in_place: bool = False,
    on_copied: Callable[[RunRecord, RunRecord], None] | None = None,
) -> RunRecord:
    """``record``, or its copy for results when it is shipped
    (:func:`softtrack.store.run_copies.writable_run`)."""
    return run_copies.writable_run(
        record, _policy_files, runs_dir, in_place=in_place, on_copied=on_copied
    )
