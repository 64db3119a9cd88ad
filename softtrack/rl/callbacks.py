"""Stable-Baselines3 callbacks of a training run: episode table, checkpoints, heartbeat, progress.

* :class:`EpisodeLogger` collects finished episodes (``info["episode"]`` from ``VecMonitor``)
  and appends them to ``tables/train_episodes.parquet`` in batches (every ``flush_interval``
  seconds, at each checkpoint and at the end). Its episode counter continues across resumes.
  Rows of an independent run's arm carry an extra integer column ``arm``; their ``episode``
  and ``global_step`` count that arm's episodes and env steps.
* :class:`Checkpointer` writes ``checkpoints/step-<global step>/`` of the policy's directory
  (:class:`~softtrack.store.layout.PolicyDir`) atomically every
  ``training.checkpoint_interval`` env steps: ``model.zip``, ``replay_buffer.pkl``
  (off-policy, if ``training.save_replay_buffer``; only its filled rows, see
  :mod:`softtrack.rl.replay_file`), ``vecnormalize.pkl`` (if normalising) and
  ``state.json`` (global step, episode count, training wall time). Older checkpoints beyond
  ``training.keep_checkpoints`` are deleted. An ``after_save`` hook (validation, see
  :mod:`softtrack.rl.validation`) runs after each periodic checkpoint.
* :class:`RandomisationWarmup` raises the training environments' realism strength
  (:attr:`softtrack.env.realism.RealismModel.strength`) linearly from 0 to 1 over
  ``training.randomisation_warmup_steps`` env steps (a curriculum); it follows the model's step
  count, so a resumed run continues the ramp where it stopped.
* :class:`GoalMotionWarmup` (``training.goal_warmup_steps``) likewise raises the transport
  goal's motion from still to full (:mod:`softtrack.env.transport_env`).
* :class:`ProgressMonitor` updates run.json's heartbeat, shows a progress bar (steps/s and the
  latest episode return) on a terminal, or otherwise (a log file, a cluster job) prints whole
  progress lines: one at every :data:`PROGRESS_LINE_PERCENT` % of the budget and at least
  every :data:`PROGRESS_LINE_INTERVAL_S` seconds, and a final line (steps, elapsed time,
  steps/s) when training ends; it stops training when a stop was requested (signal).
"""

from __future__ import annotations

import math
import os
import shutil
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from softtrack.env.vec_env import TrackingVecEnv
from softtrack.rl.learning_rate import learning_rate_at
from softtrack.rl.replay_file import save_replay_buffer as save_replay_buffer_file
from softtrack.store.atomic import atomic_dir, atomic_write_json
from softtrack.store.layout import PolicyDir
from softtrack.store.runs import RunRecord, RunStore, utc_now
from softtrack.store.tables import append_rows

__all__ = [
    "PROGRESS_LINE_INTERVAL_S",
    "PROGRESS_LINE_PERCENT",
    "RECENT_EPISODES",
    "Checkpointer",
    "EpisodeLogger",
    "GoalMotionWarmup",
    "LearningRateDecay",
    "LinearWarmup",
    "ProgressMonitor",
    "RandomisationWarmup",
    "TrainingClock",
    "final_progress_line",
    "progress_line",
    "reached",
    "save_checkpoint",
    "unfinished_episodes",
]

PROGRESS_LINE_INTERVAL_S = 120.0
"""Longest time between progress lines when stderr is not a terminal (no bar), s."""
PROGRESS_LINE_PERCENT = 5.0
"""A progress line at every this many percent of the budget when stderr is not a terminal."""
RECENT_EPISODES = 20
"""The progress shows the mean return of this many last training episodes."""
#: Non-finite training returns that each get a warning line.
NON_FINITE_WARNINGS = 3


class TrainingClock:
    """Wall-clock seconds of training, continuing across resumes; time spent inside
    :meth:`paused` (validation episodes) does not count."""

    def __init__(self, offset: float = 0.0) -> None:
        self.offset = float(offset)
        self.start = time.monotonic()

    def elapsed(self) -> float:
        """Seconds since the clock's start plus its offset, less the paused time."""
        return self.offset + time.monotonic() - self.start

    @contextmanager
    def paused(self) -> Iterator[None]:
        """Stop the clock while the block runs."""
        began = time.monotonic()
        try:
            yield
        finally:
            self.offset -= time.monotonic() - began


