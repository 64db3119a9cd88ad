"""The report's transport section: how well the arms carry the sphere, whether they drop it,
how they hold it (docs/environment.md, "Transport").

Only for controllers whose evaluations recorded the sphere (``eval_metrics`` column
``object_rmse_3d``). A table per controller and trajectory (the sphere's 3-D RMSE against its
goal, its carry score, drops, the time both arms held it, each arm's mean squeeze), a table
of the held-out random targets per controller (episodes carried to the end, the carry score
with its interval), a figure of holding against carrying (one point per run:
:mod:`softtrack.report.transport_frontier`) and a figure per controller (rows) and trajectory
(columns): the sphere's path and its goal's from the front and from above, with the arms and
the sphere drawn at the instants ``eval_snapshots`` kept.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.patches import Circle

from softtrack.env.targets import EVAL_TRAJECTORIES
from softtrack.evaluation.scores import CARRY_SCORE, with_carry_score
from softtrack.report import figures as fg
from softtrack.report.compare import compare_controllers, controller_scores, scored_rows
from softtrack.report.contact_section import draw_arm
from softtrack.report.data import Group, RunData
from softtrack.report.document import Context, Doc
from softtrack.report.families import MAX_SERIES
from softtrack.report.text import mean_pm_std
from softtrack.report.transport_frontier import (
    frontier_figure,
    hold_track_frontier,
    longest_holding,
)

__all__ = [
    "figure_runs",
    "random_summary",
    "transport_figure",
    "transport_section",
    "transport_summary",
]

_MAX_FIGURE_GROUPS = 4  # controllers drawn in the figure (the rest: the table)
_STUDY_WORST = 0.065  # m, the study's worst single-arm 3-D RMSE: the carrying target
_VIEW = ((-0.7, 0.7), (-0.1, 1.1), (-0.7, 0.7))  # x, y, z limits of the panels, m: the arms' reach


def _ordered(names: set[str]) -> list[str]:
    """Trajectory names in the study's order, others after them by name."""
    known = [t for t in EVAL_TRAJECTORIES if t in names]
    return known + sorted(names - set(known))


def _carried(run: RunData) -> bool:
    return run.metrics is not None and "object_rmse_3d" in run.metrics


def transport_summary(groups: Sequence[Group]) -> pd.DataFrame:
    """One row per group with transport evaluations and trajectory: ``object_rmse`` (m),
    ``carry_score`` (m, every step after a drop at 1 m; NaN without the planned episode
    length), ``two_arm_contact`` (fraction of steps), ``force`` (N, mean over both arms) as
    ``<name>_mean``/``<name>_std`` across seeds, ``drops`` (seeds that dropped the sphere) and
    ``n`` (seeds)."""
    rows = []
    for group in groups:
        runs = [r for r in group.runs if _carried(r)]
        for trajectory in _ordered({str(t) for r in runs for t in r.metrics["trajectory"]}):  # type: ignore[index]
            per_seed: dict[str, list[float]] = {
                "object_rmse": [],
                "carry_score": [],
                "two_arm_contact": [],
                "force": [],
            }
            drops = 0
            for run in runs:
                assert run.metrics is not None
                part = run.metrics[run.metrics["trajectory"] == trajectory]
                if part.empty:
                    continue
                per_seed["object_rmse"].append(float(part["object_rmse_3d"].iloc[0]))
                per_seed["carry_score"].append(_carry_score(run, part))
                per_seed["two_arm_contact"].append(float(part["two_arm_contact"].iloc[0]))
                per_seed["force"].append(float(part["object_force_mean"].mean()))
                drops += int(bool(part["dropped"].iloc[0]))
            row: dict[str, object] = {
                "group": group.label,
                "trajectory": trajectory,
                "n": len(per_seed["object_rmse"]),
                "drops": drops,
            }
            for name, values in per_seed.items():
                row[f"{name}_mean"] = float(np.mean(values))
                row[f"{name}_std"] = (
                    float(np.std(values, ddof=1)) if len(values) > 1 else float("nan")
                )
            rows.append(row)
    return pd.DataFrame(rows)


