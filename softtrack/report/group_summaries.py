"""Evaluation metrics and actuation-moment peaks of run groups (mean and std across seeds), and
the checkpoints their validation selected."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from softtrack.evaluation import validation_score
from softtrack.evaluation.metrics import ACTION_STATISTICS, SAFETY_STATISTICS, TORQUE_STATISTICS
from softtrack.report.data import DIRECTIONS, METRIC_COLUMNS, Group, RunData
from softtrack.store.layout import PolicyDir

__all__ = [
    "controller_differences",
    "metrics_summary",
    "moment_peaks",
    "random_target_summary",
    "summary_row",
    "validation_scores",
    "validation_summary",
]


# ---- evaluation metrics ---------------------------------------------------------------------
# Per-arm columns of eval_metrics summarised beside the tracking metrics (each absent from
# tables written before it was added).
_EXTRA_COLUMNS = (*ACTION_STATISTICS, *TORQUE_STATISTICS, *SAFETY_STATISTICS)


def metrics_summary(groups: Sequence[Group]) -> pd.DataFrame:
    """Evaluation metrics per group, trajectory and arm: mean and sample std across seeds.

    Columns: group, algo, controller, trajectory, arm, n, seeds, terminated (runs whose episode
    ended early), and ``<metric>_mean`` / ``<metric>_std`` / ``<metric>_n`` (runs with a value)
    for every metric column stored: ``rmse_x`` … ``max_error`` and their ``_steady`` forms, in
    m, ``action_saturation``, ``action_change``, ``action_rms`` (dimensionless),
    ``torque_rate_rms`` (N·m/s), ``peak_moment`` (N·m), ``min_arm_distance`` (m) and
    ``collision_steps``. A metric no run of a group stores has no columns (or NaN where another
    group has it).
    """
    rows = []
    for group in groups:
        frames = []
        for run in group.runs:
            if run.metrics is not None:
                frames.append(run.metrics.assign(seed=run.seed))
        if not frames:
            continue
        df = pd.concat(frames, ignore_index=True)
        metric_cols = [
            c
            for c in df.columns
            if c.removesuffix("_steady") in METRIC_COLUMNS or c in _EXTRA_COLUMNS
        ]
        for (trajectory, arm), part in df.groupby(["trajectory", "arm"], sort=False):
            row: dict[str, object] = {
                "group": group.label,
                "algo": group.algo,
                "controller": group.controller,
                "trajectory": str(trajectory),
                "arm": int(arm),
                "n": len(part),
                "seeds": sorted(int(s) for s in part["seed"]),
                "terminated": int(part["terminated"].astype(bool).sum())
                if "terminated" in part
                else 0,
            }
            for col in metric_cols:
                values = pd.to_numeric(part[col], errors="coerce").dropna().to_numpy(float)
                row[f"{col}_mean"] = float(values.mean()) if values.size else np.nan
                row[f"{col}_std"] = float(values.std(ddof=1)) if values.size >= 2 else np.nan
                row[f"{col}_n"] = int(values.size)
            rows.append(row)
    return pd.DataFrame(rows)


def summary_row(summary: pd.DataFrame, group: str, trajectory: str, arm: int) -> pd.Series | None:
    """The :func:`metrics_summary` row of ``group`` (its label), ``trajectory`` and ``arm``
    (0-indexed), or None where nothing is stored."""
    if summary.empty:
        return None
    sel = summary[
        (summary["group"] == group)
        & (summary["trajectory"] == trajectory)
        & (summary["arm"] == arm)
    ]
    return None if sel.empty else sel.iloc[0]


def controller_differences(summary: pd.DataFrame, groups: Sequence[Group]) -> pd.DataFrame:
    """3-D RMSE of each centralized group minus that of each independent group of the same
    algorithm, per trajectory and arm, from their seed means (``summary``:
    :func:`metrics_summary`).

    Columns: reference (the independent group's label), group, trajectory, arm, difference
    (centralized − independent mean, m; negative: the centralized controller tracks better),
    se (standard error of that difference, sqrt(s₁²/n₁ + s₂²/n₂), m), p_value (Welch's
    two-sided t-test of the seeds' values), n and n_reference (seeds). se and p_value are NaN
    unless both groups have at least 2 seeds with a value.
    """
    columns = [
        "reference",
        "group",
        "trajectory",
        "arm",
        "difference",
        "se",
        "p_value",
        "n",
        "n_reference",
    ]
    if summary.empty:
        return pd.DataFrame(columns=columns)
    rows = []
    for reference in (g for g in groups if g.controller == "independent"):
        ref_rows = summary[summary["group"] == reference.label]
        for group in groups:
            if group.controller == "independent" or group.algo != reference.algo:
                continue
            for _, ref in ref_rows.iterrows():
                row = summary_row(summary, group.label, ref["trajectory"], int(ref["arm"]))
                if row is None:
                    continue
                n, n_ref = int(row["rmse_3d_n"]), int(ref["rmse_3d_n"])
                se = p_value = np.nan
                if n >= 2 and n_ref >= 2:
                    var, var_ref = row["rmse_3d_std"] ** 2 / n, ref["rmse_3d_std"] ** 2 / n_ref
                    se = float(np.sqrt(var + var_ref))
                    if se > 0:
                        p_value = float(
                            stats.ttest_ind_from_stats(
                                row["rmse_3d_mean"],
                                row["rmse_3d_std"],
                                n,
                                ref["rmse_3d_mean"],
                                ref["rmse_3d_std"],
                                n_ref,
                                equal_var=False,
                            ).pvalue
                        )
                rows.append(
                    {
                        "reference": reference.label,
                        "group": group.label,
                        "trajectory": ref["trajectory"],
                        "arm": int(ref["arm"]),
                        "difference": float(row["rmse_3d_mean"] - ref["rmse_3d_mean"]),
                        "se": se,
                        "p_value": p_value,
                        "n": n,
                        "n_reference": n_ref,
                    }
                )
    return pd.DataFrame(rows, columns=columns)


def random_target_summary(groups: Sequence[Group]) -> pd.DataFrame:
    """3-D RMSE on the random-target episodes (``eval_random``) per group and arm.

    A run's value is the mean over its episodes; columns: group, arm, ``rmse_3d_mean`` and
    ``rmse_3d_std`` (mean and sample std of the runs' values across seeds, m), n (runs),
    episodes (the fewest episodes of a run), terminated (episodes that ended early). Groups
    without the table are left out.
    """
    rows = []
    for group in groups:
        per_run = [run.random for run in group.runs if run.random is not None]
        for arm in (0, 1):
            parts = [r[r["arm"] == arm] for r in per_run]
            parts = [p for p in parts if len(p)]
            if not parts:
                continue
            values = np.array([p["rmse_3d"].mean() for p in parts], dtype=float)
            rows.append(
                {
                    "group": group.label,
                    "arm": arm,
                    "rmse_3d_mean": float(values.mean()),
                    "rmse_3d_std": float(values.std(ddof=1)) if len(values) >= 2 else np.nan,
                    "n": len(values),
                    "episodes": min(len(p) for p in parts),
                    "terminated": int(sum(p["terminated"].astype(bool).sum() for p in parts)),
                }
            )
    return pd.DataFrame(rows)


def validation_scores(run: RunData) -> pd.DataFrame:
    """Validation score per policy and checkpoint of one run (``tables/validation.parquet``).

    Columns: ``policy`` (-1 for a centralized run's one policy, else the arm of an independent
    run's policy), ``global_step`` (the policy's env steps), ``score`` (m, see
    :func:`softtrack.evaluation.validation_score`). Empty without the table.
    """
    columns = ["policy", "global_step", "score"]
    df = run.validation
    if df is None:
        return pd.DataFrame(columns=columns)
    independent = run.record.info.controller == "independent"
    policy = df["arm"] if independent else pd.Series(-1, index=df.index)
    rows = [
        {
            "policy": int(k),
            "global_step": int(step),
            "score": validation_score(part, run.eval_duration, run.scored_targets),
        }
        for (k, step), part in df.groupby([policy, df["global_step"]], sort=True)
    ]
    return pd.DataFrame(rows, columns=columns)


def validation_summary(
    scores: Sequence[tuple[Group, RunData, int, pd.DataFrame]],
) -> pd.DataFrame:
    """The checkpoint each validated policy selects.

    Args:
        scores: (group, run, policy, that policy's rows of :func:`validation_scores`).

    Returns:
        One row per entry: group (label), seed, run_id, policy (as in
        :func:`validation_scores`), checkpoints (validated), best_step and best_score (the
        lowest score, the earliest on ties: the model ``best/`` keeps), last_step and
        last_score (the last validated checkpoint), confirmed_best and confirmed_last (the
        two candidates' scores in the confirmation after training, m; NaN without one:
        :mod:`softtrack.rl.confirmation`), kept (``best`` or ``last``: the run's policy,
        from ``training.final_policy`` and the confirmation).
    """
    rows = []
    for group, run, policy, part in scores:
        part = part.sort_values("global_step")
        best = part.loc[part["score"].idxmin()]
        last = part.iloc[-1]
        training = run.record.raw_spec().get("training")
        uses_best = isinstance(training, dict) and training.get("final_policy") == "best_validated"
        confirmed = _confirmation(run, policy) if uses_best else {}
        rows.append(
            {
                "group": group.label,
                "seed": run.seed,
                "run_id": run.run_id,
                "policy": int(policy),
                "checkpoints": len(part),
                "best_step": int(best["global_step"]),
                "best_score": float(best["score"]),
                "last_step": int(last["global_step"]),
                "last_score": float(last["score"]),
                "confirmed_best": confirmed.get("scores", {}).get("best", np.nan),
                "confirmed_last": confirmed.get("scores", {}).get("last", np.nan),
                "kept": confirmed.get("model", "best") if uses_best else "last",
            }
        )
    return pd.DataFrame(rows)


def _confirmation(run: RunData, policy: int) -> dict[str, Any]:
    """``confirmed.json`` of a run's policy (-1: the centralized one), or {} without one."""
    return PolicyDir.of_run(run.record.path, None if policy < 0 else policy).read_confirmed() or {}


def moment_peaks(groups: Sequence[Group]) -> pd.DataFrame:
    """Peak absolute element moment (N·m) over an evaluation episode, per group, trajectory,
    direction and arm (``arm`` -1: both arms), as mean and sample std across seeds.

    Columns: group, algo, controller, trajectory, direction (``normal``/``binormal``), arm, n,
    mean, std. Each run's peaks are :attr:`RunData.peaks` (``eval_moment_peaks``, or the
    ``max_abs_moment`` column of an older ``eval_moments``).
    """
    rows = []
    for group in groups:
        peaks: dict[tuple[str, str, int], list[float]] = {}
        for run in group.runs:
            df = run.peaks  # both table formats: see softtrack.report.data.episode_peaks
            if df is None:
                continue
            value = df["peak_abs_moment"]
            per = value.groupby([df["trajectory"], df["direction"], df["arm"]]).max()
            both = value.groupby([df["trajectory"], df["direction"]]).max()
            for (trajectory, direction, arm), peak in per.items():
                key = (str(trajectory), _direction(direction), int(arm))
                peaks.setdefault(key, []).append(float(peak))
            for (trajectory, direction), peak in both.items():
                peaks.setdefault((str(trajectory), _direction(direction), -1), []).append(
                    float(peak)
                )
        for (trajectory, direction, arm), values in peaks.items():
            arr = np.array(values)
            rows.append(
                {
                    "group": group.label,
                    "algo": group.algo,
                    "controller": group.controller,
                    "trajectory": trajectory,
                    "direction": direction,
                    "arm": arm,
                    "n": int(arr.size),
                    "mean": float(arr.mean()),
                    "std": float(arr.std(ddof=1)) if arr.size >= 2 else np.nan,
                }
            )
    return pd.DataFrame(rows)


def _direction(value: Any) -> str:
    """A table's direction cell (an index into DIRECTIONS, or already a name) as a name."""
    try:
        return DIRECTIONS[int(value)]
    except (ValueError, TypeError, IndexError):
        return str(value)
