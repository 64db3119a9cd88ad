"""Run a set of runs of the store on an executor, follow them, and say what is missing.

Used by :func:`softtrack.api.sweep` and :func:`softtrack.api.resume_runs`. The store is the
single source of truth: progress and the final account are read from ``run.json`` files, so
two sweeps writing into one runs directory only ever count their own runs.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from softtrack.executors.base import Job, failed_by_signal
from softtrack.executors.sweep import progress_counts
from softtrack.spec import ClusterSpec
from softtrack.store.ids import new_id
from softtrack.store.runs import RunRecord, RunStore, RunStoreError, lock_held
from softtrack.store.status import effective_status

__all__ = [
    "ExecOptions",
    "Outcome",
    "execute",
    "progress_line",
    "resumable",
    "select_resumable_runs",
]

EXECUTORS = ("local", "slurm")


@dataclass(frozen=True)
class ExecOptions:
    """Where and how the runs execute (command-line options; ``None``: the default).

    The SLURM fields fall back to the spec's ``cluster`` section.
    """

    executor: str = "local"
    workers: int | None = None
    detach: bool = False
    partition: str | None = None
    time_min: int | None = None
    cpus_per_task: int | None = None
    mem_gb: float | None = None
    slurm_folder: str | None = None
    cluster: str | None = None


@dataclass
class Outcome:
    """How a set of runs ended (or, detached, how it stood at submission).

    Attributes:
        sweep_id: the sweep (or resume) id.
        run_ids: the runs, in submission order.
        statuses: each run's (effective) status at the end.
        detached: the runs were handed to a background pool or to SLURM.
        stop_signal: the signal that stopped the pool, if any.
        log: the detached pool's log file, or submitit's folder.
    """

    sweep_id: str
    run_ids: list[str]
    statuses: dict[str, str] = field(default_factory=dict)
    detached: bool = False
    stop_signal: int | None = None
    log: str | None = None

    @property
    def missing(self) -> list[tuple[str, str]]:
        """(run id, status) of every run that is not completed."""
        return [
            (r, self.statuses.get(r, "?"))
            for r in self.run_ids
            if self.statuses.get(r) != "completed"
        ]

    @property
    def exit_code(self) -> int:
        if self.detached:
            return 0
        if self.stop_signal is not None:
            return 128 + self.stop_signal
        return 1 if self.missing else 0


def progress_line(label: str, records: Sequence[RunRecord]) -> str:
    """``sweep 01X…: 4 runs: 1 completed, 2 running, 1 queued; 2,340 steps/s``."""
    counts = progress_counts(records, effective_status)
    parts = [
        f"{counts[s]} {s}"
        for s in ("completed", "running", "queued", "interrupted", "failed", "lost")
        if counts[s] or s in ("completed", "running", "failed")
    ]
    return (
        f"{label}: {len(records)} runs: {', '.join(parts)}; "
        f"{counts['steps_per_second']:,.0f} steps/s"
    )


def _records(store: RunStore, run_ids: Sequence[str]) -> list[RunRecord]:
    out = []
    for run_id in run_ids:
        try:
            out.append(store.get_run(run_id))
        except RunStoreError:
            continue
    return out


def slurm_options(opts: ExecOptions, cluster: ClusterSpec, store: RunStore) -> Any:
    """The :class:`~softtrack.executors.slurm.SlurmOptions` of ``opts`` (else ``cluster``'s)."""
    from softtrack.executors.slurm import SlurmOptions  # submitit: only for --executor slurm

    return SlurmOptions(
        folder=opts.slurm_folder or str(store.root / ".submitit"),
        partition=opts.partition if opts.partition is not None else cluster.partition,
        time_min=opts.time_min or cluster.time_min,
        cpus_per_task=opts.cpus_per_task or cluster.cpus_per_task,
        mem_gb=opts.mem_gb or cluster.mem_gb,
        max_requeues=cluster.max_requeues,
        parallelism=opts.workers,
        cluster=opts.cluster,
    )


def execute(
    store: RunStore,
    run_ids: Sequence[str],
    opts: ExecOptions,
    sweep_id: str,
    *,
    cluster: ClusterSpec | None = None,
    on_progress: Callable[[str], None] | None = None,
    label: str | None = None,
) -> Outcome:
    """Run ``run_ids`` on ``opts.executor``; returns when all ended (or at once if detached)."""
    label = label or f"sweep {sweep_id}"
    outcome = Outcome(sweep_id, list(run_ids))
    jobs = [Job(str(store.root), r) for r in run_ids]
    last_line = [""]

    def tick() -> None:
        if on_progress is None:
            return
        line = progress_line(label, _records(store, run_ids))
        if line != last_line[0]:
            last_line[0] = line
            on_progress(line)

    if opts.executor == "local":
        from softtrack.executors.local import LocalPool  # the pool: only when it runs

        if opts.detach:
            log = store.root / f"sweep-{sweep_id}.log"
            with open(log, "ab") as fh:
                cmd = [
                    sys.executable,
                    "-m",
                    "softtrack.executors.local",
                    "--runs-dir",
                    str(store.root),
                ]
                if opts.workers:
                    cmd += ["--workers", str(opts.workers)]
                subprocess.Popen(
                    [*cmd, *run_ids],
                    stdin=subprocess.DEVNULL,
                    stdout=fh,
                    stderr=subprocess.STDOUT,
                    start_new_session=True,
                )
            outcome.detached, outcome.log = True, str(log)
        else:
            pool = LocalPool(opts.workers)
            pool.run(jobs, on_tick=tick)
            outcome.stop_signal = pool.stop_signal
    elif opts.executor == "slurm":
        from softtrack.executors.slurm import submit_jobs  # submitit, as above

        slurm = slurm_options(opts, cluster or ClusterSpec(), store)
        submitted = submit_jobs(jobs, slurm)
        outcome.log = slurm.folder
        if opts.detach:
            outcome.detached = True
        else:
            while not all(j.done() for j in submitted):
                tick()
                time.sleep(2.0)
            # the last heartbeat may lag the job's end by a moment
            deadline = time.monotonic() + 10
            while time.monotonic() < deadline and any(
                lock_held(r) for r in _records(store, run_ids)
            ):
                time.sleep(0.2)
            tick()
    else:
        raise RunStoreError(f"--executor {opts.executor}: unknown executor; use local or slurm")
    outcome.statuses = {r.run_id: effective_status(r) for r in _records(store, run_ids)}
    return outcome


def resumable(record: RunRecord) -> bool:
    """Interrupted (but not pruned by ``softtrack tune``), queued (never started),
    failed-by-signal and lost runs; never a shipped (read-only) run, which has no checkpoints
    (``notes.incomplete`` says why a shipped run stopped early)."""
    if record.read_only:
        return False
    status = effective_status(record)
    if status == "interrupted" and "pruned" in (record.info.notes or {}):
        return False
    return status in ("interrupted", "queued", "lost") or failed_by_signal(record.info)


def select_resumable_runs(store: RunStore, selection: Sequence[str]) -> list[RunRecord]:
    """The runs ``softtrack resume`` continues.

    Each item is an experiment name or a sweep id (its resumable runs: see :func:`resumable`)
    or a run id / unique prefix (that run, unless it is completed or still training; a pruned
    run too). No items: every resumable run of the store. Runs whose ``spec.yaml`` is missing
    or unreadable are left out (:func:`unresumable_runs` names them).

    Raises:
        RunStoreError: an item matches nothing, or a named run cannot be resumed.
    """
    records = store.list_runs()
    if not selection:
        return [r for r in records if resumable(r) and _resumes(r)]
    chosen: dict[str, RunRecord] = {}
    for item in selection:
        group = [
            r
            for r in records
            if r.info.name == item
            or str((r.info.notes or {}).get("sweep", "")).upper() == item.upper()
        ]
        if group:
            chosen.update((r.run_id, r) for r in group if resumable(r) and _resumes(r))
            continue
        record = store.get_run(item)  # raises RunNotFoundError with the fix
        problem = record.spec_problem()
        if problem is not None:
            raise RunStoreError(problem)
        if record.info.status == "completed":
            raise RunStoreError(f"run {record.run_id} is already completed; nothing to resume")
        problem = record.checkpoint_problem()
        if problem is not None:
            raise RunStoreError(problem)
        if lock_held(record) is True:
            raise RunStoreError(
                f"run {record.run_id} is still training (pid {record.info.pid} "
                f"on {record.info.host}); stop it first"
            )
        chosen[record.run_id] = record
    return sorted(chosen.values(), key=lambda r: r.run_id)


def unresumable_runs(store: RunStore) -> list[str]:
    """One line per run that :func:`select_resumable_runs` leaves out although it would be
    resumable: its run.json or spec.yaml is missing or unreadable (with what to do)."""
    lines = [
        f"run {item.path.name} left out: {item.reason}; {item.fix}"
        for item in store.list_unreadable()
    ]
    for record in store.list_runs():
        problem = record.spec_problem() or record.checkpoint_problem()
        if problem is not None and resumable(record):
            lines.append(f"run {record.run_id} left out: {problem}")
    return lines


def _resumes(record: RunRecord) -> bool:
    """Whether a resumable run can resume: its spec reads and its checkpoints are there."""
    return record.spec_problem() is None and record.checkpoint_problem() is None


def new_sweep_id() -> str:
    return new_id()


def cluster_of(store: RunStore, run_ids: Sequence[str]) -> ClusterSpec:
    """The ``cluster`` section of the first run's spec (defaults if unreadable)."""
    for record in _records(store, run_ids[:1]):
        try:
            return record.load_spec().cluster
        except Exception:
            break
    return ClusterSpec()
