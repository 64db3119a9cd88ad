"""Figures that compare controllers: training curves, final-stage returns, tracking error,
validation and robustness.

Each draws the controllers a :class:`~softtrack.report.plan.Selection` chose (at most
:data:`~softtrack.report.families.MAX_SERIES` per panel), in the colour the report's
:class:`~softtrack.report.plan.FigurePlan` gave each, as small multiples: one panel per family
or task, never two tasks or two kinds of return on one axis. Units: m, env steps; returns are
dimensionless and stated with their episode length.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.ticker import FuncFormatter, LogLocator

from softtrack.report.curves import Curve, Smoothing, episode_seconds
from softtrack.report.data import Group
from softtrack.report.figures import (
    new_figure,
    no_data_figure,
    save_figure,
    steps_axis,
    suptitle,
    trajectory_title,
)
from softtrack.report.plan import Selection

__all__ = [
    "CurvePanel",
    "budget_text",
    "final_returns_figure",
    "return_axis_label",
    "rmse_comparison_figure",
    "robustness_figure",
    "training_curves_figure",
    "validation_figure",
]

_LEGEND_FONT = 7.5
_RMSE_TOP = (
    0.3  # m: the tracking-error axes end here at the most (a diverged controller's bars are cut)
)


@dataclass(frozen=True)
class CurvePanel:
    """One panel of :func:`training_curves_figure`: a family's curves
    (:func:`softtrack.report.curves.training_curves` of its shown controllers)."""

    selection: Selection
    curves: Sequence[Curve]
    smoothing: Smoothing


def budget_text(group: Group) -> str:
    """``1e6`` env steps per run, ``2e6/arm`` for an independent controller's arm policies,
    ``1e6–4e6`` when its runs differ, ``planner`` for a controller that does not train."""
    if group.controller == "mpc":
        return "planner"
    if group.controller == "independent":
        budgets = sorted({r.arm_budget for r in group.runs})
        suffix = "/arm"
    else:
        budgets = sorted({r.total_timesteps for r in group.runs})
        suffix = ""
    texts = [f"{b:.0e}".replace("e+0", "e") for b in budgets]
    return "–".join(dict.fromkeys(texts)) + suffix


def return_axis_label(per_arm: bool, seconds: Sequence[float], per_second: bool) -> str:
    """The y label of a return: both arms or one arm policy's, with the episode length."""
    whose = "one arm policy's return" if per_arm else "episode return, both arms"
    if per_second:
        return f"{whose} per second of episode (1/s)"
    return f"{whose} ({'/'.join(f'{s:g}' for s in sorted(set(seconds)))}-s episodes, –)"


def _grid(n: int, width: float, height: float) -> tuple[int, int, float, float]:
    """(rows, columns, figure width, figure height) for ``n`` panels of ``width``×``height``."""
    cols = 1 if n == 1 else 2
    rows = math.ceil(n / cols)
    return rows, cols, width * cols, height * rows + 0.9


def _panel_title(ax: Axes, selection: Selection) -> None:
    text = selection.title + (f"\n({selection.note})" if selection.note else "")
    ax.set_title(text, fontsize=9.5)


def _legend_below(ax: Axes, ncol: int = 2) -> None:
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(
            handles,
            labels,
            loc="upper center",
            bbox_to_anchor=(0.5, -0.2),
            ncol=ncol,
            fontsize=_LEGEND_FONT,
            frameon=False,
        )


def _seeds(n: int) -> str:
    return f"{n} seed{'s' if n != 1 else ''}"


