"""Copy a finished run into a small, self-contained run directory (for ``models/``, sharing).

An exported directory keeps what evaluation and reports read -- ``spec.yaml``, ``run.json``,
``tables/``, the training log -- and leaves out what only resuming needs: ``checkpoints/``
(models and replay buffers), the run lock and temporary files of killed writers. Its models
are laid out for users (:mod:`softtrack.store.layout`): each policy directory's ``model.zip``
is the run's policy, its other models sit in ``other_models/<name>/``, and ``policy.json``
says which model ``model.zip`` is. ``softtrack evaluate DIR`` and
``softtrack report NAME --runs-dir PARENT`` accept the result like any run. It is marked
read-only (``notes.read_only``): ``evaluate`` and ``robustness`` store their results in a copy
in the runs directory unless given ``--in-place``.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import zipfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from softtrack.store.atomic import (
    atomic_dir,
    atomic_write_json,
    atomic_write_text,
    is_temp_file,
    remove_stale_temp_files,
)
from softtrack.store.runs import RunInfo, RunRecord, RunStoreError

__all__ = ["EXCLUDED_NAMES", "MODEL_FILES", "ModelCopy", "export_run", "mark_read_only"]

EXCLUDED_NAMES = frozenset({"checkpoints", "run.lock", "replay_buffer.pkl"})
"""File and directory names never exported, at any depth of the run directory."""

MODEL_FILES = frozenset({"model.zip", "vecnormalize.pkl", "best", "other_models", "policy.json"})
"""Names of a policy directory that the export writes from :class:`ModelCopy` entries instead
of copying."""

_BESIDE_MODEL = ("vecnormalize.pkl",)


@dataclass(frozen=True)
class ModelCopy:
    """One model file to export.

    Attributes:
        source: the model file in the run (``model.zip``); its normalisation statistics
            (``vecnormalize.pkl``) beside it go along.
        dest: where it goes, relative to the exported directory (``…/model.zip``).
    """

    source: Path
    dest: Path


def export_run(
    record: RunRecord,
    models: Sequence[ModelCopy],
    manifests: Mapping[Path, Mapping[str, Any]],
    dest: str | os.PathLike[str],
    write_model: Callable[[Path, Path], object] = shutil.copy2,
    *,
    replacing: bool = False,
) -> Path:
    """Copy ``record``'s run directory to ``dest`` without checkpoints or replay buffers,
    writing its models as ``models`` lists them.

    Args:
        models: every model to export; each source must exist (the run is finished).
        manifests: ``policy.json`` contents by policy directory (relative to ``dest``).
        dest: the new directory; it must not exist. It appears complete or not at all.
        write_model: writes one model file (source, destination), e.g. an inference-only
            copy (:func:`softtrack.rl.policy_export.save_inference_model`).
        replacing: ``dest`` will take the run's own place (``softtrack upgrade``), so its
            directory may hold the run.

    Returns:
        ``dest`` as a :class:`Path`.

    Raises:
        RunStoreError: ``dest`` exists or lies inside the run, or a model file is missing.
    """
    dest = Path(dest)
    missing = [m.source for m in models if not m.source.is_file()]
    if missing:
        raise RunStoreError(
            f"{missing[0]}: run {record.run_id} has no final model (status "
            f"{record.info.status}); finish it with `softtrack train --resume {record.run_id}` "
            "before exporting"
        )
    for model in models:
        problem = _zip_problem(model.source)
        if problem is not None:
            raise RunStoreError(
                f"{model.source}: {problem}, so run {record.run_id} cannot be exported; "
                "restore the file from a copy of the run (nothing was written)"
            )
    source = record.path.resolve()
    _check_destination(record, source, dest, replacing)
    remove_stale_temp_files(dest)  # a killed export's copy (its writer is gone)
    policy_dirs = {source / relative for relative in manifests}
    try:
        with atomic_dir(dest) as tmp:
            _copy_run(source, tmp, models, manifests, policy_dirs, write_model)
    except FileExistsError:  # another export took the name first (its copy stays whole)
        raise RunStoreError(
            f"{dest} was created by another process while this export copied; choose a new "
            "directory (nothing of this export was kept)"
        ) from None
    except OSError as exc:
        if exc.errno in (errno.ENOTEMPTY, errno.EEXIST):
            raise RunStoreError(
                f"{dest} was created by another process while this export copied; choose a "
                "new directory (nothing of this export was kept)"
            ) from None
        raise
    return dest


def _check_destination(record: RunRecord, source: Path, dest: Path, replacing: bool) -> None:
    """Refuse (one line) a destination that exists, lies inside the run, under a file, or in
    a directory that already holds this run (the run id would appear twice there)."""
    if dest.exists() or dest.is_symlink():
        raise RunStoreError(f"{dest} already exists; choose a new directory or remove it first")
    full = dest.resolve()
    if full.is_relative_to(source):
        raise RunStoreError(f"{dest} is inside the run directory {source}; choose another place")
    for parent in full.parents:
        if parent.exists():
            if not parent.is_dir():
                raise RunStoreError(
                    f"{dest}: {parent} is a file, not a directory; choose a destination under "
                    "a directory"
                )
            break
    parent = full.parent
    if parent.is_dir() and not replacing:
        for sibling in parent.iterdir():
            if _same_run(sibling, record.info.run_id):
                raise RunStoreError(
                    f"{dest}: {parent} already holds run {record.info.run_id} (in "
                    f"{sibling.name}), and one runs directory holds a run once; export it "
                    "into another directory"
                )


def _zip_problem(path: Path) -> str | None:
    """Why the model file ``path`` is not a whole zip archive (truncated, damaged), or None."""
    try:
        with zipfile.ZipFile(path) as archive:
            # a truncated archive can open as the torch zip nested inside it: no "data"
            if "data" not in archive.namelist():
                return "not a whole model archive (no 'data' member: truncated?)"
            bad = archive.testzip()
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        return f"not a readable model archive ({str(exc) or type(exc).__name__})"
    return None if bad is None else f"its member {bad!r} is damaged (CRC mismatch)"


def _same_run(directory: Path, run_id: str) -> bool:
    """Whether ``directory`` holds a run whose run.json names ``run_id``."""
    path = directory / "run.json"
    try:
        if not path.is_file():
            return False
        return bool(json.loads(path.read_bytes()).get("run_id") == run_id)
    except (OSError, ValueError, AttributeError):
        return False


def _copy_run(
    source: Path,
    tmp: Path,
    models: Sequence[ModelCopy],
    manifests: Mapping[Path, Mapping[str, Any]],
    policy_dirs: set[Path],
    write_model: Callable[[Path, Path], object],
) -> None:
    """The export's files into ``tmp`` (see :func:`export_run`)."""
    for root, dirs, files in os.walk(source):
        skip = MODEL_FILES if Path(root) in policy_dirs else frozenset()
        dirs[:] = [d for d in dirs if d not in EXCLUDED_NAMES | skip and not is_temp_file(d)]
        target = tmp / Path(root).relative_to(source)
        target.mkdir(parents=True, exist_ok=True)
        for name in files:
            if name not in EXCLUDED_NAMES | skip and not is_temp_file(name):
                shutil.copy2(Path(root) / name, target / name)
    for model in models:
        target = tmp / model.dest
        target.parent.mkdir(parents=True, exist_ok=True)
        write_model(model.source, target)
        for name in _BESIDE_MODEL:
            if (model.source.parent / name).is_file():
                shutil.copy2(model.source.parent / name, target.parent / name)
    for relative, manifest in manifests.items():
        atomic_write_json(tmp / relative / "policy.json", dict(manifest))
    mark_read_only(tmp)


def mark_read_only(run_path: Path) -> None:
    """Mark a run directory as shipped: ``notes.read_only`` in its ``run.json``, so commands
    that store results write them into a copy (``softtrack evaluate --in-place`` overrides)."""
    info = RunInfo.model_validate_json((run_path / "run.json").read_bytes())
    info.notes = {**info.notes, "read_only": True}
    atomic_write_text(run_path / "run.json", info.model_dump_json(indent=2) + "\n")
