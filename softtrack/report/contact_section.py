"""The report's contact section: do the arms touch, how deep, how hard, and what it costs.

Only for controllers whose evaluations recorded contact (``eval_metrics`` columns
``contact_steps`` …, written since contact exists). A table per controller (task, contact on or
off, the quadratic mean of the two arms' 3-D RMSE against the shared-target floor, contact
steps, deepest overlap, contact force); centralized against independent controllers with
contact, per cell, with Welch's interval; for the first few controllers with contact on, a
figure of clearance and contact force against time and a figure that draws both arms with
their radius at the instants ``eval_snapshots`` kept, so a reader sees whether their surfaces
overlap.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.patches import Circle

from softtrack.evaluation.statistics import mean_difference
from softtrack.report import figures as fg
from softtrack.report.data import Group, RunData, representative_run
from softtrack.report.document import Context, Doc
from softtrack.report.text import mean_pm_std

__all__ = [
    "arms_figure",
    "centralized_vs_independent",
    "contact_section",
    "contact_summary",
    "contact_timeline_figure",
    "draw_arm",
]

_MAX_FIGURE_GROUPS = 4  # controllers drawn in the contact figures (the rest: the table)


_TASK_ORDER = {"shared": 0, "viewpoints": 1, "transport": 2}


def _spec_value(run: RunData, section: str, key: str, default: object) -> object:
    spec = run.record.raw_spec()
    value = spec.get("env", {}).get(section, {}) if isinstance(spec, dict) else {}
    return value.get(key, default) if isinstance(value, dict) else default


def _task(run: RunData) -> str:
    return str(_spec_value(run, "task", "name", "shared"))


def _contact_on(run: RunData) -> bool:
    value = _spec_value(run, "physics", "contact_k", 0.0)
    return isinstance(value, int | float) and value > 0.0


def _has_contact_columns(run: RunData) -> bool:
    return run.metrics is not None and "contact_steps" in run.metrics


def contact_summary(groups: Sequence[Group], radius: float = 0.05) -> pd.DataFrame:
    """One row per group whose runs recorded contact.

    A seed's values are over its evaluated trajectories: ``quadratic_mean`` the mean over
    trajectories of sqrt((RMSE₁² + RMSE₂²)/2) (m; ≥ r on the shared target with contact),
    ``contact_share`` the fraction of steps in contact, ``max_penetration`` the deepest overlap
    (m), ``mean_force`` the mean contact force (N). Columns: group, task, contact, n, and
    ``<value>_mean``/``<value>_std`` across seeds, plus ``floor`` (r on the shared task, NaN
    on viewpoints).
    """
    rows = []
    for group in groups:
        runs = [r for r in group.runs if _has_contact_columns(r)]
        if not runs:
            continue
        values: dict[str, list[float]] = {
            "quadratic_mean": [],
            "contact_share": [],
            "max_penetration": [],
            "mean_force": [],
        }
        for run in runs:
            metrics = run.metrics
            assert metrics is not None
            per_traj = metrics.groupby("trajectory")
            rmse = per_traj["rmse_3d"].apply(lambda s: math.sqrt(float((s**2).mean())))
            steps = per_traj["duration"].first() / 0.002
            values["quadratic_mean"].append(float(rmse.mean()))
            values["contact_share"].append(
                float((per_traj["contact_steps"].first() / steps).mean())
            )
            values["max_penetration"].append(float(per_traj["max_penetration"].first().max()))
            values["mean_force"].append(float(per_traj["mean_contact_force"].first().mean()))
        task = _task(runs[0])
        row: dict[str, object] = {
            "group": group.label,
            "task": task,
            "contact": "on" if _contact_on(runs[0]) else "off",
            "n": len(runs),
            "floor": radius if task == "shared" else float("nan"),
        }
        for name, seeds in values.items():
            row[f"{name}_mean"] = float(np.mean(seeds))
            row[f"{name}_std"] = float(np.std(seeds, ddof=1)) if len(seeds) > 1 else float("nan")
        rows.append(row)
    return pd.DataFrame(rows)


def contact_section(doc: Doc, ctx: Context) -> None:
    """The table and the two figures (module docstring); nothing when no run recorded contact."""
    summary = contact_summary(ctx.groups)
    if summary.empty:
        return
    doc.h(3, "Contact between the arms")
    rows = []
    for _, r in summary.iterrows():
        rows.append(
            [
                str(r["group"]),
                str(r["task"]),
                str(r["contact"]),
                str(int(r["n"])),
                mean_pm_std(r["quadratic_mean_mean"], r["quadratic_mean_std"], 4),
                "–" if not np.isfinite(r["floor"]) else f"{r['floor']:.3f}",
                f"{100 * r['contact_share_mean']:.0f} %",
                f"{1e3 * r['max_penetration_mean']:.1f}",
                f"{r['mean_force_mean']:.1f}",
            ]
        )
    doc.table(
        [
            "controller",
            "task",
            "contact",
            "seeds",
            "quadratic mean of the arms' 3-D RMSE (m)",
            "floor (m)",
            "steps in contact",
            "deepest overlap (mm)",
            "mean contact force (N)",
        ],
        rows,
    )
    doc.p(
        "Per seed, over the evaluated trajectories: the quadratic mean sqrt((RMSE₁² + "
        "RMSE₂²)/2) of the two arms' 3-D RMSE (mean over trajectories), the share of control "
        "steps in contact, the deepest overlap of the arms' surfaces (with contact off the "
        "arms pass through each other and this is how deep), and the mean contact force; "
        "mean ± sample std across seeds. On the shared target two real arms of radius r = "
        "0.05 m cannot both reach the centre: touching tips are ≥ 2r apart, so the quadratic "
        'mean is ≥ r (the floor). docs/physics.md, "Contact between the arms".'
    )
    comparison = centralized_vs_independent(ctx.groups)
    if comparison:
        doc.p(
            "**Centralized against independent, with contact** (per trajectory and arm: the "
            "difference of the seed means of 3-D RMSE, centralized − independent, m, with "
            "Welch's 95 % interval; negative: the centralized controller tracks better):"
        )
        doc.table(
            [
                "task",
                "centralized",
                "independent",
                "seeds",
                "trajectory",
                "arm 1: difference [95 % CI]",
                "arm 2: difference [95 % CI]",
            ],
            comparison,
        )
    touching = set(summary.loc[summary["contact"] == "on", "group"])
    trajectory = "circle"
    # the controllers with a drawable run, the shared target first, then viewpoints, transport
    drawable = [
        (g, run)
        for g in ctx.groups
        if g.label in touching and (run := representative_run(g, trajectory)) is not None
    ]
    drawable.sort(key=lambda item: _TASK_ORDER.get(_task(item[1]), len(_TASK_ORDER)))
    drawn = [g for g, _ in drawable[:_MAX_FIGURE_GROUPS]]
    runs = [(g.label, run) for g, run in drawable[:_MAX_FIGURE_GROUPS]]
    if not runs:
        return
    path, rel = ctx.figure("contact_timeline.png")
    contact_timeline_figure(runs, trajectory, path, ctx.footer(drawn))
    doc.img(rel, "clearance and contact force against time")
    path, rel = ctx.figure("contact_arms.png")
    arms_figure(runs, trajectory, path, ctx.footer(drawn))
    doc.img(rel, "both arms with their radius at four instants")


def _cell_values(group: Group, trajectory: str, arm: int) -> list[float]:
    """One 3-D RMSE per seed of ``group`` on ``trajectory`` and ``arm`` (m)."""
    values = []
    for run in group.runs:
        if run.metrics is None:
            continue
        rows = run.metrics[(run.metrics["trajectory"] == trajectory) & (run.metrics["arm"] == arm)]
        if len(rows):
            values.append(float(rows["rmse_3d"].iloc[0]))
    return values


def centralized_vs_independent(groups: Sequence[Group]) -> list[list[str]]:
    """Table rows comparing each centralized group with contact to each independent group of
    the same task with contact: per trajectory, each arm's difference of seed means with
    Welch's 95 % interval (:func:`softtrack.evaluation.statistics.mean_difference`)."""

    def key(group: Group) -> tuple[str, bool] | None:
        runs = [r for r in group.runs if _has_contact_columns(r)]
        return (_task(runs[0]), _contact_on(runs[0])) if runs else None

    rows = []
    for central in (g for g in groups if g.controller == "centralized"):
        for independent in (g for g in groups if g.controller == "independent"):
            pair = key(central)
            if pair is None or not pair[1] or pair != key(independent):
                continue
            for trajectory in sorted(
                {
                    str(t)
                    for r in central.runs
                    if r.metrics is not None
                    for t in r.metrics["trajectory"]
                }
            ):
                cells = []
                for arm in (0, 1):
                    a = _cell_values(central, trajectory, arm)
                    b = _cell_values(independent, trajectory, arm)
                    cells.append(mean_difference(a, b).text(4) if a and b else "–")
                rows.append(
                    [
                        pair[0],
                        central.label,
                        independent.label,
                        f"{len(central.runs)} / {len(independent.runs)}",
                        trajectory,
                        *cells,
                    ]
                )
    return rows


