"""Validation during training: held-out random-target episodes on each checkpoint's model.

With ``training.validation_episodes: K`` (or, with K = 0, ``training.validation_paths`` ≥ 1),
every periodic checkpoint of a policy
(each ``training.checkpoint_interval`` env steps) is followed by K deterministic episodes of
``training.eval_duration`` on the policy's own random training target, from seeds
:data:`VALIDATION_SEED` + k. Training seeds its environments with the run seed + env index and
``softtrack evaluate --random`` uses ``RANDOM_TARGET_SEED`` + k, so validation episodes are
held out from both. The centralized policy is validated in the dual-arm scene; an independent
run's arm policy in the single-arm scene of its arm.

* ``tables/validation.parquet`` gets one row per checkpoint, episode and arm: ``global_step``
  (the policy's env steps), ``wall_time`` (the training clock at the checkpoint, s, which
  validation does not advance; absent in tables written before), ``episode``, ``seed`` and the
  columns of
  :func:`softtrack.evaluation.metrics_table`, with ``arm`` the arm's index in the dual-arm
  scene (an independent arm's rows carry its own index).
* With ``training.validation_trajectories`` the checkpoint's model also runs one
  deterministic episode of each ``training.eval_trajectories`` trajectory (what ``softtrack
  evaluate`` runs after training), stored as rows with that ``trajectory``, ``episode`` 0 and
  ``seed`` 0 (unused): the accuracy on the evaluation trajectories against env steps and
  ``wall_time``, for time-to-accuracy (``benchmarks/bench_time_to_accuracy.py``).
* With ``training.validation_paths: P`` the checkpoint's model also runs P held-out path
  episodes (target mode ``paths``: the trajectories' shapes scaled, moved, started at another
  phase, run either way round; path k from seed ``VALIDATION_PATH_SEED`` + k), rows with
  ``trajectory`` ``paths`` and ``episode`` K + k.
* The checkpoint's **validation score** is the mean 3-D RMSE over its random-target and
  held-out path rows (m), or ∞ if an episode went non-finite; the evaluation trajectories'
  rows never enter it.
* A model whose score is below every earlier one of its policy is saved to
  ``<policy>/best/step-<step>/`` (:class:`~softtrack.store.layout.PolicyDir`): ``model.zip``,
  ``vecnormalize.pkl`` when normalising, ``state.json`` (``global_step``, ``score``,
  ``episodes``). With ``training.final_policy: best_validated`` the newest such model is the
  run's policy.

Resuming from a checkpoint at step S drops the policy's rows and best models of steps after S
(:func:`truncate_validation`), and validates the restored checkpoint if that was cut short.
(Only a fallback past a corrupt checkpoint can drop the best model; only the newest is kept,
so the best then restarts from the next validation.)
Validation does not draw from training's random generators, so it leaves training unchanged.
"""

from __future__ import annotations

import contextlib
import json
import math
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from softtrack.env.settings import TrackingConfig
from softtrack.evaluation import (
    VALIDATION_PATH_SEED,
    VALIDATION_SEED,
    Episode,
    Policy,
    metrics_table,
    run_episodes,
    validation_score,
)
from softtrack.evaluation.episodes import EPISODE_BATCH
from softtrack.evaluation.scores import HELD_OUT_TARGETS, scored_targets
from softtrack.rl.callbacks import TrainingClock, reached
from softtrack.rl.numpy_actor import numpy_actor
from softtrack.rl.policy import deterministic_policy
from softtrack.rl.target_actor import acting_with_target_actor
from softtrack.spec import ExperimentSpec
from softtrack.spec.env_config import env_config
from softtrack.store.atomic import atomic_dir, atomic_write_json
from softtrack.store.layout import PolicyDir
from softtrack.store.runs import RunRecord, utc_now
from softtrack.store.tables import append_rows, read_table, write_table

__all__ = [
    "VALIDATION_SEED",
    "VALIDATION_TABLE",
    "BestModel",
    "Validator",
    "best_model",
    "checkpoint_rows",
    "held_out_rows",
    "truncate_validation",
    "validated_steps",
    "validation_score",
]

VALIDATION_TABLE = "validation"


