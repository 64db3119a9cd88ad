"""Which controllers each comparison figure of a report draws, and their colours.

Decided once per report, before any figure is drawn, so that a controller has one colour in
every figure (:func:`softtrack.report.families.assign_colors`) and every figure draws at most
:data:`~softtrack.report.families.MAX_SERIES` controllers:

* training curves and final-stage returns: one panel per family (task × kind, planners
  excepted), its controllers ranked by final-stage return; a training shared by a derived
  experiment is drawn once (:func:`~softtrack.report.families.training_groups`);
* tracking error: one figure per task of the headline controllers (:func:`headline`);
* validation: one panel per family of the validated controllers, ranked by their best
  validation score;
* robustness: the controllers with robustness tables, ranked by their nominal error.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from softtrack.report.curves import episode_seconds, final_stage_table
from softtrack.report.data import Group
from softtrack.report.families import (
    MAX_SERIES,
    Family,
    assign_colors,
    best_first,
    families,
    kind_of,
    task_of,
    training_groups,
)
from softtrack.report.featured import mean_rmse
from softtrack.report.group_summaries import validation_scores
from softtrack.report.reference import STUDY_TOTAL_TIMESTEPS

__all__ = ["PER_KIND", "FigurePlan", "Selection", "headline", "plan_figures"]

PER_KIND = 3
"""The most controllers of one kind a tracking-error figure draws."""


@dataclass(frozen=True)
class Selection:
    """The controllers one figure or panel draws.

    Attributes:
        title: the family or task, e.g. ``centralized variants · shared target, no contact``.
        shown: at most :data:`MAX_SERIES` controllers, best first.
        ranked_by: what ranked them, for the caption (e.g. ``final-stage return``).
        total: how many controllers the family has (``total - len(shown)`` are in the tables
            only).
    """

    title: str
    shown: tuple[Group, ...]
    ranked_by: str
    total: int

    @property
    def hidden(self) -> int:
        return self.total - len(self.shown)

    @property
    def note(self) -> str:
        """``best 8 of 19 by final-stage return`` or empty when all are drawn."""
        if not self.hidden:
            return ""
        return f"best {len(self.shown)} of {self.total} by {self.ranked_by}"


@dataclass(frozen=True)
class FigurePlan:
    """Every comparison figure's selection, and the colour of each drawn controller."""

    training: tuple[Selection, ...] = ()
    headline: tuple[Selection, ...] = ()
    validation: tuple[Selection, ...] = ()
    robustness: Selection | None = None
    colors: dict[str, str] = field(default_factory=dict)

    def color(self, group: Group) -> str:
        """The controller's colour (grey for one no figure plans to draw)."""
        return self.colors.get(group.label, "#7f7f7f")


def _select(
    title: str,
    groups: Sequence[Group],
    score: Callable[[Group], float],
    ranked_by: str,
    *,
    higher: bool = False,
) -> Selection:
    ranked = best_first(groups, score, higher=higher)
    return Selection(title, tuple(ranked[:MAX_SERIES]), ranked_by, len(ranked))


def _final_return_score(table: pd.DataFrame) -> Callable[[Group], float]:
    """A group's final-stage return (the mean over its arm policies), NaN without one."""

    def score(group: Group) -> float:
        if table.empty:
            return math.nan
        values = table.loc[table["group"] == group.label, "mean"].to_numpy(float)
        values = values[np.isfinite(values)]
        return float(values.mean()) if values.size else math.nan

    return score


def _rmse_score(summary: pd.DataFrame) -> Callable[[Group], float]:
    def score(group: Group) -> float:
        n, value = mean_rmse(summary, group)
        return value if n else math.nan

    return score


