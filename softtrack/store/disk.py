"""One-line messages for the storage faults a user fixes outside softtrack: a full disk (or
quota), a read-only file system, a directory without write permission.

:func:`storage_problem` turns such an ``OSError`` (also pyarrow's, which carry the errno in
their text) into a line that names the directory, the free space and an estimate of the space
the write needed, or ``None`` for any other error (a bug: let its traceback show).
"""

from __future__ import annotations

import errno
import os
import re
import shutil
from pathlib import Path

from softtrack.store.atomic import is_temp_file

__all__ = ["FULL_ERRNOS", "READ_ONLY_ERRNOS", "storage_problem"]

#: "No space left on device" and "Disk quota exceeded".
FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT})
#: A read-only file system, or a directory this user may not write.
READ_ONLY_ERRNOS = frozenset({errno.EROFS, errno.EACCES, errno.EPERM})

_ERRNO_IN_TEXT = re.compile(r"\[errno (\d+)\]", re.IGNORECASE)
_PATH_IN_TEXT = re.compile(r"(/[^\s'\"]+)")


def _own_errno(exc: BaseException) -> int | None:
    """The errno of ``exc`` itself (pyarrow's OSErrors keep it in their text)."""
    code = getattr(exc, "errno", None)
    if code is None and isinstance(exc, OSError):
        found = _ERRNO_IN_TEXT.search(str(exc))
        code = int(found.group(1)) if found else None
    return int(code) if code is not None else None


def _errno(exc: BaseException) -> int | None:
    """The errno of ``exc`` or of an OSError it was raised from (pyarrow keeps it in the text)."""
    seen: BaseException | None = exc
    while seen is not None:
        if isinstance(seen, OSError) and _own_errno(seen) is not None:
            return _own_errno(seen)
        seen = seen.__cause__ or seen.__context__
    return None


def _path(exc: BaseException, attribute: str = "filename") -> Path | None:
    """The file ``exc`` (or an error it was raised from) names: its ``attribute``
    (``filename2``: the destination of a failed rename, the path the user chose rather than the
    temporary), else, for ``filename``, a path in its text."""
    seen: BaseException | None = exc
    while seen is not None:
        name = getattr(seen, attribute, None)
        if name:
            return Path(os.fsdecode(name))
        found = _PATH_IN_TEXT.search(str(seen)) if attribute == "filename" else None
        if found:
            return Path(found.group(1))
        seen = seen.__cause__ or seen.__context__
    return None


def _size(path: Path) -> int:
    if path.is_file():
        return path.stat().st_size
    total = 0
    for root, _dirs, files in os.walk(path):
        for name in files:
            try:
                total += (Path(root) / name).stat().st_size
            except OSError:
                pass
    return total


def _needed(path: Path) -> int | None:
    """What the failed write needed, estimated by the size of what it was replacing: the
    largest finished sibling of a temporary file or checkpoint directory (or the file itself)."""
    directory = path if path.is_dir() and not is_temp_file(path) else path.parent
    if not directory.is_dir():
        return None
    siblings = [p for p in directory.iterdir() if not is_temp_file(p)]
    sizes = [_size(p) for p in siblings if p.is_dir() or p.suffix == path.suffix]
    return max(sizes) if sizes and max(sizes) > 0 else None


def _mb(size: int) -> str:
    return f"{size / 1e6:.1f} MB" if size < 1e9 else f"{size / 1e9:.2f} GB"


def _existing_dir(path: Path) -> Path:
    directory = path if path.is_dir() and not is_temp_file(path) else path.parent
    while not directory.exists() and directory != directory.parent:
        directory = directory.parent
    return directory


#: The address space (bytes) a process needs once JAX and numba are loaded and a policy runs:
#: measured with ``ulimit -v`` on `softtrack evaluate` (2.86 GiB worked; 2.4 GiB hung in XLA's
#: allocator, 1.9 GiB aborted it), so a smaller limit is refused before anything starts.
MIN_ADDRESS_SPACE = 3_000_000 * 1024


class MachineLimitError(Exception):
    """The machine's limits (memory, open files) stop the command; one line with the fix,
    exit code 1 (not the user's input: 2)."""


def check_address_space(what: str) -> None:
    """Raise :class:`MachineLimitError` when the process's address-space limit
    (``ulimit -v``) is below :data:`MIN_ADDRESS_SPACE`: JAX would hang or abort in native code
    (no Python error to catch), so the command stops before it starts ``what``."""
    import resource

    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft != resource.RLIM_INFINITY and soft < MIN_ADDRESS_SPACE:
        raise MachineLimitError(
            f"the address-space limit (ulimit -v) is {_mb(soft)}, below the "
            f"{_mb(MIN_ADDRESS_SPACE)} that JAX and numba reserve to {what}; raise it "
            f"(e.g. ulimit -v {MIN_ADDRESS_SPACE // 1024 + 1_000_000}) and run the command again"
        )


