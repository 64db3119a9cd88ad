"""What ``softtrack runs`` shows of a run: its effective status, progress and final-stage return.

A run's status comes from its ``run.json``, except that a ``running`` run whose process is gone
(nobody holds its ``run.lock``, and its heartbeat is stale or its pid is dead on this host)
shows as ``lost``; run.json itself is never changed here. The final-stage return is computed
from the run's ``train_episodes`` table; :func:`final_stage_returns` is its one implementation,
also behind the report's final-stage table.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

import numpy as np
import pandas as pd

from softtrack.store.liveness import heartbeat_stale, is_lost_process, stale_after_s
from softtrack.store.run_records import RunInfo, RunRecord
from softtrack.store.table_reading import read_table

__all__ = [
    "DEFAULT_FINAL_STAGE_FRACTION",
    "DEFAULT_HEARTBEAT_INTERVAL_S",
    "complete_episodes",
    "effective_status",
    "episodes_by_arm",
    "eval_duration",
    "final_stage_budget",
    "final_stage_fraction",
    "final_stage_return",
    "final_stage_returns",
    "heartbeat_interval",
    "is_lost",
    "stale_after_s",
    "training_seconds",
    "validation_score_setting",
]

#: ``training.final_stage_fraction`` of a spec that does not set it.
DEFAULT_FINAL_STAGE_FRACTION = 0.1
#: ``training.heartbeat_interval`` (s) of a spec that does not set it.
DEFAULT_HEARTBEAT_INTERVAL_S = 30.0


def _training_value(raw: dict[str, Any], key: str, default: float) -> float:
    training = raw.get("training")
    value = training.get(key) if isinstance(training, dict) else None
    return (
        float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else default
    )


# ---- final-stage return ---------------------------------------------------------------------
def final_stage_fraction(raw_spec: dict[str, Any]) -> float:
    """``training.final_stage_fraction`` of a run's spec as plain data (``spec.yaml``, not
    validated), or :data:`DEFAULT_FINAL_STAGE_FRACTION` where it is absent or not in (0, 1]."""
    value = _training_value(raw_spec, "final_stage_fraction", DEFAULT_FINAL_STAGE_FRACTION)
    return value if 0 < value <= 1 else DEFAULT_FINAL_STAGE_FRACTION


def validation_score_setting(raw_spec: dict[str, Any]) -> str:
    """``training.validation_score`` of a run's spec as plain data (``""`` where absent: the
    default's episodes)."""
    training = raw_spec.get("training")
    value = training.get("validation_score") if isinstance(training, dict) else None
    return value if isinstance(value, str) else ""


def eval_duration(raw_spec: dict[str, Any]) -> float | None:
    """``training.eval_duration`` of a run's spec as plain data (s), or ``None`` where it is
    absent or not positive."""
    value = _training_value(raw_spec, "eval_duration", 0.0)
    return value if value > 0 else None


def complete_episodes(train: pd.DataFrame) -> pd.DataFrame:
    """The rows of a ``train_episodes`` table that are whole episodes: without those marked
    ``truncated`` (an episode cut by a stop, whose return is partial; ``truncated`` null or
    absent means whole)."""
    if "truncated" not in train:
        return train
    return train[~train["truncated"].fillna(False).astype(bool).to_numpy()]


def episodes_by_arm(train: pd.DataFrame) -> dict[int | None, pd.DataFrame]:
    """A ``train_episodes`` table's whole episodes (:func:`complete_episodes`) split by policy:
    ``{None: all}`` without an ``arm`` column, else ``{0: arm 1's rows, 1: arm 2's}`` (and
    ``None`` for rows with no arm: a null or negative ``arm``, a centralized policy's)."""
    train = complete_episodes(train)
    if "arm" not in train:
        return {None: train}
    arm = pd.to_numeric(train["arm"], errors="coerce").fillna(-1).astype(int)
    parts: dict[int | None, pd.DataFrame] = {}
    if (arm < 0).any():
        parts[None] = train[arm < 0]
    for a in sorted(set(arm[arm >= 0])):
        parts[int(a)] = train[arm == a]
    return parts


def final_stage_returns(
    train: pd.DataFrame, fraction: float, total_timesteps: int, arm_budget: int
) -> dict[int | None, tuple[float | None, int]]:
    """docs/environment.md per policy of a run: the mean return of the training episodes that ended
    after ``(1 − fraction) · budget`` env steps, and their count. An infinite return is kept,
    so the mean is ``±inf`` (``nan`` with both signs) and says so; only a return that is not a
    number at all (unreadable, NaN) is left out.

    Args:
        train: the run's ``train_episodes`` table (``global_step``, ``return``, maybe ``arm``),
            split by :func:`episodes_by_arm`.
        total_timesteps: the budget of the rows without an arm (a centralized policy).
        arm_budget: the budget of an arm's policy, whose ``global_step`` counts its own steps
            (:attr:`~softtrack.store.run_records.RunInfo.policy_budget`).

    Returns:
        ``{arm or None: (mean return or None if no episode qualifies, episode count)}``.
    """
    out: dict[int | None, tuple[float | None, int]] = {}
    for arm, part in episodes_by_arm(train).items():
        budget = total_timesteps if arm is None else arm_budget
        step = pd.to_numeric(part["global_step"], errors="coerce")
        ret = pd.to_numeric(part["return"], errors="coerce")
        final = ret[(step > (1.0 - fraction) * budget) & ret.notna()]
        out[arm] = (float(final.mean()) if len(final) else None, len(final))
    return out