class EpisodeLogger(BaseCallback):
    """Append finished training episodes to the run's ``train_episodes`` table.

    Args:
        record: the run.
        clock: the run's training clock (``wall_time`` column, s).
        next_episode: index of the next episode (the number already in the table).
        flush_interval: seconds between table appends.
        columns: extra constant columns of every row, e.g. ``{"arm": 1}``.
    """

    def __init__(
        self,
        record: RunRecord,
        clock: TrainingClock,
        next_episode: int = 0,
        flush_interval: float = 5.0,
        columns: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__(verbose=0)
        self.record = record
        self.clock = clock
        self.columns = dict(columns or {})
        self.next_episode = int(next_episode)
        self.flush_interval = flush_interval
        self.pending: list[dict[str, Any]] = []
        self.recent: deque[float] = deque(maxlen=RECENT_EPISODES)
        #: training episodes with an infinite or NaN return so far (this session)
        self.non_finite = 0
        self._last_flush = time.monotonic()

    @property
    def recent_return(self) -> float | None:
        """The mean return of the last :data:`RECENT_EPISODES` finished episodes (fewer at the
        start; ``None`` before the first)."""
        return sum(self.recent) / len(self.recent) if self.recent else None

    @property
    def path(self) -> Path:
        """The episode table."""
        return self.record.table_path("train_episodes")

    def _on_step(self) -> bool:
        infos = self.locals.get("infos") or []
        for info in infos:
            episode = info.get("episode") if isinstance(info, dict) else None
            if episode is None:
                continue
            ret = float(episode["r"])
            if not math.isfinite(ret):
                self._warn_non_finite(ret)
            self.pending.append(
                {
                    "run_id": self.record.run_id,
                    "episode": self.next_episode,
                    "global_step": int(self.num_timesteps),
                    "return": ret,
                    "length": int(episode["l"]),
                    "wall_time": float(self.clock.elapsed()),
                    **self.columns,
                }
            )
            self.next_episode += 1
            self.recent.append(ret)
        if self.pending and time.monotonic() - self._last_flush >= self.flush_interval:
            self.flush()
        return True

    def _warn_non_finite(self, ret: float) -> None:
        """One line for each of the first :data:`NON_FINITE_WARNINGS` non-finite returns."""
        self.non_finite += 1
        if self.non_finite <= NON_FINITE_WARNINGS:
            more = (
                "; later ones are stored without a line"
                if self.non_finite == NON_FINITE_WARNINGS
                else ""
            )
            print(
                f"warning: training episode {self.next_episode} (ending at env step "
                f"{int(self.num_timesteps):,}) has a return of {ret}: the simulation diverged "
                f"or the reward overflowed; the return is stored and makes the final-stage "
                f"return {ret} if it falls in that stage{more}",
                file=sys.stderr,
                flush=True,
            )

    def add_truncated(self, episodes: list[dict[str, Any]], step: int, wall_time: float) -> None:
        """Queue rows for episodes cut short at a checkpoint that training resumes from
        (:func:`unfinished_episodes` of that checkpoint), marked ``truncated`` with their
        partial return, so the episodes cover every env step."""
        for episode in episodes:
            self.pending.append(
                {
                    "run_id": self.record.run_id,
                    "episode": self.next_episode,
                    "global_step": int(step),
                    "return": float(episode["return"]),
                    "length": int(episode["length"]),
                    "wall_time": float(wall_time),
                    "truncated": True,
                    **self.columns,
                }
            )
            self.next_episode += 1

    def flush(self) -> None:
        """Append the pending episodes to the table (atomic replace)."""
        if self.pending:
            append_rows(self.path, self.pending)
            self.pending = []
        self._last_flush = time.monotonic()


def unfinished_episodes(env: Any) -> list[dict[str, float | int]]:
    """The episodes under way in each env of ``env`` (found through its ``VecMonitor``): their
    return so far and length, control steps; empty where none is under way or no monitor."""
    from stable_baselines3.common.vec_env import VecMonitor

    while env is not None and not isinstance(env, VecMonitor):
        env = getattr(env, "venv", None)
    if env is None:
        return []
    return [
        {"return": float(ret), "length": int(length)}
        for ret, length in zip(env.episode_returns, env.episode_lengths, strict=True)
        if int(length) > 0
    ]


def save_checkpoint(
    model: Any,
    policy: PolicyDir,
    episodes: EpisodeLogger,
    clock: TrainingClock,
    *,
    save_replay_buffer: bool,
    keep: int,
) -> Path | None:
    """Flush the episodes and write the policy's ``checkpoints/step-<num_timesteps>/`` atomically.

    Returns the checkpoint directory, or ``None`` if one for this step already exists.
    """
    episodes.flush()
    step = int(model.num_timesteps)
    target = policy.checkpoint_dir(step)
    if target.exists():
        return None
    with atomic_dir(target) as tmp:
        model.save(tmp / "model.zip")
        if save_replay_buffer and getattr(model, "replay_buffer", None) is not None:
            save_replay_buffer_file(model.replay_buffer, tmp / "replay_buffer.pkl")
        vec_normalize = model.get_vec_normalize_env()
        if vec_normalize is not None:
            vec_normalize.save(str(tmp / "vecnormalize.pkl"))
        atomic_write_json(
            tmp / "state.json",
            {
                "global_step": step,
                "episodes": episodes.next_episode,
                "wall_time": clock.elapsed(),
                "saved": utc_now(),
                "unfinished_episodes": unfinished_episodes(model.get_env()),
            },
            fsync=False,
        )
    for old in policy.list_checkpoints()[:-keep]:
        shutil.rmtree(old, ignore_errors=True)
    return target


def _tracking_core(env: Any) -> Any:
    """The :class:`~softtrack.env.core.TrackingCore` of a ``TrackingVecEnv``, possibly wrapped
    (``VecMonitor``, ``VecNormalize``)."""
    while not isinstance(env, TrackingVecEnv):
        if not hasattr(env, "venv"):
            raise TypeError(f"{type(env).__name__} wraps no TrackingVecEnv to ramp")
        env = env.venv
    return env.core


class LinearWarmup(BaseCallback):
    """A training curriculum: calls ``set_strength(min(1, step / warmup_steps))`` at
    construction for ``step``, so that the episodes the model's first reset starts are already
    ramped, then after every env step for the next one.

    Args:
        warmup_steps: env steps (the model's ``num_timesteps``) to reach full strength, > 0.
        set_strength: applies a strength in [0, 1] to the training environments.
        step: the model's step count when training (re)starts.

    Raises:
        ValueError: ``warmup_steps`` ≤ 0.
    """

    def __init__(
        self, warmup_steps: int, set_strength: Callable[[float], None], step: int = 0
    ) -> None:
        super().__init__()
        if warmup_steps <= 0:
            raise ValueError(f"warmup_steps={warmup_steps!r} must be > 0")
        self.warmup_steps = int(warmup_steps)
        self.set_strength = set_strength
        set_strength(self.strength_at(step))

    def strength_at(self, step: int) -> float:
        """The strength after ``step`` env steps, in [0, 1]."""
        return min(1.0, step / self.warmup_steps)

    def _on_step(self) -> bool:
        self.set_strength(self.strength_at(self.num_timesteps))
        return True


class RandomisationWarmup(LinearWarmup):
    """Raises the realism strength of the training environments (``env``: a
    ``TrackingVecEnv`` with realism settings, possibly wrapped) over ``warmup_steps`` env
    steps (:class:`LinearWarmup`; ``training.randomisation_warmup_steps``).

    Raises:
        ValueError: ``warmup_steps`` ≤ 0, or an environment without realism settings.
    """

    def __init__(self, warmup_steps: int, env: Any, step: int = 0) -> None:
        realism = _tracking_core(env).realism
        if realism is None:
            raise ValueError("a randomisation warm-up needs env.realism settings to ramp")
        self.realism = realism
        super().__init__(warmup_steps, self._set, step)

    def _set(self, strength: float) -> None:
        self.realism.strength = strength


class GoalMotionWarmup(LinearWarmup):
    """Raises the transport goal's motion in the training environments (``env``, as for
    :class:`RandomisationWarmup`) from still at the sphere's start to the full approach and
    path over ``warmup_steps`` env steps (``training.goal_warmup_steps``;
    :attr:`softtrack.env.transport_env.TransportModel.goal_motion`).

    Raises:
        ValueError: ``warmup_steps`` ≤ 0, or an environment without the transport task.
    """

    def __init__(self, warmup_steps: int, env: Any, step: int = 0) -> None:
        transport = _tracking_core(env).transport
        if transport is None:
            raise ValueError("a goal warm-up needs the transport task (env.task.name: transport)")
        self.transport = transport
        super().__init__(warmup_steps, self._set, step)

    def _set(self, strength: float) -> None:
        self.transport.goal_motion = strength


class Checkpointer(BaseCallback):
    """Save a checkpoint whenever ``num_timesteps`` crosses a multiple of ``interval``, then
    call ``after_save(model)`` (if given) with the model just saved; when that returns a
    score at or below ``stop_score`` (m), training stops there (:attr:`stopped_early`)."""

    def __init__(
        self,
        policy: PolicyDir,
        episodes: EpisodeLogger,
        clock: TrainingClock,
        interval: int,
        keep: int,
        save_replay_buffer: bool,
        after_save: Callable[[Any], Any] | None = None,
        stop_score: float | None = None,
    ) -> None:
        super().__init__(verbose=0)
        self.stop_score = stop_score
        self.stopped_early = False
        self.policy = policy
        self.episodes = episodes
        self.clock = clock
        self.interval = int(interval)
        self.keep = int(keep)
        self.save_replay_buffer = save_replay_buffer
        self.after_save = after_save
        self._last_bucket: int | None = None

    def _on_training_start(self) -> None:
        if self.interval > 0:
            self._last_bucket = self.num_timesteps // self.interval

    def _on_step(self) -> bool:
        if self.interval <= 0:
            return True
        bucket = self.num_timesteps // self.interval
        if self._last_bucket is not None and bucket > self._last_bucket:
            self._last_bucket = bucket
            if self.save() is not None and self.after_save is not None:
                score = self.after_save(self.model)
                if reached(score, self.stop_score):
                    self.stopped_early = True
                    return False
        return True

    def save(self) -> Path | None:
        """Write a checkpoint now (see :func:`save_checkpoint`)."""
        return save_checkpoint(
            self.model,
            self.policy,
            self.episodes,
            self.clock,
            save_replay_buffer=self.save_replay_buffer,
            keep=self.keep,
        )


def reached(score: float | None, stop_score: float | None) -> bool:
    """Whether a validation ``score`` (m; ``None``: cut short) ends training early at
    ``stop_score`` (m; ``None``: never)."""
    return stop_score is not None and score is not None and score <= stop_score


def _progress_enabled() -> bool:
    return sys.stderr.isatty() and not os.environ.get("CI")


def progress_line(
    name: str,
    step: int,
    total: int,
    steps_per_second: float | None,
    recent_return: float | None,
    updates_start: int = 0,
) -> str:
    """One line of training progress for a log, e.g. ``5JP1EEN4 2,650,720/4,000,000 steps
    (66.3%), 378 steps/s, mean return of the last 20 episodes 14,169.21, 59:29 min left`` (the
    episode return: the reward summed over a training episode, :attr:`EpisodeLogger.recent_return`).

    Before ``updates_start`` (the model's ``learning_starts``, env steps) the env steps run
    without gradient updates, several times faster than after: the line says when updates
    start instead of a time left that ``steps_per_second`` would underestimate."""
    parts = [f"{name} {step:,}/{total:,} steps ({100.0 * step / max(total, 1):.1f}%)"]
    if steps_per_second:
        parts.append(f"{steps_per_second:,.0f} steps/s")
    if recent_return is not None and math.isfinite(recent_return):
        parts.append(f"mean return of the last {RECENT_EPISODES} episodes {recent_return:,.2f}")
    if step < updates_start:
        parts.append(f"updates start at {updates_start:,} steps")
    elif steps_per_second and step < total:
        parts.append(f"{_elapsed((total - step) / steps_per_second)} left")
    return ", ".join(parts)


def _elapsed(seconds: float) -> str:
    """``5:49 min`` or ``2:03:07 h``."""
    total = max(0, round(seconds))
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d} h" if hours else f"{minutes}:{secs:02d} min"