def training_curves_figure(
    panels: Sequence[CurvePanel],
    colors: Mapping[str, str],
    path: str | os.PathLike[str],
    footer: str | None = None,
) -> Path:
    """Episode return against env steps, mean ± 1 sample std across seeds: one panel per
    family with its own axes (budgets and kinds of return differ between families); an
    independent controller's two arm policies are solid (arm 1) and dashed (arm 2)."""
    panels = [p for p in panels if p.curves]
    if not panels:
        return no_data_figure(
            path, "Training curves", "no selected run has training episodes", footer
        )
    rows, cols, width, height = _grid(len(panels), 6.4, 4.6)
    fig = new_figure(width, height)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax, panel in zip(axes, panels, strict=False):
        per_arm = any(c.arm is not None for c in panel.curves)
        for curve in panel.curves:
            color = colors.get(curve.group.label, "0.5")
            label = None
            if curve.arm in (None, 0):
                label = f"{curve.group.name} · {budget_text(curve.group)} ({_seeds(curve.n_runs)})"
            ax.plot(curve.steps, curve.mean, "--" if curve.arm == 1 else "-", color=color, lw=1.5)
            ax.lines[-1].set_label(label or "_")
            band = np.isfinite(curve.std)
            if band.any():
                ax.fill_between(
                    curve.steps,
                    curve.mean - curve.std,
                    curve.mean + curve.std,
                    where=band,
                    color=color,
                    alpha=0.15,
                    lw=0,
                )
        steps_axis(ax)
        seconds = [c.episode_seconds for c in panel.curves]
        ylabel = return_axis_label(per_arm, seconds, panel.smoothing.per_second)
        ax.set_ylabel(ylabel + ("\nsolid: arm 1, dashed: arm 2" if per_arm else ""), fontsize=8.5)
        _panel_title(ax, panel.selection)
        _legend_below(ax, 1)
    for ax in axes[len(panels) :]:
        ax.set_axis_off()
    fraction = panels[0].smoothing.window_fraction
    suptitle(
        fig,
        "Training curves: mean ± 1 sample std across seeds",
        12,
        f"each curve smoothed over a centred window of {fraction:.0%} of its own training "
        "length; legend: experiment · budget in env steps (seeds)",
    )
    return save_figure(fig, path, footer)


def final_returns_figure(
    panels: Sequence[tuple[Selection, pd.DataFrame]],
    colors: Mapping[str, str],
    path: str | os.PathLike[str],
    footer: str | None = None,
) -> Path:
    """Horizontal bars of the final-stage return, mean ± sample std across seeds (dots: the
    seeds): one panel per family, both-arm and one-arm-policy returns never on one axis.

    Args:
        panels: (the family's selection, its rows of
            :func:`softtrack.report.curves.final_stage_table`).
    """
    panels = [(s, t[t["n"] > 0]) for s, t in panels if not t.empty and (t["n"] > 0).any()]
    if not panels:
        return no_data_figure(
            path, "Final-stage return", "no run has episodes in the last part of its budget", footer
        )
    bars = [len(t) for _, t in panels]
    fig = new_figure(9.0, 0.28 * sum(bars) + 1.1 * len(panels) + 1.0)
    axes = fig.subplots(len(panels), 1, squeeze=False, height_ratios=[n + 2.5 for n in bars])
    for ax, (selection, table) in zip(axes.ravel(), panels, strict=True):
        by_label = {g.label: g for g in selection.shown}
        order = [g.label for g in selection.shown]
        table = table.assign(order=table["group"].map(order.index)).sort_values(["order", "arm"])
        y = np.arange(len(table))[::-1]
        names = []
        for yi, row in zip(y, table.itertuples(), strict=True):
            group = by_label[str(row.group)]
            color = colors.get(group.label, "0.5")
            std = 0.0 if not np.isfinite(row.std) else float(row.std)
            ax.barh(yi, row.mean, xerr=std, color=color, alpha=0.8, capsize=3, height=0.7)
            values = list(row.values.values())
            ax.plot(values, [yi] * len(values), "k.", ms=5)
            arm = "" if row.arm < 0 else f", arm {int(row.arm) + 1}"
            names.append(f"{group.name} · {budget_text(group)}{arm}")
        ax.set_yticks(y, names, fontsize=7.5)
        per_arm = bool((table["arm"] >= 0).any())
        seconds = [episode_seconds(r) for g in selection.shown for r in g.runs]
        ax.set_xlabel(return_axis_label(per_arm, seconds, False), fontsize=8.5)
        ax.axvline(0, color="0.5", lw=0.8)
        ax.grid(axis="x", alpha=0.3)
        ax.set_ylim(-0.6, len(table) - 0.4)
        _panel_title(ax, selection)
    suptitle(
        fig,
        "Final-stage return: mean episode return over the last 10 % of training",
        12,
        "bars: mean ± sample std across seeds; dots: the seeds; label: experiment · budget in "
        "env steps",
    )
    return save_figure(fig, path, footer)