@dataclass(frozen=True)
class BestModel:
    """The best-validated model of a policy so far.

    Attributes:
        step: the policy's env steps at its checkpoint.
        score: its validation score, mean 3-D RMSE, m.
    """

    step: int
    score: float


def best_model(policy: PolicyDir) -> BestModel | None:
    """The newest readable entry of ``policy``'s ``best/``, or ``None`` if it has none."""
    for directory in reversed(policy.list_best()):
        with contextlib.suppress(OSError, ValueError, KeyError, TypeError):
            state = json.loads((directory / "state.json").read_text(encoding="utf-8"))
            if (directory / "model.zip").is_file():
                score = state["score"]  # null: every episode failed (a score of ∞)
                return BestModel(
                    int(state["global_step"]), math.inf if score is None else float(score)
                )
    return None


def truncate_validation(record: RunRecord, policy: PolicyDir, step: int | None) -> None:
    """Drop ``policy``'s validation rows and best models of steps after ``step`` (all of them
    for ``step=None``: the policy starts over). Other arms' rows are kept."""
    for directory in policy.list_best():
        if step is None or int(directory.name.split("-")[1]) > step:
            shutil.rmtree(directory, ignore_errors=True)
    path = record.table_path(VALIDATION_TABLE)
    if not path.exists():
        return
    df = read_table(path)
    drop = policy.row_mask(df)
    if step is not None:
        drop &= (df["global_step"] > step).to_numpy()
    if not drop.any():
        return
    if drop.all():
        path.unlink()
    else:
        write_table(path, df[~drop].reset_index(drop=True))


def validated_steps(record: RunRecord, policy: PolicyDir) -> set[int]:
    """The steps of ``policy``'s checkpoints that have validation rows."""
    path = record.table_path(VALIDATION_TABLE)
    if not path.exists():
        return set()
    df = read_table(path, columns=["global_step", "arm"])
    return {int(s) for s in df.loc[policy.row_mask(df), "global_step"]}


def held_out_rows(
    run_id: str,
    act: Policy,
    config: TrackingConfig,
    duration: float,
    first_seed: int,
    episodes: int,
    arm: int | None,
    stop_requested: Callable[[], bool] = lambda: False,
) -> pd.DataFrame | None:
    """Run ``episodes`` deterministic random-target episodes of ``act`` (episode k from seed
    ``first_seed + k``, ``duration`` s each) and return their metrics: one row per episode
    and arm, the columns of :func:`softtrack.evaluation.metrics_table` plus ``episode`` and
    ``seed`` (``arm`` set to ``arm`` for an independent run's arm policy). ``None`` if
    ``stop_requested`` turned true between two episodes."""
    parts: list[pd.DataFrame] = []
    seeds = [first_seed + k for k in range(episodes)]
    for first in range(0, episodes, EPISODE_BATCH):
        if stop_requested():
            return None
        chunk = seeds[first : first + EPISODE_BATCH]
        parts.extend(
            _episode_rows(run_id, episode, first + j, seed, arm)
            for j, (seed, episode) in enumerate(
                zip(chunk, run_episodes(act, config, "random", duration, chunk), strict=True)
            )
        )
    return pd.concat(parts, ignore_index=True)


def _episode_rows(
    run_id: str, episode: Episode, index: int, seed: int, arm: int | None
) -> pd.DataFrame:
    """One validation episode's metrics rows with ``episode`` ``index``, its ``seed`` and, for
    an independent run's arm policy, that ``arm``."""
    metrics = metrics_table(run_id, episode)
    if arm is not None:
        metrics["arm"] = arm
    metrics.insert(2, "episode", index)
    metrics.insert(3, "seed", seed)
    return metrics


#: Validation episodes run as one batch (random-target episodes, held-out paths and
#: trajectories together): up to this many at a time, the policy always called with this many
#: rows (16 until 2026-12-07: 10 random targets, 16 paths and 3 trajectories took two batches,
#: one policy call per batch and control step; benchmarks/bench_validation.py).
VALIDATION_BATCH = 32


