"""A ``softtrack tune`` worker: take a trial, train its run, report its score; repeat.

:func:`work` loops until the study has no ticket left (:mod:`softtrack.tune.study`). For
each trial it draws the values, builds and validates the trial's run spec, creates the run
(run.json ``notes["tune"]``: study, trial number(s), storage) and trains it with
:func:`softtrack.rl.train.train_run`, reporting every checkpoint's validation score to Optuna
(``trial.report(score, step)``, step = the run's env steps; a centralized run's rounded down to
a multiple of ``training.checkpoint_interval``) and stopping the run when
``trial.should_prune()`` says so. The trial ends

* ``COMPLETE`` with the run's best validation score (:func:`run_score`),
* ``PRUNED`` (the run ``interrupted`` with ``notes["pruned"]``),
* ``FAIL`` when interrupted (the run ``interrupted``, resumable; a retry ticket resumes it),
  when training raised (the run ``failed``) or when its spec is invalid.

A retry ticket carries the run of the trial it retries: a completed run is only scored, an
interrupted or lost one resumes (its earlier validation scores are reported again first).

``python -m softtrack.tune.worker --storage URL --study NAME --runs-dir D`` is the process
the local pool and SLURM start; its exit code: 0 no ticket left, 128 + signal stopped, 1 it
stopped after :data:`~softtrack.tune.study.MAX_ERRORS_IN_A_ROW` failed trials, 2 a user error.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any

from softtrack.env.tasks import N_ARMS
from softtrack.evaluation.scores import scored_targets
from softtrack.evaluation.seed_statistics import interquartile_mean
from softtrack.executors.base import failed_by_signal
from softtrack.rl.factory import check_supported
from softtrack.rl.train import train_run
from softtrack.rl.validation import VALIDATION_TABLE, best_model, validation_score
from softtrack.signals import StopFlag, stop_on_signals
from softtrack.spec import ExperimentSpec, SpecError, spec_hash
from softtrack.store.runs import RunRecord, RunStore, RunStoreError
from softtrack.store.status import effective_status
from softtrack.store.tables import read_table
from softtrack.tune import TuneError
from softtrack.tune.study import (
    HEARTBEAT_S,
    MAX_ERRORS_IN_A_ROW,
    TuneStudy,
    enqueue_fresh,
    enqueue_retry,
    load_study,
    optuna_module,
    run_attr,
    shown_url,
    suggest,
    take_trial,
    trial_name,
    trial_spec,
)

__all__ = ["aggregate_scores", "main", "run_score", "run_trial", "work"]

Log = Callable[[str], None]


def _stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


@contextlib.contextmanager
def _heartbeat(storage: Any, trial_id: int) -> Iterator[None]:
    """Record the trial's Optuna heartbeat every :data:`HEARTBEAT_S` s while inside."""
    stop = threading.Event()

    def beat() -> None:
        while not stop.wait(HEARTBEAT_S):
            with contextlib.suppress(Exception):
                storage.record_heartbeat(trial_id)

    thread = threading.Thread(target=beat, name="optuna-heartbeat", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


def run_score(record: RunRecord, spec: ExperimentSpec) -> float:
    """The objective of a finished run: its best validation score (mean 3-D RMSE, m); for an
    independent run the mean over its arms' best.

    Raises:
        TuneError: a policy of the run has no validated checkpoint.
    """
    arms = [None] if spec.controller == "centralized" else list(range(N_ARMS))
    scores = []
    for arm in arms:
        best = best_model(record.policy_dir(arm))
        if best is None:
            raise TuneError(f"run {record.run_id} has no validated checkpoint to score")
        scores.append(best.score)
    return float(sum(scores) / len(scores))


def _report_step(spec: ExperimentSpec, step: int) -> int:
    interval = spec.training.checkpoint_interval
    if spec.controller == "centralized" and interval > 0:
        return int(step - step % interval)
    return int(step)


def _replay_scores(trial: Any, record: RunRecord, spec: ExperimentSpec) -> None:
    """Report a resumed run's validation scores so far to its new trial."""
    path = record.table_path(VALIDATION_TABLE)
    if not path.exists():
        return
    df = read_table(path)
    duration = float(spec.training.eval_duration)
    targets = scored_targets(spec.training.validation_score)
    if spec.controller == "centralized":
        for step, rows in df.groupby("global_step"):
            score = validation_score(rows, duration, targets)
            trial.report(float(score), _report_step(spec, int(step)))
        return
    budget = int(spec.training.total_timesteps)
    for (arm, step), rows in df.groupby(["arm", "global_step"]):
        score = validation_score(rows, duration, targets)
        trial.report(float(score), int(arm) * budget + int(step))


def _note_trial(store: RunStore, record: RunRecord, ts: TuneStudy, number: int) -> RunRecord:
    notes = dict(record.info.notes)
    tune = dict(notes.get("tune") or {})
    trials = [*tune.get("trials", [tune["trial"]] if "trial" in tune else []), number]
    tune.update(study=ts.name, trial=number, trials=trials, storage=shown_url(ts.url))
    return store.update_run(record.run_id, notes={**notes, "tune": tune})


def _same_values(ts: TuneStudy, values: dict[str, Any], record: RunRecord) -> bool:
    """Whether ``record`` was trained with the trial's ``values`` (its spec hash is that of
    the trial's spec under the run's own name)."""
    try:
        return spec_hash(trial_spec(ts, values, record.info.name)) == record.info.spec_hash
    except SpecError:
        return False


def _trial_run(
    ts: TuneStudy,
    trial: Any,
    spec: ExperimentSpec,
    store: RunStore,
    values: dict[str, Any],
    log: Log = _stderr,
    index: int = 0,
) -> tuple[RunRecord, str]:
    """The trial's run of seed index ``index`` (seed ``spec.seeds[0] + index``) and what to do
    with it: ``train``, ``resume``, ``score`` (completed), ``pruned``, ``failed`` (raised
    before) or ``busy`` (still training elsewhere).

    A retry's run is used only if it was trained with the trial's values; otherwise (or if it
    is gone) the trial gets a fresh run of its own."""
    attr = run_attr(index)
    run_id = trial.user_attrs.get(attr)
    if run_id:
        try:
            record = store.get_run(str(run_id))
        except RunStoreError:
            record = None
        if record is not None and not _same_values(ts, values, record):
            log(
                f"trial {trial.number}: run {record.run_id} was trained with other values; "
                "starting a fresh run for this trial"
            )
            record = None
        if record is not None:
            record = _note_trial(store, record, ts, trial.number)
            status = effective_status(record)
            if status == "completed":
                return record, "score"
            if status == "interrupted" and "pruned" in record.info.notes:
                return record, "pruned"
            if status in ("interrupted", "lost") or failed_by_signal(record.info):
                return record, "resume"
            if status == "queued":
                return record, "resume" if record.info.global_step else "train"
            return record, "failed" if status == "failed" else "busy"
    notes = {
        "tune": {
            "study": ts.name,
            "trial": trial.number,
            "trials": [trial.number],
            "storage": shown_url(ts.url),
        }
    }
    seed = spec.seeds[0] + index
    record = store.create_run(spec, seed, notes=notes, spec_files=ts.spec_files)
    trial.set_user_attr(attr, record.run_id)
    return record, "train"


def _fail(ts: TuneStudy, trial: Any, key: str, text: str) -> None:
    optuna = optuna_module()
    with contextlib.suppress(Exception):
        trial.set_user_attr(key, " ".join(text.split())[:500])
    with contextlib.suppress(optuna.exceptions.UpdateFinishedTrialError):
        ts.study.tell(trial, state=optuna.trial.TrialState.FAIL)


def aggregate_scores(scores: list[float], how: str) -> float:
    """A trial's objective from its runs' scores: their ``mean`` or ``iqm`` (interquartile
    mean, :func:`softtrack.evaluation.seed_statistics.interquartile_mean`)."""
    if how == "iqm":
        return interquartile_mean(scores)
    return float(sum(scores) / len(scores))


def run_trial(
    ts: TuneStudy,
    trial: Any,
    store: RunStore,
    log: Log = _stderr,
    show_progress: bool | None = None,
) -> tuple[str, int]:
    """Run one taken trial to its end (module docstring): its ``tune.seeds_per_trial`` runs
    one after another, the first watched by the pruner; returns (``complete``, ``pruned``,
    ``interrupted`` or ``failed``, the exit code of its training)."""
    number = trial.number
    try:
        values = suggest(trial, ts.tune)
        spec = trial_spec(ts, values, trial_name(ts.spec.name, number))
        check_supported(spec, f"study {ts.name} trial {number}")
    except (SpecError, RunStoreError) as exc:
        log(f"trial {number}: failed: {exc}")
        _fail(ts, trial, "error", str(exc))
        enqueue_fresh(ts.study, replaces=number)
        return "failed", 1
    scores = []
    for index in range(ts.tune.seeds_per_trial):
        state, code, score = _run_seed(ts, trial, store, spec, values, index, log, show_progress)
        if state != "complete":
            return state, code
        scores.append(score)
    score = aggregate_scores(scores, ts.tune.aggregate)
    try:
        ts.study.tell(trial, score)
    except optuna_module().exceptions.UpdateFinishedTrialError:
        log(
            f"trial {number}: already failed by another process (its heartbeat was late); "
            "its score is not counted"
        )
        return "failed", 1
    seeds = ""
    if len(scores) > 1:
        seeds = f" ({ts.tune.aggregate} of {', '.join(f'{v:.4f}' for v in scores)})"
    log(f"trial {number}: complete, validation score {score:.4f} m{seeds}")
    return "complete", 0


def _run_seed(
    ts: TuneStudy,
    trial: Any,
    store: RunStore,
    spec: ExperimentSpec,
    values: dict[str, Any],
    index: int,
    log: Log,
    show_progress: bool | None,
) -> tuple[str, int, float]:
    """Train (or resume, or score) the trial's run of seed index ``index``; returns its state
    as :func:`run_trial` does, the exit code and, when complete, its score. Only the first
    run reports its validation scores to the pruner."""
    optuna = optuna_module()
    number = trial.number
    watched = index == 0
    try:
        record, action = _trial_run(ts, trial, spec, store, values, log, index)
        spec = record.load_spec()
    except (SpecError, RunStoreError) as exc:
        log(f"trial {number}: failed: {exc}")
        _fail(ts, trial, "error", str(exc))
        enqueue_fresh(ts.study, replaces=number)
        return "failed", 1, math.nan
    shown = ", ".join(
        f"{p}={v:.4g}" if isinstance(v, float) else f"{p}={v}" for p, v in values.items()
    )
    verb = {"train": "training", "resume": "resuming"}.get(action, action)
    of = ""
    if ts.tune.seeds_per_trial > 1:
        of = f" (seed {record.info.seed}, run {index + 1} of {ts.tune.seeds_per_trial})"
    log(f"trial {number}: {verb} run {record.run_id} ({shown}){of}")
    if action in ("failed", "busy"):
        why = record.info.error if action == "failed" else "its run is training elsewhere"
        _fail(ts, trial, "error", f"run {record.run_id}: {why}")
        if action == "failed":
            enqueue_fresh(ts.study, replaces=number)
        return "failed", 1, math.nan
    if watched and action in ("resume", "pruned"):
        _replay_scores(trial, record, spec)
    if action == "pruned":
        ts.study.tell(trial, state=optuna.trial.TrialState.PRUNED)
        return "pruned", 0, math.nan
    if action in ("train", "resume"):
        taken_over: list[bool] = []

        def on_validation(step: int, score: float) -> bool:
            if not watched:
                return False
            try:
                trial.report(score if math.isfinite(score) else math.inf, _report_step(spec, step))
                return bool(trial.should_prune())
            except optuna.exceptions.UpdateFinishedTrialError:
                taken_over.append(True)  # failed by another process: stop, keep the run
                return True

        try:
            outcome = train_run(
                store,
                record,
                resume=action == "resume",
                show_progress=show_progress,
                on_validation=on_validation,
            )
        except Exception as exc:
            line = " ".join(f"{type(exc).__name__}: {exc}".split())
            log(f"trial {number}: failed: {line}")
            _fail(ts, trial, "error", line)
            enqueue_fresh(ts.study, replaces=number)
            return "failed", 1, math.nan
        if taken_over:
            notes = store.get_run(record.run_id).info.notes
            store.update_run(record.run_id, notes={k: v for k, v in notes.items() if k != "pruned"})
            log(
                f"trial {number}: failed by another process while training (its heartbeat "
                f"was late); run {record.run_id} stopped at a checkpoint for the retry"
            )
            return "failed", 1, math.nan
        if outcome.status == "interrupted":
            log(
                f"trial {number}: interrupted at step {outcome.global_step:,}; run "
                f"{record.run_id} resumes when the study continues"
            )
            _fail(ts, trial, "interrupted", f"interrupted at step {outcome.global_step}")
            enqueue_retry(ts.study, ts.storage.get_trial(ts.trial_id(number)), died=False)
            return "interrupted", outcome.exit_code, math.nan
        if outcome.status == "failed":
            log(f"trial {number}: failed: {outcome.error}")
            _fail(ts, trial, "error", f"run {record.run_id} failed: {outcome.error}")
            enqueue_fresh(ts.study, replaces=number)
            return "failed", 1, math.nan
        if outcome.status == "pruned":
            pruned = store.get_run(record.run_id).info.notes.get("pruned", {})
            log(
                f"trial {number}: pruned at step {pruned.get('global_step', 0):,} "
                f"(validation score {pruned.get('score', math.nan):.4f} m)"
            )
            ts.study.tell(trial, state=optuna.trial.TrialState.PRUNED)
            return "pruned", 0, math.nan
        record = store.get_run(record.run_id)
    try:
        return "complete", 0, run_score(record, spec)
    except TuneError as exc:
        _fail(ts, trial, "error", str(exc))
        enqueue_fresh(ts.study, replaces=number)
        return "failed", 1, math.nan


def _interrupted(ts: TuneStudy, trial: Any, why: str) -> None:
    """Fail a trial this worker still runs as interrupted, with a retry ticket for its slot."""
    trial_id = ts.trial_id(trial.number)
    if ts.storage.get_trial(trial_id).state.name != "RUNNING":
        return
    _fail(ts, trial, "interrupted", why)
    enqueue_retry(ts.study, ts.storage.get_trial(trial_id), died=False)


def work(
    ts: TuneStudy, runs_dir: str, *, log: Log = _stderr, show_progress: bool | None = None
) -> int:
    """Take and run the study's trials until none is left; the exit code (module docstring)."""
    store = RunStore(runs_dir)
    flag = StopFlag()
    errors = 0
    with stop_on_signals(flag):
        while not flag():
            trial = take_trial(ts, store)
            if trial is None:
                return 0
            if flag():  # a signal while the ticket was taken: hand it back as a retry
                _interrupted(ts, trial, "interrupted before training")
                break
            try:
                with _heartbeat(ts.storage, ts.trial_id(trial.number)):
                    result, code = run_trial(ts, trial, store, log, show_progress)
            except BaseException:  # a second Ctrl-C (the run is marked interrupted), a bug
                _interrupted(ts, trial, "interrupted (stopped at once)")
                raise
            if result == "interrupted":
                return code
            errors = errors + 1 if result == "failed" else 0
            if errors >= MAX_ERRORS_IN_A_ROW:
                log(
                    f"worker: {errors} failed trials in a row; stopping (see `softtrack tune "
                    f"--status {ts.name}` and `softtrack runs --failed`)"
                )
                return 1
    return 128 + (flag.signum or 2)


def main(argv: list[str] | None = None) -> int:
    """``python -m softtrack.tune.worker --storage URL --study NAME --runs-dir D``."""
    parser = argparse.ArgumentParser(prog="python -m softtrack.tune.worker")
    parser.add_argument("--storage", required=True, help="the study's storage URL")
    parser.add_argument("--study", required=True, help="the study name")
    parser.add_argument("--runs-dir", required=True, help="directory holding the runs")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    args = parser.parse_args(argv)
    import torch

    torch.set_num_threads(args.threads)
    try:
        ts = load_study(args.storage, args.study)
        return work(ts, args.runs_dir)  # its log: progress lines, not a bar
    except (TuneError, SpecError, RunStoreError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
