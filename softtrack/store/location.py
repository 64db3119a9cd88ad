"""Where the runs are: the runs directory a command uses, and the shipped run the quickstart
shows."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["QUICKSTART_PRETRAINED", "RUNS_DIR_ENV", "resolve_runs_dir"]

RUNS_DIR_ENV = "SOFTTRACK_RUNS_DIR"
QUICKSTART_PRETRAINED = "models/td3-sbx-1e7-seed0"
"""The shipped policy the quickstart shows beside its own short training (repo-relative)."""


def resolve_runs_dir(option: str | os.PathLike[str] | None = None) -> Path:
    """The runs directory: ``option`` if given, else ``$SOFTTRACK_RUNS_DIR``, else ``runs/``."""
    if option is not None and str(option) != "":
        return Path(option)
    env = os.environ.get(RUNS_DIR_ENV)
    return Path(env) if env else Path("runs")
