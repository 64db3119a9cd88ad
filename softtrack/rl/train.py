"""Train one run of the store, from scratch or resumed from its latest checkpoint(s).

:func:`train_run` owns the run while it trains: it marks it ``running``, trains its policies
with :class:`~softtrack.rl.policy_training.PolicyTrainer`, and ends it as

* ``completed``: every policy's budget is done and its final model saved (and, with
  ``training.confirm_episodes``, its kept model confirmed: :mod:`softtrack.rl.confirmation`);
* ``interrupted``: SIGINT or SIGTERM arrived (:mod:`softtrack.signals`); the current step
  finished, a checkpoint was saved and the pending episodes written (exit code 128 + signal:
  130 for SIGINT);
* ``failed``: an exception; run.json's ``error`` has its one-line summary and ``traceback``
  the full traceback. A full disk or a read-only one (:mod:`softtrack.store.disk`) ends the
  run ``interrupted`` instead, with the one-line reason in ``error`` and exit code 1: nothing
  is wrong with the run, and it resumes once there is space.

A caller may watch the validation scores (``on_validation``, used by ``softtrack tune``) and
stop the run after one (a *pruned* trial): training then stops as after a signal (checkpoint
saved), the run ends ``interrupted`` with run.json's ``notes["pruned"]`` =
``{"global_step", "score"}``, and the outcome's status is ``pruned``. ``softtrack resume``
leaves pruned runs alone unless named by id; resuming one drops the note.

A **centralized** run has one policy (``model.zip`` and ``checkpoints/`` in the run directory).
An **independent** run (docs/environment.md) trains one single-arm policy per arm, one after the other
(arm 0, then arm 1), each on the single-arm environment of its arm, with the run's algorithm
settings and ``training.total_timesteps`` env steps *per arm*; arm k's files are under
``models/arm<k>/`` (:mod:`softtrack.store.layout`), its seed is
:func:`~softtrack.rl.policy_training.arm_seed`, and its episode rows carry ``arm = k``.
run.json's ``global_step`` is the sum over the arms and ``arm_steps`` the steps per arm.

Resuming continues each unfinished policy from its newest checkpoint that loads (falling back
to older ones if one is corrupt, starting the policy over if none loads) and skips finished
arms (those with a ``model.zip``). A run killed with SIGKILL (status still ``running``)
resumes the same way. While it trains, the process holds the run's ``run.lock``
(:func:`~softtrack.store.runs.run_lock`), so two processes never train one run at once.
"""

from __future__ import annotations

import os
import signal
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from softtrack.env.tasks import N_ARMS
from softtrack.rl.confirmation import confirm_run
from softtrack.rl.factory import check_supported
from softtrack.rl.policy_training import (
    PolicyJob,
    PolicyTrainer,
    arm_seed,
    finished_state,
)
from softtrack.signals import StopFlag, stop_on_signals
from softtrack.spec import ExperimentSpec
from softtrack.store.atomic import remove_temp_files
from softtrack.store.disk import check_address_space, storage_problem
from softtrack.store.runs import (
    RunRecord,
    RunStore,
    RunStoreError,
    lock_held,
    pid_alive,
    run_lock,
)

__all__ = ["TrainOutcome", "check_resumable", "policy_jobs", "train_run"]


@dataclass(frozen=True)
class TrainOutcome:
    """How a call of :func:`train_run` ended.

    Attributes:
        run_id: the run.
        status: ``completed``, ``interrupted``, ``failed`` or ``pruned`` (stopped by
            ``on_validation``; the run itself is ``interrupted``).
        global_step: env steps done (over all sessions; independent: over both arms).
        steps_per_second: throughput of this session, env steps/s.
        exit_code: 0 (completed or pruned), 128 + signal number, or 1 (failed).
        error: one-line error of a failed run.
    """

    run_id: str
    status: str
    global_step: int
    steps_per_second: float | None
    exit_code: int
    error: str | None = None


