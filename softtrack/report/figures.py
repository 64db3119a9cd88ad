"""Report figures: matplotlib ``Figure`` objects rendered with the Agg canvas to PNG.

No pyplot state is touched (the figures are built with :class:`matplotlib.figure.Figure`),
so the module is safe in any process. Every function takes already-loaded table data, writes
one PNG atomically at :data:`DPI`, and returns its path; where the data is missing it draws a
figure that says so (:func:`no_data_figure`) instead of failing. Units: m, s, N·m, env steps.

The trajectory and error figures take one row per controller (:class:`PathRow`), so a report
can put a few chosen controllers side by side in one figure per trajectory.
"""

from __future__ import annotations

import math
import os
import textwrap
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.layout_engine import ConstrainedLayoutEngine
from matplotlib.ticker import MaxNLocator

from softtrack.report.curves import Curve, Smoothing
from softtrack.report.data import DIRECTIONS
from softtrack.report.reference import TRAJECTORY_TITLES
from softtrack.store.atomic import atomic_path

__all__ = [
    "DPI",
    "PathRow",
    "final_returns_figure",
    "moments_figure",
    "no_data_figure",
    "rmse_comparison_figure",
    "robustness_figure",
    "tracking_errors_figure",
    "training_curves_figure",
    "trajectory_3d_figure",
    "validation_figure",
]

DPI = 110  # a 12-inch-wide figure is 1,320 px: sharp in a browser, ~4x smaller than 150 dpi
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


def _wrap(text: str, width_in: float, fontsize: float) -> str:
    """``text`` wrapped to ``width_in`` inches at ``fontsize`` points (without breaking run
    names at their hyphens)."""
    chars = max(30, int(width_in * 72 / (0.56 * fontsize)))
    return "\n".join(textwrap.wrap(text, width=chars, break_on_hyphens=False))


def _suptitle(fig: Figure, title: str, fontsize: float, subtitle: str = "") -> None:
    """A short one-line ``title`` and, below it, ``subtitle`` wrapped to the figure's width."""
    width = fig.get_size_inches()[0]
    text = title if not subtitle else f"{title}\n{_wrap(subtitle, width, fontsize - 1)}"
    fig.suptitle(text, fontsize=fontsize, linespacing=1.35)


def _save(fig: Figure, path: str | os.PathLike[str], footer: str | None) -> Path:
    if footer:  # wrapped to the figure's width, below the axes
        width, height = fig.get_size_inches()
        lines = textwrap.wrap(footer, width=max(40, int(width * 17)))
        bottom = (0.14 * len(lines) + 0.06) / height
        engine = fig.get_layout_engine()
        assert isinstance(engine, ConstrainedLayoutEngine)  # made by _new
        engine.set(rect=(0, bottom, 1, 1 - bottom))
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


def _palette(n: int) -> Sequence[object]:
    """:data:`GROUP_COLORS`, or the 20 colours of ``tab20`` for more than 10 groups."""
    if n <= len(GROUP_COLORS):
        return GROUP_COLORS
    from matplotlib import colormaps

    tab20 = colormaps["tab20"]
    assert isinstance(tab20, ListedColormap)
    # a tuple of RGB tuples; the stubs type ``colors`` as any ArrayLike or colour
    return list(cast(Sequence[object], tab20.colors))


def _steps_axis(ax: Axes) -> None:
    ax.set_xlabel("environment steps")
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
    ax.grid(alpha=0.3)


