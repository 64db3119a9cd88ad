"""Evaluate stored runs and write their evaluation tables.

``evaluate_run`` loads a run's policy, runs one deterministic episode per trajectory and
writes its tables into the run's ``tables/`` (all of them or none: :func:`~softtrack.store.tables.write_tables`;
replacing the rows of the trajectories it evaluated and keeping the others):

* ``eval_trajectories.parquet``: tip and target positions at every control step, and the
  arms' clearance, penetration and contact force at that step;
* ``eval_snapshots.parquet``: both arms' centrelines at four instants (figures that draw the
  arms with their radius);
* ``eval_metrics.parquet``: the metrics of docs/environment.md per arm (also over the steady window t ≥ 1 s),
  the CPU kind that computed them (``cpu``: a deterministic episode's rounding, and so its
  numbers, differ slightly between CPU kinds; tables written before lack it), and the arm's
  action statistics (``action_saturation``, ``action_change``, ``action_rms``), its torque
  smoothness and peak (``torque_rate_rms``, ``peak_moment``) and the episode's inter-arm
  safety (``min_arm_distance``, ``collision_steps``) and contact (``max_penetration``,
  ``contact_steps``, ``mean_contact_force``, ``max_contact_force``); tables written before
  these were added lack them, and readers treat them as optional;
* ``eval_moments.parquet``: the spatial RMS of the element torques per step, arm and direction
  (docs/environment.md, float32);
* ``eval_moment_peaks.parquet``: each element's largest absolute torque over the episode, per
  arm and direction;
* ``eval_element_moments.parquet``, only with ``full_moments=True``: every element torque at
  every step (about 2 MB per trajectory; left out by default).

``evaluate_random_targets`` runs N episodes on the run's own random training target instead,
from seeds that training never uses (:data:`softtrack.evaluation.episodes.RANDOM_TARGET_SEED` + k),
and writes their metrics, one row per episode and arm, to ``eval_random.parquet`` (replacing
the table): how well the policy tracks the target it was trained on, beside how well it
tracks the closed-form paths.

Both evaluate the run's policy unless told another of its models (``model``:
:data:`softtrack.store.layout.ModelChoice`, e.g. ``last`` beside a kept best-validated policy).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import pandas as pd

from softtrack.env.settings import TrackingConfig
from softtrack.evaluation.episode_tables import (
    element_moments_table,
    metrics_table,
    moment_peaks_table,
    moments_table,
    snapshot_table,
    trajectory_table,
)
from softtrack.evaluation.episodes import (
    EVAL_TRAJECTORIES,
    RANDOM_TARGET_SEED,
    Episode,
    Policy,
    iter_episodes,
    run_episode,
)
from softtrack.spec import ExperimentSpec
from softtrack.spec.env_config import env_config
from softtrack.store.layout import ModelChoice
from softtrack.store.provenance import cpu_kind
from softtrack.store.runs import (
    RunRecord,
)
from softtrack.store.tables import read_table, write_table, write_tables

__all__ = [
    "ELEMENT_MOMENTS_TABLE",
    "EVAL_TABLES",
    "RANDOM_TABLE",
    "SNAPSHOT_TABLE",
    "PolicyLoader",
    "evaluate_random_targets",
    "evaluate_run",
    "has_evaluation",
]

EVAL_TABLES = ("eval_trajectories", "eval_metrics", "eval_moments", "eval_moment_peaks")
ELEMENT_MOMENTS_TABLE = "eval_element_moments"
SNAPSHOT_TABLE = "eval_snapshots"  # the arms' shapes at four instants (figures)
RANDOM_TABLE = "eval_random"


def has_evaluation(record: RunRecord, trajectories: Sequence[str] = EVAL_TRAJECTORIES) -> bool:
    """True if the run's metrics table holds every listed trajectory."""
    path = record.table_path("eval_metrics")
    if not path.exists():
        return False
    done = set(read_table(path, columns=["trajectory"])["trajectory"])  # TableError if damaged
    return set(trajectories) <= done


def _replaced_rows(
    path: Path, new: pd.DataFrame, trajectories: Sequence[str]
) -> pd.DataFrame | None:
    """The table at ``path`` with the rows of ``trajectories`` replaced by ``new`` (columns of
    an older table format that ``new`` lacks are dropped); ``None`` if no row is left.

    Raises:
        TableError: the existing file is unreadable (before anything is written).
    """
    if path.is_file():
        old = read_table(path)
        old = old[~old["trajectory"].isin(list(trajectories))]
        if len(new.columns):
            old = old[[c for c in old.columns if c in new.columns]]
        new = pd.concat([old, new], ignore_index=True) if len(old) else new
    return new.reset_index(drop=True) if len(new) else None


#: Loads a run's deterministic policy: (run, its spec, which model) → observation → action
#: (``softtrack.rl.policy.load_policy``; passed in, so evaluation never imports training).
PolicyLoader = Callable[[RunRecord, ExperimentSpec, ModelChoice], Policy]


def _episode_setup(
    record: RunRecord, load: PolicyLoader, model: ModelChoice = "policy"
) -> tuple[Policy, TrackingConfig, float]:
    """The deterministic policy of the run's ``model``, its environment settings and its
    evaluation episode length (``training.eval_duration``, s)."""
    spec = record.load_spec()
    return load(record, spec, model), env_config(spec), float(spec.training.eval_duration)


