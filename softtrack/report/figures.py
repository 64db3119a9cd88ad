"""Report figures: matplotlib ``Figure`` objects rendered with the Agg canvas to PNG.

No pyplot state is touched (the figures are built with :class:`matplotlib.figure.Figure`),
so the module is safe in any process. Every function takes already-loaded table data, writes
one PNG atomically at :data:`DPI`, and returns its path; where the data is missing it draws a
figure that says so (:func:`no_data_figure`) instead of failing. Units: m, s, N·m, env steps.
"""

from __future__ import annotations

import os
import textwrap
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from softtrack.report.curves import Curve, Smoothing
from softtrack.report.data import DIRECTIONS
from softtrack.report.reference import TRAJECTORY_TITLES
from softtrack.store.atomic import atomic_path

__all__ = [
    "DPI",
    "final_returns_figure",
    "moments_figure",
    "no_data_figure",
    "rmse_comparison_figure",
    "tracking_errors_figure",
    "training_curves_figure",
    "trajectory_3d_figure",
    "validation_figure",
]

DPI = 150
ARM_COLORS = ("tab:blue", "tab:orange")
AXIS_COLORS = {"x": "tab:red", "y": "tab:green", "z": "tab:purple"}
GROUP_COLORS = (
    "tab:blue",
    "tab:orange",
    "tab:green",
    "tab:red",
    "tab:purple",
    "tab:brown",
    "tab:pink",
    "tab:olive",
    "tab:cyan",
    "tab:gray",
)
STEADY_START = 1.0  # s, the start of the "steady" metrics


def _new(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _suptitle(fig: Figure, text: str, fontsize: float) -> None:
    """The figure's title, wrapped to its width (a long run name would be cut off)."""
    chars = max(40, int(fig.get_size_inches()[0] * 17 * 7 / fontsize * 0.9))
    fig.suptitle("\n".join(textwrap.wrap(text, width=chars, break_on_hyphens=False)),
                 fontsize=fontsize)


def _save(fig: Figure, path: str | os.PathLike[str], footer: str | None) -> Path:
    if footer:  # wrapped to the figure's width, below the axes
        width, height = fig.get_size_inches()
        lines = textwrap.wrap(footer, width=max(40, int(width * 17)))
        bottom = (0.14 * len(lines) + 0.06) / height
        fig.get_layout_engine().set(rect=(0, bottom, 1, 1 - bottom))
        fig.text(
            0.01, 0.04 / height, "\n".join(lines), fontsize=7, color="0.3", ha="left", va="bottom"
        )
    path = Path(path)
    with atomic_path(path, fsync=False) as tmp:
        fig.savefig(tmp, dpi=DPI, format="png")
    return path


def no_data_figure(
    path: str | os.PathLike[str], title: str, reason: str, footer: str | None = None
) -> Path:
    """A figure that states that ``title`` has no data, and why."""
    fig = _new(7, 3)
    ax = fig.add_subplot()
    ax.set_axis_off()
    ax.text(
        0.5,
        0.62,
        title,
        ha="center",
        va="center",
        fontsize=13,
        weight="bold",
        transform=ax.transAxes,
    )
    ax.text(
        0.5,
        0.35,
        f"no data: {reason}",
        ha="center",
        va="center",
        fontsize=11,
        color="tab:red",
        transform=ax.transAxes,
        wrap=True,
    )
    return _save(fig, path, footer)


def _traj_title(trajectory: str) -> str:
    return TRAJECTORY_TITLES.get(trajectory, trajectory)


def training_curves_figure(
    curves: Sequence[Curve],
    smoothing: Smoothing,
    path: str | os.PathLike[str],
    footer: str | None = None,
) -> Path:
    """Episode return against env steps: mean ± 1 sample std across seeds, one curve per
    algorithm (per arm policy for independent controllers), all smoothed alike."""
    if not curves:
        return no_data_figure(
            path, "Training curves", "no selected run has training episodes", footer
        )
    fig = _new(9, 5.2)
    ax = fig.add_subplot()
    colors: dict[str, str] = {}
    for curve in curves:
        color = colors.setdefault(curve.group.label, GROUP_COLORS[len(colors) % len(GROUP_COLORS)])
        style = "-" if curve.arm in (None, 0) else "--"
        seeds = f"{curve.n_runs} seed{'s' if curve.n_runs != 1 else ''}"
        ax.plot(
            curve.steps, curve.mean, style, color=color, lw=1.8, label=f"{curve.label} ({seeds})"
        )
        band = np.isfinite(curve.std)
        if band.any():
            ax.fill_between(
                curve.steps,
                curve.mean - curve.std,
                curve.mean + curve.std,
                where=band,
                color=color,
                alpha=0.2,
                lw=0,
            )
    ax.set_xlabel("environment steps")
    ax.set_ylabel("episode return (sum of rewards, –)")
    ax.set_title(
        "Training curves: mean ± 1 sample std across seeds\n"
        f"(smoothing: centred window of {smoothing.window:,.0f} env steps, same for "
        "every curve)",
        fontsize=11,
    )
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    return _save(fig, path, footer)


def final_returns_figure(
    table: pd.DataFrame, path: str | os.PathLike[str], footer: str | None = None
) -> Path:
    """Bars of the final-stage return per algorithm, mean ± sample std across seeds, with the
    individual seeds as dots."""
    rows = table[table["n"] > 0] if not table.empty else table
    if rows.empty:
        return no_data_figure(
            path, "Final-stage return", "no run has episodes in the last part of its budget", footer
        )
    fig = _new(max(5.0, 1.4 * len(rows) + 2), 4.5)
    ax = fig.add_subplot()
    labels = [
        r.group if r.arm < 0 else f"{r.group}\narm {int(r.arm) + 1} policy"
        for r in rows.itertuples()
    ]
    x = np.arange(len(rows))
    std = rows["std"].fillna(0.0).to_numpy()
    ax.bar(
        x,
        rows["mean"],
        yerr=std,
        capsize=5,
        color=[GROUP_COLORS[i % 10] for i in x],
        alpha=0.75,
        label="mean ± sample std",
    )
    for i, values in enumerate(rows["values"]):
        ax.plot(
            [i] * len(values),
            list(values.values()),
            "k.",
            ms=8,
            label="one seed" if i == 0 else None,
        )
    ax.set_xticks(x, labels, fontsize=9)
    ax.set_ylabel("final-stage episode return (–)")
    ax.set_title("Final-stage return: mean episode return at the end of training (SPEC §4)")
    ax.axhline(0, color="0.5", lw=0.8)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path, footer)