def training_curves_figure(
    curves: Sequence[Curve],
    smoothing: Smoothing,
    path: str | os.PathLike[str],
    footer: str | None = None,
) -> Path:
    """Episode return against env steps: mean ± 1 sample std across seeds, one curve per
    algorithm (per arm policy for independent controllers), each smoothed over a window
    proportional to its group's training length. Returns are per second of episode when the
    groups' episodes differ in length (:attr:`Smoothing.per_second`); groups whose training
    lengths differ more than tenfold get their own panels (own x axis, shared y axis)."""
    if not curves:
        return no_data_figure(
            path, "Training curves", "no selected run has training episodes", footer
        )
    groups = list(dict.fromkeys(c.group.label for c in curves))
    length = {g: max(float(c.steps[-1]) for c in curves if c.group.label == g) for g in groups}
    split = max(length.values()) > 10 * min(length.values())
    panels = [[c for c in curves if c.group.label == g] for g in groups] if split else [curves]
    ncols = min(3, len(panels))
    nrows = math.ceil(len(panels) / ncols)
    many = not split and len(curves) > 8  # the legend goes beside the axes
    width = 9 if ncols == 1 else 5.2 * ncols
    fig = _new(
        width + (4.5 if many else 0),
        max(5.2, 0.22 * len(curves) + 1.5) if many else 5.2 if nrows == 1 else 4.0 * nrows + 1.2,
    )
    axes = fig.subplots(nrows, ncols, squeeze=False, sharey=True).ravel()
    palette = _palette(len(groups))
    colors = {g: palette[i % len(palette)] for i, g in enumerate(groups)}
    for ax, panel in zip(axes, panels, strict=False):
        for curve in panel:
            color = colors[curve.group.label]
            style = "-" if curve.arm in (None, 0) else "--"
            seeds = f"{curve.n_runs} seed{'s' if curve.n_runs != 1 else ''}"
            if curve.per_second:
                seeds += f", {curve.episode_seconds:g}-s episodes"
            ax.plot(
                curve.steps,
                curve.mean,
                style,
                color=color,
                lw=1.8,
                label=f"{curve.label} ({seeds})",
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
        _steps_axis(ax)
        if many:
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
        else:
            ax.legend(loc="best", fontsize=8 if split else 9)
    for ax in axes[len(panels) :]:
        ax.set_axis_off()
    if smoothing.per_second:
        ylabel = "return per second (episode return / episode duration, 1/s)"
    else:
        seconds = sorted({c.episode_seconds for c in curves})
        ylabel = f"episode return ({', '.join(f'{s:g}' for s in seconds)}-s episodes, –)"
    for ax in axes[::ncols]:
        ax.set_ylabel(ylabel)
    windows = sorted({c.window for c in curves})
    span = (
        f"{windows[0]:,.0f} env steps"
        if len(windows) == 1
        else f"{windows[0]:,.0f}–{windows[-1]:,.0f} env steps"
    )
    _suptitle(
        fig,
        "Training curves: mean ± 1 sample std across seeds",
        12,
        f"smoothing: centred window of {smoothing.window_fraction:.0%} of each group's steps "
        f"({span})" + ("; own x axis per group" if split else ""),
    )
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
    ax.set_title(
        "Final-stage return: mean episode return at the end of training (docs/environment.md)"
    )
    ax.axhline(0, color="0.5", lw=0.8)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path, footer)


def _arm_frame(traj: pd.DataFrame, arm: int) -> pd.DataFrame:
    return traj[traj["arm"] == arm].sort_values("step")


@dataclass(frozen=True)
class PathRow:
    """One controller's row of :func:`trajectory_3d_figure` / :func:`tracking_errors_figure`.

    Attributes:
        title: the controller, e.g. ``TD3 [td3-sbx-1e7] (study protocol)``.
        traj: its ``eval_trajectories`` rows of one run and trajectory (``None``: no data).
        caption: which run, e.g. ``seed 0, run td3-sbx-1e7-seed0 (median 3-D RMSE of 3 seeds)``.
        rmse: the stored 3-D RMSE per arm (m), for the legend.
    """

    title: str
    traj: pd.DataFrame | None
    caption: str = ""
    rmse: Mapping[int, float] = field(default_factory=dict)

    @property
    def has_data(self) -> bool:
        return self.traj is not None and not self.traj.empty


def _row_figures(fig: Figure, rows: Sequence[PathRow]) -> list[Figure]:
    """One subfigure per row, titled with the row's controller and run."""
    subs = fig.subfigures(len(rows), 1, squeeze=False, hspace=0.02).ravel()
    width = fig.get_size_inches()[0]
    for sub, row in zip(subs, rows, strict=True):
        text = f"{row.title}: {row.caption}" if row.caption else row.title
        sub.suptitle(_wrap(text, width, 10), fontsize=10, x=0.01, ha="left")
    return list(subs)


def _no_row_data(sub: Figure, what: str) -> None:
    ax = sub.add_subplot()
    ax.set_axis_off()
    ax.text(
        0.5,
        0.5,
        f"no data: {what}",
        ha="center",
        va="center",
        color="tab:red",
        fontsize=11,
        transform=ax.transAxes,
    )