def final_stage_budget(info: RunInfo) -> int:
    """The env steps whose last fraction is a centralized run's final stage: its
    ``total_timesteps``, or the steps it trained when it completed early
    (``training.stop_score``)."""
    if info.status == "completed" and 0 < info.global_step < info.total_timesteps:
        return int(info.global_step)
    return int(info.total_timesteps)


def training_seconds(train: pd.DataFrame | None) -> float | None:
    """A run's training wall time, s: its training clock at the last logged episode (the
    largest ``wall_time`` of ``train_episodes``; the clock carries on across resumed sessions
    and from one arm of an independent run to the next, and leaves out time spent stopped).
    ``None`` without a positive clock reading."""
    if train is None or "wall_time" not in train or not len(train):
        return None
    seconds = float(pd.to_numeric(train["wall_time"], errors="coerce").max())
    return seconds if seconds > 0 else None


def final_stage_return(
    record: RunRecord, fraction: float | None = None, train: pd.DataFrame | None = None
) -> tuple[float | None, int, int]:
    """Mean training-episode return over the last ``fraction`` of the run's budget (docs/environment.md).

    Episodes count when their ``global_step`` (at the episode's end) exceeds
    ``(1 - fraction) · total_timesteps`` (:func:`final_stage_returns`; the steps trained for a
    run that stopped early, :func:`final_stage_budget`). ``fraction`` defaults
    to the run's ``training.final_stage_fraction`` (0.1).

    An independent run's table has an ``arm`` column (0, 1) and counts ``global_step`` per arm:
    each arm's final stage is the last ``fraction`` of its own budget (``arm_total_timesteps``),
    and the result is the mean over the arms of their final-stage means (single-arm returns,
    not comparable with dual-arm ones). Rows without an arm (column absent, null or negative)
    are a centralized policy's.

    ``train``: the run's ``train_episodes`` table if already read (else it is read here).

    Returns:
        ``(mean return or None if no episode qualifies, number of such episodes,
        env steps the table reaches: its largest global_step, summed over the arms, or 0)``.
    """
    if fraction is None:
        fraction = final_stage_fraction(record.raw_spec())
    df = (
        read_table(record.table_path("train_episodes"), missing_ok=True) if train is None else train
    )
    if df.empty or not {"global_step", "return"} <= set(df.columns):
        return None, 0, 0
    info = record.info
    results = final_stage_returns(df, fraction, final_stage_budget(info), info.policy_budget)
    arms = [arm for arm in results if arm is not None]
    if not arms:
        mean, count = results[None]
        return mean, count, int(df["global_step"].max())
    parts = episodes_by_arm(df)
    means = [m for m, _ in (results[arm] for arm in arms) if m is not None]
    count = sum(results[arm][1] for arm in arms)
    last_step = sum(int(parts[arm]["global_step"].max()) for arm in arms)
    return (float(np.mean(means)) if means else None), count, last_step


# ---- status ---------------------------------------------------------------------------------
def _is_stale(record: RunRecord, interval_s: float, now: datetime) -> bool:
    info = record.info
    return heartbeat_stale(
        info.status, info.heartbeat or info.started or info.created, interval_s, now
    )


def heartbeat_interval(raw_spec: dict[str, Any]) -> float:
    """``training.heartbeat_interval`` of a run's spec as plain data (s), or
    :data:`DEFAULT_HEARTBEAT_INTERVAL_S` where it is absent."""
    return _training_value(raw_spec, "heartbeat_interval", DEFAULT_HEARTBEAT_INTERVAL_S)


def is_lost(record: RunRecord, *, now: datetime | None = None, stale: bool | None = None) -> bool:
    """A ``running`` run whose process is gone: nobody holds its ``run.lock``, and its
    heartbeat is stale or (on this host) its pid is not alive."""
    info = record.info
    if info.status != "running":
        return False
    if stale is None:
        stale = _is_stale(record, heartbeat_interval(record.raw_spec()), now or datetime.now(UTC))
    return is_lost_process(record.path, stale=stale, host=info.host, pid=info.pid)


def effective_status(record: RunRecord, *, now: datetime | None = None) -> str:
    """run.json's status, or ``lost`` for a running run whose process is gone (:func:`is_lost`);
    run.json itself is never changed by this."""
    return "lost" if is_lost(record, now=now) else record.info.status