def check_resumable(record: RunRecord) -> None:
    """Raise :class:`RunStoreError` if ``record`` is completed, still running here, or has
    lost the checkpoints it would resume from."""
    info = record.info
    if info.status == "completed":
        raise RunStoreError(
            f"run {record.run_id} is already completed; start a new run with `softtrack train SPEC`"
        )
    problem = record.checkpoint_problem()
    if problem is not None:
        raise RunStoreError(problem)
    if info.status == "running" and info.pid and info.pid != os.getpid():
        import socket

        held = lock_held(record)
        if held is False:  # the lock is free: nobody trains the run (pid may be reused)
            return
        if held or info.host == socket.gethostname():
            if not held and not pid_alive(info.pid):
                return
            raise RunStoreError(
                f"run {record.run_id} is still running (pid {info.pid}); stop it first "
                "(Ctrl-C or kill -TERM) and resume it then"
            )


def policy_jobs(spec: ExperimentSpec, record: RunRecord) -> list[PolicyJob]:
    """The policies of the run, in training order: one (centralized) or one per arm, each
    with the budget ``training.total_timesteps`` (run.json: :attr:`RunInfo.policy_budget
    <softtrack.store.run_records.RunInfo.policy_budget>`)."""
    seed = int(record.info.seed)
    total = int(spec.training.total_timesteps)
    if spec.controller == "independent":
        return [PolicyJob(record.policy_dir(k), arm_seed(seed, k), total) for k in range(N_ARMS)]
    return [PolicyJob(record.policy_dir(), seed, total)]


class _Progress:
    """Env steps per policy and the run.json fields they give."""

    def __init__(self, n_policies: int, independent: bool) -> None:
        self.steps = [0] * n_policies
        self.independent = independent
        self.known = False  # whether ``steps`` holds anything learned in this session

    def set(self, k: int, step: int) -> None:
        """Policy ``k`` is at ``step``."""
        self.steps[k] = int(step)
        self.known = True

    def fields(self, steps: list[int] | None = None) -> dict[str, Any]:
        steps = self.steps if steps is None else steps
        out: dict[str, Any] = {"global_step": int(sum(steps))}
        if self.independent:
            out["arm_steps"] = [int(s) for s in steps]
        return out

    def live(self, k: int) -> Callable[[int], dict[str, Any]]:
        """Fields while policy ``k`` is at a given step."""
        return lambda step: self.fields([*self.steps[:k], step, *self.steps[k + 1 :]])


def train_run(
    store: RunStore,
    record: RunRecord,
    *,
    resume: bool = False,
    show_progress: bool | None = None,
    on_validation: Callable[[int, float], bool] | None = None,
) -> TrainOutcome:
    """Train ``record`` to its budget; see the module docstring for the statuses.

    Args:
        store: the run store holding ``record``.
        record: the run (its ``spec.yaml`` defines everything).
        resume: continue from the latest checkpoint(s) (the run must not be completed).
        show_progress: force the progress bar on/off (default: on a terminal without ``CI``).
        on_validation: called after each validation of a checkpoint with the run's env steps
            at that checkpoint (for an independent run's arm k: the budgets of the arms before
            it plus the arm's own steps) and the validation score (m); returning true stops
            the run there (pruned, see the module docstring).

    Raises:
        SpecError: the run's spec is invalid or not supported.
        RunStoreError: the run cannot be resumed (completed, or still running).
    """
    spec = record.load_spec()
    check_supported(spec, str(record.spec_path))
    check_address_space("train")
    if resume:
        check_resumable(record)
    with run_lock(record):  # no other process can train this run while we hold it
        if resume:
            record = store.get_run(record.run_id)  # as it is now that we own it
            if record.info.status == "completed":
                check_resumable(record)
            remove_temp_files(record.path)
        return _train_locked(store, record, spec, resume, show_progress, on_validation)