def _arm_frame(traj: pd.DataFrame, arm: int) -> pd.DataFrame:
    return traj[traj["arm"] == arm].sort_values("step")


def trajectory_3d_figure(
    traj: pd.DataFrame | None,
    trajectory: str,
    path: str | os.PathLike[str],
    *,
    subtitle: str = "",
    rmse: Mapping[int, float] | None = None,
    footer: str | None = None,
) -> Path:
    """3-D path of the target and both tips (y up), and the view from above (x–z plane).

    Args:
        traj: the ``eval_trajectories`` rows of one run and trajectory.
        rmse: 3-D RMSE per arm (m) for the legend.
    """
    title = f"{_traj_title(trajectory)}: target and tip paths"
    if traj is None or traj.empty:
        return no_data_figure(
            path,
            f"{title}{' — ' + subtitle if subtitle else ''}",
            "no stored evaluation trajectory",
            footer,
        )
    fig = _new(12, 6.0)
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    target = _arm_frame(traj, int(traj["arm"].min()))
    ax3.plot(
        target["target_x"], target["target_z"], target["target_y"], "k--", lw=1.5, label="target"
    )
    ax2.plot(target["target_x"], target["target_z"], "k--", lw=1.5, label="target")
    for arm in sorted(int(a) for a in traj["arm"].unique()):
        df = _arm_frame(traj, arm)
        color = ARM_COLORS[arm % 2]
        label = f"arm {arm + 1} tip"
        if rmse and arm in rmse and np.isfinite(rmse[arm]):
            label += f" (3-D RMSE {rmse[arm]:.3f} m)"
        ax3.plot(df["tip_x"], df["tip_z"], df["tip_y"], color=color, lw=1.4, label=label)
        ax3.scatter(
            df["tip_x"].iloc[:1],
            df["tip_z"].iloc[:1],
            df["tip_y"].iloc[:1],
            color=color,
            marker="o",
            s=25,
        )
        ax2.plot(df["tip_x"], df["tip_z"], color=color, lw=1.4, label=label)
        ax2.plot(df["tip_x"].iloc[:1], df["tip_z"].iloc[:1], "o", color=color, ms=5)
    ax3.set_xlabel("x (m)")
    ax3.set_ylabel("z (m)")
    ax3.set_zlabel("y (m)")
    ax3.set_title("3-D view (y up; dots: start)")
    ax2.set_xlabel("x (m)")
    ax2.set_ylabel("z (m)")
    ax2.set_aspect("equal", adjustable="datalim")
    ax2.set_title("seen from above (x–z plane)")
    ax2.grid(alpha=0.3)
    ax2.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=9)
    _suptitle(fig, f"{title}{' — ' + subtitle if subtitle else ''}", 12)
    return _save(fig, path, footer)