def headline(task: str, groups: Sequence[Group], summary: pd.DataFrame) -> Selection:
    """The controllers of one task that its tracking-error figure draws: one of each kind
    (the study protocol at the study's budget where there is one, otherwise the best; the
    best of the other kinds) by mean 3-D RMSE over the evaluated cells, then the next best,
    at most :data:`PER_KIND` of a kind and :data:`MAX_SERIES` in all."""
    score = _rmse_score(summary)
    candidates = [g for g in training_groups(groups) if math.isfinite(score(g))]
    chosen: list[Group] = []
    for family in families(candidates):
        ranked = best_first(family.groups, score)
        at_budget = [g for g in ranked if _at_study_budget(g)]
        chosen.append(at_budget[0] if family.kind == "study protocol" and at_budget else ranked[0])
    kinds = {g.label: kind_of(g) for g in candidates}
    for group in best_first(candidates, score):
        if len(chosen) >= MAX_SERIES:
            break
        same_kind = sum(kinds[c.label] == kinds[group.label] for c in chosen)
        if group not in chosen and same_kind < PER_KIND:
            chosen.append(group)
    shown = tuple(best_first(chosen, score))
    return Selection(task, shown, "mean 3-D RMSE, at most 3 of a kind", len(candidates))


def _at_study_budget(group: Group) -> bool:
    return all(r.total_timesteps == STUDY_TOTAL_TIMESTEPS for r in group.runs)


def _by_episode_length(family: Family) -> list[tuple[str, list[Group]]]:
    """The family's groups by training episode length (s), so that returns are compared at
    equal length; the title names the length where the family has several."""
    by_length: dict[float, list[Group]] = {}
    for group in family.groups:
        seconds = max(episode_seconds(r) for r in group.runs) if group.runs else 0.0
        by_length.setdefault(seconds, []).append(group)
    if len(by_length) == 1:
        return [(family.title, list(family.groups))]
    return [(f"{family.title}, {s:g}-s episodes", g) for s, g in sorted(by_length.items())]


def _validation_score(group: Group) -> float:
    best = [
        float(part["score"].min())
        for run in group.runs
        for _, part in validation_scores(run).groupby("policy")
        if len(part)
    ]
    return float(np.mean(best)) if best else math.nan


def _has_levels(group: Group) -> bool:
    """Some run of the group has a one-factor perturbation at two or more numeric levels."""
    for table in (r.robustness for r in group.runs):
        if table is None:
            continue
        levels = pd.to_numeric(table["level"], errors="coerce")
        graded = table[np.isfinite(levels) & (table["perturbation"] != "nominal")]
        if graded.groupby("perturbation")["level"].nunique().max() >= 2:
            return True
    return False


def _nominal_robustness(group: Group) -> float:
    """The group's mean 3-D RMSE in the ``nominal`` robustness setting (NaN without one, or
    without two levels of a perturbation to draw)."""
    if not _has_levels(group):
        return math.nan
    values = [
        float(pd.to_numeric(table.loc[table["setting"] == "nominal", "rmse_3d"]).mean())
        for table in (r.robustness for r in group.runs)
        if table is not None
    ]
    values = [v for v in values if math.isfinite(v)]
    return float(np.mean(values)) if values else math.nan


def plan_figures(groups: Sequence[Group], summary: pd.DataFrame) -> FigurePlan:
    """The selections and colours of a report of ``groups`` (``summary``:
    :func:`~softtrack.report.group_summaries.metrics_summary`)."""
    trained = [g for g in training_groups(groups) if g.controller != "mpc"]
    final_score = _final_return_score(final_stage_table(trained))
    training = tuple(
        _select(title, members, final_score, "final-stage return", higher=True)
        for family in families(trained)
        for title, members in _by_episode_length(family)
    )
    tasks = list(dict.fromkeys(f.task for f in families(groups)))
    headlines = tuple(
        s
        for task in tasks
        if (s := headline(task, [g for g in groups if task_of(g) == task], summary)).shown
    )
    validated = [g for g in trained if math.isfinite(_validation_score(g))]
    validation = tuple(
        _select(f.title, f.groups, _validation_score, "best validation score")
        for f in families(validated)
    )
    study_task = tasks[0] if tasks else ""
    robust = [
        g
        for g in training_groups(groups)
        if task_of(g) == study_task and math.isfinite(_nominal_robustness(g))
    ]
    robustness = (
        _select(study_task, robust, _nominal_robustness, "nominal 3-D RMSE") if robust else None
    )
    figures: list[Sequence[str]] = [[g.label for g in s.shown] for s in headlines]
    figures += [[g.label for g in s.shown] for s in (*training, *validation)]
    if robustness is not None:
        figures.append([g.label for g in robustness.shown])
    return FigurePlan(training, headlines, validation, robustness, assign_colors(figures))