def contact_timeline_figure(
    runs: Sequence[tuple[str, RunData]],
    trajectory: str,
    path: str | os.PathLike[str],
    footer: str | None = None,
) -> Path:
    """Per controller (rows): the arms' surface clearance (mm; < 0: overlap) and the contact
    force between them (N) at every control step of ``trajectory``."""
    fig = fg.new_figure(11, 1.2 + 2.2 * len(runs))
    axes = fig.subplots(len(runs), 2, squeeze=False)
    for (label, run), (ax_gap, ax_force) in zip(runs, axes, strict=True):
        table = run.trajectories
        rows = (
            table[(table["trajectory"] == trajectory) & (table["arm"] == 0)]
            if table is not None and "clearance" in table
            else None
        )
        if rows is None or rows.empty:
            for ax in (ax_gap, ax_force):
                ax.text(0.5, 0.5, "not recorded", ha="center", transform=ax.transAxes)
            ax_gap.set_title(label, fontsize=9, loc="left")
            continue
        t = rows["t"].to_numpy()
        ax_gap.plot(t, 1e3 * rows["clearance"].to_numpy(), lw=0.8, color="tab:blue")
        ax_gap.axhline(0.0, color="0.3", lw=0.8, ls="--")
        ax_gap.set_title(label, fontsize=9, loc="left")
        ax_gap.set_ylabel("clearance (mm)", fontsize=9)
        ax_force.plot(t, rows["contact_force"].to_numpy(), lw=0.8, color="tab:red")
        ax_force.set_ylabel("contact force (N)", fontsize=9)
        for ax in (ax_gap, ax_force):
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("t (s)")
    fg.suptitle(
        fig,
        f"Contact between the arms, {fg.trajectory_title(trajectory)}",
        12,
        "left: gap between the surfaces (node to node, minus 2r); right: total "
        "contact force between the arms, mean over each 2-ms control step",
    )
    return fg.save_figure(fig, path, footer)


