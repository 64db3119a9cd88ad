"""The report's robustness section: tracking error under the perturbations of
``softtrack robustness`` (table ``eval_robustness``), controllers side by side.

:func:`robustness_summary` aggregates each group's runs per setting; :func:`robustness_section`
writes a table of every setting and a figure of 3-D RMSE against level per one-factor
perturbation (:func:`softtrack.report.figures.robustness_figure`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

from softtrack.evaluation.perturbations import ROBUSTNESS_SEED, factor_axis_label
from softtrack.report import comparison_figures as cf
from softtrack.report.data import Group
from softtrack.report.document import Context, Doc
from softtrack.report.text import mean_pm_std

__all__ = ["robustness_section", "robustness_summary"]


def _nominal(table: pd.DataFrame, trajectories: list[str]) -> float:
    """A run's mean 3-D RMSE over ``trajectories`` and arms in its ``nominal`` setting (m);
    NaN when that setting lacks one of them."""
    rows = table[(table["setting"] == "nominal") & table["trajectory"].isin(trajectories)]
    if set(rows["trajectory"]) != set(trajectories):
        return float("nan")
    return float(pd.to_numeric(rows["rmse_3d"], errors="coerce").mean())


def _finite(reduce: Callable[[np.ndarray], float], values: list[float]) -> float:
    """``reduce`` over the finite ``values``; NaN when there is none."""
    array = np.asarray(values, dtype=float)
    return float(reduce(array)) if np.isfinite(array).any() else float("nan")


def robustness_summary(groups: list[Group]) -> pd.DataFrame:
    """One row per group and setting of the idealised baseline (``eval_robustness``).

    A seed's value is its mean 3-D RMSE over the setting's trajectories, arms and episodes;
    its ratio is that value over the seed's ``nominal`` setting (the unperturbed baseline) on
    the same trajectories.
    Columns: group, perturbation, level, setting, n (seeds), rmse_3d_mean, rmse_3d_std
    (sample std across seeds; NaN for one seed), rmse_3d_min, rmse_3d_max (m), ratio_mean,
    diverged (episodes that ended early, all seeds), peak_moment (largest element torque,
    N·m), collision_steps (mean per episode). Empty when no run has the table.
    """
    rows = []
    for group in groups:
        per_setting: dict[str, list[dict[str, float]]] = {}
        meta: dict[str, tuple[str, float]] = {}
        for run in group.runs:
            table = run.robustness
            if table is None:
                continue
            table = table[table["baseline"] == "idealised"]
            for setting, part in table.groupby("setting", sort=False):
                value = float(pd.to_numeric(part["rmse_3d"], errors="coerce").mean())
                nominal = _nominal(table, sorted(set(part["trajectory"])))
                episodes = part.drop_duplicates(["trajectory", "episode"])
                per_setting.setdefault(str(setting), []).append(
                    {
                        "value": value,
                        "ratio": value / nominal if nominal > 0 else float("nan"),
                        "diverged": float(episodes["terminated"].astype(bool).sum()),
                        "peak": float(pd.to_numeric(part.get("peak_moment"), errors="coerce").max())
                        if "peak_moment" in part
                        else float("nan"),
                        "collisions": float(
                            pd.to_numeric(episodes.get("collision_steps"), errors="coerce").mean()
                        )
                        if "collision_steps" in part
                        else float("nan"),
                    }
                )
                meta[str(setting)] = (
                    str(part["perturbation"].iloc[0]),
                    float(part["level"].iloc[0]),
                )
        for setting, seeds in per_setting.items():
            values = np.array([s["value"] for s in seeds])
            rows.append(
                {
                    "group": group.label,
                    "perturbation": meta[setting][0],
                    "level": meta[setting][1],
                    "setting": setting,
                    "n": len(seeds),
                    "rmse_3d_mean": float(values.mean()),
                    "rmse_3d_std": float(values.std(ddof=1)) if len(values) > 1 else float("nan"),
                    "rmse_3d_min": float(values.min()),
                    "rmse_3d_max": float(values.max()),
                    "ratio_mean": _finite(np.nanmean, [s["ratio"] for s in seeds]),
                    "diverged": int(sum(s["diverged"] for s in seeds)),
                    "peak_moment": _finite(np.nanmax, [s["peak"] for s in seeds]),
                    "collision_steps": _finite(np.nanmean, [s["collisions"] for s in seeds]),
                }
            )
    return pd.DataFrame(rows)


def _cell(row: pd.Series) -> str:
    text = mean_pm_std(row["rmse_3d_mean"], row["rmse_3d_std"], 4)
    if np.isfinite(row["ratio_mean"]):
        text += f" ({row['ratio_mean']:.2f}×)"
    if row["diverged"]:
        text += f", {row['diverged']} diverged"
    return text


def robustness_section(doc: Doc, ctx: Context) -> None:
    """RMSE under each perturbation setting per controller (only when some run has
    ``eval_robustness``)."""
    summary = robustness_summary(ctx.groups)
    if summary.empty:
        return
    doc.h(3, "Robustness to perturbations")
    labels = list(dict.fromkeys(summary["group"]))
    order = (
        summary.drop_duplicates("setting")
        .assign(first=lambda df: df["setting"] != "nominal")
        .sort_values(["first", "perturbation", "level", "setting"], kind="stable")
    )
    rows = []
    for _, setting in order.iterrows():
        row = [str(setting["perturbation"]), f"`{setting['setting']}`"]
        for label in labels:
            hit = summary[(summary["group"] == label) & (summary["setting"] == setting["setting"])]
            row.append(_cell(hit.iloc[0]) if len(hit) else "–")
        rows.append(row)
    doc.table(["perturbation", "setting", *[f"{label} 3-D RMSE (m)" for label in labels]], rows)
    seeds = ", ".join(
        f"{label}: {int(summary[summary['group'] == label]['n'].max())}" for label in labels
    )
    doc.p(
        "Each controller's deterministic policy under one perturbation setting (`softtrack "
        "robustness RUN... --grid FACTOR=LEVELS`, docs/robustness.md) on the evaluated "
        "trajectories, from the idealised environment (the run's own realism settings off). "
        "A seed's value is its mean 3-D RMSE over trajectories, arms and episodes (noise from "
        f"seed {ROBUSTNESS_SEED:,} + k); mean ± sample std across seeds ({seeds} seeds), and "
        "in brackets the mean ratio to the seed's `nominal` row (the unperturbed baseline) on "
        "the same trajectories."
    )
    one_factor = summary[np.isfinite(summary["level"].astype(float))]
    if one_factor.groupby("perturbation")["level"].nunique().max() >= 2:
        path, rel = ctx.figure("robustness.png")
        selection = ctx.plan.robustness
        assert selection is not None  # planned from the same tables
        axis_labels = {f: factor_axis_label(f) for f in set(one_factor["perturbation"])}
        cf.robustness_figure(
            one_factor,
            selection,
            ctx.plan.colors,
            axis_labels,
            path,
            ctx.footer(list(selection.shown)),
        )
        doc.img(rel, "3-D RMSE against perturbation level")