def machine_limit(exc: BaseException) -> str | None:
    """A one-line message when ``exc`` (or an error it was raised from) is the machine's
    limit rather than softtrack's input: memory (``MemoryError``, ``ENOMEM``, a limit such as
    ``ulimit -v``), open files (``EMFILE``/``ENFILE``, ``ulimit -n``) or the size of a file
    (``EFBIG``, ``ulimit -f``); ``None`` otherwise."""
    import resource

    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        seen.add(id(current))
        if isinstance(current, MachineLimitError):
            return str(current)
        code = _own_errno(current)
        mapping = isinstance(current, ImportError) and "failed to map segment" in str(current)
        duckdb_memory = str(current).startswith(("Out of Memory Error", "query: Out of Memory"))
        if isinstance(current, MemoryError) or code == errno.ENOMEM or mapping or duckdb_memory:
            soft, _ = resource.getrlimit(resource.RLIMIT_AS)
            limit = (
                "no address-space limit"
                if soft == resource.RLIM_INFINITY
                else (f"the process may use {_mb(soft)} (ulimit -v)")
            )
            return (
                f"out of memory ({limit}); raise the limit or free memory, or ask for less "
                "(fewer episodes or runs at once, a narrower query)"
            )
        text = str(current)
        if code in (errno.EMFILE, errno.ENFILE) or "Too many open files" in text:  # DuckDB: text
            soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
            return (
                f"too many open files (the process may open {soft}: ulimit -n); raise the "
                "limit (e.g. ulimit -n 4096) and run the command again; no file is damaged"
            )
        if code == errno.EFBIG or "File too large" in text:  # pyarrow: text
            soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
            size = "no limit" if soft == resource.RLIM_INFINITY else f"{soft:,} bytes"
            return (
                f"a file reached the file-size limit ({size}: ulimit -f); raise the limit "
                "(e.g. ulimit -f unlimited) and run the command again; no stored file changed"
            )
        current = current.__cause__ or current.__context__
    return None


#: A path of the wrong kind: a file where a directory belongs (or the other way round).
PATH_KIND_ERRNOS = (errno.EEXIST, errno.ENOTDIR, errno.EISDIR)


def _path_kind_problem(code: int, path: Path, then: str) -> str:
    """One line for a file where softtrack needs a directory, or a directory where it needs
    a file (``mkdir`` onto a file, a path under a file, a directory opened as a file)."""
    after = f"; {then}" if then else ""
    if code == errno.EISDIR:
        return f"{path} is a directory where softtrack needs a file: move it away{after}"
    blocker = path
    if code == errno.ENOTDIR:  # some parent of the path is a file
        blocker = next((p for p in reversed(path.parents) if p.is_file()), path)
    return (
        f"{blocker} is a file where softtrack needs a directory: move it away or choose "
        f"another path{after}"
    )


def storage_problem(
    exc: BaseException, then: str = "", where: str | os.PathLike[str] | None = None
) -> str | None:
    """A one-line message for a full disk, a read-only/unwritable directory or a path of the
    wrong kind (a file where a directory belongs, or the other way round) behind ``exc``,
    ending with ``then`` (what to do once it is fixed); ``None`` for any other error.

    ``where``: the directory being written when the error does not name its file (a library
    writing through its own file object), e.g. the run's directory."""
    code = _errno(exc)
    if code is not None and code in PATH_KIND_ERRNOS:
        kind_path = _path(exc, "filename2") if code == errno.EISDIR else None
        kind_path = kind_path or _path(exc)
        if kind_path is not None and (code != errno.EEXIST or kind_path.is_file()):
            return _path_kind_problem(code, kind_path, then)
    if code not in FULL_ERRNOS and code not in READ_ONLY_ERRNOS:
        return None
    path = _path(exc) or (Path(where) if where is not None else None)
    directory = _existing_dir(path) if path is not None else Path.cwd()
    after = f"; {then}" if then else ""
    if code in FULL_ERRNOS:
        try:
            free = f"{_mb(shutil.disk_usage(directory).free)} free"
        except OSError:
            free = "free space unknown"
        need = _needed(path) if path is not None else None
        needed = f", about {_mb(need)} needed" if need else ""
        what = "disk quota exceeded" if code == errno.EDQUOT else "no space left on the device"
        return f"{what} writing in {directory} ({free}{needed}): free some space{after}"
    what = "is on a read-only file system" if code == errno.EROFS else "is not writable"
    return (
        f"{directory} {what} ({os.strerror(code)}): softtrack needs to write there; "
        f"use a writable runs directory (--runs-dir DIR or SOFTTRACK_RUNS_DIR){after}"
    )
