"""The store's user-facing error and the fix for an unreadable run (a module of its own, so
light modules can raise and name them)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["RunStoreError", "unreadable_fix"]


class RunStoreError(Exception):
    """A user-facing problem with the run store; the message is one line with the fix."""


def unreadable_fix(run_path: Path) -> str:
    """What to do about a run directory whose ``run.json`` is missing or unreadable."""
    return (
        f"restore {run_path / 'run.json'} from a backup or copy, or move the directory "
        "out of the runs directory"
    )
