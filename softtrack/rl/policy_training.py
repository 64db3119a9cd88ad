"""Train one policy of a run: the centralized policy, or one arm's policy of an independent run.

:class:`PolicyTrainer` builds (or restores from the policy's newest loadable checkpoint) the
SB3 model and its environment, trains it to its budget with the callbacks of
:mod:`softtrack.rl.callbacks`, and either saves the final model (budget done) or, when a stop
was requested (signal), a checkpoint. The run's status is left to :mod:`softtrack.rl.train`.

Resuming restores the step count, replay buffer and normalisation statistics, and drops the
policy's rows of ``train_episodes`` written after that checkpoint (for an arm: only that arm's
rows), so the policy's episodes have no gaps or duplicates; the episodes the checkpoint cut
short become rows marked ``truncated`` (partial return), so every env step lies in a row.
Without a loadable checkpoint the policy starts over: its rows and checkpoints are deleted
first.
"""

from __future__ import annotations

import contextlib
import json
import shutil
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from softtrack.rl.callbacks import (
    Checkpointer,
    EpisodeLogger,
    GoalMotionWarmup,
    LearningRateDecay,
    ProgressMonitor,
    RandomisationWarmup,
    TrainingClock,
    reached,
    save_checkpoint,
)
from softtrack.rl.factory import build_model, load_model, make_vec_env
from softtrack.rl.replay_file import load_replay_buffer
from softtrack.rl.validation import Validator, truncate_validation, validated_steps
from softtrack.spec import ExperimentSpec
from softtrack.store.atomic import atomic_path, atomic_write_json
from softtrack.store.layout import PolicyDir
from softtrack.store.runs import RunRecord, RunStore, utc_now
from softtrack.store.tables import read_table, write_table

__all__ = ["PolicyJob", "PolicyResult", "PolicyTrainer", "arm_seed", "finished_state"]

_SEED_MODULUS = 2**32


def arm_seed(seed: int, arm: int) -> int:
    """The seed of arm ``arm``'s policy in an independent run of seed ``seed``.

    ``numpy.random.SeedSequence((seed, arm))``'s first 32-bit word: distinct per (seed, arm)
    with high probability, so the two arms see different targets and initial weights.
    """
    return int(np.random.SeedSequence([int(seed), int(arm)]).generate_state(1)[0])


def _offset_seed(seed: int, step: int) -> int:
    """The seed of a session resumed at ``step`` (kept below 2**32 for NumPy)."""
    return (int(seed) + int(step)) % _SEED_MODULUS


@dataclass(frozen=True)
class PolicyJob:
    """One policy of a run to train.

    Attributes:
        policy: where its files go (run directory, or ``models/arm<k>/``).
        seed: its seed (the run's seed, or :func:`arm_seed` for an arm).
        total_timesteps: its budget, env steps.
    """

    policy: PolicyDir
    seed: int
    total_timesteps: int

    @property
    def arm(self) -> int | None:
        """The arm index, or ``None`` for the centralized policy."""
        return self.policy.arm

    @property
    def columns(self) -> dict[str, Any]:
        """Extra columns of its episode rows: ``{"arm": k}`` for an arm, none otherwise."""
        return {} if self.arm is None else {"arm": int(self.arm)}


@dataclass(frozen=True)
class PolicyResult:
    """How :meth:`PolicyTrainer.run` ended.

    Attributes:
        step: the policy's env steps done (over all sessions).
        episodes: its episodes in the table.
        wall_time: training wall time of the run when it ended, s.
        steps_per_second: throughput of this session (``None`` if no step was taken).
        finished: the budget is done and the final model saved (else a checkpoint was saved).
    """

    step: int
    episodes: int
    wall_time: float
    steps_per_second: float | None
    finished: bool


