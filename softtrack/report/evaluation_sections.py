"""Report sections on the evaluation episodes: tracking error (study Table 4), policy actions,
trajectories and errors over time (study Figs. 4–9) and actuation moments (study Fig. 10).

Each section appends its headings, tables and figures to a
:class:`~softtrack.report.document.Doc`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from softtrack.evaluation import RANDOM_TARGET_SEED
from softtrack.report import comparison_figures as cf
from softtrack.report import figures as fg
from softtrack.report.actions import ACTIONS_HEADER, actions_caption, actions_rows
from softtrack.report.data import DIRECTIONS, Group, RunData, episode_rmse, representative_run
from softtrack.report.document import NOT_IN_STUDY, Context, Doc, num_text, study_text
from softtrack.report.families import MAX_SERIES
from softtrack.report.featured import Featured
from softtrack.report.group_summaries import (
    controller_differences,
    moment_peaks,
    random_target_summary,
    summary_row,
)
from softtrack.report.plan import PER_KIND
from softtrack.report.reference import (
    STUDY_PEAK_MOMENTS,
    STUDY_RMSE_3D,
    STUDY_TOTAL_TIMESTEPS,
    TRAJECTORY_TITLES,
    study_peak_moment,
    study_rmse_3d,
)
from softtrack.report.text import mean_pm_std

__all__ = [
    "actions_section",
    "errors_section",
    "moments_section",
    "random_targets_section",
    "trajectories_section",
]


def _cell(row: pd.Series, metric: str) -> str:
    """``mean ± std`` of ``metric`` in a :func:`metrics_summary` row (m, 4 decimals)."""
    return mean_pm_std(row.get(f"{metric}_mean"), row.get(f"{metric}_std"), 4)


def _metric_rows(
    summary: pd.DataFrame, group: Group, trajectories: Sequence[str]
) -> list[list[str]]:
    rows = []
    for trajectory in trajectories:
        for arm in (0, 1):
            r = summary_row(summary, group.label, trajectory, arm)
            study = study_text(study_rmse_3d(group.algo, group.controller, trajectory, arm), 3)
            name = TRAJECTORY_TITLES.get(trajectory, trajectory)
            if r is None:
                rows.append([name, f"arm {arm + 1}"] + ["no data"] * 8 + [study, "no data", "0"])
                continue
            rows.append(
                [name, f"arm {arm + 1}"]
                + [
                    _cell(r, c)
                    for c in (
                        "rmse_x",
                        "rmse_y",
                        "rmse_z",
                        "mae_x",
                        "mae_y",
                        "mae_z",
                        "mean_spatial_error",
                        "rmse_3d",
                    )
                ]
                + [study, _cell(r, "rmse_3d_steady"), str(r["n"])]
            )
    return rows


def errors_section(
    doc: Doc, ctx: Context, summary: pd.DataFrame, trajectories: Sequence[str]
) -> None:
    """Per-axis and 3-D tracking errors per group against the study, and the 3-D RMSE of all
    groups side by side (``summary``: :func:`~softtrack.report.group_summaries.metrics_summary`)."""
    doc.h(2, "Tracking error (study Table 4)")
    header = [
        "trajectory",
        "arm",
        "RMSE x (m)",
        "RMSE y (m)",
        "RMSE z (m)",
        "MAE x (m)",
        "MAE y (m)",
        "MAE z (m)",
        "mean spatial error (m)",
        "3-D RMSE (m)",
        "study 3-D RMSE (m)",
        "3-D RMSE, t ≥ 1 s (m)",
        "seeds",
    ]
    for group in ctx.groups:
        doc.h(3, f"{group.label}")
        doc.table(header, _metric_rows(summary, group, trajectories))
        doc.p(
            "Mean ± sample std across seeds of one deterministic evaluation episode per "
            "trajectory (docs/environment.md). The study gives its 3-D RMSE only (centralized TD3 "
            f"and the independent TD3 baseline); {NOT_IN_STUDY}: no study value."
        )
    doc.h(3, "Centralized against independent controllers")
    cells = [(t, arm) for t in trajectories for arm in (0, 1)]
    header = ["controller", "seeds"] + [f"{_cell_title(t, arm)} (m)" for t, arm in cells]
    rows = []
    for group in ctx.groups:
        found = [summary_row(summary, group.label, t, arm) for t, arm in cells]
        seeds = max((int(r["n"]) for r in found if r is not None), default=0)
        rows.append(
            [group.label, str(seeds)]
            + [
                "no data" if r is None else mean_pm_std(r["rmse_3d_mean"], r["rmse_3d_std"], 4)
                for r in found
            ]
        )
    for controller in ("centralized", "independent"):
        rows.append(
            [f"study {controller} TD3", "—"]
            + [study_text(study_rmse_3d("td3", controller, t, arm), 3) for t, arm in cells]
        )
    doc.table(header, rows)
    doc.p(
        "3-D RMSE, mean ± sample std across seeds of one deterministic evaluation episode "
        "per trajectory."
    )
    _differences_tables(doc, ctx, controller_differences(summary, ctx.groups), cells)
    study = {
        f"study {controller} TD3": {(t, a): v[a] for t, v in values.items() for a in (0, 1)}
        for controller, values in STUDY_RMSE_3D.items()
    }
    shown = [g for s in ctx.plan.headline for g in s.shown]
    path, rel = ctx.figure("rmse_comparison.png")
    cf.rmse_comparison_figure(
        ctx.plan.headline, summary, ctx.plan.colors, study, trajectories, path, ctx.footer(shown)
    )
    doc.img(rel, "3-D RMSE per trajectory and arm against the study, one panel per task")
    doc.p(
        "One panel per task (a controller trained and evaluated with contact is never drawn "
        "beside one without). Each panel draws one controller of each kind (the study "
        "protocol at the study's budget, the best centralized variant, the best independent "
        "controller, the best planner) and then the next best by mean 3-D RMSE over the cells, "
        f"at most {PER_KIND} of a kind and {MAX_SERIES} in all; every controller is in the "
        "tables above. Study markers: the study's values (without contact)."
    )


def _cell_title(trajectory: str, arm: int) -> str:
    """``figure-eight arm 2`` (``arm`` 0-indexed)."""
    return f"{TRAJECTORY_TITLES.get(trajectory, trajectory)} arm {arm + 1}"


def _difference_text(row: pd.Series) -> str:
    """``+0.0053 ± 0.0039 (p 0.27)``: a :func:`controller_differences` row (m)."""
    text = f"{row['difference']:+.4f}"
    if np.isfinite(row["se"]):
        text += f" ± {row['se']:.4f}"
    if np.isfinite(row["p_value"]):
        text += f" (p {row['p_value']:.2f})"
    return text


def _differences_tables(
    doc: Doc, ctx: Context, differences: pd.DataFrame, cells: Sequence[tuple[str, int]]
) -> None:
    """One table per independent group: each centralized group's 3-D RMSE minus its own."""
    for reference, part in differences.groupby("reference", sort=False):
        doc.p(
            f"**Centralized minus {reference}** (m; negative: the centralized controller "
            "tracks better):"
        )
        header = ["controller", "seeds"] + [_cell_title(t, arm) for t, arm in cells]
        rows = []
        for group, rows_of_group in part.groupby("group", sort=False):
            by_cell = {(r["trajectory"], int(r["arm"])): r for _, r in rows_of_group.iterrows()}
            rows.append(
                [str(group), str(rows_of_group["n"].max())]
                + [_difference_text(by_cell[c]) if c in by_cell else "no data" for c in cells]
            )
        doc.table(header, rows)
        n_reference = int(part["n_reference"].max())
        doc.p(
            f"Difference of the seed means; ± its standard error; p: Welch's two-sided t-test "
            f"over the seeds' values ({reference}: {n_reference} seed"
            f"{'' if n_reference == 1 else 's'}). Both only where both controllers have at "
            "least 2 seeds. Across this many cells a few p below 0.05 are expected by chance."
        )