def _carry_score(run: RunData, rows: pd.DataFrame) -> float:
    """The :data:`~softtrack.evaluation.episode_tables.CARRY_SCORE` of the first of ``rows`` (one
    episode's rows of ``run``), m; NaN without the run's planned episode length."""
    scored = with_carry_score(rows, run.eval_duration)
    return float(scored[CARRY_SCORE].iloc[0]) if CARRY_SCORE in scored else float("nan")


def random_summary(groups: Sequence[Group], reps: int = 2000) -> pd.DataFrame:
    """One row per group with transport episodes on the held-out random targets
    (``eval_random``): ``n`` (seeds), ``episodes``, ``carried`` (episodes held to their end),
    ``median_hold`` (s, a held episode counting its full length), and the interquartile mean
    of the carry score over (seed, episode) with its 95 % stratified bootstrap interval
    (``score``, ``score_low``, ``score_high``, m)."""
    rows = []
    for group in groups:
        tables = [
            (run.seed, scored[scored["arm"] == 0], float(run.eval_duration))
            for run in group.runs
            if run.eval_duration is not None
            if (scored := scored_rows(run, random=True)) is not None and CARRY_SCORE in scored
        ]
        if not tables:
            continue
        episodes = pd.concat([t for _, t, _ in tables])
        held = np.concatenate(
            [
                np.where(
                    t["dropped"].fillna(False).astype(bool),
                    t["drop_time"].to_numpy(dtype=float),
                    planned,
                )
                for _, t, planned in tables
            ]
        )
        cells = sorted({str(t) for t in episodes["trajectory"]}, key=lambda t: int(t.split()[-1]))
        scores = controller_scores(
            group.label, [(seed, t) for seed, t, _ in tables], CARRY_SCORE, cells, "eval_random"
        )
        interval = compare_controllers([scores], CARRY_SCORE, reps=reps, cells=False).overall[
            group.label
        ]
        rows.append(
            {
                "group": group.label,
                "n": len(tables),
                "episodes": len(episodes),
                "carried": int((~episodes["dropped"].fillna(False).astype(bool)).sum()),
                "median_hold": float(np.median(held)),
                "score": interval.value,
                "score_low": interval.low,
                "score_high": interval.high,
            }
        )
    return pd.DataFrame(rows)


def transport_section(doc: Doc, ctx: Context) -> None:
    """The table and the figure (module docstring); nothing when no run carried a sphere."""
    summary = transport_summary(ctx.groups)
    if summary.empty:
        return
    doc.h(3, "Cooperative transport")
    doc.table(
        [
            "controller",
            "trajectory",
            "seeds",
            "sphere 3-D RMSE (m)",
            "carry score (m)",
            "seeds that dropped it",
            "held by both arms",
            "mean squeeze per arm (N)",
        ],
        [
            [
                str(r["group"]),
                fg.trajectory_title(str(r["trajectory"])),
                str(int(r["n"])),
                mean_pm_std(r["object_rmse_mean"], r["object_rmse_std"], 4),
                mean_pm_std(r["carry_score_mean"], r["carry_score_std"], 4),
                f"{int(r['drops'])} of {int(r['n'])}",
                f"{100 * r['two_arm_contact_mean']:.0f} %",
                f"{r['force_mean']:.1f}",
            ]
            for _, r in summary.iterrows()
        ],
    )
    doc.p(
        "The sphere's centre against its goal over the whole episode (the approach from the "
        "sphere's start to the path's start included), mean ± sample std across seeds; a seed "
        "that drops the sphere ends its episode there (its error is over the steps it ran). "
        "Carry score: the sphere's 3-D RMSE over the whole planned episode with every step "
        "after a drop counted at 1 m, so that dropping it early never scores better "
        "(`softtrack compare --metric object_carry_score`). "
        "Held by both arms: the share of control steps on which both touched it. "
        f"Target: carried along all three trajectories without a drop at ≤ {_STUDY_WORST} m "
        '(the study\'s worst single-arm 3-D RMSE). docs/environment.md, "Transport".'
    )
    _random_table(doc, ctx)
    _frontier(doc, ctx)
    drawn_runs = figure_runs(ctx.groups, _MAX_FIGURE_GROUPS)
    if not drawn_runs:
        return
    drawn = [g for g, _ in drawn_runs]
    runs = [(g.label, run) for g, run in drawn_runs]
    path, rel = ctx.figure("transport.png")
    transport_figure(runs, path, ctx.footer(drawn))
    doc.img(rel, "the arms carrying the sphere along each trajectory")