def _train_locked(
    store: RunStore,
    record: RunRecord,
    spec: ExperimentSpec,
    resume: bool,
    show_progress: bool | None,
    on_validation: Callable[[int, float], bool] | None = None,
) -> TrainOutcome:
    jobs = policy_jobs(spec, record)
    progress = _Progress(len(jobs), spec.controller == "independent")
    flag = StopFlag(second_sigint_raises=True)
    trainer: PolicyTrainer | None = None
    k = 0
    pruned: dict[str, Any] = {}

    def validated(k: int) -> Callable[[int, float], None] | None:
        """The hook of policy ``k``: its steps → the run's, then ``on_validation``."""
        if on_validation is None:
            return None
        offset = sum(job.total_timesteps for job in jobs[:k])

        def hook(step: int, score: float) -> None:
            if not pruned and on_validation(offset + step, score):
                pruned.update(global_step=offset + step, score=score)
                flag.request()

        return hook

    notes = store.get_run(record.run_id).info.notes
    if "pruned" in notes:  # resumed on purpose: it is no longer a pruned run
        store.update_run(
            record.run_id, notes={key: v for key, v in notes.items() if key != "pruned"}
        )
    store.mark_running(record.run_id)
    try:
        with stop_on_signals(flag):
            clock_offset = 0.0
            sps: float | None = None
            finished = 0
            for k, job in enumerate(jobs):
                done = finished_state(job, record) if resume and job.arm is not None else None
                if done is not None:  # a finished arm of an earlier session
                    progress.set(k, done["global_step"])
                    clock_offset = done["wall_time"]
                    finished += 1
                    continue
                if flag():  # stopped between two arms: nothing to checkpoint
                    break
                trainer = PolicyTrainer(
                    store, record, spec, job, flag, show_progress, on_validation=validated(k)
                )
                result = trainer.run(
                    resume=resume, clock_offset=clock_offset, run_fields=progress.live(k)
                )
                trainer.close()
                trainer = None
                progress.set(k, result.step)
                clock_offset = result.wall_time
                sps = result.steps_per_second if result.steps_per_second is not None else sps
                if not result.finished:
                    break
                finished += 1
            fields = progress.fields()
            if sps is not None:
                fields["steps_per_second"] = sps
            step = fields["global_step"]
            if finished == len(jobs) and not confirm_run(record, spec, flag):
                finished -= 1  # stopped during the confirmation: resuming confirms again
            if finished < len(jobs) and pruned and flag.signum is None:
                notes = {**store.get_run(record.run_id).info.notes, "pruned": pruned}
                store.mark_finished(record.run_id, "interrupted", notes=notes, **fields)
                return TrainOutcome(record.run_id, "pruned", step, sps, 0)
            if finished < len(jobs):  # only a stop request ends the loop early
                signum = flag.signum if flag.signum is not None else signal.SIGINT
                store.mark_finished(record.run_id, "interrupted", **fields)
                return TrainOutcome(record.run_id, "interrupted", step, sps, 128 + signum)
            store.mark_finished(record.run_id, "completed", **fields)
            return TrainOutcome(record.run_id, "completed", step, sps, 0)
    except KeyboardInterrupt:  # a second Ctrl-C: stop now, without a checkpoint
        _finish_abruptly(store, record, trainer, progress, k, "interrupted", None)
        raise
    except Exception as exc:
        problem = storage_problem(
            exc, f"then continue with `softtrack train --resume {record.run_id}`", record.path
        )
        if problem is not None:  # a full or read-only disk: resumable once fixed
            fields = _finish_abruptly(store, record, trainer, progress, k, "interrupted", problem)
            step = int(fields.get("global_step", record.info.global_step))
            return TrainOutcome(record.run_id, "interrupted", step, None, 1, problem)
        text = "".join(traceback.format_exception(exc))
        line = " ".join(f"{type(exc).__name__}: {exc}".split())
        fields = _finish_abruptly(
            store, record, trainer, progress, k, "failed", line, traceback=text
        )
        step = int(fields.get("global_step", record.info.global_step))
        return TrainOutcome(record.run_id, "failed", step, None, 1, " ".join(line.split()))
    finally:
        if trainer is not None:
            trainer.close()


def _finish_abruptly(
    store: RunStore,
    record: RunRecord,
    trainer: PolicyTrainer | None,
    progress: _Progress,
    k: int,
    status: Any,
    error: str | None,
    **extra: Any,
) -> dict[str, Any]:
    """Keep what can be kept and record ``status``; returns the progress fields written."""
    if trainer is not None:
        trainer.abort()
        if trainer.step is not None:
            progress.set(k, trainer.step)
    fields = progress.fields() if progress.known else {}
    store.mark_finished(record.run_id, status, error=error, **extra, **fields)
    return fields
