"""Training curves and final-stage returns of run groups, aggregated across seeds.

Both read the ``train_episodes`` table of each run (:class:`softtrack.report.data.RunData`);
an independent run's table holds one episode series per arm policy (column ``arm``).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from softtrack.report.data import Group, RunData, episodes_by_arm

__all__ = [
    "Curve",
    "Smoothing",
    "final_stage_table",
    "run_final_stage_returns",
    "training_curves",
]


# ---- training curves ------------------------------------------------------------------------
@dataclass(frozen=True)
class Smoothing:
    """The smoothing applied to every training curve of a report.

    At each of ``n_points`` evenly spaced env steps g in (0, max step], a run's value is the
    mean return of its episodes that ended within the centred window (g − w/2, g + w/2].
    """

    window: float  # env steps
    n_points: int
    window_fraction: float

    def describe(self) -> str:
        return (
            f"each run's episode returns averaged over a centred window of {self.window:,.0f} "
            f"env steps ({self.window_fraction:.0%} of the longest run), at {self.n_points} "
            "points; the same window for every curve"
        )


@dataclass(frozen=True)
class Curve:
    """Smoothed training return of one group (and arm policy), mean and std across seeds.

    Attributes:
        steps: (n_points,) env steps.
        mean: (n_points,) mean over runs of the smoothed return (NaN where no run has data).
        std: (n_points,) sample std across runs (NaN where fewer than 2 runs have data).
        arm: the arm of an independent controller's policy (0/1), or ``None`` for one policy.
    """

    label: str
    group: Group
    arm: int | None
    steps: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    n_runs: int


def _window_means(steps: np.ndarray, returns: np.ndarray, grid: np.ndarray, w: float) -> np.ndarray:
    order = np.argsort(steps, kind="stable")
    steps, returns = steps[order], returns[order]
    csum = np.concatenate([[0.0], np.cumsum(returns)])
    lo = np.searchsorted(steps, grid - w / 2, side="right")
    hi = np.searchsorted(steps, grid + w / 2, side="right")
    count = hi - lo
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, (csum[hi] - csum[lo]) / np.maximum(count, 1), np.nan)


def training_curves(
    groups: Sequence[Group], n_points: int = 200, window_fraction: float = 0.05
) -> tuple[list[Curve], Smoothing]:
    """One curve per group (per arm policy for independent controllers), all smoothed alike."""
    max_step = 0
    for group in groups:
        for run in group.runs:
            if run.train is not None:
                max_step = max(max_step, int(run.train["global_step"].max()))
    window = max(1.0, window_fraction * max_step)
    smoothing = Smoothing(window, n_points, window_fraction)
    if max_step <= 0:
        return [], smoothing
    grid = np.linspace(0.0, float(max_step), n_points + 1)[1:]
    curves = []
    for group in groups:
        series: dict[int | None, list[np.ndarray]] = {}
        for run in group.runs:
            if run.train is None:
                continue
            for arm, part in episodes_by_arm(run.train).items():
                ret = pd.to_numeric(part["return"], errors="coerce").to_numpy(float)
                step = pd.to_numeric(part["global_step"], errors="coerce").to_numpy(float)
                ok = np.isfinite(ret) & np.isfinite(step)
                if ok.any():
                    series.setdefault(arm, []).append(
                        _window_means(step[ok], ret[ok], grid, window)
                    )
        for arm in sorted(series, key=lambda a: -1 if a is None else a):
            stack = np.vstack(series[arm])
            with warnings.catch_warnings():  # all-NaN columns: 'mean of empty slice'
                warnings.simplefilter("ignore", RuntimeWarning)
                mean = np.nanmean(stack, axis=0)
                std = np.nanstd(stack, axis=0, ddof=1)
            std = np.where(np.sum(np.isfinite(stack), axis=0) >= 2, std, np.nan)
            label = group.label if arm is None else f"{group.label}, arm {arm + 1} policy"
            curves.append(Curve(label, group, arm, grid, mean, std, len(stack)))
    return curves, smoothing


# ---- final-stage return ---------------------------------------------------------------------
def run_final_stage_returns(run: RunData) -> dict[int | None, tuple[float | None, int]]:
    """SPEC §4 for one run: mean return of the episodes that ended after
    ``(1 − final_stage_fraction) · budget`` env steps, per arm policy. The budget is the run's
    ``total_timesteps``; for an arm policy of an independent run (``arm`` column ≥ 0, whose
    ``global_step`` counts that arm's own steps) it is the arm's budget (:attr:`RunData.arm_budget`).

    Returns ``{arm or None: (mean return or None if no episode qualifies, episode count)}``.
    """
    if run.train is None:
        return {}
    out: dict[int | None, tuple[float | None, int]] = {}
    for arm, part in episodes_by_arm(run.train).items():
        budget = run.total_timesteps if arm is None else run.arm_budget
        threshold = (1.0 - run.final_stage_fraction) * budget
        step = pd.to_numeric(part["global_step"], errors="coerce")
        ret = pd.to_numeric(part["return"], errors="coerce")
        final = ret[(step > threshold) & np.isfinite(ret)]
        out[arm] = (float(final.mean()) if len(final) else None, len(final))
    return out


def final_stage_table(groups: Sequence[Group]) -> pd.DataFrame:
    """Final-stage return per group (and arm policy): mean ± sample std across seeds.

    Columns: group, algo, controller, arm (-1 for one policy of both arms), seeds (all runs),
    values ({seed: return} of runs with a final stage), n, mean, std (NaN for n < 2),
    episodes (summed over runs), missing (seeds without a final stage).
    """
    rows = []
    for group in groups:
        per_arm: dict[int | None, dict[str, object]] = {}
        for run in group.runs:
            results = run_final_stage_returns(run) or {None: (None, 0)}
            for arm, (value, count) in results.items():
                row = per_arm.setdefault(arm, {"values": {}, "episodes": 0, "missing": []})
                row["episodes"] = int(row["episodes"]) + count  # type: ignore[call-overload]
                if value is None:
                    row["missing"].append(run.seed)  # type: ignore[attr-defined]
                else:
                    row["values"][run.seed] = value  # type: ignore[index]
        for arm in sorted(per_arm, key=lambda a: -1 if a is None else a):
            row = per_arm[arm]
            arm_value = -1 if arm is None else int(arm)
            values = np.array(list(row["values"].values()), dtype=float)  # type: ignore[attr-defined]
            rows.append(
                {
                    "group": group.label,
                    "algo": group.algo,
                    "controller": group.controller,
                    "arm": arm_value,
                    "seeds": group.seeds,
                    "values": row["values"],
                    "n": int(values.size),
                    "mean": float(values.mean()) if values.size else np.nan,
                    "std": float(values.std(ddof=1)) if values.size >= 2 else np.nan,
                    "episodes": row["episodes"],
                    "missing": row["missing"],
                }
            )
    return pd.DataFrame(rows)
