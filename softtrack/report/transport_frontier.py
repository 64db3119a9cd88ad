"""Holding against carrying: where each transport run sits between keeping the sphere and
moving it onto its goal.

A transport controller can buy a longer hold with a lazier grasp (the sphere stays near its
start, far from the goal) or a smaller error with a grasp that loses the sphere sooner. One
point per run and set of episodes makes that trade-off, and the distance of every run from the
issue's target (held to the end at ≤ 0.065 m), visible at a glance.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.lines import Line2D

from softtrack.report import figures as fg
from softtrack.report.data import Group, RunData
from softtrack.report.families import assign_colors

__all__ = ["EPISODE_SETS", "frontier_figure", "hold_track_frontier", "longest_holding"]

EPISODE_SETS = ("random", "trajectories")  # eval_random's episodes, eval_metrics' trajectories


def _episodes(run: RunData, episodes: str) -> pd.DataFrame | None:
    """Arm 0's rows of the run's transport episodes of one set (one row per episode: the
    sphere's values are the same in both arms' rows), or ``None`` without them."""
    rows = run.random if episodes == "random" else run.metrics
    if rows is None or "object_rmse_3d" not in rows or "dropped" not in rows or rows.empty:
        return None
    return rows[rows["arm"] == 0]


def hold_track_frontier(groups: Sequence[Group]) -> pd.DataFrame:
    """One row per transport run and episode set (``episodes``: "random" for the held-out
    random targets, "trajectories" for circle, rectangle and figure-eight): ``group``,
    ``seed``, ``n`` (episodes), ``held_fraction`` (the mean share of the planned episode the
    sphere was held, 1 for an episode carried to its end), ``carried`` (episodes carried to
    the end) and ``error`` (the median over episodes of the sphere's 3-D RMSE while held, m).
    Runs without a planned episode length (``training.eval_duration``) are left out."""
    rows = []
    for group in groups:
        for run in group.runs:
            if run.eval_duration is None:
                continue
            planned = float(run.eval_duration)
            for episodes in EPISODE_SETS:
                part = _episodes(run, episodes)
                if part is None:
                    continue
                dropped = part["dropped"].fillna(False).astype(bool).to_numpy()
                held = np.where(dropped, part["drop_time"].to_numpy(dtype=float), planned)
                rows.append(
                    {
                        "group": group.label,
                        "seed": run.seed,
                        "episodes": episodes,
                        "n": len(part),
                        "held_fraction": float(np.mean(np.minimum(held, planned) / planned)),
                        "carried": int((~dropped).sum()),
                        "error": float(np.median(part["object_rmse_3d"].to_numpy(dtype=float))),
                    }
                )
    return pd.DataFrame(
        rows, columns=["group", "seed", "episodes", "n", "held_fraction", "carried", "error"]
    )


def longest_holding(frontier: pd.DataFrame, count: int) -> pd.DataFrame:
    """The rows of the ``count`` controllers that hold the sphere longest (the mean
    ``held_fraction`` over their rows; the smaller median ``error`` on ties)."""
    ranked = (
        frontier.groupby("group", sort=False)
        .agg(held=("held_fraction", "mean"), error=("error", "median"))
        .sort_values(["held", "error"], ascending=[False, True])
    )
    return frontier[frontier["group"].isin(set(ranked.index[:count]))]


def frontier_figure(
    frontier: pd.DataFrame,
    path: str | os.PathLike[str],
    target: float,
    footer: str | None = None,
) -> Path:
    """The :func:`hold_track_frontier` as a scatter: per episode set a panel, the share of
    the episode held (x) against the sphere's error while held (y, m), one point per run
    labelled with its seed, one colour per controller; the target corner (held to the end at
    ≤ ``target`` m) shaded."""
    sets = [s for s in EPISODE_SETS if (frontier["episodes"] == s).any()]
    labels = list(dict.fromkeys(frontier["group"]))
    fig = fg.new_figure(5.0 * max(1, len(sets)) + 4.0, 5.2)
    axes = fig.subplots(1, max(1, len(sets)), squeeze=False)[0]
    colors = assign_colors([labels])
    top = max(0.1, float(frontier["error"].max()) * 1.1) if len(frontier) else 1.0
    for ax, episodes in zip(axes, sets, strict=False):
        part = frontier[frontier["episodes"] == episodes]
        ax.axhspan(0.0, target, xmin=0.95, xmax=1.0, color="tab:green", alpha=0.15, lw=0)
        ax.axhline(target, color="tab:green", ls=":", lw=1)
        for label in labels:
            own = part[part["group"] == label]
            if own.empty:
                continue
            ax.scatter(own["held_fraction"], own["error"], color=colors[label], s=28, label=label)
            for _, row in own.iterrows():
                ax.annotate(
                    str(int(row["seed"])),
                    (row["held_fraction"], row["error"]),
                    textcoords="offset points",
                    xytext=(4, 3),
                    fontsize=7,
                    color=colors[label],
                )
        ax.set_xlim(0.0, 1.05)
        ax.set_ylim(0.0, top)
        ax.set_xlabel("share of the episode the sphere was held (mean)", fontsize=8)
        ax.set_ylabel("sphere's 3-D RMSE while held, median (m)", fontsize=8)
        ax.set_title(
            "held-out random targets"
            if episodes == "random"
            else "circle, rectangle, figure-eight",
            fontsize=9,
        )
        ax.tick_params(labelsize=7)
    handles = [
        Line2D([], [], ls="", marker="o", color=colors[label], label=label) for label in labels
    ]
    axes[len(sets) - 1].legend(
        handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False
    )
    fg.suptitle(
        fig,
        "Holding against carrying",
        12,
        f"one point per run (its seed), the green corner: held to the end at ≤ {target} m",
    )
    return fg.save_figure(fig, path, footer)