def random_targets_section(doc: Doc, ctx: Context) -> None:
    """3-D RMSE per group and arm on held-out episodes of the random training target (only
    when some run has ``eval_random``)."""
    summary = random_target_summary(ctx.groups)
    if summary.empty:
        return
    doc.h(3, "Random training targets (held-out episodes)")
    rows = []
    evaluated = []
    for group in ctx.groups:
        cells = summary[summary["group"] == group.label].set_index("arm")
        if cells.empty:
            continue
        evaluated.append(group)
        row = [group.label, str(int(cells["n"].max())), str(int(cells["episodes"].min()))]
        for arm in (0, 1):
            if arm in cells.index:
                c = cells.loc[arm]
                row.append(mean_pm_std(c["rmse_3d_mean"], c["rmse_3d_std"], 4))
            else:
                row.append("no data")
        row.append(str(int(cells["terminated"].max())))  # an episode ends for both arms
        rows.append(row)
    header = [
        "controller",
        "seeds",
        "episodes per seed",
        "3-D RMSE arm 1 (m)",
        "3-D RMSE arm 2 (m)",
        "diverged episodes",
    ]
    doc.table(header, rows)
    missing = [g.label for g in ctx.groups if g not in evaluated]
    doc.p(
        "Each seed's deterministic policy on episodes of the random target it was trained on "
        f"(`softtrack evaluate RUN --random N`): episode k from seed {RANDOM_TARGET_SEED:,} + k, which "
        "training never uses, so runs with the same target settings meet the same paths. "
        "A seed's value is its mean over the episodes; mean ± sample std across seeds. The "
        "study reports no such figure."
        + (f" Not evaluated this way: {', '.join(missing)}." if missing else "")
    )