def tracking_errors_figure(
    traj: pd.DataFrame | None,
    trajectory: str,
    path: str | os.PathLike[str],
    *,
    subtitle: str = "",
    footer: str | None = None,
) -> Path:
    """Per-axis error tip − target and spatial error ‖tip − target‖ against time, both arms."""
    title = f"{_traj_title(trajectory)}: tracking error"
    if traj is None or traj.empty:
        return no_data_figure(
            path,
            f"{title}{' — ' + subtitle if subtitle else ''}",
            "no stored evaluation trajectory",
            footer,
        )
    arms = sorted(int(a) for a in traj["arm"].unique())
    fig = _new(12, 3.2 * len(arms) + 0.8)
    axes = fig.subplots(len(arms), 2, sharex=True, squeeze=False)
    for row, arm in enumerate(arms):
        df = _arm_frame(traj, arm)
        t = df["t"].to_numpy(float)
        e = {a: df[f"tip_{a}"].to_numpy(float) - df[f"target_{a}"].to_numpy(float) for a in "xyz"}
        d = np.sqrt(e["x"] ** 2 + e["y"] ** 2 + e["z"] ** 2)
        ax = axes[row, 0]
        for a in "xyz":
            ax.plot(t, e[a], color=AXIS_COLORS[a], lw=1.2, label=f"e_{a}")
        ax.axhline(0, color="0.5", lw=0.8)
        low = min(0.0, *(float(np.min(v)) for v in e.values())) if t.size else -1.0
        high = max(0.0, *(float(np.max(v)) for v in e.values())) if t.size else 1.0
        span = max(high - low, 1e-3)
        ax.set_ylim(low - 0.05 * span, high + 0.3 * span)  # headroom for the legend
        ax.set_ylabel(f"arm {arm + 1}: error (m)")
        ax.set_title(f"arm {arm + 1}: per-axis error tip − target")
        ax.legend(loc="upper right", fontsize=8, ncol=3)
        ax = axes[row, 1]
        ax.plot(t, d, color=ARM_COLORS[arm % 2], lw=1.4, label="spatial error d(t)")
        rmse = float(np.sqrt(np.mean(d**2))) if d.size else np.nan
        ax.axhline(
            float(np.mean(d)),
            color="0.3",
            ls="--",
            lw=1,
            label=f"mean {np.mean(d):.3f} m, 3-D RMSE {rmse:.3f} m",
        )
        ax.set_ylabel(f"arm {arm + 1}: spatial error (m)")
        ax.set_ylim(0, 1.3 * float(np.max(d)) if d.size and np.max(d) > 0 else 1.0)
        ax.set_title(f"arm {arm + 1}: spatial error ‖tip − target‖")
        ax.legend(loc="upper right", fontsize=8)
        for ax in axes[row]:
            ax.grid(alpha=0.3)
            if t.size and t.max() > STEADY_START:
                ax.axvline(STEADY_START, color="0.6", ls=":", lw=1)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    _suptitle(
        fig,
        f"{title}{' — ' + subtitle if subtitle else ''}  (dotted: t = 1 s, start of "
        "the steady metrics)",
        11,
    )
    return _save(fig, path, footer)


def moments_figure(
    moments: Mapping[str, pd.DataFrame | None],
    path: str | os.PathLike[str],
    *,
    title: str = "Actuation moments",
    subtitles: Mapping[str, str] | None = None,
    footer: str | None = None,
) -> Path:
    """Spatial-RMS element moment against time per trajectory (rows), arm (columns) and
    direction (lines), with each line's peak absolute element moment in the legend.

    Args:
        moments: ``eval_moments`` rows of one run per trajectory (``None`` where missing).
    """
    if not any(df is not None and not df.empty for df in moments.values()):
        return no_data_figure(path, title, "no stored evaluation moments", footer)
    trajectories = list(moments)
    fig = _new(12, 2.9 * len(trajectories) + 0.8)
    axes = fig.subplots(len(trajectories), 2, sharex=True, squeeze=False)
    for row, trajectory in enumerate(trajectories):
        df = moments[trajectory]
        for arm in (0, 1):
            ax = axes[row, arm]
            name = f"{_traj_title(trajectory)}, arm {arm + 1}"
            if subtitles and subtitles.get(trajectory):
                name += f" ({subtitles[trajectory]})"
            ax.set_title(name, fontsize=10)
            ax.grid(alpha=0.3)
            ax.set_ylabel("RMS moment (N·m)")
            part = None if df is None else df[df["arm"] == arm]
            if part is None or part.empty:
                ax.text(
                    0.5,
                    0.5,
                    "no data",
                    ha="center",
                    va="center",
                    color="tab:red",
                    transform=ax.transAxes,
                )
                continue
            top = 0.0
            for direction, style in ((0, "-"), (1, "--")):
                sub = part[part["direction"] == direction].sort_values("step")
                if sub.empty:
                    continue
                peak = float(sub["max_abs_moment"].max())
                top = max(top, float(sub["rms_moment"].max()))
                ax.plot(
                    sub["t"],
                    sub["rms_moment"],
                    style,
                    color=ARM_COLORS[arm],
                    lw=1.3,
                    label=f"{DIRECTIONS[direction]} (peak element {peak:.1f} N·m)",
                )
            ax.set_ylim(0, 1.35 * top if top > 0 else 1.0)  # room for the legend
            ax.legend(loc="upper right", fontsize=8, ncol=2)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    _suptitle(fig, f"{title}: spatial RMS over the 20 elements", 12)
    return _save(fig, path, footer)


