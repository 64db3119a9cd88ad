"""Atomic file writes: temporary file in the same directory, fsync, then ``os.replace``.

A reader sees either the old complete file or the new complete file, never a partial one,
even if the writer is killed with SIGKILL or the machine loses power (the data is fsync-ed
before the rename and the directory after it). A killed writer can leave its temporary file
behind; temporary names start with ``.`` and contain ``.tmp-`` (see :func:`is_temp_file`), so
every reader in :mod:`softtrack.store` skips them and :func:`remove_temp_files` cleans them up.
Temporary names carry the writer's pid, so :func:`remove_stale_temp_files` can sweep those of
dead writers before the next write of the same file.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from softtrack.store.liveness import pid_alive

__all__ = [
    "TEMP_MARK",
    "atomic_dir",
    "atomic_path",
    "atomic_write_bytes",
    "atomic_write_json",
    "atomic_write_text",
    "fsync_dir",
    "fsync_file",
    "is_temp_file",
    "remove_stale_temp_files",
    "remove_temp_files",
    "temp_name",
]

TEMP_MARK = ".tmp-"
"""What every temporary name of this module contains (after a leading ``.``)."""


def _split(path: Path) -> tuple[str, str]:
    suffix = "".join(path.suffixes[-1:])
    return (path.name[: len(path.name) - len(suffix)] if suffix else path.name), suffix


def temp_name(path: Path) -> Path:
    """A fresh temporary sibling of ``path`` keeping its suffix and naming the writing
    process: ``.model.tmp-4711-3fa29c1b.zip`` (pid 4711)."""
    stem, suffix = _split(path)
    return path.with_name(f".{stem}{TEMP_MARK}{os.getpid()}-{os.urandom(4).hex()}{suffix}")


def _writer_alive(name: str) -> bool:
    """Whether the process named in a temporary file's name still runs (names without a pid,
    from older versions, count as dead)."""
    pid_text = name.partition(TEMP_MARK)[2].split("-", 1)[0]
    if not pid_text.isdigit() or "-" not in name.partition(TEMP_MARK)[2]:
        return False
    return pid_alive(int(pid_text))


def remove_stale_temp_files(path: str | os.PathLike[str]) -> list[Path]:
    """Delete the temporary siblings of ``path`` left by writers that died (killed before
    their cleanup could run); those of live processes stay. Returns the removed paths."""
    path = Path(path)
    stem, suffix = _split(path)
    prefix = f".{stem}{TEMP_MARK}"
    removed: list[Path] = []
    try:
        siblings = list(path.parent.iterdir())
    except OSError:
        return removed
    for sibling in siblings:
        name = sibling.name
        if name.startswith(prefix) and name.endswith(suffix) and not _writer_alive(name):
            if sibling.is_dir():
                shutil.rmtree(sibling, ignore_errors=True)
            else:
                sibling.unlink(missing_ok=True)
            removed.append(sibling)
    return removed


def is_temp_file(path: str | os.PathLike[str]) -> bool:
    """True for the name of a temporary file or directory made by this module."""
    name = Path(path).name
    return name.startswith(".") and TEMP_MARK in name


def fsync_file(path: Path) -> None:
    """Flush ``path``'s data to the disk."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_dir(path: Path) -> None:
    """Flush a directory's entries (a rename in it) to the disk, where supported."""
    try:
        fsync_file(path)
    except OSError:  # not supported on some platforms/file systems; the rename is still atomic
        pass


@contextmanager
def atomic_path(path: str | os.PathLike[str], *, fsync: bool = True) -> Iterator[Path]:
    """Yield a temporary path to write; on success it replaces ``path`` atomically.

    For writers that need a file name (``pyarrow.parquet.write_table``, ``model.save``)::

        with atomic_path(run.model_path) as tmp:
            model.save(tmp)

    The temporary file keeps ``path``'s suffix, so such writers do not append another one.
    If the block raises, the temporary file is removed and ``path`` is untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_name(path)
    try:
        yield tmp
        if not tmp.exists():
            raise FileNotFoundError(f"the writer did not create {tmp}")
        if fsync:
            fsync_file(tmp)
        os.replace(tmp, path)
        if fsync:
            fsync_dir(path.parent)
    except BaseException:
        try:
            tmp.unlink()
        except FileNotFoundError:
            pass
        raise


@contextmanager
def atomic_dir(path: str | os.PathLike[str], *, fsync: bool = True) -> Iterator[Path]:
    """Yield a temporary directory; on success it is renamed to ``path`` (which must not exist).

    For multi-file artefacts such as a checkpoint (model + replay buffer + normalisation
    state): the checkpoint directory appears complete or not at all. On error the temporary
    directory is deleted.

    Raises:
        FileExistsError: ``path`` already exists (checked before and at the rename).
    """
    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{path} already exists")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_name(path)
    tmp.mkdir()
    try:
        yield tmp
        if fsync:
            for root, _dirs, files in os.walk(tmp):
                for name in files:
                    fsync_file(Path(root) / name)
                fsync_dir(Path(root))
        os.rename(tmp, path)  # fails if path appeared meanwhile (non-empty dir) or is a file
        if fsync:
            fsync_dir(path.parent)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, *, fsync: bool = True) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path, fsync=fsync) as tmp, open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()


def atomic_write_text(
    path: str | os.PathLike[str], text: str, *, encoding: str = "utf-8", fsync: bool = True
) -> None:
    """Write ``text`` to ``path`` atomically."""
    atomic_write_bytes(path, text.encode(encoding), fsync=fsync)


def atomic_write_json(path: str | os.PathLike[str], obj: Any, *, fsync: bool = True) -> None:
    """Write ``obj`` as indented JSON (UTF-8, trailing newline) to ``path`` atomically.

    Non-finite floats are rejected (they are not JSON); serialise them as ``None`` first.
    """
    text = json.dumps(obj, indent=2, ensure_ascii=False, allow_nan=False) + "\n"
    atomic_write_text(path, text, fsync=fsync)


def remove_temp_files(directory: str | os.PathLike[str], *, recursive: bool = True) -> list[Path]:
    """Delete temporary files/directories left by killed writers under ``directory``.

    Only call this when no other process is writing there (e.g. when resuming a run).
    Returns the removed paths.
    """
    directory = Path(directory)
    if not directory.is_dir():
        return []
    removed: list[Path] = []
    for root, dirs, files in os.walk(directory):
        for name in list(dirs):
            if is_temp_file(name):
                shutil.rmtree(Path(root) / name, ignore_errors=True)
                removed.append(Path(root) / name)
                dirs.remove(name)
        for name in files:
            if is_temp_file(name):
                (Path(root) / name).unlink(missing_ok=True)
                removed.append(Path(root) / name)
        if not recursive:
            break
    return removed