def evaluate_run(
    record: RunRecord,
    trajectories: Sequence[str] = EVAL_TRAJECTORIES,
    on_episode: Callable[[RunRecord, Episode, pd.DataFrame], None] | None = None,
    *,
    load: PolicyLoader,
    write: bool = True,
    model: ModelChoice = "policy",
    full_moments: bool = False,
) -> pd.DataFrame:
    """Evaluate one run on ``trajectories`` and write its tables (``write=False``: only return
    the metrics, leaving the run directory untouched, e.g. for a committed run under models/).

    Args:
        on_episode: called after each trajectory with the run, the episode and its metrics.
        load: loads the run's policy (:data:`PolicyLoader`).
        model: the run's model to evaluate (default its policy).
        full_moments: also store every element torque at every step
            (``eval_element_moments``); otherwise rows of these trajectories in an existing
            full table are removed, since they no longer match the new evaluation.

    Returns:
        The metrics rows of this evaluation (one per trajectory and arm).

    Raises:
        RunStoreError: the run has no readable model; SpecError: its spec no longer validates.
    """
    policy, config, duration = _episode_setup(record, load, model)
    tables = {
        "eval_trajectories": trajectory_table,
        "eval_metrics": metrics_table,
        "eval_moments": moments_table,
        "eval_moment_peaks": moment_peaks_table,
        SNAPSHOT_TABLE: snapshot_table,
    }
    if full_moments:
        tables[ELEMENT_MOMENTS_TABLE] = element_moments_table
    frames: dict[str, list[pd.DataFrame]] = {name: [] for name in tables}
    cpu = cpu_kind()
    for trajectory in trajectories:
        episode = run_episode(policy, config, trajectory, duration)
        for name, make_table in tables.items():
            frames[name].append(make_table(record.info.run_id, episode))
        frames["eval_metrics"][-1]["cpu"] = cpu
        if on_episode is not None:
            on_episode(record, episode, frames["eval_metrics"][-1])
    if write:  # every table or none (a corrupt old table stops it before any write)
        changes: dict[Path, pd.DataFrame | None] = {
            record.table_path(name): _replaced_rows(
                record.table_path(name), pd.concat(parts, ignore_index=True), trajectories
            )
            for name, parts in frames.items()
        }
        stale = record.table_path(ELEMENT_MOMENTS_TABLE)
        if not full_moments and stale.is_file():
            changes[stale] = _replaced_rows(stale, pd.DataFrame(), trajectories)
        write_tables(changes)
    return pd.concat(frames["eval_metrics"], ignore_index=True)


def evaluate_random_targets(
    record: RunRecord,
    episodes: int,
    on_episode: Callable[[RunRecord, Episode, pd.DataFrame], None] | None = None,
    *,
    load: PolicyLoader,
    write: bool = True,
    model: ModelChoice = "policy",
    on_progress: Callable[[int, int], None] | None = None,
) -> pd.DataFrame:
    """Evaluate one run on ``episodes`` random-target episodes (module docstring).

    Each episode lasts ``training.eval_duration`` from the straight initial state; episode k
    uses seed ``RANDOM_TARGET_SEED + k``, so every run meets the same target paths when their
    specs share the target settings.

    Args:
        episodes: number of episodes, ≥ 1.
        on_episode: called after each episode with the run, the episode and its metrics.
        write: store ``eval_random.parquet`` in the run (``False``: only return the rows).
        model: the run's model to evaluate (default its policy).
        on_progress: called with (episodes done, episodes asked) after each episode.

    Returns:
        One row per episode and arm: ``episode``, ``seed`` and the columns of
        :func:`softtrack.evaluation.episode_tables.metrics_table` (``trajectory`` is ``random``).

    Interrupted (Ctrl-C, SIGTERM), it keeps what it finished: with ``write`` the episodes done
    so far (0 … k−1, the same as a run of k episodes) are stored before the interruption goes
    on.
    """
    if episodes < 1:
        raise ValueError(f"episodes={episodes} must be at least 1")
    policy, config, duration = _episode_setup(record, load, model)
    cpu = cpu_kind()
    parts = []
    seeds = [RANDOM_TARGET_SEED + k for k in range(episodes)]
    try:
        for k, episode in enumerate(iter_episodes(policy, config, "random", duration, seeds)):
            metrics = metrics_table(record.info.run_id, episode)
            metrics.insert(2, "episode", k)
            metrics.insert(3, "seed", seeds[k])
            metrics["cpu"] = cpu
            parts.append(metrics)
            if on_episode is not None:
                on_episode(record, episode, metrics)
            if on_progress is not None:
                on_progress(k + 1, episodes)
    except (KeyboardInterrupt, SystemExit) as stop:
        if write and parts:  # the finished episodes are kept
            path = record.table_path(RANDOM_TABLE)
            write_table(path, pd.concat(parts, ignore_index=True))
            stop.add_note(f"kept the {len(parts)} finished episodes of {episodes} in {path}")
        raise
    table = pd.concat(parts, ignore_index=True)
    if write:
        write_table(record.table_path(RANDOM_TABLE), table)
    return table