def finished_state(job: PolicyJob, record: RunRecord) -> dict[str, Any] | None:
    """``{"global_step", "episodes", "wall_time"}`` of a finished arm, ``None`` if unfinished.

    An arm is finished when its ``model.zip`` exists; the values come from its ``state.json``
    (or, if that is unreadable, from its rows of the episode table).
    """
    if not job.policy.model_path.is_file():
        return None
    with contextlib.suppress(OSError, ValueError, KeyError, TypeError):
        state = json.loads(job.policy.state_path.read_text(encoding="utf-8"))
        return {
            "global_step": int(state["global_step"]),
            "episodes": int(state["episodes"]),
            "wall_time": float(state.get("wall_time", 0.0)),
        }
    rows = _job_rows(read_table(record.table_path("train_episodes"), missing_ok=True), job)
    return {
        "global_step": max(int(rows["global_step"].max()) if len(rows) else 0, job.total_timesteps),
        "episodes": len(rows),
        "wall_time": float(rows["wall_time"].max()) if len(rows) else 0.0,
    }


def _job_rows(df: Any, job: PolicyJob) -> Any:
    return df[job.policy.row_mask(df)] if len(df) else df


def _truncate_episodes(
    record: RunRecord, job: PolicyJob, step: int | None, episodes: int | None
) -> int:
    """Keep ``job``'s episodes written up to ``step`` (and below index ``episodes``); with
    ``step=None`` drop all of them. Other arms' rows are kept. Returns how many of ``job``'s
    rows remain (= its next episode index)."""
    path = record.table_path("train_episodes")
    if not path.exists():
        return 0
    df = read_table(path)
    mine = job.policy.row_mask(df)
    keep = ~mine if step is None else ~mine | (df["global_step"] <= step).to_numpy()
    if episodes is not None and step is not None:
        keep &= ~mine | (df["episode"] < episodes).to_numpy()
    if keep.all():
        return int(mine.sum())
    if not keep.any():
        path.unlink()
        return 0
    order = ["arm", "episode"] if "arm" in df.columns else ["episode"]
    kept = df[keep].sort_values(order, kind="stable").reset_index(drop=True)
    write_table(path, kept)
    return int((mine & keep).sum())


def _warn_fallback(failed: tuple[Path, str], fallback: Path | None) -> None:
    """Say on stderr (the run's ``train.log`` under an executor) that a checkpoint is corrupt."""
    path, reason = failed
    then = f"falling back to {fallback.name}" if fallback else "no older checkpoint: starting over"
    print(
        f"warning: {path}: corrupt checkpoint ({reason[:300]}); {then}", file=sys.stderr, flush=True
    )


