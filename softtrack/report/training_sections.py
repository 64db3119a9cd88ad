"""Report sections on the runs themselves: the runs table, training curves (study Fig. 3),
final-stage returns (study Table 3) and, for runs validated during training, the checkpoint
each selected.

Each section appends its headings, tables and figures to a
:class:`~softtrack.report.document.Doc`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from softtrack.evaluation import CONFIRM_SEED, VALIDATION_SEED
from softtrack.report import comparison_figures as cf
from softtrack.report.curves import final_stage_table, training_curves
from softtrack.report.data import RunData
from softtrack.report.document import NOT_IN_STUDY, Context, Doc, commit_text, seeds_text
from softtrack.report.group_summaries import validation_scores, validation_summary
from softtrack.report.plan import Selection
from softtrack.report.text import mean_pm_std
from softtrack.store.status import training_seconds

__all__ = ["final_section", "runs_section", "training_section", "validation_section"]


def runs_section(doc: Doc, ctx: Context, runs: Sequence[RunData]) -> None:
    """The runs table: identity, status, progress, speed, CPU, provenance and stored tables of
    every run, and the problems met reading them."""
    doc.h(2, "Runs")
    rows = []
    for g in ctx.groups:
        for r in g.runs:
            info = r.record.info
            tables = [
                name
                for name, df in (
                    ("train", r.train),
                    ("trajectories", r.trajectories),
                    ("metrics", r.metrics),
                    ("moments", r.moments),
                )
                if df is not None
            ]
            rows.append(
                [
                    f"`{r.run_id}`",
                    info.name,
                    info.algo,
                    info.controller,
                    str(info.seed),
                    info.status,
                    "— (planner)"
                    if info.controller == "mpc"
                    else f"{r.last_step:,} / {info.total_timesteps:,}",
                    *_training_speed(r),
                    info.cpu or "—",
                    info.spec_hash[:12],
                    commit_text(r),
                    ", ".join(tables) or "none",
                ]
            )
    doc.table(
        [
            "run",
            "experiment",
            "algorithm",
            "controller",
            "seed",
            "status",
            "env steps / budget",
            "training time",
            "env steps/s",
            "CPU (speed depends on it)",
            "spec hash",
            "commit",
            "stored tables",
        ],
        rows,
    )
    problems = [p for r in runs for p in r.problems]
    if problems:
        doc.p("Problems: " + "; ".join(problems) + ".")


def _training_speed(run: RunData) -> tuple[str, str]:
    """(training wall time, env steps per second) of a run from its training clock, summed over
    sessions (the ``wall_time`` of its last logged episode); "—" without training episodes."""
    seconds = training_seconds(run.train)
    if seconds is None:
        return "—", "—"
    duration = f"{seconds / 60:.0f} min" if seconds < 5400 else f"{seconds / 3600:.2f} h"
    return duration, f"{run.last_step / seconds:,.0f}"


def training_section(doc: Doc, ctx: Context) -> None:
    """Episode return against environment steps per group (study Fig. 3)."""
    doc.h(2, "Training curves (study Fig. 3)")
    panels = [
        cf.CurvePanel(selection, *training_curves(selection.shown))
        for selection in ctx.plan.training
    ]
    shown = [g for p in panels for g in p.selection.shown]
    path, rel = ctx.figure("training_curves.png")
    cf.training_curves_figure(panels, ctx.plan.colors, path, ctx.footer(shown))
    doc.img(rel, "Training curves: episode return against environment steps")
    if any(p.curves for p in panels):
        doc.p(
            "Episode return against environment steps, mean ± 1 sample std across seeds, one "
            "panel per family of controllers (docs/report.md), each with its own axes: budgets "
            "differ between families, and an independent controller's curves are one arm "
            "policy's return, not both arms'. Smoothing: each run's episode returns averaged "
            f"over a centred window of {panels[0].smoothing.window_fraction:.0%} of its "
            "controller's training steps (at least two episode ends). "
            + _hidden_text(ctx.plan.training)
            + "The study's curves are not published as numbers."
        )
    else:
        doc.p("No data: no selected run has stored training episodes.")


def _hidden_text(selections: Sequence[Selection]) -> str:
    """Which panels draw only their best controllers (the rest: the tables)."""
    partial = [f"{s.title}: {s.note}" for s in selections if s.hidden]
    if not partial:
        return ""
    return (
        f"Panels that draw only their best controllers ({'; '.join(partial)}); the others "
        "are in the tables. "
    )


def final_section(doc: Doc, ctx: Context) -> None:
    """Final-stage return per group and policy, per seed and against the study (Table 3)."""
    doc.h(2, "Final-stage return (study Table 3)")
    table = final_stage_table([g for g in ctx.groups if g.controller != "mpc"])
    rows = []
    for row in table.itertuples():
        group = next(g for g in ctx.groups if g.label == row.group)
        per_seed = ", ".join(f"{s}: {v:.2f}" for s, v in sorted(row.values.items())) or "none"
        if row.missing:
            per_seed += f" (no final stage: seed {seeds_text(row.missing)})"
        rows.append(
            [
                row.group,
                "both arms" if row.arm < 0 else f"arm {int(row.arm) + 1} policy",
                f"{row.n} of {len(row.seeds)}",
                mean_pm_std(row.mean, row.std, 2),
                per_seed,
                NOT_IN_STUDY,
                ", ".join(group.budgets),
                "10,000,000 env steps per run",
            ]
        )
    doc.table(
        [
            "algorithm",
            "policy",
            "seeds with data",
            "final-stage return (mean ± std)",
            "per seed",
            "study",
            "budget",
            "study budget",
        ],
        rows,
    )
    doc.p(
        "Final-stage return: the mean episode return over the last 10 % of a run's training "
        "budget (docs/environment.md; the run's `training.final_stage_fraction`), then mean ± sample std "
        f"across seeds. Study values: {NOT_IN_STUDY} = the study does not state them."
    )
    panels = [
        (s, table[table["group"].isin([g.label for g in s.shown])]) for s in ctx.plan.training
    ]
    shown = [g for s in ctx.plan.training for g in s.shown]
    path, rel = ctx.figure("final_returns.png")
    cf.final_returns_figure(panels, ctx.plan.colors, path, ctx.footer(shown))
    doc.img(rel, "Final-stage return per family of controllers")
    doc.p(
        "One panel per family, as the training curves; a controller derived from another's "
        "runs (the same training) is drawn once. " + _hidden_text(ctx.plan.training)
    )


def validation_section(doc: Doc, ctx: Context) -> None:
    """Per validated policy: the checkpoint its validation kept, against the last one (only
    when some run has ``tables/validation.parquet``)."""
    scores = [
        (g, r, int(k), part)
        for g in ctx.groups
        for r in g.runs
        for k, part in validation_scores(r).groupby("policy", sort=True)
    ]
    if not scores:
        return
    summary = validation_summary(scores)
    doc.h(2, "Model selection (validation during training)")
    rows = []
    for row in summary.itertuples():
        rows.append(
            [
                row.group,
                str(row.seed),
                "both arms" if row.policy < 0 else f"arm {row.policy + 1} policy",
                str(row.checkpoints),
                f"{row.best_step:,}",
                f"{row.best_score:.4f}",
                f"{row.last_step:,}",
                f"{row.last_score:.4f}",
                "–"
                if np.isnan(row.confirmed_best)
                else f"{row.confirmed_best:.4f} / {row.confirmed_last:.4f}",
                row.kept,
            ]
        )
    doc.table(
        [
            "controller",
            "seed",
            "policy",
            "validated checkpoints",
            "best checkpoint (env steps)",
            "its validation 3-D RMSE (m)",
            "last checkpoint (env steps)",
            "its validation 3-D RMSE (m)",
            "confirmation 3-D RMSE best / last (m)",
            "run's policy",
        ],
        rows,
    )
    doc.p(
        "Each periodic checkpoint's deterministic policy on held-out episodes of the random "
        f"training target (`training.validation_episodes`; episode k from seed "
        f"{VALIDATION_SEED:,} + k, which neither training nor `evaluate --random` uses); its "
        "score is the mean 3-D RMSE over the episodes and arms (an independent run validates "
        "each arm's policy in its own single-arm scene). \"run's policy\": the model every "
        "evaluation in this report uses, `best` where `training.final_policy: best_validated` "
        "makes it the best checkpoint, `last` where the final model is used. "
        '"confirmation": with `training.confirm_episodes`, after training the best and the '
        "last model each ran that many more held-out episodes (episode k from seed "
        f'{CONFIRM_SEED:,} + k), and the lower score decided the run\'s policy; "–": no '
        "confirmation."
    )
    panels = [
        (
            selection,
            {
                (g.label, r.seed, k): part
                for g, r, k, part in scores
                if g.label in {s.label for s in selection.shown}
            },
        )
        for selection in ctx.plan.validation
    ]
    shown = [g for s in ctx.plan.validation for g in s.shown]
    path, rel = ctx.figure("validation.png")
    cf.validation_figure(panels, ctx.plan.colors, path, ctx.footer(shown))
    doc.img(rel, "Validation 3-D RMSE against environment steps")
