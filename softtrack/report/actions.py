"""The "Policy actions" table of a report: per-arm action statistics across seeds.

Built from :func:`softtrack.report.group_summaries.metrics_summary` (columns ``action_saturation``,
``action_change``, ``action_rms`` of ``eval_metrics``); metrics tables written before the
action statistics existed have no such columns, their cells read "no data", and only then
does the caption say so. After them, the smoothness and safety columns (``torque_rate_rms``,
``peak_moment``, ``min_arm_distance``, ``collision_steps``), "–" where no run's table has
them (written before they existed).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import pandas as pd

from softtrack.evaluation.metrics import SATURATION_THRESHOLD
from softtrack.report.data import Group
from softtrack.report.group_summaries import summary_row
from softtrack.report.reference import (
    CALIBRATION_ACTION_CHANGE,
    CALIBRATION_ACTION_SATURATION,
    TRAJECTORY_TITLES,
)
from softtrack.report.text import mean_pm_std

__all__ = ["ACTIONS_HEADER", "actions_caption", "actions_rows"]

ACTIONS_HEADER = (
    "algorithm",
    "trajectory",
    "arm",
    "action saturation (%)",
    "mean |Δa| per step",
    "action RMS",
    "seeds with data",
    "torque rate RMS (N·m/s)",
    "peak moment (N·m)",
    "min clearance (m)",
    "collision steps",
)
# (column, scale, decimals) of the statistic cells
_CELLS = (("action_saturation", 100.0, 1), ("action_change", 1.0, 3), ("action_rms", 1.0, 3))
# ... and of the smoothness and safety cells ("–" where not stored)
_SAFETY_CELLS = (
    ("torque_rate_rms", 1.0, 0),
    ("peak_moment", 1.0, 1),
    ("min_arm_distance", 1.0, 3),
    ("collision_steps", 1.0, 0),
)
_NOT_STORED = "–"


def _pm(row: pd.Series | None, column: str, scale: float, digits: int) -> str:
    """``mean ± std`` of ``column`` × ``scale`` in a summary row, or "no data"."""
    if row is None:
        return "no data"
    return mean_pm_std(row.get(f"{column}_mean"), row.get(f"{column}_std"), digits, scale)


def _pm_or_dash(row: pd.Series | None, column: str, scale: float, digits: int) -> str:
    """``mean ± std`` of ``column`` × ``scale``, or "–" where no seed has a finite value."""
    mean = row.get(f"{column}_mean") if row is not None else None
    if mean is None or not math.isfinite(mean):
        return _NOT_STORED
    return _pm(row, column, scale, digits)


def actions_rows(
    summary: pd.DataFrame, groups: Sequence[Group], trajectories: Sequence[str]
) -> list[list[str]]:
    """One row per group, trajectory and arm (rows of "no data" where nothing is stored)."""
    rows = []
    for group in groups:
        for trajectory in trajectories:
            for arm in (0, 1):
                row = summary_row(summary, group.label, trajectory, arm)
                n_data = row.get("action_saturation_n") if row is not None else None
                n_data = int(n_data) if n_data is not None and math.isfinite(n_data) else 0
                seeds = f"{n_data} of {int(row['n']) if row is not None else len(group.runs)}"
                rows.append(
                    [group.label, TRAJECTORY_TITLES.get(trajectory, trajectory), f"arm {arm + 1}"]
                    + [_pm(row, *cell) for cell in _CELLS]
                    + [seeds]
                    + [_pm_or_dash(row, *cell) for cell in _SAFETY_CELLS]
                )
    return rows


def _missing(summary: pd.DataFrame, group: Group, column: str = "action_saturation") -> bool:
    """Whether some of ``group``'s evaluated runs lack ``column`` (default: the action
    statistics)."""
    if summary.empty:
        return False
    rows = summary[summary["group"] == group.label]
    if rows.empty:
        return False
    n_data = rows.get(f"{column}_n", pd.Series(0, index=rows.index)).fillna(0)
    return bool((n_data < rows["n"]).any())


def actions_caption(summary: pd.DataFrame, groups: Sequence[Group]) -> str:
    """What the columns mean, the calibration values of docs/environment.md to compare them with, and, only
    where a run's metrics table lacks the statistics, which controllers that concerns."""
    text = (
        "Per arm over each evaluation episode, actions clipped to [−1, 1] as the environment "
        "applies them: saturation is the share of the arm's 12 control values with "
        f"|a| ≥ {SATURATION_THRESHOLD:g}, mean |Δa| their mean absolute change from one control "
        "step to the next (0–2) and RMS their root mean square (0–1), each as mean ± sample std "
        "across seeds; for comparison, the TD3 calibration prototype of docs/environment.md had "
        f"{100 * CALIBRATION_ACTION_SATURATION:.0f} % saturation and a mean change of "
        f"{CALIBRATION_ACTION_CHANGE:.2f}, i.e. accurate but bang-bang."
        " Torque rate RMS is the root mean square of the arm's element torques' change per "
        "second (all elements, both directions) and peak moment their largest |torque| over the "
        "episode; min clearance is the closest approach of the two arms' surfaces (smallest "
        "distance between nodes of their centrelines minus both radii) and collision steps "
        "counts the control steps with a clearance below the reward's collision margin (0 m by "
        "default: contact); these two are per episode, the same in both arms' rows."
    )
    missing = [g.label for g in groups if _missing(summary, g)]
    if missing:
        text += (
            f" Some runs of {', '.join(missing)} have metrics stored before these statistics "
            'existed (fewer "seeds with data" than seeds, "no data" where none has them): '
            "run `softtrack evaluate` on them again."
        )
    older = [g.label for g in groups if _missing(summary, g, "torque_rate_rms")]
    if older:
        text += (
            f" Metrics of some runs of {', '.join(older)} were stored before the torque and "
            'clearance columns existed: their means leave those runs out, and "–" marks '
            "cells where no run has them (`softtrack evaluate` adds them)."
        )
    return text
