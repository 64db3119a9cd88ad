"""The ``softtrack tune`` command: start or continue a study and run its workers.

:func:`tune` validates the spec (its ``tune:`` section included), creates the study or checks
that the existing one tunes the same spec, fills the free trial slots
(:func:`~softtrack.tune.study.top_up`: a dead worker's trial and an interrupted one are
retried, resuming their runs) and runs the workers (:func:`softtrack.tune.worker.work`):

* ``--executor local`` (default) with one worker: in this process;
* ``--executor local --workers N``: N worker processes (:class:`TuneWorker` in
  :class:`~softtrack.executors.local.LocalPool`), each pulling trials from the study, output
  appended to ``<runs dir>/tune-<study>-w<k>.log``; Ctrl-C/SIGTERM stops them cleanly;
* ``--executor slurm --workers N``: N SLURM jobs running the same worker
  (:func:`~softtrack.executors.slurm.submit_commands`), requeued and continued after a
  preemption; the storage must be reachable from the nodes (a SQLite file on a shared file
  system, or a database server);
* ``--detach``: start (or submit) the workers and return.

It returns a :class:`TuneOutcome`; running ``softtrack tune`` again with the same study
continues until ``--trials`` trials are finished.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from softtrack.executors import dispatch
from softtrack.executors.base import worker_env
from softtrack.executors.dispatch import ExecOptions, slurm_options
from softtrack.executors.local import LocalPool
from softtrack.rl.factory import check_supported
from softtrack.spec import SpecError, load_spec, spec_chain
from softtrack.store.atomic import atomic_write_text
from softtrack.store.provenance import portable_path
from softtrack.store.runs import RunStore, resolve_runs_dir
from softtrack.tune import TuneError
from softtrack.tune.study import (
    TuneStudy,
    best_spec_text,
    best_trial,
    counts,
    create_or_continue,
    default_storage,
    format_status,
    load_study,
    summary_line,
    top_up,
)

__all__ = ["TuneOutcome", "TuneWorker", "tune", "tune_best", "tune_status"]

_SAFE = re.compile(r"[^A-Za-z0-9_.-]+")


@dataclass(frozen=True)
class TuneWorker:
    """One worker process of a study for :class:`~softtrack.executors.local.LocalPool`."""

    runs_dir: str
    storage: str
    study: str
    index: int

    @property
    def key(self) -> str:
        return f"w{self.index}"

    @property
    def command(self) -> list[str]:
        return [
            sys.executable,
            "-m",
            "softtrack.tune.worker",
            "--storage",
            self.storage,
            "--study",
            self.study,
            "--runs-dir",
            str(self.runs_dir),
        ]

    def log_path(self) -> Path:
        """``<runs dir>/tune-<study>-w<k>.log`` (appended)."""
        return Path(self.runs_dir) / f"tune-{_SAFE.sub('_', self.study)}-w{self.index}.log"

    def after_exit(self, returncode: int) -> None:
        """Nothing: a trial its worker left running is failed and retried by the next worker
        that takes a trial (or the next ``softtrack tune``)."""


@dataclass
class TuneOutcome:
    """How ``softtrack tune`` ended.

    Attributes:
        study: the study name.
        storage: its storage URL.
        n_trials: the finished trials asked for.
        counts: trials per state (:func:`~softtrack.tune.study.counts`).
        summary: the study's one-line summary.
        detached: the workers were started (or submitted) in the background.
        stop_signal: the signal that stopped the workers, if any.
        log: the workers' log files (local pool) or submitit's folder.
    """

    study: str
    storage: str
    n_trials: int
    counts: dict[str, int] = field(default_factory=dict)
    summary: str = ""
    detached: bool = False
    stop_signal: int | None = None
    log: str | None = None
    #: workers that ended with an error: ``(name, exit code)`` (not a stop by signal)
    crashed: list[tuple[str, int]] = field(default_factory=list)

    @property
    def missing(self) -> int:
        """Trials still to finish."""
        return max(0, self.n_trials - self.counts.get("finished", 0))

    @property
    def exit_code(self) -> int:
        if self.detached:
            return 0
        if self.stop_signal is not None:
            return 128 + self.stop_signal
        return 1 if self.missing or self.crashed else 0


def _storage_url(storage: str | None, runs_dir: Path) -> str:
    return storage if storage else default_storage(runs_dir)


def tune(
    path: str | os.PathLike[str],
    overrides: Sequence[str] = (),
    *,
    trials: int,
    study: str | None = None,
    storage: str | None = None,
    runs_dir: str | os.PathLike[str] | None = None,
    options: ExecOptions | None = None,
    log: Callable[[str], None] | None = None,
    on_progress: Callable[[str], None] | None = None,
    show_progress: bool | None = None,
) -> TuneOutcome:
    """Tune ``path``'s ``tune:`` search space until ``trials`` trials are finished (module
    docstring). ``study`` defaults to the spec's name, ``storage`` to
    ``sqlite:///<runs dir>/optuna.db``.

    Raises:
        SpecError: the spec (or its tune section) is invalid, or has no tune section.
        TuneError: the study tunes another spec; the storage cannot be opened.
    """
    options = options or ExecOptions()
    if options.executor not in dispatch.EXECUTORS:
        raise SpecError(
            "--executor", f"unknown executor {options.executor!r}", "use local or slurm"
        )
    if trials < 1:
        raise SpecError("--trials", f"{trials} trials", "give 1 or more")
    spec = load_spec(path, overrides)
    if spec.tune is None:
        raise SpecError(
            str(path),
            "no tune: section, so there is nothing to search",
            "add one, e.g. tune: {params: {algo.learning_rate: {type: float, low: "
            "1.0e-4, high: 3.0e-3, log: true}}} (docs/tuning.md)",
            field="tune",
        )
    check_supported(spec, str(path))
    name = study or spec.name
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,127}", name):
        raise SpecError(
            "--study",
            f"invalid study name {name!r}",
            "use letters, digits, '_', '-' or '.', starting with a letter or digit",
        )
    root = resolve_runs_dir(runs_dir)
    url = _storage_url(storage, root)
    chain = [portable_path(f) for f in spec_chain(path)]
    ts = create_or_continue(url, name, spec, chain, os.path.abspath(path))
    store = RunStore(root)
    added = top_up(ts, store, trials)
    say = log or (lambda line: None)
    say(f"{summary_line(ts)}; {added} new trial{'s' if added != 1 else ''} queued")
    outcome = TuneOutcome(name, url, trials)
    workers = options.workers or 1
    if options.executor == "local":
        jobs = [TuneWorker(str(root), url, name, k) for k in range(workers)]
        if options.detach:
            for job in jobs:
                with open(job.log_path(), "ab") as fh:
                    subprocess.Popen(
                        job.command,
                        stdin=subprocess.DEVNULL,
                        stdout=fh,
                        stderr=subprocess.STDOUT,
                        start_new_session=True,
                        env=_worker_env(),
                    )
            outcome.detached, outcome.log = True, str(jobs[0].log_path().parent)
        elif workers == 1:
            # here, not at the top: the trainer (torch, JAX) loads when a trial runs here
            from softtrack.tune.worker import work

            code = work(ts, str(root), log=say, show_progress=show_progress)
            if code >= 128:
                outcome.stop_signal = code - 128
            elif code:
                outcome.crashed.append(("worker", code))
        else:
            pool = LocalPool(workers)
            root.mkdir(parents=True, exist_ok=True)
            codes = pool.run(jobs, on_tick=_ticker(ts, on_progress))
            outcome.stop_signal = pool.stop_signal
            if pool.stop_signal is None:
                outcome.crashed = [
                    (str(job.log_path()), codes[job.key])
                    for job in jobs
                    if codes.get(job.key, 0) != 0
                ]
            outcome.log = ", ".join(str(j.log_path()) for j in jobs)
    else:
        outcome.log = _run_on_slurm(ts, root, url, options, workers, on_progress)
        outcome.detached = options.detach
    outcome.counts = counts(ts.trials())
    outcome.summary = summary_line(ts)
    return outcome


def _worker_env() -> dict[str, str]:
    return worker_env(1)


def _ticker(ts: TuneStudy, on_progress: Callable[[str], None] | None) -> Callable[[], None]:
    last = [""]

    def tick() -> None:
        if on_progress is None:
            return
        line = summary_line(ts)
        if line != last[0]:
            last[0] = line
            on_progress(line)

    return tick


def _run_on_slurm(
    ts: TuneStudy,
    root: Path,
    url: str,
    options: ExecOptions,
    workers: int,
    on_progress: Callable[[str], None] | None,
) -> str:
    slurm = slurm_options(options, ts.spec.cluster, RunStore(root))
    root.mkdir(parents=True, exist_ok=True)
    jobs = [TuneWorker(str(root), url, ts.name, k) for k in range(workers)]
    from softtrack.executors.slurm import submit_commands  # submitit: for --executor slurm

    submitted = submit_commands(
        [(j.command, str(j.log_path())) for j in jobs], slurm, name=f"tune-{ts.name}"
    )
    if not options.detach:
        tick = _ticker(ts, on_progress)
        while not all(j.done() for j in submitted):
            tick()
            time.sleep(2.0)
        tick()
    return slurm.folder


def tune_status(
    study: str, *, storage: str | None = None, runs_dir: str | os.PathLike[str] | None = None
) -> str:
    """The study's summary and one line per trial (number, state, score, step, run, params,
    note: for a running trial, its training's step from the run store)."""
    root = resolve_runs_dir(runs_dir)
    return format_status(load_study(_storage_url(storage, root), study), RunStore(root))


def tune_best(
    study: str,
    out: str | os.PathLike[str] | None = None,
    *,
    storage: str | None = None,
    runs_dir: str | os.PathLike[str] | None = None,
) -> tuple[Path, Any]:
    """Write the study's best trial as a spec file (default ``<study>-best.yaml`` in the
    current directory; see :func:`~softtrack.tune.study.best_spec_text`); returns the file
    and the best trial (``optuna.trial.FrozenTrial``).

    Raises:
        TuneError: no such study, or no complete trial yet.
    """
    root = resolve_runs_dir(runs_dir)
    ts = load_study(_storage_url(storage, root), study)
    target = Path(out) if out is not None else Path(f"{_SAFE.sub('_', study)}-best.yaml")
    if target.is_dir():
        raise TuneError(
            f"--out {target}: is a directory; give a file name, e.g. "
            f"{target / (study + '-best.yaml')}"
        )
    text = best_spec_text(ts, target, root)
    atomic_write_text(target, text)
    return target, best_trial(ts)
