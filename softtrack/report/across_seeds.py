"""The report's across-seed comparison: per task, the headline controllers' interquartile mean
3-D RMSE with its stratified bootstrap interval, the probability that the best of them improves
on each other, and their performance profiles (the statistics of ``softtrack compare``,
:mod:`softtrack.report.compare`; docs/statistics.md)."""

from __future__ import annotations

from collections.abc import Sequence

from softtrack.report.compare import (
    CROSS_CPU_NOTE,
    Comparison,
    ControllerScores,
    compare_controllers,
    controller_scores,
    profile_figure,
)
from softtrack.report.document import Context, Doc, seeds_text
from softtrack.store.runs import RunStoreError

__all__ = ["across_seeds_section", "headline_scores"]


def headline_scores(
    ctx: Context, trajectories: Sequence[str]
) -> list[tuple[str, list[ControllerScores]]]:
    """Per task (headline selection) with stored metrics: its title and its controllers'
    3-D RMSE score matrices."""
    tasks = []
    for selection in ctx.plan.headline:
        controllers = []
        for group in selection.shown:
            metrics = [(run.seed, run.metrics) for run in group.runs]
            try:
                controllers.append(controller_scores(group.label, metrics, "rmse_3d", trajectories))
            except RunStoreError:  # no stored metric: the tables say so
                continue
        if controllers:
            tasks.append((selection.title, controllers))
    return tasks


def _comparisons(ctx: Context, trajectories: Sequence[str]) -> list[tuple[str, Comparison]]:
    return [
        (title, compare_controllers(controllers, cells=False))
        for title, controllers in headline_scores(ctx, trajectories)
    ]


def across_seeds_section(doc: Doc, ctx: Context, trajectories: Sequence[str]) -> None:
    """One table per task and the performance profile figure (nothing without metrics)."""
    panels = _comparisons(ctx, trajectories)
    if not panels:
        return
    doc.h(
        2,
        "Best controllers per task, across seeds: interquartile mean and probability of improvement",
    )
    names = {g.label: g.name for g in ctx.groups}
    for title, comparison in panels:
        first = comparison.controllers[0]
        rows = []
        for c in comparison.controllers:
            improves = comparison.improvement.get(c.label)
            cpus = ", ".join(f"{kind} ({n})" for kind, n in sorted(c.cpus.items()))
            rows.append(
                [
                    names.get(c.label, c.label),
                    str(len(c.seeds)),
                    seeds_text(c.seeds),
                    comparison.overall[c.label].text(),
                    "—" if improves is None else improves.text(2),
                    cpus,
                ]
            )
        doc.p(f"**{title}** (best first: {names.get(first.label, first.label)}):")
        doc.table(
            [
                "controller",
                "runs",
                "seeds",
                "IQM 3-D RMSE, all cells (m) [95 % interval]",
                f"P({names.get(first.label, first.label)} improves on it) [95 %]",
                "CPU kinds (cells)",
            ],
            rows,
        )
    path, rel = ctx.figure("performance_profile.png")
    shown = [g for s in ctx.plan.headline for g in s.shown]
    profile_figure(panels, path, ctx.plan.colors, ctx.footer(shown), names)
    doc.img(rel, "Performance profile: fraction of runs and cells below each 3-D RMSE")
    doc.p(
        "The controllers of the tracking-error figure, per task. IQM: the mean of the middle "
        "50 % of all (run, trajectory/arm cell) values, with a 95 % stratified bootstrap "
        "interval (2000 resamples of the runs within each cell); P(A improves on B): the "
        "probability that a random run of A has the lower 3-D RMSE than a random run of B in "
        "the same cell, averaged over the cells (0.5: no difference). With three runs the "
        "intervals are wide; `softtrack compare A B` gives the same per cell (docs/statistics.md). "
        f"{CROSS_CPU_NOTE[0].upper()}{CROSS_CPU_NOTE[1:]}."
    )