def _fixed_batch(act: Policy, rows: int) -> Policy:
    """``act`` (which takes batches) called with ``rows`` observations every time, zeros below
    the real ones: a batch's matrix products round by its shape, so a fixed shape makes an
    episode's actions independent of how many episodes share its batch (a checkpoint's
    random-target episodes score the same with or without the trajectories beside them)."""

    def padded(observation: np.ndarray) -> np.ndarray:
        batch = np.atleast_2d(observation)
        full = np.zeros((max(rows, len(batch)), batch.shape[1]), dtype=batch.dtype)
        full[: len(batch)] = batch
        actions = np.asarray(act(full), dtype=np.float64)[: len(batch)]
        return actions[0] if observation.ndim == 1 else actions

    padded.accepts_batches = True  # type: ignore[attr-defined]
    return padded


def checkpoint_rows(
    run_id: str,
    act: Policy,
    config: TrackingConfig,
    duration: float,
    episodes: int,
    trajectories: Sequence[str],
    arm: int | None,
    stop_requested: Callable[[], bool] = lambda: False,
    paths: int = 0,
    batch: int = VALIDATION_BATCH,
) -> pd.DataFrame | None:
    """One checkpoint's validation episodes, all in one batch of environments (up to
    ``batch``, default :data:`VALIDATION_BATCH`, at a time) with one call of ``act`` per
    control step when it accepts batches: ``episodes`` random-target episodes (episode k from seed
    :data:`VALIDATION_SEED` + k), ``paths`` held-out path episodes (target mode ``paths``,
    path k from seed :data:`VALIDATION_PATH_SEED` + k, numbered ``episodes`` + k) and one
    episode per trajectory of ``trajectories``.

    Returns their metrics as :func:`held_out_rows` does, the random episodes' rows first, then
    the paths', the trajectories' rows with ``episode`` and ``seed`` 0; ``None`` if
    ``stop_requested`` turned true between two batches. ``act`` must take batches: it is
    always called with ``batch`` rows (:func:`_fixed_batch`)."""
    act = _fixed_batch(act, batch)
    names = ["random"] * episodes + ["paths"] * paths + list(trajectories)
    seeds = (
        [VALIDATION_SEED + k for k in range(episodes)]
        + [VALIDATION_PATH_SEED + k for k in range(paths)]
        + [0] * len(trajectories)
    )
    indices = list(range(episodes + paths)) + [0] * len(trajectories)
    parts: list[pd.DataFrame] = []
    for first in range(0, len(names), batch):
        if stop_requested():
            return None
        chunk = slice(first, first + batch)
        ran = run_episodes(act, config, names[chunk], duration, seeds[chunk])
        parts.extend(
            _episode_rows(run_id, episode, index, seed, arm)
            for episode, index, seed in zip(ran, indices[chunk], seeds[chunk], strict=True)
        )
    return pd.concat(parts, ignore_index=True)


