"""Where a run's code came from: the git commit of the checkout and the library versions."""

from __future__ import annotations

import functools
import importlib.metadata
import platform
import subprocess
from pathlib import Path

__all__ = ["git_info", "library_versions"]

_TRACKED_LIBRARIES = (
    "softtrack",
    "numpy",
    "scipy",
    "numba",
    "torch",
    "stable_baselines3",
    "sbx-rl",
    "jax",
    "gymnasium",
    "pyelastica",
    "pydantic",
    "pyarrow",
)


@functools.cache
def git_info(directory: str | None = None) -> tuple[str | None, bool | None]:
    """``(commit, dirty)`` of the git checkout containing ``directory`` (default: the
    softtrack package), or ``(None, None)`` outside git or without a git executable.

    ``dirty`` is true when tracked files differ from the commit or untracked (non-ignored)
    files exist. Read-only: ``--no-optional-locks`` keeps ``git status`` from touching the index.
    """
    cwd = directory or str(Path(__file__).resolve().parents[1])
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            check=False,
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=10,
        )
        if commit.returncode != 0:
            return None, None
        status = subprocess.run(
            ["git", "--no-optional-locks", "status", "--porcelain"],
            check=False,
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=30,
        )
    except (OSError, subprocess.SubprocessError):
        return None, None
    dirty = bool(status.stdout.strip()) if status.returncode == 0 else None
    return commit.stdout.strip() or None, dirty


def library_versions() -> dict[str, str]:
    """Versions of Python and the installed libraries that matter for results.

    Uses package metadata only (no imports, so torch is not loaded); absent ones are left out.
    """
    versions = {"python": platform.python_version()}
    for name in _TRACKED_LIBRARIES:
        try:
            versions[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    return versions
