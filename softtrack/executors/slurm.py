"""A SLURM job array through ``submitit`` (``softtrack sweep --executor slurm``).

Install with ``pip install 'softtrack[cluster]'``. Each array task runs :class:`RunJob`: it
starts the worker process of its run and waits. When SLURM announces a preemption or the
time limit (submitit asks for ``USR2`` shortly before), submitit calls
:meth:`RunJob.checkpoint`: the worker gets SIGTERM, saves a checkpoint and marks the run
``interrupted``; the job is then requeued, and its next start resumes the run from that
checkpoint. ``cluster="local"`` (or ``$SOFTTRACK_SUBMITIT_CLUSTER=local``) uses submitit's
local executor, which runs the same code path without a cluster (the tests do).
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from softtrack.executors.base import Job, record_worker_exit, worker_env
from softtrack.store.runs import RunStore, RunStoreError, lock_held

__all__ = ["CLUSTER_ENV", "CommandJob", "RunJob", "SlurmOptions", "submit_commands", "submit_jobs"]

CLUSTER_ENV = "SOFTTRACK_SUBMITIT_CLUSTER"
STOP_WAIT_S = 120.0


def _submitit() -> Any:
    try:
        import submitit
    except ImportError:
        raise RunStoreError(
            "--executor slurm needs submitit; install it with `pip install 'softtrack[cluster]'`"
        ) from None
    return submitit


@dataclass(frozen=True)
class SlurmOptions:
    """Resources of each job (from the command line, else the spec's ``cluster`` section).

    Attributes:
        partition: SLURM partition (``None``: the default one).
        time_min: time limit of one job, min.
        cpus_per_task: cores per job.
        mem_gb: memory per job, GB.
        max_requeues: requeues allowed after preemption/time-out.
        parallelism: most array tasks running at once (``None``: no limit).
        folder: submitit's folder (job scripts, logs, pickles).
        cluster: ``None`` (SLURM if available), ``"slurm"``, ``"local"`` or ``"debug"``.
    """

    folder: str
    partition: str | None = None
    time_min: int = 240
    cpus_per_task: int = 1
    mem_gb: float = 4.0
    max_requeues: int = 10
    parallelism: int | None = None
    cluster: str | None = None


def _stop_worker(proc: subprocess.Popen[bytes] | None, job: Job) -> None:
    """SIGTERM the worker and wait (without ``Popen.wait``: we may be inside a signal handler
    that interrupted it) until it released the run's lock."""
    if proc is None or proc.returncode is not None:
        return
    try:
        os.kill(proc.pid, signal.SIGTERM)
    except ProcessLookupError:
        return
    store = RunStore(job.runs_dir)
    deadline = time.monotonic() + STOP_WAIT_S
    while time.monotonic() < deadline:
        try:
            if lock_held(store.get_run(job.run_id)) is not True:
                break
        except RunStoreError:
            break
        time.sleep(0.2)
    else:
        os.kill(proc.pid, signal.SIGKILL)


def _checkpointable_base() -> type:
    try:
        import submitit

        return submitit.helpers.Checkpointable
    except ImportError:  # softtrack works without the cluster extra
        return object


class RunJob(_checkpointable_base()):  # type: ignore[misc]
    """The submitit callable of one run: ``RunJob()(runs_dir, run_id)`` → worker exit code."""

    def __init__(self) -> None:
        self._proc: subprocess.Popen[bytes] | None = None

    def __getstate__(self) -> dict[str, Any]:
        return {}  # never pickle a live process

    def __setstate__(self, state: dict[str, Any]) -> None:
        self._proc = None

    def __call__(self, runs_dir: str, run_id: str) -> int:
        job = Job(runs_dir, run_id)
        threads = int(os.environ.get("SLURM_CPUS_PER_TASK", "1") or 1)
        with open(job.log_path(), "ab") as log:
            self._proc = subprocess.Popen(
                job.command,
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                env=worker_env(threads),
            )
        while self._proc.poll() is None:  # poll, not wait: checkpoint() may interrupt us
            time.sleep(0.5)
        code = int(self._proc.returncode)
        record_worker_exit(runs_dir, run_id, code)
        return code

    def checkpoint(self, runs_dir: str, run_id: str) -> Any:
        """Preempted or timed out: stop the worker (it checkpoints), then requeue a fresh job
        that resumes the run."""
        _stop_worker(self._proc, Job(runs_dir, run_id))
        submitit = _submitit()
        return submitit.helpers.DelayedSubmission(RunJob(), runs_dir, run_id)


class CommandJob(_checkpointable_base()):  # type: ignore[misc]
    """The submitit callable of any worker command (a ``softtrack tune`` worker):
    ``CommandJob()(command, log)`` runs ``command`` with its output appended to ``log`` and
    returns its exit code. Preempted or timed out, it SIGTERMs the worker (which ends its work
    cleanly), waits for it to exit (at most :data:`STOP_WAIT_S`, then SIGKILL) and requeues
    the same command."""

    def __init__(self) -> None:
        self._proc: subprocess.Popen[bytes] | None = None

    def __getstate__(self) -> dict[str, Any]:
        return {}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self._proc = None

    def __call__(self, command: list[str], log: str) -> int:
        threads = int(os.environ.get("SLURM_CPUS_PER_TASK", "1") or 1)
        with open(log, "ab") as fh:
            self._proc = subprocess.Popen(
                command,
                stdin=subprocess.DEVNULL,
                stdout=fh,
                stderr=subprocess.STDOUT,
                env=worker_env(threads),
            )
        while self._proc.poll() is None:
            time.sleep(0.5)
        return int(self._proc.returncode)

    def checkpoint(self, command: list[str], log: str) -> Any:
        proc = self._proc
        if proc is not None and proc.returncode is None:
            try:
                os.kill(proc.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
            else:
                if not _exited(proc.pid, STOP_WAIT_S):
                    os.kill(proc.pid, signal.SIGKILL)
        return _submitit().helpers.DelayedSubmission(CommandJob(), command, log)


def _exited(pid: int, timeout: float) -> bool:
    """Wait up to ``timeout`` s for child ``pid`` to exit (with ``waitpid``, not ``Popen``'s
    methods: we may be inside a signal handler that interrupted one of them)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if os.waitpid(pid, os.WNOHANG)[0]:
                return True
        except ChildProcessError:
            return True
        time.sleep(0.2)
    return False


def _executor(options: SlurmOptions) -> Any:
    """submitit's executor with ``options``' resources."""
    submitit = _submitit()
    cluster = options.cluster or os.environ.get(CLUSTER_ENV) or None
    Path(options.folder).mkdir(parents=True, exist_ok=True)
    executor = submitit.AutoExecutor(
        folder=str(Path(options.folder) / "%j"),
        cluster=cluster,
        slurm_max_num_timeout=options.max_requeues,
        local_max_num_timeout=options.max_requeues,
    )
    params: dict[str, Any] = {
        "timeout_min": int(options.time_min),
        "cpus_per_task": int(options.cpus_per_task),
        "mem_gb": float(options.mem_gb),
        "name": "softtrack",
    }
    if options.partition:
        params["slurm_partition"] = options.partition
    if options.parallelism:
        params["slurm_array_parallelism"] = int(options.parallelism)
    executor.update_parameters(**params)
    return executor


def submit_jobs(jobs: Sequence[Job], options: SlurmOptions) -> list[Any]:
    """Submit one array task per job; returns the submitit jobs."""
    executor = _executor(options)
    if not jobs:
        return []
    return list(executor.map_array(RunJob(), [j.runs_dir for j in jobs], [j.run_id for j in jobs]))


def submit_commands(
    commands: Sequence[tuple[list[str], str]], options: SlurmOptions, name: str = "softtrack"
) -> list[Any]:
    """Submit one array task per (command line, log file) (:class:`CommandJob`); returns the
    submitit jobs."""
    executor = _executor(options)
    executor.update_parameters(name=name)
    if not commands:
        return []
    return list(
        executor.map_array(
            CommandJob(), [list(c) for c, _ in commands], [log for _, log in commands]
        )
    )
