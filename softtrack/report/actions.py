"""The "Policy actions" table of a report: per-arm action statistics across seeds.

Built from :func:`softtrack.report.summaries.metrics_summary`; metrics tables written before the
action statistics existed have no such columns, and their cells read "no data".
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import pandas as pd

from softtrack.metrics import SATURATION_THRESHOLD
from softtrack.report.data import Group
from softtrack.report.reference import (
    CALIBRATION_ACTION_CHANGE,
    CALIBRATION_ACTION_SATURATION,
    TRAJECTORY_TITLES,
)
from softtrack.report.summaries import summary_row
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
)
# (column, scale, decimals) of the statistic cells
_CELLS = (("action_saturation", 100.0, 1), ("action_change", 1.0, 3), ("action_rms", 1.0, 3))


def _pm(row: pd.Series | None, column: str, scale: float, digits: int) -> str:
    """``mean ± std`` of ``column`` × ``scale`` in a summary row, or "no data"."""
    if row is None:
        return "no data"
    return mean_pm_std(row.get(f"{column}_mean"), row.get(f"{column}_std"), digits, scale)


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
                )
    return rows


def actions_caption() -> str:
    """What the columns mean, and the SPEC's calibration values to compare them with."""
    return (
        "Per arm over each evaluation episode, actions clipped to [−1, 1] as the environment "
        "applies them: saturation is the share of the arm's 12 control values with "
        f"|a| ≥ {SATURATION_THRESHOLD:g}, mean |Δa| their mean absolute change from one control "
        "step to the next (0–2) and RMS their root mean square (0–1), each as mean ± sample std "
        "across seeds; for comparison, the SPEC's TD3 calibration prototype (§5) had "
        f"{100 * CALIBRATION_ACTION_SATURATION:.0f} % saturation and a mean change of "
        f"{CALIBRATION_ACTION_CHANGE:.2f}, i.e. accurate but bang-bang. No data: the run's "
        "metrics were stored before these statistics existed (run `softtrack evaluate` again)."
    )
