"""Training curves and final-stage returns of run groups, aggregated across seeds.

Both read the ``train_episodes`` table of each run (:class:`softtrack.report.data.RunData`);
an independent run's table holds one episode series per arm policy (column ``arm``).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypedDict

import numpy as np
import pandas as pd

from softtrack.report.data import Group, RunData, episodes_by_arm
from softtrack.store.status import final_stage_budget, final_stage_returns

__all__ = [
    "Curve",
    "Smoothing",
    "episode_seconds",
    "final_stage_table",
    "run_final_stage_returns",
    "training_curves",
]


# ---- training curves ------------------------------------------------------------------------
DEFAULT_EPISODE_SECONDS = 10.0  # env.episode_duration of a spec that does not state it


@dataclass(frozen=True)
class Smoothing:
    """The smoothing rule of a report's training curves, and their unit.

    Each curve is smoothed over a centred window that scales with its own group's training
    length: ``window_fraction`` of the group's last env step, but at least twice the typical
    spacing of its runs' episode ends (so every window holds episodes). At each of
    ``n_points`` evenly spaced env steps g in (0, the group's last step], a run's value is the
    mean return of its episodes that ended within (g − w/2, g + w/2].

    ``per_second``: the groups' training episodes differ in length, so every return is divided
    by its run's episode duration (``env.episode_duration``, s) and plotted per second.
    """

    n_points: int
    window_fraction: float
    per_second: bool = False
    windows: tuple[tuple[str, float], ...] = ()  # (group label, window in env steps)

    def describe(self) -> str:
        distinct = dict.fromkeys(self.windows)  # curves of one group share their window
        values = sorted({w for _, w in distinct})
        if len(distinct) <= 4:
            windows = "; ".join(f"{label}: {w:,.0f}" for label, w in distinct)
        else:
            windows = f"{values[0]:,.0f} to {values[-1]:,.0f}"
        text = (
            f"each run's episode returns averaged over a centred window of "
            f"{self.window_fraction:.0%} of its group's training steps (at least two episode "
            f"ends), at {self.n_points} points per curve (windows in env steps: "
            f"{windows or 'none'})"
        )
        if self.per_second:
            text += (
                "; the runs' training episodes differ in length, so each return is divided by "
                "its episode duration (return per second of episode)"
            )
        return text


@dataclass(frozen=True)
class Curve:
    """Smoothed training return of one group (and arm policy), mean and std across seeds.

    Attributes:
        steps: (n_points,) env steps, spanning this group's own training length.
        mean: (n_points,) mean over runs of the smoothed return (NaN where no run has data),
            per second of episode when ``per_second``.
        std: (n_points,) sample std across runs (NaN where fewer than 2 runs have data).
        arm: the arm of an independent controller's policy (0/1), or ``None`` for one policy.
        window: the smoothing window (env steps).
        episode_seconds: the runs' training episode duration (s; the largest if they differ).
        per_second: ``mean``/``std`` are returns divided by ``episode_seconds``.
    """

    label: str
    group: Group
    arm: int | None
    steps: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    n_runs: int
    window: float = 0.0
    episode_seconds: float = DEFAULT_EPISODE_SECONDS
    per_second: bool = False


def episode_seconds(run: RunData) -> float:
    """A run's training episode duration (``env.episode_duration`` of its spec, s)."""
    env = run.record.raw_spec().get("env")
    value = env.get("episode_duration") if isinstance(env, dict) else None
    if isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0:
        return float(value)
    return DEFAULT_EPISODE_SECONDS


def _window_means(steps: np.ndarray, returns: np.ndarray, grid: np.ndarray, w: float) -> np.ndarray:
    order = np.argsort(steps, kind="stable")
    steps, returns = steps[order], returns[order]
    csum = np.concatenate([[0.0], np.cumsum(returns)])
    lo = np.searchsorted(steps, grid - w / 2, side="right")
    hi = np.searchsorted(steps, grid + w / 2, side="right")
    count = hi - lo
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, (csum[hi] - csum[lo]) / np.maximum(count, 1), np.nan)


def _episode_spacing(steps: np.ndarray) -> float:
    """The median spacing of the distinct env steps at which episodes ended (0 if < 2)."""
    ends = np.unique(steps)
    return float(np.median(np.diff(ends))) if ends.size >= 2 else 0.0


