"""Copy a finished run into a small, self-contained run directory (for ``models/``, sharing).

An exported directory keeps what evaluation and reports read -- ``spec.yaml``, ``run.json``,
the final model(s) with their normalisation statistics, ``tables/`` and the training log -- and
leaves out what only resuming needs: ``checkpoints/`` (models and replay buffers), the run lock
and temporary files of killed writers. ``softtrack evaluate DIR`` and
``softtrack report NAME --runs-dir PARENT`` accept the result like any run.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from softtrack.store.atomic import atomic_dir, is_temp_file
from softtrack.store.runs import RunRecord, RunStoreError

__all__ = ["EXCLUDED_NAMES", "export_run"]

EXCLUDED_NAMES = frozenset({"checkpoints", "run.lock", "replay_buffer.pkl"})
"""File and directory names never exported, at any depth of the run directory."""


def export_run(record: RunRecord, model_files: list[Path], dest: str | os.PathLike[str]) -> Path:
    """Copy ``record``'s run directory to ``dest`` without checkpoints or replay buffers.

    Args:
        model_files: the run's final model file(s); each must exist (the run is finished).
        dest: the new directory; it must not exist. It appears complete or not at all.

    Returns:
        ``dest`` as a :class:`Path`.

    Raises:
        RunStoreError: ``dest`` exists, or a model file is missing.
    """
    dest = Path(dest)
    missing = [p for p in model_files if not p.is_file()]
    if missing:
        raise RunStoreError(
            f"{missing[0]}: run {record.run_id} has no final model (status "
            f"{record.info.status}); finish it with `softtrack train --resume {record.run_id}` "
            "before exporting"
        )
    if dest.exists():
        raise RunStoreError(f"{dest} already exists; choose a new directory or remove it first")
    source = record.path.resolve()
    if dest.resolve().is_relative_to(source):
        raise RunStoreError(f"{dest} is inside the run directory {source}; choose another place")
    with atomic_dir(dest) as tmp:
        for root, dirs, files in os.walk(source):
            dirs[:] = [d for d in dirs if d not in EXCLUDED_NAMES and not is_temp_file(d)]
            target = tmp / Path(root).relative_to(source)
            target.mkdir(parents=True, exist_ok=True)
            for name in files:
                if name not in EXCLUDED_NAMES and not is_temp_file(name):
                    shutil.copy2(Path(root) / name, target / name)
    return dest