def figure_runs(groups: Sequence[Group], limit: int) -> list[tuple[Group, RunData]]:
    """The transport figure's controllers, in the groups' order, at most ``limit``: each
    group's first run that carried a sphere and kept its per-step positions
    (``eval_trajectories``; the shipped runs of most experiments drop them), groups without
    one left out so that they take no place in the figure."""
    drawn = []
    for group in groups:
        run = next((r for r in group.runs if _carried(r) and r.trajectories is not None), None)
        if run is not None:
            drawn.append((group, run))
    return drawn[:limit]


def _random_table(doc: Doc, ctx: Context) -> None:
    """The held-out random targets' table (:func:`random_summary`), if any run has them."""
    summary = random_summary(ctx.groups)
    if summary.empty:
        return
    doc.table(
        [
            "controller",
            "seeds",
            "episodes carried to the end",
            "median time held (s)",
            "carry score (m): IQM [95 % CI]",
        ],
        [
            [
                str(r["group"]),
                str(int(r["n"])),
                f"{int(r['carried'])} of {int(r['episodes'])}",
                f"{r['median_hold']:.1f}",
                f"{r['score']:.3f} [{r['score_low']:.3f}, {r['score_high']:.3f}]",
            ]
            for _, r in summary.iterrows()
        ],
    )
    doc.p(
        "The held-out random targets (`softtrack evaluate RUN --random 20`: the same targets "
        "for every run): episodes that kept the sphere to their end, the median time it was "
        "held, and the interquartile mean of the carry score over every seed and episode with "
        "its stratified bootstrap interval (episodes as cells). `softtrack compare A B --random "
        "--metric object_carry_score` compares two controllers on them."
    )


def _frontier(doc: Doc, ctx: Context) -> None:
    """The holding-against-carrying figure (:mod:`softtrack.report.transport_frontier`)."""
    frontier = hold_track_frontier(ctx.groups)
    if frontier.empty:
        return
    shown = longest_holding(frontier, MAX_SERIES)
    drawn = [g for g in ctx.groups if g.label in set(shown["group"])]
    path, rel = ctx.figure("transport_frontier.png")
    frontier_figure(shown, path, _STUDY_WORST, ctx.footer(drawn))
    doc.img(rel, "holding the sphere against carrying it, one point per run")
    left_out = frontier["group"].nunique() - len(drawn)
    doc.p(
        (
            f"The {len(drawn)} controllers that hold the sphere longest ({left_out} left out). "
            if left_out
            else ""
        )
        + "One point per run: how much of its episodes it kept the sphere (x) and how far the "
        "sphere was from its goal while held (y, the median over the episodes). A lazy grasp "
        "holds long and lags the goal; a grasp that moves the sphere loses it sooner. The "
        f"green corner is the target: held to the end at ≤ {_STUDY_WORST} m."
    )