def rmse_comparison_figure(
    selections: Sequence[Selection],
    summary: pd.DataFrame,
    colors: Mapping[str, str],
    study: Mapping[str, Mapping[tuple[str, int], float]],
    trajectories: Sequence[str],
    path: str | os.PathLike[str],
    footer: str | None = None,
) -> Path:
    """3-D RMSE per trajectory and arm, one panel per task (its headline controllers: bars of
    mean ± sample std across seeds) with the study's values as markers.

    Args:
        summary: :func:`softtrack.report.group_summaries.metrics_summary` output.
        study: ``{marker label: {(trajectory, arm): value}}``.
    """
    title = "3-D RMSE per trajectory and arm"
    selections = [s for s in selections if s.shown]
    if summary.empty or "rmse_3d_mean" not in summary or not selections:
        return no_data_figure(path, title, "no stored evaluation metrics", footer)
    slots = [(t, a) for t in trajectories for a in (0, 1)]
    x = np.arange(len(slots))
    fig = new_figure(12, 3.9 * len(selections) + 0.8)
    axes = fig.subplots(len(selections), 1, squeeze=False).ravel()
    for ax, selection in zip(axes, selections, strict=True):
        width = 0.8 / len(selection.shown)
        for i, group in enumerate(selection.shown):
            part = summary[summary["group"] == group.label].set_index(["trajectory", "arm"])
            mean = [part["rmse_3d_mean"].get(s, np.nan) for s in slots]
            std = [part["rmse_3d_std"].get(s, np.nan) for s in slots]
            seeds = int(part["n"].max()) if len(part) else 0
            ax.bar(
                x - 0.4 + width * (i + 0.5),
                mean,
                width,
                yerr=np.nan_to_num(std),
                capsize=2,
                color=colors.get(group.label, "0.5"),
                alpha=0.85,
                label=f"{group.name} · {budget_text(group)} ({_seeds(seeds)})",
            )
        for marker, (label, values) in zip(("k*", "kx"), study.items(), strict=False):
            ys = [values.get(s, np.nan) for s in slots]
            if np.isfinite(ys).any():
                ax.plot(x, ys, marker, ms=8, label=label)
        ax.set_xticks(x, [f"{trajectory_title(t)}, arm {a + 1}" for t, a in slots], fontsize=8.5)
        ax.set_ylabel("3-D RMSE (m)")
        drawn = summary[summary["group"].isin([g.label for g in selection.shown])]
        top = float(np.nanmax(drawn["rmse_3d_mean"] + drawn["rmse_3d_std"].fillna(0)))
        ax.set_ylim(0, min(1.12 * top, _RMSE_TOP) if np.isfinite(top) else _RMSE_TOP)
        ax.grid(axis="y", alpha=0.3)
        _panel_title(ax, selection)
        ax.legend(fontsize=_LEGEND_FONT, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    suptitle(
        fig,
        title,
        12,
        "one panel per task; bars: mean ± sample std across seeds; label: experiment · budget "
        f"in env steps (seeds); bars above {_RMSE_TOP:g} m are cut at the top edge",
    )
    return save_figure(fig, path, footer)


def validation_figure(
    panels: Sequence[tuple[Selection, Mapping[tuple[str, int, int], pd.DataFrame]]],
    colors: Mapping[str, str],
    path: str | os.PathLike[str],
    footer: str | None = None,
) -> Path:
    """Validation score against env steps, one panel per family: one line per seed (and arm
    policy, dashed for arm 2), the checkpoint kept as best circled, on a log scale.

    Args:
        panels: (the family's selection, (group label, seed, policy) → rows ``global_step``,
            ``score`` (m) of :func:`softtrack.report.group_summaries.validation_scores`).
    """
    panels = [(s, scores) for s, scores in panels if scores]
    if not panels:
        return no_data_figure(path, "Validation", "no selected run has validation episodes", footer)
    rows, cols, width, height = _grid(len(panels), 6.4, 4.6)
    fig = new_figure(width, height)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax, (selection, scores) in zip(axes, panels, strict=False):
        names = {g.label: g for g in selection.shown}
        labelled: set[str] = set()
        for (label, _seed, policy), part in scores.items():
            group = names[label]
            color = colors.get(label, "0.5")
            finite = part[np.isfinite(part["score"]) & (part["score"] > 0)]
            legend = None
            if label not in labelled:
                labelled.add(label)
                legend = f"{group.name} · {budget_text(group)} ({_seeds(len(group.runs))})"
            ax.plot(
                finite["global_step"],
                finite["score"],
                "--" if policy == 1 else "-",
                color=color,
                lw=1.1,
                alpha=0.85,
                marker=".",
                ms=3,
                label=legend,
            )
            if len(finite):
                best = finite.loc[finite["score"].idxmin()]
                ax.plot(best["global_step"], best["score"], "o", mfc="none", mec=color, ms=8)
        ax.set_yscale("log")
        ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _: ""))
        steps_axis(ax)
        ax.set_xlabel("environment steps (of the policy)")
        ax.set_ylabel("validation 3-D RMSE (m, log scale)")
        _panel_title(ax, selection)
        _legend_below(ax, 1)
    for ax in axes[len(panels) :]:
        ax.set_axis_off()
    suptitle(
        fig,
        "Validation: mean 3-D RMSE on held-out random-target episodes per checkpoint",
        12,
        "one line per seed (dashed: an independent controller's arm-2 policy); circled: the "
        "checkpoint kept as best",
    )
    return save_figure(fig, path, footer)