class Validator:
    """Validate one policy of a run after its checkpoints (module docstring).

    Args:
        record, spec: the run and its spec (``training.validates``: random-target or held-out
            path episodes).
        policy: the policy's directory (its arm selects the scene).
        stop_requested: a callable; when it turns true, validation stops between episodes
            and writes nothing (the checkpoint is validated when training resumes).
        log: where the one-line summary of each validation goes (default: stderr).
        clock: the run's training clock: its reading at the checkpoint goes into each row
            (``wall_time``, s) and it is paused while the episodes run, so training time
            leaves validation out (time-to-accuracy is training time).
        on_score: called with (the policy's step, the score) after each validation whose rows
            were written (``softtrack tune`` reports it to Optuna and may stop training).
    """

    def __init__(
        self,
        record: RunRecord,
        spec: ExperimentSpec,
        policy: PolicyDir,
        stop_requested: Callable[[], bool] = lambda: False,
        log: Callable[[str], None] | None = None,
        clock: TrainingClock | None = None,
        on_score: Callable[[int, float], None] | None = None,
    ) -> None:
        self.record = record
        self.on_score = on_score
        self.clock = clock
        self.policy = policy
        self.episodes = int(spec.training.validation_episodes)
        self.paths = int(spec.training.validation_paths)
        self.stop_score = spec.training.stop_score
        self.scored = scored_targets(spec.training.validation_score)
        if not spec.training.validates:
            raise ValueError(
                "training.validation_episodes and validation_paths are 0; a Validator needs "
                "at least one episode"
            )
        self.duration = float(spec.training.eval_duration)
        self.act_with_target_actor = spec.algo.act_with_target_actor
        self.trajectories = (
            list(spec.training.eval_trajectories) if spec.training.validation_trajectories else []
        )
        self.config = env_config(spec, policy.arm)
        self.stop_requested = stop_requested
        self.log = log or (lambda line: print(line, file=sys.stderr, flush=True))
        self.best = best_model(policy)

    def validate(self, model: Any) -> float | None:
        """Run the validation episodes of ``model`` at its current step, append their rows,
        keep it in ``best/`` if it beats the best so far, and return its score (m); ``None``
        if a stop request cut the episodes short."""
        step = int(model.num_timesteps)
        started = time.monotonic()
        normalizer = model.get_vec_normalize_env()
        wall_time = None if self.clock is None else self.clock.elapsed()
        with (
            self.clock.paused() if self.clock is not None else contextlib.nullcontext(),
            acting_with_target_actor(model, self.act_with_target_actor),
        ):
            act = numpy_actor(model, normalizer) or deterministic_policy(
                model, normalizer, batches=True
            )
            rows = checkpoint_rows(
                self.record.run_id,
                act,
                self.config,
                self.duration,
                self.episodes,
                self.trajectories,
                self.policy.arm,
                self.stop_requested,
                self.paths,
            )
        if rows is None:
            return None
        tracked = rows[~rows["trajectory"].isin(HELD_OUT_TARGETS)] if self.trajectories else None
        rows.insert(1, "global_step", step)
        if wall_time is not None:
            rows.insert(2, "wall_time", wall_time)
        score = validation_score(rows, self.duration, self.scored)
        improved = self.best is None or score < self.best.score
        if improved:  # before the rows: a kill in between leaves the step to validate again
            self._save_best(model, normalizer, step, score)
        append_rows(self.record.table_path(VALIDATION_TABLE), rows.to_dict("records"))
        assert self.best is not None
        name = f"{self.record.run_id[-8:]} {self.policy.label}".rstrip()
        tracking = ""
        carried = "object_rmse_3d" in rows  # transport: the sphere's error, once per episode
        if tracked is not None:
            column = "object_rmse_3d" if carried else "rmse_3d"
            per_trajectory = tracked.drop_duplicates("trajectory") if carried else tracked
            cells = per_trajectory.groupby("trajectory", sort=False)[column]
            tracking = (
                "; "
                + ", ".join(f"{t} {'/'.join(f'{v:.3f}' for v in part)}" for t, part in cells)
                + " m"
            )
        what = "the sphere's 3-D RMSE (a drop counts 1 m after it)" if carried else "3-D RMSE"
        scored = (self.episodes if "random" in self.scored else 0) + self.paths
        self.log(
            f"{name} validation at {step:,} steps: {what} {score:.4f} m over {scored} "
            f"episode{'s' if scored != 1 else ''} in {time.monotonic() - started:.0f} s"
            f"{' (new best)' if improved else ''}; "
            f"best {self.best.score:.4f} m at {self.best.step:,}{tracking}"
            + (
                f"; at or below training.stop_score {self.stop_score:g} m: training ends here"
                if reached(score, self.stop_score)
                else ""
            )
        )
        if self.on_score is not None:
            self.on_score(step, score)
        return score

    def _save_best(self, model: Any, normalizer: Any, step: int, score: float) -> None:
        target = self.policy.best_step_dir(step)
        if target.exists():  # saved before a kill cut its rows: validated again
            shutil.rmtree(target)
        with atomic_dir(target) as tmp:
            model.save(tmp / "model.zip")
            if normalizer is not None:
                normalizer.save(str(tmp / "vecnormalize.pkl"))
            atomic_write_json(
                tmp / "state.json",
                {
                    "global_step": step,
                    "score": score if math.isfinite(score) else None,
                    "episodes": self.episodes,
                    "saved": utc_now(),
                },
                fsync=False,
            )
        for older in self.policy.list_best()[:-1]:
            shutil.rmtree(older, ignore_errors=True)
        self.best = BestModel(step, score)