class PolicyTrainer:
    """Train one :class:`PolicyJob` of a run; the attributes are for the caller's cleanup.

    Args:
        store, record, spec: the run and its spec.
        job: the policy to train.
        stop_requested: a callable; true once a signal asked training to stop.
        show_progress: force the progress bar on/off.
        on_validation: called with (the policy's step, the validation score) after each
            validation (:class:`~softtrack.rl.validation.Validator`'s ``on_score``).
    """

    def __init__(
        self,
        store: RunStore,
        record: RunRecord,
        spec: ExperimentSpec,
        job: PolicyJob,
        stop_requested: Any,
        show_progress: bool | None = None,
        on_validation: Callable[[int, float], None] | None = None,
    ) -> None:
        self.on_validation = on_validation
        self.store = store
        self.record = record
        self.spec = spec
        self.job = job
        self.stop_requested = stop_requested
        self.show_progress = show_progress
        self.model: Any = None
        self.env: Any = None
        self.episodes: EpisodeLogger | None = None
        self.monitor: ProgressMonitor | None = None

    @property
    def step(self) -> int | None:
        """The model's env steps, once a model exists."""
        return None if self.model is None else int(self.model.num_timesteps)

    def _tensorboard_dir(self) -> Path | None:
        """``<run>/tb`` when the spec logs to TensorBoard (``training.tensorboard``)."""
        return self.record.path / "tb" if self.spec.training.tensorboard else None

    def _restore(self) -> dict[str, Any] | None:
        """Load the newest loadable checkpoint into ``model``/``env``; its state, or None."""
        from stable_baselines3.common.vec_env import VecNormalize

        spec, job = self.spec, self.job
        failed: list[tuple[Path, str]] = []
        for checkpoint in reversed(job.policy.list_checkpoints()):
            if failed:
                _warn_fallback(failed[-1], checkpoint)
            env = None
            try:
                state = json.loads((checkpoint / "state.json").read_text(encoding="utf-8"))
                step = int(state["global_step"])
                env = make_vec_env(spec, _offset_seed(job.seed, step), job.arm, normalize=False)
                if spec.algo.normalize:
                    env = VecNormalize.load(str(checkpoint / "vecnormalize.pkl"), env)
                model = load_model(spec, checkpoint / "model.zip", env)
                buffer = checkpoint / "replay_buffer.pkl"
                if spec.algo.is_off_policy and buffer.exists():
                    load_replay_buffer(model, buffer)
                if int(model.num_timesteps) != step:
                    raise ValueError("model and state.json disagree on the step count")
                model.tensorboard_log = self._tensorboard_dir()  # None: off
                self.model, self.env = model, env
                return dict(state)
            except Exception as exc:
                if env is not None:
                    env.close()
                failed.append((checkpoint, " ".join(f"{type(exc).__name__}: {exc}".split())))
                continue
        if failed:
            _warn_fallback(failed[-1], None)
        return None

    def run(
        self,
        *,
        resume: bool,
        clock_offset: float,
        run_fields: Callable[[int], dict[str, Any]] | None = None,
    ) -> PolicyResult:
        """Train to the budget, or until a stop is requested.

        Args:
            resume: continue from the policy's newest checkpoint (or start it over cleanly).
            clock_offset: the run's training wall time so far, s (used without a checkpoint).
            run_fields: for :class:`ProgressMonitor`: the model's step → run.json fields.
        """
        spec, job, record = self.spec, self.job, self.record
        state = self._restore() if resume else None
        clock = TrainingClock(clock_offset)
        if state is not None:
            step = int(self.model.num_timesteps)
            next_episode = _truncate_episodes(record, job, step, state.get("episodes"))
            clock = TrainingClock(float(state.get("wall_time", clock_offset)))
            self.model.set_random_seed(_offset_seed(job.seed, step))
        else:
            if resume:  # nothing to resume from: start this policy over, cleanly
                _truncate_episodes(record, job, None, None)
                for old in job.policy.list_checkpoints():
                    shutil.rmtree(old, ignore_errors=True)
            self.env = make_vec_env(spec, job.seed, job.arm)
            self.model = build_model(spec, self.env, job.seed, self._tensorboard_dir())
            next_episode = 0
        training = spec.training
        episodes = EpisodeLogger(record, clock, next_episode, columns=job.columns)
        if state is not None and state.get("unfinished_episodes"):
            episodes.add_truncated(
                state["unfinished_episodes"],
                int(self.model.num_timesteps),
                float(state.get("wall_time", clock_offset)),
            )
            episodes.flush()
        self.episodes = episodes
        validator = self._validator(state, clock)
        checkpointer = Checkpointer(
            job.policy,
            episodes,
            clock,
            training.checkpoint_interval,
            training.keep_checkpoints,
            training.save_replay_buffer,
            after_save=None if validator is None else validator.validate,
            stop_score=training.stop_score,
        )
        self.monitor = ProgressMonitor(
            self.store,
            record,
            episodes,
            job.total_timesteps,
            training.heartbeat_interval,
            self.stop_requested,
            show=self.show_progress,
            run_fields=run_fields,
            label=job.policy.label,
        )
        from stable_baselines3.common.callbacks import CallbackList

        callbacks: list[Any] = [episodes, checkpointer, self.monitor]
        curricula = (
            (training.randomisation_warmup_steps, RandomisationWarmup),
            (training.goal_warmup_steps, GoalMotionWarmup),
        )
        for warmup_steps, curriculum in curricula:
            if warmup_steps > 0:
                step = int(self.model.num_timesteps)
                callbacks.insert(0, curriculum(warmup_steps, self.model.get_env(), step))
        if spec.algo.learning_rate_final is not None:
            callbacks.insert(
                0,
                LearningRateDecay(
                    job.total_timesteps,
                    spec.algo.learning_rate,
                    spec.algo.learning_rate_final,
                    spec.algo.learning_rate_decay_from,
                ),
            )
        remaining = job.total_timesteps - int(self.model.num_timesteps)
        if validator is not None and validator.best is not None:  # resumed past the stop
            checkpointer.stopped_early = reached(validator.best.score, training.stop_score)
        if remaining > 0 and not self.stop_requested() and not checkpointer.stopped_early:
            self.model.learn(
                total_timesteps=remaining if state is not None else job.total_timesteps,
                callback=CallbackList(callbacks),
                reset_num_timesteps=state is None,
                tb_log_name=job.policy.label or "policy",
                progress_bar=False,
            )
        self.monitor.close(checkpointer.stopped_early)
        sps = self.monitor.steps_per_second()
        if self.stop_requested():
            save_checkpoint(
                self.model,
                job.policy,
                episodes,
                clock,
                save_replay_buffer=training.save_replay_buffer,
                keep=training.keep_checkpoints,
            )
            finished = False
        else:
            episodes.flush()
            self._save_final(clock)
            finished = True
        return PolicyResult(
            int(self.model.num_timesteps), episodes.next_episode, clock.elapsed(), sps, finished
        )

    def _validator(self, state: dict[str, Any] | None, clock: TrainingClock) -> Validator | None:
        """The policy's :class:`Validator` (``None`` without validation episodes,
        :attr:`~softtrack.spec.TrainingSpec.validates`),
        after matching its table and best models to where training (re)starts. When the
        restored checkpoint lies in a checkpoint interval that has no validation yet (a
        validation cut short by a stop or a kill), it is validated now."""
        training, job = self.spec.training, self.job
        step = int(self.model.num_timesteps)
        truncate_validation(self.record, job.policy, None if state is None else step)
        if not training.validates:
            return None
        validator = Validator(
            self.record,
            self.spec,
            job.policy,
            self.stop_requested,
            clock=clock,
            on_score=self.on_validation,
        )
        interval = training.checkpoint_interval
        if state is not None and interval > 0 and step >= interval:
            done = {s // interval for s in validated_steps(self.record, job.policy)}
            if step // interval not in done:
                validator.validate(self.model)
        return validator

    def _save_final(self, clock: TrainingClock) -> None:
        """``vecnormalize.pkl``, (for an arm) ``state.json``, then ``model.zip``: the model
        comes last, so its presence means the policy is finished."""
        policy = self.job.policy
        vec_normalize = self.model.get_vec_normalize_env()
        if vec_normalize is not None:
            with atomic_path(policy.vecnormalize_path) as tmp:
                vec_normalize.save(str(tmp))
        if policy.arm is not None:
            assert self.episodes is not None
            atomic_write_json(
                policy.state_path,
                {
                    "arm": policy.arm,
                    "global_step": int(self.model.num_timesteps),
                    "episodes": self.episodes.next_episode,
                    "wall_time": clock.elapsed(),
                    "seed": self.job.seed,
                    "saved": utc_now(),
                },
            )
        with atomic_path(policy.model_path) as tmp:
            self.model.save(tmp)

    def abort(self) -> None:
        """Close the bar and write the pending episodes, ignoring errors (the status matters more)."""
        if self.monitor is not None:
            with contextlib.suppress(Exception):
                self.monitor.close()
        if self.episodes is not None:
            with contextlib.suppress(Exception):
                self.episodes.flush()

    def close(self) -> None:
        """Close the environment."""
        if self.env is not None:
            self.env.close()
            self.env = None