def draw_arm(
    ax: Axes, x: np.ndarray, y: np.ndarray, radius: float, color: str, shade: float = 1.0
) -> None:
    """The arm's tube in projection: circles of ``radius`` along its centreline (m);
    ``shade`` in (0, 1] scales its opacity (lighter for earlier instants)."""
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
    dense = np.linspace(0.0, s[-1], max(2, int(s[-1] / (radius / 3)) + 1))
    for px, py in zip(np.interp(dense, s, x), np.interp(dense, s, y), strict=True):
        ax.add_patch(Circle((px, py), radius, color=color, alpha=0.18 * shade, lw=0))
    ax.plot(x, y, color=color, lw=1.2, alpha=shade)


def arms_figure(
    runs: Sequence[tuple[str, RunData]],
    trajectory: str,
    path: str | os.PathLike[str],
    footer: str | None = None,
    radius: float = 0.05,
) -> Path:
    """Per controller (rows), at each kept instant (columns): both arms' centrelines and
    tubes of radius ``radius`` seen from the front (x–y) and from above (x–z), with the
    target point(s) and the 3-D surface clearance at that instant."""
    snapshots = [(label, run, run.snapshots) for label, run in runs]
    n_cols = max(
        (int(s["step"].nunique()) for _, _, s in snapshots if s is not None and not s.empty),
        default=0,
    )
    if n_cols == 0:
        return fg.no_data_figure(
            path,
            "Both arms with their radius",
            "no eval_snapshots (evaluate again to record them)",
            footer,
        )
    fig = fg.new_figure(2.6 * n_cols, 0.8 + 4.6 * len(runs))
    grid = fig.subfigures(len(runs), 1, squeeze=False)
    for (label, run, snap), sub in zip(snapshots, grid[:, 0], strict=True):
        sub.suptitle(label, fontsize=10)
        axes = sub.subplots(2, n_cols, squeeze=False)
        if snap is None or snap.empty:
            for ax in axes.ravel():
                ax.set_axis_off()
            continue
        snap = snap[snap["trajectory"] == trajectory]
        targets = run.trajectories
        for ax in axes[:, snap["step"].nunique() :].ravel():  # the episode ended before
            ax.set_axis_off()
        for col, (step, part) in enumerate(snap.groupby("step")):
            for row, (a, b, names) in enumerate(((0, 1, ("x", "y")), (0, 2, ("x", "z")))):
                ax = axes[row, col]
                for arm, color in zip((0, 1), fg.ARM_COLORS, strict=True):
                    nodes = part[part["arm"] == arm].sort_values("node")
                    coords = nodes[["x", "y", "z"]].to_numpy()
                    draw_arm(ax, coords[:, a], coords[:, b], radius, color)
                    if targets is not None:
                        hit = targets[
                            (targets["trajectory"] == trajectory)
                            & (targets["step"] == step)
                            & (targets["arm"] == arm)
                        ]
                        if len(hit):
                            goal = hit[["target_x", "target_y", "target_z"]].to_numpy()[0]
                            ax.plot(goal[a], goal[b], "x", color=color, ms=7, mew=2)
                ax.set_aspect("equal")
                ax.set_xlabel(f"{names[0]} (m)", fontsize=8)
                ax.set_ylabel(f"{names[1]} (m)", fontsize=8)
                ax.tick_params(labelsize=7)
                if row == 0:
                    gap = _clearance_at(targets, trajectory, int(step))
                    ax.set_title(
                        f"t = {float(part['t'].iloc[0]):.1f} s"
                        + (f", gap {1e3 * gap:.1f} mm" if np.isfinite(gap) else ""),
                        fontsize=9,
                    )
    fg.suptitle(
        fig,
        f"Both arms with their radius ({radius:g} m), {fg.trajectory_title(trajectory)}",
        12,
        "top row: front view (x–y), bottom row: from above (x–z); shaded tubes are "
        "the rods' surfaces, crosses each arm's target point; 'gap' is the 3-D "
        "surface clearance (negative: the arms overlap)",
    )
    return fg.save_figure(fig, path, footer)


def _clearance_at(table: pd.DataFrame | None, trajectory: str, step: int) -> float:
    if table is None or "clearance" not in table:
        return float("nan")
    hit = table[(table["trajectory"] == trajectory) & (table["step"] == step)]
    return float(hit["clearance"].iloc[0]) if len(hit) else float("nan")