def rmse_comparison_figure(
    summary: pd.DataFrame,
    study: Mapping[str, Mapping[tuple[str, int], float]],
    trajectories: Sequence[str],
    path: str | os.PathLike[str],
    footer: str | None = None,
) -> Path:
    """3-D RMSE per trajectory and arm: one bar (mean ± std across seeds) per group, and the
    study's values as markers.

    Args:
        summary: :func:`softtrack.report.summaries.metrics_summary` output.
        study: ``{marker label: {(trajectory, arm): value}}``.
    """
    title = "3-D RMSE per trajectory and arm"
    if summary.empty or "rmse_3d_mean" not in summary:
        return no_data_figure(path, title, "no stored evaluation metrics", footer)
    groups = list(dict.fromkeys(summary["group"]))
    slots = [(t, a) for t in trajectories for a in (0, 1)]
    x = np.arange(len(slots))
    width = 0.8 / max(1, len(groups))
    fig = _new(max(8.0, 1.3 * len(slots) + 2), 4.8)
    ax = fig.add_subplot()
    for i, group in enumerate(groups):
        part = summary[summary["group"] == group].set_index(["trajectory", "arm"])
        mean = [part["rmse_3d_mean"].get(s, np.nan) for s in slots]
        std = [part["rmse_3d_std"].get(s, np.nan) for s in slots]
        ax.bar(
            x - 0.4 + width * (i + 0.5),
            mean,
            width,
            yerr=np.nan_to_num(std),
            capsize=3,
            color=GROUP_COLORS[i % 10],
            alpha=0.8,
            label=group,
        )
    markers = ("k*", "kx", "k^", "ks")
    for j, (label, values) in enumerate(study.items()):
        ys = [values.get(s, np.nan) for s in slots]
        if np.isfinite(ys).any():
            ax.plot(x, ys, markers[j % len(markers)], ms=9, label=label)
    ax.set_xticks(x, [f"{_traj_title(t)}\narm {a + 1}" for t, a in slots], fontsize=9)
    ax.set_ylabel("3-D RMSE (m)")
    ax.set_title(f"{title} (bars: mean ± sample std across seeds)")
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return _save(fig, path, footer)


def validation_figure(
    scores: Mapping[tuple[str, int, int], pd.DataFrame],
    path: str | os.PathLike[str],
    footer: str | None = None,
) -> Path:
    """Validation score against env steps, one line per (group, seed, policy) with the selected
    checkpoint circled; colour by group, dashed for an independent run's arm-2 policy.

    Args:
        scores: (group label, seed, policy) → rows ``global_step``, ``score`` (m) of
            :func:`softtrack.report.summaries.validation_scores`; policy -1 is a centralized
            run's, 0/1 an independent run's arm.
    """
    if not scores:
        return no_data_figure(path, "Validation", "no selected run has validation episodes",
                              footer)
    fig = _new(9, 5.2)
    ax = fig.add_subplot()
    colors: dict[str, str] = {}
    labelled: set[tuple[str, int]] = set()
    for (group, _seed, policy), rows in scores.items():
        color = colors.setdefault(group, GROUP_COLORS[len(colors) % len(GROUP_COLORS)])
        finite = rows[np.isfinite(rows["score"])]
        label = None
        if (group, policy) not in labelled:
            labelled.add((group, policy))
            label = group if policy < 0 else f"{group}, arm {policy + 1} policy"
        ax.plot(finite["global_step"], finite["score"], "--" if policy == 1 else "-",
                color=color, lw=1.3, alpha=0.8, marker=".", label=label)
        if len(finite):
            best = finite.loc[finite["score"].idxmin()]
            ax.plot(best["global_step"], best["score"], "o", mfc="none", mec=color, ms=10)
    ax.set_xlabel("environment steps (of the policy)")
    ax.set_ylabel("validation 3-D RMSE (m)")
    ax.set_title("Validation: mean 3-D RMSE on held-out random-target episodes per checkpoint\n"
                 "(one line per seed; circled: the checkpoint kept as best)", fontsize=11)
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    return _save(fig, path, footer)