def final_progress_line(
    name: str,
    step: int,
    total: int,
    seconds: float,
    steps_per_second: float | None,
    stopped_early: bool = False,
) -> str:
    """The last progress line of a training session, e.g. ``5JP1EEN4 finished: 100,000/100,000
    steps (100.0%) in 5:49 min, 286 steps/s`` (``stopped`` before the budget is reached,
    ``finished early`` at ``training.stop_score``)."""
    state = "finished" if step >= total else "finished early" if stopped_early else "stopped"
    line = (
        f"{name} {state}: {step:,}/{total:,} steps ({100.0 * step / max(total, 1):.1f}%) "
        f"in {_elapsed(seconds)}"
    )
    if steps_per_second:
        line += f", {steps_per_second:,.0f} steps/s"
    return line


class ProgressMonitor(BaseCallback):
    """Heartbeat into run.json, a progress bar, and a stop switch.

    Args:
        store, record: the run.
        episodes: the episode logger (for the latest return).
        total_timesteps: the budget (for the bar).
        heartbeat_interval: seconds between run.json updates.
        stop_requested: a callable; when it returns true, training stops after this step.
        show: ``True`` a tqdm bar on stderr, ``False`` nothing, ``None`` (default) a bar when
            stderr is a terminal and ``CI`` is unset, else whole lines on stderr: a
            :func:`progress_line` at every :data:`PROGRESS_LINE_PERCENT` % of the budget and
            at least every ``line_interval`` seconds, and a :func:`final_progress_line` when
            the monitor is closed.
        run_fields: maps the model's step count to the run.json progress fields (default
            ``{"global_step": step}``; an independent run adds the other arm's steps).
        label: shown after the run id in the bar, e.g. ``arm1``.
        line_interval: the longest time between progress lines, s (default
            :data:`PROGRESS_LINE_INTERVAL_S`).
    """

    def __init__(
        self,
        store: RunStore,
        record: RunRecord,
        episodes: EpisodeLogger,
        total_timesteps: int,
        heartbeat_interval: float,
        stop_requested: Any,
        show: bool | None = None,
        run_fields: Callable[[int], dict[str, Any]] | None = None,
        label: str = "",
        line_interval: float | None = None,
    ) -> None:
        super().__init__(verbose=0)
        self.store = store
        self.record = record
        self.episodes = episodes
        self.total_timesteps = int(total_timesteps)
        self.heartbeat_interval = heartbeat_interval
        self.stop_requested = stop_requested
        self.show = _progress_enabled() if show is None else show
        self.print_lines = show is None and not self.show
        self.line_interval = PROGRESS_LINE_INTERVAL_S if line_interval is None else line_interval
        self.run_fields = run_fields or (lambda step: {"global_step": step})
        self.label = label
        self._bar: Any = None
        self._start_time = time.monotonic()
        self._start_step = 0
        self._last_beat = time.monotonic()
        self._last_bar = 0.0
        self._last_line = time.monotonic()
        self._last_milestone = 0
        self._final_printed = False
        self._updates_from = (self._start_time, 0)  # (monotonic s, env step)

    @property
    def name(self) -> str:
        """The run's short id and the policy's label, e.g. ``5JP1EEN4 arm1``."""
        return f"{self.record.run_id[-8:]} {self.label}".rstrip()

    def _milestone(self, step: int) -> int:
        """How many :data:`PROGRESS_LINE_PERCENT` steps of the budget ``step`` has passed."""
        return int(100.0 * step / max(self.total_timesteps, 1) // PROGRESS_LINE_PERCENT)

    def steps_per_second(self) -> float | None:
        """Env steps per second of this session (``None`` before the first step)."""
        dt = time.monotonic() - self._start_time
        done = self.num_timesteps - self._start_step
        return done / dt if dt > 0 and done > 0 else None

    @property
    def updates_start(self) -> int:
        """The env step from which the model makes gradient updates (its ``learning_starts``;
        0 for an on-policy model)."""
        return int(getattr(self.model, "learning_starts", 0) or 0)

    def updating_steps_per_second(self) -> float | None:
        """Env steps per second of this session since the model's updates began (validation
        pauses included): the rate the rest of the training runs at. Before updates begin,
        the session's rate (``None`` before the first step)."""
        if self.num_timesteps < self.updates_start:
            return self.steps_per_second()
        since, step = self._updates_from
        dt = time.monotonic() - since
        done = self.num_timesteps - step
        return done / dt if dt > 0 and done > 0 else None

    def _on_training_start(self) -> None:
        self._start_time = self._last_line = time.monotonic()
        self._start_step = int(self.num_timesteps)
        self._updates_from = (self._start_time, self._start_step)
        self._last_milestone = self._milestone(self._start_step)
        if self.show:
            from tqdm import tqdm

            self._bar = tqdm(
                total=self.total_timesteps,
                initial=self._start_step,
                unit="step",
                desc=self.name,
                file=sys.stderr,
                dynamic_ncols=True,
            )

    def _on_step(self) -> bool:
        now = time.monotonic()
        if self.num_timesteps < self.updates_start:  # the last step before the updates
            self._updates_from = (now, int(self.num_timesteps))
        if now - self._last_beat >= self.heartbeat_interval:
            self._last_beat = now
            fields = self.run_fields(int(self.num_timesteps))
            self.store.heartbeat(
                self.record.run_id, steps_per_second=self.steps_per_second(), **fields
            )
        if self.print_lines:
            step = min(int(self.num_timesteps), self.total_timesteps)
            milestone = self._milestone(step)
            due = milestone > self._last_milestone or now - self._last_line >= self.line_interval
            if due and step < self.total_timesteps:  # the budget's end: the final line
                self._last_line, self._last_milestone = now, milestone
                line = progress_line(
                    self.name,
                    step,
                    self.total_timesteps,
                    self.updating_steps_per_second(),
                    self.episodes.recent_return,
                    self.updates_start,
                )
                print(line, file=sys.stderr, flush=True)
        if self._bar is not None and now - self._last_bar >= 0.2:
            self._last_bar = now
            self._bar.n = min(self.num_timesteps, self.total_timesteps)
            sps = self.updating_steps_per_second()
            ret = self.episodes.recent_return
            self._bar.set_postfix(
                {
                    "steps/s": "-" if sps is None else f"{sps:,.0f}",
                    f"return (mean of last {RECENT_EPISODES})": "-"
                    if ret is None or not math.isfinite(ret)
                    else f"{ret:.2f}",
                },
                refresh=True,
            )
        return not self.stop_requested()

    def close(self, stopped_early: bool = False) -> None:
        """Close the progress bar (if shown), or print the final progress line (once;
        ``stopped_early``: training reached ``training.stop_score``)."""
        if self.print_lines and not self._final_printed:
            self._final_printed = True
            step = min(int(self.num_timesteps), self.total_timesteps)
            line = final_progress_line(
                self.name,
                step,
                self.total_timesteps,
                time.monotonic() - self._start_time,
                self.steps_per_second(),
                stopped_early,
            )
            print(line, file=sys.stderr, flush=True)
        if self._bar is not None:
            self._bar.n = min(self.num_timesteps, self.total_timesteps)
            self._bar.refresh()
            self._bar.close()
            self._bar = None


class LearningRateDecay(BaseCallback):
    """Sets the learning rate of an sbx TD3/DDPG model's actor and critic optimizers (built with
    :func:`softtrack.rl.learning_rate.settable_adam`; the schedule: that module's docstring)
    from the env steps so far, at the start and after each vectorised step (so before the
    updates that follow it).

    Args:
        total_timesteps: T, the run's budget (env steps).
        initial: lr₀. final: lr₁. decay_from: f, the fraction of T where the decay starts.
    """

    def __init__(self, total_timesteps: int, initial: float, final: float, decay_from: float):
        super().__init__(verbose=0)
        self.total_timesteps = int(total_timesteps)
        self.initial, self.final, self.decay_from = float(initial), float(final), float(decay_from)

    def _set_rate(self) -> None:
        rate = learning_rate_at(
            int(self.model.num_timesteps),
            self.total_timesteps,
            self.initial,
            self.final,
            self.decay_from,
        )
        policy: Any = self.model.policy
        for state in (policy.actor_state, policy.qf_state):
            hyperparams = getattr(state.opt_state, "hyperparams", None)
            if hyperparams is None or "learning_rate" not in hyperparams:
                raise ValueError(
                    "a decaying learning rate needs optimizers built by "
                    "softtrack.rl.learning_rate.settable_adam"
                )
            # a float32 array: the jitted update sees the same argument type every time
            hyperparams["learning_rate"] = np.asarray(rate, dtype=np.float32)
        self.logger.record("train/learning_rate", rate)

    def _on_training_start(self) -> None:
        self._set_rate()

    def _on_step(self) -> bool:
        self._set_rate()
        return True