def robustness_figure(
    summary: pd.DataFrame,
    selection: Selection,
    colors: Mapping[str, str],
    axis_labels: Mapping[str, str],
    path: str | os.PathLike[str],
    footer: str | None = None,
) -> Path:
    """3-D RMSE against level, one panel per one-factor perturbation with at least two
    levels; one line per shown controller (seed mean) with its min–max band across seeds.

    Args:
        summary: rows of :func:`softtrack.report.robustness_section.robustness_summary` with a
            numeric ``level``.
        axis_labels: factor → x label with its unit.
    """
    labels = [g.label for g in selection.shown]
    summary = summary[summary["group"].isin(labels)]
    counts = summary.groupby("perturbation")["level"].nunique()
    factors = [f for f in dict.fromkeys(summary["perturbation"]) if counts[f] >= 2]
    if not factors:
        return no_data_figure(path, "Robustness", "no perturbation with two levels", footer)
    cols = min(3, len(factors))
    n_rows = -(-len(factors) // cols)
    fig = new_figure(max(6.0, 4.3 * cols) + 3.0, 3.3 * n_rows + 1.4)
    for i, factor in enumerate(factors):
        ax = fig.add_subplot(n_rows, cols, i + 1)
        for group in selection.shown:
            part = summary[(summary["perturbation"] == factor) & (summary["group"] == group.label)]
            part = part.sort_values("level")
            if part.empty:
                continue
            color = colors.get(group.label, "0.5")
            ax.plot(
                part["level"],
                part["rmse_3d_mean"],
                "-o",
                ms=4,
                color=color,
                label=f"{group.name} · {budget_text(group)}",
            )
            ax.fill_between(
                part["level"], part["rmse_3d_min"], part["rmse_3d_max"], color=color, alpha=0.12
            )
        ax.set_xlabel(axis_labels.get(factor, factor), fontsize=9)
        ax.set_ylabel("3-D RMSE (m)")
        ax.grid(alpha=0.3)
    handles, names = fig.axes[0].get_legend_handles_labels()
    fig.axes[cols - 1].legend(
        handles, names, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8, frameon=False
    )
    note = f" ({selection.note})" if selection.note else ""
    suptitle(
        fig,
        "Tracking error under perturbations",
        12,
        f"{selection.title}{note}; mean over trajectories and arms; line: seed mean; band: "
        "min–max of seeds",
    )
    return save_figure(fig, path, footer)