def actions_section(
    doc: Doc, ctx: Context, summary: pd.DataFrame, trajectories: Sequence[str]
) -> None:
    """Statistics of the policies' actions during the evaluation episodes."""
    doc.h(3, "Policy actions")
    doc.table(ACTIONS_HEADER, actions_rows(summary, ctx.groups, trajectories))
    doc.p(actions_caption(summary, ctx.groups))


def _run_caption(group: Group, run: RunData, trajectory: str) -> str:
    n = sum(1 for r in group.runs if np.isfinite(episode_rmse(r, trajectory)))
    seeds = "1 seed" if n == 1 else f"{n} seeds"
    return f"seed {run.seed}, run {run.run_id} (median 3-D RMSE of {seeds})"


def _path_row(featured: Featured, trajectory: str) -> tuple[fg.PathRow, RunData | None]:
    """The figure row of a controller's median-RMSE run on ``trajectory``, and that run."""
    group = featured.group
    run = representative_run(group, trajectory)
    if run is None or run.trajectories is None:
        return fg.PathRow(featured.title, None), run
    traj = run.trajectories[run.trajectories["trajectory"] == trajectory]
    rmse: dict[int, float] = {}
    if run.metrics is not None:
        m = run.metrics[run.metrics["trajectory"] == trajectory]
        rmse = {int(a): float(v) for a, v in zip(m["arm"], m["rmse_3d"], strict=True)}
    return fg.PathRow(featured.title, traj, _run_caption(group, run, trajectory), rmse), run


def _rmse_line(featured: Featured, row: fg.PathRow, run: RunData | None, trajectory: str) -> str:
    """``TD3 …: seed 0, run … 3-D RMSE arm 1 / arm 2: 0.0544 / 0.0512 m (study: …)``."""
    group = featured.group
    if run is None:
        return (
            f"No data for {group.label} on the {trajectory}: no run has a stored "
            "evaluation trajectory (run `softtrack evaluate` on its runs)."
        )
    study = [
        study_text(study_rmse_3d(group.algo, group.controller, trajectory, a), 3) for a in (0, 1)
    ]
    measured = [num_text(row.rmse.get(a), 4) for a in (0, 1)]
    return (
        f"{featured.title}, {row.caption}: 3-D RMSE arm 1 / arm 2: {measured[0]} / "
        f"{measured[1]} m (study: {study[0]} / {study[1]} m)."
    )


def _shown_text(ctx: Context, featured: Sequence[Featured]) -> str:
    """Which controllers the figures show, and where the others are."""
    if ctx.all_figures or len(featured) == len(ctx.groups):
        return "Every controller of this report is drawn."
    others = len(ctx.groups) - len(featured)
    if any(f.role == "chosen" for f in featured):
        return (
            f"Drawn: {', '.join(f.group.label for f in featured)} (chosen with "
            f"`--figures-for`). The other {others} "
            f"controller{'s are' if others != 1 else ' is'} in the Tracking error tables."
        )
    return (
        f"Drawn: {', '.join(f.title for f in featured)}; chosen as the study protocol "
        f"(centralized TD3, {STUDY_TOTAL_TIMESTEPS:,} env steps per run) and the centralized "
        "and the independent controller with the lowest mean 3-D RMSE over the trajectories "
        f"and arms (Tracking error tables). The other {others} "
        f"controller{'s are' if others != 1 else ' is'} in those tables; "
        "`softtrack report … --all-figures` draws every controller."
    )


