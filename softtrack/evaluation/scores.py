"""Scores computed from stored evaluation rows: a checkpoint's validation score and the
transport task's carry score. Pure pandas/NumPy, so ``softtrack compare`` and the report
read runs without loading the simulator (:mod:`softtrack.evaluation.episode_tables` builds the rows)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd

__all__ = [
    "CARRY_SCORE",
    "HELD_OUT_TARGETS",
    "LOST_OBJECT_ERROR",
    "SCORED_TARGETS",
    "VALIDATION_SCORED_COLUMNS",
    "carry_errors",
    "scored_targets",
    "validation_score",
    "with_carry_score",
]

#: The error a dropped sphere counts, in a validation score, for every step of its episode
#: after the drop, m: about the arms' reach, more than any carrying error.
LOST_OBJECT_ERROR = 1.0


#: The ``trajectory`` values of the validation rows that enter a checkpoint's score: the
#: held-out random targets and the held-out paths (target modes).
HELD_OUT_TARGETS = ("random", "paths")
#: The rows each ``training.validation_score`` setting averages.
SCORED_TARGETS = {"random_and_paths": HELD_OUT_TARGETS, "paths": ("paths",)}


def scored_targets(setting: object) -> tuple[str, ...]:
    """The ``trajectory`` values a ``training.validation_score`` setting scores (plain data
    from a spec file: anything else, or absent, is the default's)."""
    return SCORED_TARGETS.get(str(setting), HELD_OUT_TARGETS)


#: The columns of ``tables/validation.parquet`` that :func:`validation_score` and the report's
#: validation section read; a shipped run may keep only these (experiments/reproduce_study.py).
VALIDATION_SCORED_COLUMNS = (
    "global_step",
    "trajectory",
    "episode",
    "arm",
    "rmse_3d",
    "terminated",
    "object_rmse_3d",
    "dropped",
    "drop_time",
)


def validation_score(
    rows: pd.DataFrame,
    episode_duration: float | None = None,
    targets: Sequence[str] = HELD_OUT_TARGETS,
) -> float:
    """The validation score of one checkpoint from its rows of ``tables/validation.parquet``
    (one per episode and arm), m: the mean ``rmse_3d`` of its random-target and held-out
    path episodes (``training.validation_paths``), or ∞ if one terminated (went
    non-finite). Rows of the evaluation trajectories (``training.validation_trajectories``)
    are left out: models are never selected on the evaluation's own trajectories.
    ``targets``: the rows' ``trajectory`` values that count (``training.validation_score``:
    :func:`scored_targets`).

    In the transport task (``object_rmse_3d`` rows) with ``episode_duration`` (s, the
    validation episodes' planned length), a drop ends an episode early: each episode scores
    the sphere's 3-D RMSE over the whole planned length with every step after the drop counted
    at :data:`LOST_OBJECT_ERROR`, sqrt((e²·t + L²·(T − t)) / T) for an error e over the t s it
    was carried, and the score is their mean. A checkpoint that carries it longer scores
    lower, and one that carries it through scores its mean error, as before. Without
    ``episode_duration`` any drop scores ∞."""
    if "trajectory" in rows:
        rows = rows[rows["trajectory"].isin(list(targets))]
    if len(rows) == 0:
        return math.inf
    carried = "object_rmse_3d" in rows and rows["object_rmse_3d"].notna().all()
    if carried and episode_duration is not None and "dropped" in rows:
        return _carry_score(rows, float(episode_duration))
    if rows["terminated"].astype(bool).any():
        return math.inf
    if carried:
        return float(rows["object_rmse_3d"].mean())
    return float(rows["rmse_3d"].mean())


def _carry_score(rows: pd.DataFrame, planned: float) -> float:
    """:func:`validation_score` of transport rows (one per episode and arm; the sphere's
    columns are the same in both arms' rows), ``planned`` s per episode."""
    keys = [column for column in ("trajectory", "episode") if column in rows]
    episodes = rows.drop_duplicates(keys) if keys else rows
    dropped = episodes["dropped"].fillna(False).astype(bool).to_numpy()
    failed = episodes["terminated"].astype(bool).to_numpy() & ~dropped  # went non-finite
    per_episode = carry_errors(episodes, planned)
    if failed.any() or not np.isfinite(per_episode).all():
        return math.inf
    return float(per_episode.mean())


#: The eval_metrics / eval_random column :func:`with_carry_score` derives (``softtrack compare
#: --metric object_carry_score``), m.
CARRY_SCORE = "object_carry_score"


def carry_errors(rows: pd.DataFrame, planned: float) -> np.ndarray:
    """(rows,) the sphere's 3-D RMSE of each transport row over the whole planned episode of
    ``planned`` s, with every step after a drop counted at :data:`LOST_OBJECT_ERROR`,
    sqrt((e²·t + L²·(T − t)) / T) for the error e over the t s it was carried, m. A row
    without a drop keeps its ``object_rmse_3d``; NaN where that is NaN."""
    error = rows["object_rmse_3d"].to_numpy(dtype=np.float64)
    dropped = rows["dropped"].fillna(False).astype(bool).to_numpy()
    ended = (
        rows["drop_time"].to_numpy(dtype=np.float64) if "drop_time" in rows else np.zeros(len(rows))
    )
    carried = np.clip(np.where(dropped, np.nan_to_num(ended), planned), 0.0, planned)
    lost = planned - carried
    return np.sqrt((error**2 * carried + LOST_OBJECT_ERROR**2 * lost) / planned)


def with_carry_score(rows: pd.DataFrame, planned: float | None) -> pd.DataFrame:
    """``rows`` (eval_metrics or eval_random of one run) with the column :data:`CARRY_SCORE`
    (:func:`carry_errors`, m) added, so that a controller that drops the sphere early cannot
    score better than one that carries it on; unchanged without transport columns or without
    the planned episode length ``planned`` (s, ``training.eval_duration``)."""
    if planned is None or not {"object_rmse_3d", "dropped"} <= set(rows.columns):
        return rows
    return rows.assign(**{CARRY_SCORE: carry_errors(rows, float(planned))})