def _path_panels(sub: Figure, row: PathRow) -> None:
    """The 3-D path (y up) and the view from above (x–z) of one row."""
    traj = row.traj
    assert traj is not None
    grid = sub.add_gridspec(1, 2, width_ratios=(1.1, 1.0), wspace=0.15)
    ax3 = sub.add_subplot(grid[0, 0], projection="3d")
    ax2 = sub.add_subplot(grid[0, 1])
    target = _arm_frame(traj, int(traj["arm"].min()))
    ax3.plot(
        target["target_x"], target["target_z"], target["target_y"], "k--", lw=1.3, label="target"
    )
    ax2.plot(target["target_x"], target["target_z"], "k--", lw=1.3, label="target")
    for arm in sorted(int(a) for a in traj["arm"].unique()):
        df = _arm_frame(traj, arm)
        color = ARM_COLORS[arm % 2]
        label = f"arm {arm + 1} tip"
        if arm in row.rmse and np.isfinite(row.rmse[arm]):
            label += f" (3-D RMSE {row.rmse[arm]:.3f} m)"
        ax3.plot(df["tip_x"], df["tip_z"], df["tip_y"], color=color, lw=1.0)
        ax3.scatter(
            df["tip_x"].iloc[:1],
            df["tip_z"].iloc[:1],
            df["tip_y"].iloc[:1],
            color=color,
            marker="o",
            s=20,
        )
        ax2.plot(df["tip_x"], df["tip_z"], color=color, lw=1.0, label=label)
        ax2.plot(df["tip_x"].iloc[:1], df["tip_z"].iloc[:1], "o", color=color, ms=4)
    for axis in (ax3.xaxis, ax3.yaxis, ax3.zaxis):
        axis.set_major_locator(MaxNLocator(4))
    ax3.tick_params(labelsize=7, pad=0)
    ax3.set_xlabel("x (m)", fontsize=8, labelpad=-2)
    ax3.set_ylabel("z (m)", fontsize=8, labelpad=-2)
    ax3.set_zlabel("y (m)", fontsize=8, labelpad=-4)
    ax3.set_box_aspect(None, zoom=0.95)  # room inside the axes for the tick and axis labels
    ax3.set_title("3-D view (y up)", fontsize=9, pad=0)
    ax2.set_xlabel("x (m)", fontsize=9)
    ax2.set_ylabel("z (m)", fontsize=9)
    ax2.tick_params(labelsize=8)
    ax2.xaxis.set_major_locator(MaxNLocator(6))
    ax2.set_aspect("equal", adjustable="datalim")
    ax2.set_title("seen from above (x–z plane)", fontsize=9)
    ax2.grid(alpha=0.3)
    ax2.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8, frameon=False)


def trajectory_3d_figure(
    rows: Sequence[PathRow],
    trajectory: str,
    path: str | os.PathLike[str],
    *,
    footer: str | None = None,
) -> Path:
    """Per row (one controller's run): the 3-D path of the target and both tips (y up) and the
    view from above (x–z plane); dots mark the start."""
    return _per_row_figure(
        rows,
        path,
        f"{_traj_title(trajectory)}: target and tip paths",
        "dashed: target; dots: start of each tip",
        (11, 4.3),
        _path_panels,
        footer,
    )


def _per_row_figure(
    rows: Sequence[PathRow],
    path: str | os.PathLike[str],
    title: str,
    subtitle: str,
    size: tuple[float, float],
    draw: Callable[[Figure, PathRow], None],
    footer: str | None,
) -> Path:
    """One sub-figure per row drawn by ``draw`` (width, height per row in inches), or a
    no-data figure when no row has a stored trajectory."""
    if not any(r.has_data for r in rows):
        names = ", ".join(r.title for r in rows)
        return no_data_figure(path, title, f"no stored evaluation trajectory ({names})", footer)
    fig = _new(size[0], size[1] * len(rows) + 0.7)
    for sub, row in zip(_row_figures(fig, rows), rows, strict=True):
        if row.has_data:
            draw(sub, row)
        else:
            _no_row_data(sub, "no stored evaluation trajectory")
    _suptitle(fig, title, 13, subtitle)
    return _save(fig, path, footer)