def _ending(run: RunData, trajectory: str) -> str:
    """``, dropped at 3.21 s`` when the run's episode on ``trajectory`` dropped the sphere."""
    metrics = run.metrics
    if metrics is None or "dropped" not in metrics:
        return ""
    rows = metrics[metrics["trajectory"] == trajectory]
    if len(rows) and bool(rows["dropped"].iloc[0]):
        return f", dropped at {float(rows['drop_time'].iloc[0]):.2f} s"
    return ""


def transport_figure(
    runs: Sequence[tuple[str, RunData]],
    path: str | os.PathLike[str],
    footer: str | None = None,
    radius: float = 0.05,
) -> Path:
    """Per controller (two rows: front x–y, above x–z) and trajectory (columns): the sphere's
    path (solid) and its goal's (dashed); the arms (tubes of ``radius``) and the sphere
    (circle) at the kept instants, lighter for earlier ones."""
    trajectories = _ordered(
        {
            str(t)
            for _, run in runs
            if run.trajectories is not None
            for t in run.trajectories["trajectory"]
        }
    )
    fig = fg.new_figure(3.4 * max(1, len(trajectories)), 1.0 + 6.4 * len(runs))
    grid = fig.subfigures(len(runs), 1, squeeze=False)
    for (label, run), sub in zip(runs, grid[:, 0], strict=True):
        sub.suptitle(label, fontsize=10)
        axes = sub.subplots(2, max(1, len(trajectories)), squeeze=False)
        table = run.trajectories
        assert table is not None
        for col, trajectory in enumerate(trajectories):
            rows = table[(table["trajectory"] == trajectory) & (table["arm"] == 0)]
            snaps = run.snapshots
            snaps = (
                snaps[snaps["trajectory"] == trajectory] if snaps is not None else pd.DataFrame()
            )
            for row, (a, b) in enumerate(((0, 1), (0, 2))):
                ax = axes[row, col]
                names = "xyz"
                if "object_x" in rows and len(rows):
                    sphere = rows[["object_x", "object_y", "object_z"]].to_numpy()
                    goal = rows[["target_x", "target_y", "target_z"]].to_numpy()
                    ax.plot(goal[:, a], goal[:, b], "--", color="0.4", lw=1, label="goal")
                    ax.plot(sphere[:, a], sphere[:, b], color="tab:green", lw=1.2, label="sphere")
                    steps = sorted(snaps["step"].unique()) if len(snaps) else []
                    for k, step in enumerate(steps):
                        shade = 0.35 + 0.65 * (k + 1) / len(steps)
                        part = snaps[snaps["step"] == step]
                        for arm, color in zip((0, 1), fg.ARM_COLORS, strict=True):
                            nodes = part[part["arm"] == arm].sort_values("node")
                            coords = nodes[["x", "y", "z"]].to_numpy()
                            draw_arm(ax, coords[:, a], coords[:, b], radius, color, shade)
                        hit = rows[rows["step"] == step]
                        if len(hit):
                            centre = hit[["object_x", "object_y", "object_z"]].to_numpy()[0]
                            ax.add_patch(
                                Circle(
                                    (centre[a], centre[b]),
                                    radius,
                                    color="tab:green",
                                    alpha=0.5 * shade,
                                )
                            )
                ax.set_xlim(*_VIEW[a])
                ax.set_ylim(*_VIEW[b])
                ax.set_aspect("equal")
                ax.set_xlabel(f"{names[a]} (m)", fontsize=8)
                ax.set_ylabel(f"{names[b]} (m)", fontsize=8)
                ax.tick_params(labelsize=7)
                if row == 0:
                    ax.set_title(
                        fg.trajectory_title(trajectory) + _ending(run, trajectory), fontsize=9
                    )
                if row == 0 and col == 0:
                    ax.legend(fontsize=7, loc="lower left")
    fg.suptitle(
        fig,
        "Two arms carrying the sphere",
        12,
        "top: front view (x–y), bottom: from above (x–z); the sphere's path (green) and its "
        "goal's (dashed); the arms and the sphere at the kept instants, darker later",
    )
    return fg.save_figure(fig, path, footer)
