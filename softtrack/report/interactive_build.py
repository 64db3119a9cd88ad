"""The interactive report page's content from a report's runs (``softtrack report --html``):
the first screen's tables, the training curves, and the featured controllers replayed for the
3-D viewer (:mod:`softtrack.report.interactive`)."""

from __future__ import annotations

import statistics
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from softtrack.evaluation.run_evaluation import PolicyLoader
from softtrack.report.across_seeds import headline_scores
from softtrack.report.animation import replay_run, rollout_of
from softtrack.report.compare import compare_controllers
from softtrack.report.curves import training_curves
from softtrack.report.data import RunData
from softtrack.report.document import Context, Doc
from softtrack.report.featured import Featured
from softtrack.report.group_summaries import validation_scores
from softtrack.report.interactive import AnswerTable, CurvePanel, interactive_page
from softtrack.report.reference import TRAJECTORY_TITLES, study_rmse_3d
from softtrack.report.training_sections import runs_section
from softtrack.report.tune_view import TuneView, tune_html_section
from softtrack.report.video import write_page
from softtrack.report.viewer import Rollout
from softtrack.store.runs import RunStoreError

__all__ = ["INTERACTIVE_PAGE", "write_interactive"]

INTERACTIVE_PAGE = "interactive.html"
#: Frames per second of the viewer's replays (a 10-s episode: 150 frames per trajectory).
VIEWER_FPS = 15.0


def _answers(ctx: Context, trajectories: Sequence[str]) -> list[AnswerTable]:
    tables = []
    for task, controllers in headline_scores(ctx, trajectories):
        comparison = compare_controllers(controllers)
        cells = controllers[0].cells
        header = ("trajectory, arm", "study (TD3, 3 seeds)", *(c.label for c in controllers))
        rows = []
        for index, (trajectory, arm) in enumerate(cells):
            study = study_rmse_3d("td3", "centralized", trajectory, arm)
            row = [
                f"{TRAJECTORY_TITLES.get(trajectory, trajectory)}, arm {arm + 1}",
                "—" if study is None else f"{study:.4f}",
            ]
            for c in controllers:
                interval = comparison.per_cell[c.label][index]
                row.append("—" if interval is None else interval.text())
            rows.append(tuple(row))
        overall = ["all cells", "", *(comparison.overall[c.label].text() for c in controllers)]
        rows.append(tuple(overall))
        title = f"{task}: 3-D RMSE (m), IQM over seeds [95 % interval]"
        tables.append(AnswerTable(title, header, tuple(rows)))
    return tables


def _panels(ctx: Context) -> list[CurvePanel]:
    panels = []
    for selection in ctx.plan.training:
        curves, smoothing = training_curves(selection.shown)
        unit = "return per second of episode" if smoothing.per_second else "episode return"
        panels.append(
            CurvePanel(
                selection.title,
                unit,
                tuple((c.label, ctx.plan.color(c.group), c.steps, c.mean, c.std) for c in curves),
            )
        )
    return panels


def _validation_panels(ctx: Context) -> list[CurvePanel]:
    """Per validated family, each controller's validation score per checkpoint (its first
    policy), mean ± 1 std across seeds at the checkpoints its runs share."""
    panels = []
    for selection in ctx.plan.validation:
        curves = []
        for group in selection.shown:
            per_run = []
            for run in group.runs:
                scores = validation_scores(run)
                if scores.empty:
                    continue
                first = scores[scores["policy"] == scores["policy"].min()]
                per_run.append(dict(zip(first["global_step"], first["score"], strict=True)))
            steps = sorted(set.intersection(*(set(r) for r in per_run))) if per_run else []
            if not steps:
                continue
            values = np.array([[r[step] for step in steps] for r in per_run], dtype=float)
            values[~np.isfinite(values)] = np.nan
            with warnings.catch_warnings():  # a checkpoint no run scored finitely
                warnings.simplefilter("ignore", RuntimeWarning)
                mean = np.nanmean(values, axis=0)
                std = np.nanstd(values, axis=0, ddof=1) if len(values) > 1 else 0.0 * mean
            curves.append((group.label, ctx.plan.color(group), np.array(steps, float), mean, std))
        if curves:
            panels.append(CurvePanel(f"validation: {selection.title}", "score (m)", tuple(curves)))
    return panels


def _median_run(runs: Sequence[RunData]) -> RunData:
    """The run with the median mean 3-D RMSE over its stored metrics (the first without)."""
    scored = [
        (float(run.metrics["rmse_3d"].mean()), run)
        for run in runs
        if run.metrics is not None and "rmse_3d" in run.metrics
    ]
    if not scored:
        return runs[0]
    middle = statistics.median_low([score for score, _ in scored])
    return next(run for score, run in scored if score == middle)


def _rollouts(
    featured: Sequence[Featured], trajectories: Sequence[str], load: PolicyLoader
) -> tuple[list[Rollout], list[str]]:
    """Each featured controller's median run replayed on every trajectory (notes: one line per
    controller that could not be replayed)."""
    rollouts, notes = [], []
    for item in featured:
        run = _median_run(item.group.runs)
        try:
            for trajectory in trajectories:
                replay = replay_run(run.record, trajectory, VIEWER_FPS, load)
                rollouts.append(rollout_of(f"{item.group.label} (seed {run.seed})", replay))
        except RunStoreError as exc:
            notes.append(f"{item.group.label}: not replayed ({str(exc).splitlines()[0]})")
    return rollouts, notes


def write_interactive(
    out_dir: Path,
    title: str,
    intro: str,
    ctx: Context,
    runs: Sequence[RunData],
    featured: Sequence[Featured],
    trajectories: Sequence[str],
    load: PolicyLoader,
    tune_views: Sequence[TuneView] = (),
) -> tuple[Path, list[str]]:
    """Write ``out_dir/interactive.html``; returns its path and one note per featured
    controller that could not be replayed. ``tune_views``: tuning studies drawn after the
    answers (parallel coordinates, parameter importance)."""
    doc = Doc()
    runs_section(doc, ctx, runs)
    table = next(b for b in doc.blocks if b[0] == "table")
    rollouts, notes = _rollouts(featured, trajectories, load)
    if notes:
        intro = f"{intro} Not in the viewer: {'; '.join(notes)}."
    page = interactive_page(
        title,
        intro,
        _answers(ctx, trajectories),
        [*_panels(ctx), *_validation_panels(ctx)],
        rollouts,
        table[1],
        table[2],
        VIEWER_FPS,
        tune_html_section(tune_views),
    )
    return write_page(page, out_dir / INTERACTIVE_PAGE), notes