def _error_panels(sub: Figure, row: PathRow) -> None:
    """Per-axis error tip − target of each arm, and both arms' spatial error, against time."""
    traj = row.traj
    assert traj is not None
    arms = sorted(int(a) for a in traj["arm"].unique())
    axes = sub.subplots(1, len(arms) + 1, sharex=True)
    top = 0.0
    for i, arm in enumerate(arms):
        df = _arm_frame(traj, arm)
        t = df["t"].to_numpy(float)
        e = {a: df[f"tip_{a}"].to_numpy(float) - df[f"target_{a}"].to_numpy(float) for a in "xyz"}
        d = np.sqrt(e["x"] ** 2 + e["y"] ** 2 + e["z"] ** 2)
        ax = axes[i]
        for a in "xyz":
            ax.plot(t, e[a], color=AXIS_COLORS[a], lw=0.9, label=f"e_{a}")
        ax.axhline(0, color="0.5", lw=0.8)
        low = min(0.0, *(float(np.min(v)) for v in e.values())) if t.size else -1.0
        high = max(0.0, *(float(np.max(v)) for v in e.values())) if t.size else 1.0
        span = max(high - low, 1e-3)
        ax.set_ylim(low - 0.05 * span, high + 0.3 * span)  # headroom for the legend
        ax.set_ylabel("error tip − target (m)", fontsize=9)
        ax.set_title(f"arm {arm + 1}: per-axis error", fontsize=9)
        ax.legend(loc="upper right", fontsize=7, ncol=3)
        ax = axes[-1]
        rmse = float(np.sqrt(np.mean(d**2))) if d.size else np.nan
        ax.plot(
            t, d, color=ARM_COLORS[arm % 2], lw=1.0, label=f"arm {arm + 1}: 3-D RMSE {rmse:.3f} m"
        )
        ax.axhline(float(np.mean(d)) if d.size else 0.0, color=ARM_COLORS[arm % 2], ls=":", lw=1)
        top = max(top, float(np.max(d)) if d.size else 0.0)
    ax = axes[-1]
    ax.set_ylim(0, 1.35 * top if top > 0 else 1.0)
    ax.set_ylabel("spatial error ‖tip − target‖ (m)", fontsize=9)
    ax.set_title("spatial error (dotted: its mean)", fontsize=9)
    ax.legend(loc="upper right", fontsize=7)
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=8)
        ax.set_xlabel("time (s)", fontsize=9)
        if ax.get_xlim()[1] > STEADY_START:
            ax.axvline(STEADY_START, color="0.6", ls=":", lw=1)


def tracking_errors_figure(
    rows: Sequence[PathRow],
    trajectory: str,
    path: str | os.PathLike[str],
    *,
    footer: str | None = None,
) -> Path:
    """Per row (one controller's run): each arm's per-axis error tip − target, and both arms'
    spatial error ‖tip − target‖, against time."""
    return _per_row_figure(
        rows,
        path,
        f"{_traj_title(trajectory)}: tracking error against time",
        f"grey dotted line: t = {STEADY_START:g} s, start of the steady metrics",
        (13, 3.1),
        _error_panels,
        footer,
    )