def trajectories_section(
    doc: Doc, ctx: Context, trajectories: Sequence[str], featured: Sequence[Featured]
) -> None:
    """3-D paths and errors over time of each drawn controller's median-RMSE seed per
    trajectory: one figure per trajectory with a row per controller (``ctx.all_figures``:
    one figure per controller and trajectory)."""
    doc.h(2, "Trajectories and errors over time (study Figs. 4–9)")
    doc.p(
        "For each trajectory and controller, the seed with the median 3-D RMSE: the 3-D paths "
        "of the target and both tips, then the per-axis error tip − target of each arm and "
        "both arms' spatial error against time. " + _shown_text(ctx, featured)
    )
    for trajectory in trajectories:
        doc.h(3, TRAJECTORY_TITLES.get(trajectory, trajectory))
        rows = [_path_row(f, trajectory) for f in featured]
        if ctx.all_figures:
            batches = [([f], [r], f.group.slug + "_") for f, r in zip(featured, rows, strict=True)]
        else:
            batches = [(list(featured), rows, "")]
        for members, batch, prefix in batches:
            footer = ctx.footer([f.group for f in members])
            names = ", ".join(f.group.label for f in members)
            path, rel = ctx.figure(f"trajectory_{prefix}{trajectory}.png")
            fg.trajectory_3d_figure([row for row, _ in batch], trajectory, path, footer=footer)
            doc.img(rel, f"{trajectory}: 3-D target and tip paths, {names}")
            path, rel = ctx.figure(f"errors_{prefix}{trajectory}.png")
            fg.tracking_errors_figure([row for row, _ in batch], trajectory, path, footer=footer)
            doc.img(rel, f"{trajectory}: tracking error against time, {names}")
            doc.p(
                " ".join(
                    _rmse_line(f, row, run, trajectory)
                    for f, (row, run) in zip(members, batch, strict=True)
                )
            )


def moments_section(
    doc: Doc, ctx: Context, trajectories: Sequence[str], featured: Sequence[Featured]
) -> None:
    """Actuation moment histories of the drawn controllers, and the peak element moments of
    every controller against the study."""
    doc.h(2, "Actuation moments (study Fig. 10)")
    if not (ctx.all_figures or len(featured) == len(ctx.groups)):
        doc.p(
            f"Moment histories of {', '.join(f.title for f in featured)}; the peaks of "
            "every controller are in the table below."
        )
    for item in featured:
        group = item.group
        moments: dict[str, pd.DataFrame | None] = {}
        peaks: dict[str, pd.DataFrame | None] = {}
        subtitles: dict[str, str] = {}
        for trajectory in trajectories:
            run = representative_run(group, trajectory)
            candidates = [run] if run is not None else list(group.runs)
            df = None
            for r in candidates:
                if r.moments is not None and (r.moments["trajectory"] == trajectory).any():
                    df = r.moments[r.moments["trajectory"] == trajectory]
                    if r.peaks is not None:
                        peaks[trajectory] = r.peaks[r.peaks["trajectory"] == trajectory]
                    subtitles[trajectory] = f"seed {r.seed}"
                    break
            moments[trajectory] = df
        path, rel = ctx.figure(f"moments_{group.slug}.png")
        fg.moments_figure(
            moments,
            path,
            title=f"Actuation moments, {item.title}",
            subtitles=subtitles,
            peaks=peaks,
            footer=ctx.footer([group]),
        )
        doc.img(rel, f"Spatial-RMS moment histories, {group.label}")
        if not any(df is not None for df in moments.values()):
            doc.p(f"No data for {group.label}: no stored evaluation moments.")
    peak_table = moment_peaks(ctx.groups)
    rows = []
    for group in ctx.groups:
        part = (
            peak_table[peak_table["group"] == group.label] if not peak_table.empty else peak_table
        )
        for trajectory in trajectories:
            for direction in DIRECTIONS:
                cells = []
                for arm in (0, 1, -1):
                    sel = (
                        part[
                            (part["trajectory"] == trajectory)
                            & (part["direction"] == direction)
                            & (part["arm"] == arm)
                        ]
                        if not part.empty
                        else part
                    )
                    peak = sel.iloc[0] if not sel.empty else None
                    cells.append(
                        "no data" if peak is None else mean_pm_std(peak["mean"], peak["std"], 1)
                    )
                study = study_peak_moment(group.algo, group.controller, trajectory, direction)
                rows.append(
                    [
                        group.label,
                        TRAJECTORY_TITLES.get(trajectory, trajectory),
                        direction,
                        *cells,
                        study_text(study, 1),
                    ]
                )
    doc.h(3, "Peak element moments")
    doc.table(
        [
            "controller",
            "trajectory",
            "direction",
            "arm 1 peak (N·m)",
            "arm 2 peak (N·m)",
            "both arms peak (N·m)",
            "study, both arms (N·m)",
        ],
        rows,
    )
    doc.p(
        "Peak: the largest absolute element torque over the evaluation episode, mean ± sample "
        "std across seeds. The study reports peaks during the figure-eight only (centralized "
        f"TD3: {STUDY_PEAK_MOMENTS['normal']} N·m normal, {STUDY_PEAK_MOMENTS['binormal']} N·m "
        f"binormal); {NOT_IN_STUDY}: no study value."
    )