def training_curves(
    groups: Sequence[Group], n_points: int = 200, window_fraction: float = 0.03
) -> tuple[list[Curve], Smoothing]:
    """One curve per group (per arm policy for independent controllers), each smoothed over
    ``window_fraction`` of its own group's training length (see :class:`Smoothing`); returns
    per second of episode when the groups' training episodes differ in length."""
    # per group and arm policy, per run: (env steps, returns, episode duration s)
    series: list[tuple[Group, int | None, list[tuple[np.ndarray, np.ndarray, float]]]] = []
    for group in groups:
        per_arm: dict[int | None, list[tuple[np.ndarray, np.ndarray, float]]] = {}
        for run in group.runs:
            if run.train is None:
                continue
            for arm, part in episodes_by_arm(run.train).items():
                ret = pd.to_numeric(part["return"], errors="coerce").to_numpy(float)
                step = pd.to_numeric(part["global_step"], errors="coerce").to_numpy(float)
                ok = np.isfinite(ret) & np.isfinite(step)
                if ok.any():
                    per_arm.setdefault(arm, []).append((step[ok], ret[ok], episode_seconds(run)))
        for arm in sorted(per_arm, key=lambda a: -1 if a is None else a):
            series.append((group, arm, per_arm[arm]))
    per_second = len({seconds for *_, runs in series for *_, seconds in runs}) > 1
    curves = []
    for group, arm, runs in series:
        max_step = max(float(step.max()) for step, *_ in runs)
        if max_step <= 0:
            continue
        floor = 2.0 * max(_episode_spacing(step) for step, *_ in runs)
        window = max(1.0, window_fraction * max_step, floor)
        grid = np.linspace(0.0, max_step, n_points + 1)[1:]
        stack = np.vstack(
            [
                _window_means(step, ret / seconds if per_second else ret, grid, window)
                for step, ret, seconds in runs
            ]
        )
        seconds = max(s for *_, s in runs)
        with warnings.catch_warnings():  # all-NaN columns: 'mean of empty slice'
            warnings.simplefilter("ignore", RuntimeWarning)
            mean = np.nanmean(stack, axis=0)
            std = np.nanstd(stack, axis=0, ddof=1)
        std = np.where(np.sum(np.isfinite(stack), axis=0) >= 2, std, np.nan)
        label = group.label if arm is None else f"{group.label}, arm {arm + 1} policy"
        curves.append(
            Curve(label, group, arm, grid, mean, std, len(stack), window, seconds, per_second)
        )
    smoothing = Smoothing(
        n_points,
        window_fraction,
        per_second,
        tuple(dict.fromkeys((c.group.label, c.window) for c in curves)),
    )
    return curves, smoothing


# ---- final-stage return ---------------------------------------------------------------------
def run_final_stage_returns(run: RunData) -> dict[int | None, tuple[float | None, int]]:
    """docs/environment.md for one run: mean return of the episodes that ended after
    ``(1 − final_stage_fraction) · budget`` env steps, per arm policy. The budget is the run's
    ``total_timesteps`` (the steps it trained if it stopped early); for an arm policy of an
    independent run (``arm`` column ≥ 0, whose ``global_step`` counts that arm's own steps) it
    is the arm's budget (:attr:`RunData.arm_budget`).

    Returns ``{arm or None: (mean return or None if no episode qualifies, episode count)}``
    (:func:`softtrack.store.status.final_stage_returns`).
    """
    if run.train is None:
        return {}
    return final_stage_returns(
        run.train, run.final_stage_fraction, final_stage_budget(run.record.info), run.arm_budget
    )


class _ArmFinalStage(TypedDict):
    """One arm policy's final-stage returns across the seeds of a group."""

    values: dict[int, float]  # seed → final-stage return
    episodes: int
    missing: list[int]  # seeds without a final stage


def final_stage_table(groups: Sequence[Group]) -> pd.DataFrame:
    """Final-stage return per group (and arm policy): mean ± sample std across seeds.

    Columns: group, algo, controller, arm (-1 for one policy of both arms), seeds (all runs),
    values ({seed: return} of runs with a final stage), n, mean, std (NaN for n < 2),
    episodes (summed over runs), missing (seeds without a final stage).
    """
    rows = []
    for group in groups:
        per_arm: dict[int | None, _ArmFinalStage] = {}
        for run in group.runs:
            results = run_final_stage_returns(run) or {None: (None, 0)}
            for arm, (value, count) in results.items():
                row = per_arm.setdefault(arm, {"values": {}, "episodes": 0, "missing": []})
                row["episodes"] = int(row["episodes"]) + count
                if value is None:
                    row["missing"].append(run.seed)
                else:
                    row["values"][run.seed] = value
        for arm in sorted(per_arm, key=lambda a: -1 if a is None else a):
            row = per_arm[arm]
            arm_value = -1 if arm is None else int(arm)
            values = np.array(list(row["values"].values()), dtype=float)
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