def moments_figure(
    moments: Mapping[str, pd.DataFrame | None],
    path: str | os.PathLike[str],
    *,
    title: str = "Actuation moments",
    subtitles: Mapping[str, str] | None = None,
    peaks: Mapping[str, pd.DataFrame | None] | None = None,
    footer: str | None = None,
) -> Path:
    """Spatial-RMS element moment against time per trajectory (rows), arm (columns) and
    direction (lines), with each line's peak absolute element moment in the legend.

    Args:
        moments: ``eval_moments`` rows of one run per trajectory (``None`` where missing).
        peaks: that run's episode peaks per trajectory (:attr:`RunData.peaks` rows: arm,
            direction, peak_abs_moment); a line without one shows no peak.
    """
    if not any(df is not None and not df.empty for df in moments.values()):
        return no_data_figure(path, title, "no stored evaluation moments", footer)
    trajectories = list(moments)
    fig = _new(12, 2.6 * len(trajectories) + 1.0)
    axes = fig.subplots(len(trajectories), 2, sharex=True, squeeze=False)
    for row, trajectory in enumerate(trajectories):
        df = moments[trajectory]
        peak_rows = (peaks or {}).get(trajectory)
        for arm in (0, 1):
            ax = axes[row, arm]
            name = f"{_traj_title(trajectory)}, arm {arm + 1}"
            if subtitles and subtitles.get(trajectory):
                name += f" ({subtitles[trajectory]})"
            ax.set_title(name, fontsize=10)
            ax.grid(alpha=0.3)
            ax.set_ylabel("RMS moment (N·m)", fontsize=9)
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
            for direction, style in ((0, "-"), (1, "--")):  # binormal darker, behind
                sub = part[part["direction"] == direction].sort_values("step")
                if sub.empty:
                    continue
                top = max(top, float(sub["rms_moment"].max()))
                label = DIRECTIONS[direction]
                if peak_rows is not None:
                    found = peak_rows[
                        (peak_rows["arm"] == arm) & (peak_rows["direction"] == direction)
                    ]
                    if len(found):
                        label += f" (peak element {float(found['peak_abs_moment'].max()):.1f} N·m)"
                ax.plot(
                    sub["t"],
                    sub["rms_moment"],
                    style,
                    color=ARM_COLORS[arm] if direction == 0 else "0.25",
                    lw=1.0,
                    alpha=1.0 if direction == 0 else 0.75,
                    zorder=3 - direction,
                    label=label,
                )
            ax.set_ylim(0, 1.35 * top if top > 0 else 1.0)  # room for the legend
            ax.legend(loc="upper right", fontsize=8, ncol=2)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    _suptitle(fig, title, 12, "spatial RMS over the 20 elements against time")
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
        return no_data_figure(path, "Validation", "no selected run has validation episodes", footer)
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
        ax.plot(
            finite["global_step"],
            finite["score"],
            "--" if policy == 1 else "-",
            color=color,
            lw=1.3,
            alpha=0.8,
            marker=".",
            label=label,
        )
        if len(finite):
            best = finite.loc[finite["score"].idxmin()]
            ax.plot(best["global_step"], best["score"], "o", mfc="none", mec=color, ms=10)
    ax.set_xlabel("environment steps (of the policy)")
    ax.set_ylabel("validation 3-D RMSE (m)")
    ax.set_title(
        "Validation: mean 3-D RMSE on held-out random-target episodes per checkpoint\n"
        "(one line per seed; circled: the checkpoint kept as best)",
        fontsize=11,
    )
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=9)
    return _save(fig, path, footer)


def robustness_figure(
    summary: pd.DataFrame, path: str | os.PathLike[str], footer: str | None = None
) -> Path:
    """3-D RMSE against level, one panel per one-factor perturbation with at least two
    levels; one line per group (seed mean) with its min–max band across seeds.

    Args:
        summary: rows of :func:`softtrack.report.robustness.robustness_summary` with a
            numeric ``level``.
    """
    counts = summary.groupby("perturbation")["level"].nunique()
    factors = [f for f in dict.fromkeys(summary["perturbation"]) if counts[f] >= 2]
    if not factors:
        return no_data_figure(path, "Robustness", "no perturbation with two levels", footer)
    cols = min(3, len(factors))
    n_rows = -(-len(factors) // cols)
    fig = _new(max(6.0, 4.2 * cols), 3.4 * n_rows + 0.8)
    groups = list(dict.fromkeys(summary["group"]))
    colors = _palette(len(groups))
    for i, factor in enumerate(factors):
        ax = fig.add_subplot(n_rows, cols, i + 1)
        for j, group in enumerate(groups):
            part = summary[(summary["perturbation"] == factor) & (summary["group"] == group)]
            part = part.sort_values("level")
            if part.empty:
                continue
            color = colors[j % len(colors)]
            ax.plot(part["level"], part["rmse_3d_mean"], "-o", ms=4, color=color, label=group)
            ax.fill_between(
                part["level"],
                part["rmse_3d_min"],
                part["rmse_3d_max"],
                color=color,
                alpha=0.15,
                lw=0,
            )
        ax.set_xlabel(factor)
        ax.set_ylabel("3-D RMSE (m)")
        ax.grid(alpha=0.3)
    fig.axes[0].legend(loc="upper left", fontsize=8)
    _suptitle(
        fig,
        "Tracking error under perturbations",
        12,
        "mean over trajectories and arms; line: seed mean; band: min–max of seeds",
    )
    return _save(fig, path, footer)
