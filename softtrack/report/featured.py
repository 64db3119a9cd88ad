"""The controllers a report draws trajectory, error and moment figures for.

A report of many experiment variants would otherwise hold one figure per variant and
trajectory; by default (:func:`featured_groups`) it draws at most a few chosen controllers,
side by side, and leaves every other controller to the tables:

* the study protocol: centralized TD3 trained for the study's budget (docs/environment.md,
  :data:`~softtrack.report.reference.STUDY_TOTAL_TIMESTEPS` env steps per run);
* the best centralized variant: the lowest mean 3-D RMSE over the trajectories and arms;
* the best independent controller (the baseline the centralized ones are compared with).

A report of at most :data:`MAX_FEATURED` controllers draws them all; ``names`` (``softtrack
report --figures-for NAME``) chooses the controllers by experiment name instead.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from softtrack.report.data import Group
from softtrack.report.reference import STUDY_TOTAL_TIMESTEPS
from softtrack.store.runs import RunStoreError

__all__ = ["MAX_FEATURED", "Featured", "featured_groups", "mean_rmse"]

MAX_FEATURED = 3
"""Reports of up to this many controllers draw every one of them."""


@dataclass(frozen=True)
class Featured:
    """A controller drawn in the figures, and why (``role``: empty when every one is drawn)."""

    group: Group
    role: str = ""

    @property
    def title(self) -> str:
        """``TD3 [td3-sbx-1e7] (study protocol)``."""
        return f"{self.group.label} ({self.role})" if self.role else self.group.label


def mean_rmse(summary: pd.DataFrame, group: Group) -> tuple[int, float]:
    """(cells with a value, mean 3-D RMSE over them, m) of ``group`` in a
    :func:`~softtrack.report.group_summaries.metrics_summary`; (0, inf) without metrics."""
    if summary.empty or "rmse_3d_mean" not in summary:
        return 0, float("inf")
    values = summary.loc[summary["group"] == group.label, "rmse_3d_mean"].to_numpy(float)
    values = values[np.isfinite(values)]
    return (int(values.size), float(values.mean())) if values.size else (0, float("inf"))


def _best(summary: pd.DataFrame, groups: Sequence[Group]) -> Group | None:
    """The group with the lowest mean 3-D RMSE among those with the most cells."""
    scored = [(mean_rmse(summary, g), i, g) for i, g in enumerate(groups)]
    scored = [((-n, value), i, g) for (n, value), i, g in scored if n > 0]
    return min(scored, key=lambda s: (s[0], s[1]))[2] if scored else None


def _study_protocol(group: Group) -> bool:
    return (
        group.algo.lower() == "td3"
        and group.controller == "centralized"
        and all(r.total_timesteps == STUDY_TOTAL_TIMESTEPS for r in group.runs)
    )


def featured_groups(
    groups: Sequence[Group],
    summary: pd.DataFrame,
    *,
    all_groups: bool = False,
    names: Sequence[str] = (),
) -> list[Featured]:
    """The controllers to draw (see the module docstring), each once, in the order study
    protocol, best centralized, best independent; every group when ``all_groups`` or when
    there are at most :data:`MAX_FEATURED`; with ``names``, the groups of those experiments
    (or labels), in that order.

    Raises:
        RunStoreError: a name is no experiment (nor label) of ``groups``.
    """
    if all_groups:
        return [Featured(g) for g in groups]
    if names:
        chosen: list[Group] = []
        for name in names:
            found = [g for g in groups if name in (g.name, g.label)]
            if not found:
                known = ", ".join(dict.fromkeys(g.name for g in groups))
                raise RunStoreError(
                    f"--figures-for {name}: no controller of this report is "
                    f"experiment {name!r}; choose from {known}"
                )
            chosen += [g for g in found if g not in chosen]
        return [Featured(g, "chosen") for g in chosen]
    if len(groups) <= MAX_FEATURED:
        return [Featured(g) for g in groups]
    roles: dict[str, list[str]] = {}
    chosen = []
    picks = (
        ("study protocol", _best(summary, [g for g in groups if _study_protocol(g)])),
        ("best centralized", _best(summary, [g for g in groups if g.controller != "independent"])),
        ("best independent", _best(summary, [g for g in groups if g.controller == "independent"])),
    )
    for role, group in picks:
        if group is None:
            continue
        if group.label not in roles:
            chosen.append(group)
        roles.setdefault(group.label, []).append(role)
    if not chosen:  # no metrics at all: the first groups
        return [Featured(g) for g in groups[:MAX_FEATURED]]
    return [Featured(g, ", ".join(roles[g.label])) for g in chosen]
