"""One version of every file a query reads, however often a statement reads it.

DuckDB reads a view's Parquet files each time a statement names the view, so a self-join (or
two statements of one query) could see a table before and after a writer replaced it (writers
replace files by renaming a temporary over them, :mod:`softtrack.store.atomic`). A
:class:`QuerySnapshot` gives each file a query reads a hard link in a directory of its own,
``<runs dir>/.softtrack-catalog/snapshots/<pid>-<token>/``: the link keeps the version that
was current when the view was made, whatever is renamed over the original later. The
directory is removed when the query closes; one left by a killed process is removed by the
next query whose process finds that pid gone.

Where a link cannot be made (a read-only runs directory, where no writer can replace a file
either; a run directory on another file system) the file is read in place.
"""

from __future__ import annotations

import os
import secrets
import shutil
from pathlib import Path

from softtrack.store.catalog_format import CATALOG_DIR

__all__ = ["SNAPSHOTS_DIR", "QuerySnapshot"]

#: Under the catalog directory: one sub-directory per open query.
SNAPSHOTS_DIR = "snapshots"


def _process_gone(name: str) -> bool:
    """Whether the process a snapshot directory is named after (``<pid>-<token>``) is gone."""
    pid_text = name.split("-", 1)[0]
    if not pid_text.isdigit():
        return False
    try:
        os.kill(int(pid_text), 0)
    except ProcessLookupError:
        return True
    except OSError:
        return False
    return False


class QuerySnapshot:
    """Hard links to the files one query reads (module docstring).

    Args:
        root: the runs directory.
    """

    def __init__(self, root: Path) -> None:
        self._parent = root / CATALOG_DIR / SNAPSHOTS_DIR
        self._directory: Path | None = None
        self._disabled = False
        self._links: dict[str, str] = {}

    def _make_directory(self) -> Path | None:
        if self._directory is None and not self._disabled:
            try:
                self._parent.mkdir(parents=True, exist_ok=True)
                for old in self._parent.iterdir():
                    if _process_gone(old.name):
                        shutil.rmtree(old, ignore_errors=True)
                directory = self._parent / f"{os.getpid()}-{secrets.token_hex(4)}"
                directory.mkdir()
            except OSError:
                self._disabled = True
                return None
            self._directory = directory
        return self._directory

    def pin(self, path: str, *, again: bool = False) -> str:
        """The path to read ``path``'s current version from for the rest of the query: a
        hard link to it, or ``path`` itself where no link can be made. A file pinned before
        keeps its first version unless ``again`` (its own writer replaced it since)."""
        if path in self._links and not again:
            return self._links[path]
        directory = self._make_directory()
        if directory is None:
            return path
        link = str(directory / f"{len(self._links)}.{Path(path).name}")
        try:
            os.link(path, link)
        except OSError:
            return path
        self._links[path] = link
        return link

    def original(self, text: str) -> str:
        """``text`` (an error message) with every link's path replaced by its file's."""
        for path, link in self._links.items():
            text = text.replace(link, path)
        return text

    def close(self) -> None:
        """Remove the links (the files themselves are untouched)."""
        if self._directory is not None:
            shutil.rmtree(self._directory, ignore_errors=True)
            self._directory = None
        self._links = {}
