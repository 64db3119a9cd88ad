"""A job (one run of the store), the worker command that trains it, and its bookkeeping."""

from __future__ import annotations

import os
import signal
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from softtrack.store.runs import RunStore, RunStoreError, lock_held

__all__ = [
    "EXIT_LOCKED",
    "Job",
    "PoolJob",
    "failed_by_signal",
    "record_worker_exit",
    "worker_env",
]

#: exit code of a worker whose run is already being trained by another process
EXIT_LOCKED = 3


@dataclass(frozen=True)
class Job:
    """One run to train: ``runs_dir`` and ``run_id``."""

    runs_dir: str
    run_id: str

    @property
    def command(self) -> list[str]:
        """The worker command line (``sys.executable -m softtrack.workers train ...``)."""
        return [
            sys.executable,
            "-m",
            "softtrack.workers",
            "train",
            "--runs-dir",
            str(self.runs_dir),
            self.run_id,
        ]

    def log_path(self) -> Path:
        """``<run>/train.log``: the worker's stdout and stderr (appended per session)."""
        return Path(self.runs_dir) / self.run_id / "train.log"

    @property
    def key(self) -> str:
        """What :class:`~softtrack.executors.local.LocalPool` knows the job by: the run id."""
        return self.run_id

    def after_exit(self, returncode: int) -> None:
        """Bookkeeping once the worker ended: :func:`record_worker_exit`."""
        record_worker_exit(self.runs_dir, self.run_id, returncode)


class PoolJob(Protocol):
    """What :class:`~softtrack.executors.local.LocalPool` runs: a :class:`Job`, or another
    worker command such as a ``softtrack tune`` worker (:mod:`softtrack.tune.command`)."""

    @property
    def key(self) -> str: ...

    @property
    def command(self) -> list[str]: ...

    def log_path(self) -> Path: ...

    def after_exit(self, returncode: int) -> None: ...


def worker_env(threads: int = 1) -> dict[str, str]:
    """The environment of a worker process: one thread for torch, BLAS and numba, no bars."""
    env = dict(os.environ)
    for key in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS"):
        env[key] = str(threads)
    env["CI"] = env.get("CI") or "1"
    return env


def record_worker_exit(runs_dir: str | os.PathLike[str], run_id: str, returncode: int) -> str:
    """After a worker process ended: if it died without recording an outcome (killed by a
    signal, e.g. SIGKILL or the OOM killer), mark the run failed-by-signal; its status now."""
    store = RunStore(runs_dir)
    try:
        record = store.get_run(run_id)
    except RunStoreError:
        return "missing"
    info = record.info
    if info.status != "running" or lock_held(record) is True or returncode == EXIT_LOCKED:
        return info.status
    if returncode < 0:
        signum = -returncode
        try:
            name = signal.Signals(signum).name
        except ValueError:
            name = f"signal {signum}"
        error = f"worker process killed by {name} ({signum}); resume it with `softtrack resume`"
    else:
        signum = None
        error = f"worker process exited with code {returncode} without recording an outcome"
    notes: dict[str, Any] = {**info.notes, "killed_by_signal": signum}
    store.mark_finished(run_id, "failed", error=error, notes=notes)
    return "failed"


def failed_by_signal(info: Any) -> bool:
    """Whether a failed run failed because its worker was killed (so it can be resumed)."""
    return info.status == "failed" and (info.notes or {}).get("killed_by_signal") is not None
