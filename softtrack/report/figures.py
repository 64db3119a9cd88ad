"""Report figures: matplotlib ``Figure`` objects rendered with the Agg canvas to PNG.

No pyplot state is touched (the figures are built with :class:`matplotlib.figure.Figure`),
so the module is safe in any process. Every function takes already-loaded table data, writes
one PNG atomically at :data:`DPI`, and returns its path; where the data is missing it draws a
figure that says so (:func:`no_data_figure`) instead of failing. Units: m, s, N·m, env steps.

The trajectory and error figures take one row per controller (:class:`PathRow`), so a report
can put a few chosen controllers side by side in one figure per trajectory.
"""

from __future__ import annotations

import os
import textwrap
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.layout_engine import ConstrainedLayoutEngine
from matplotlib.ticker import MaxNLocator

from softtrack.report.data import DIRECTIONS
from softtrack.report.reference import TRAJECTORY_TITLES
from softtrack.store.atomic import atomic_path

__all__ = [
    "DPI",
    "PathRow",
    "moments_figure",
    "new_figure",
    "no_data_figure",
    "save_figure",
    "steps_axis",
    "suptitle",
    "tracking_errors_figure",
    "trajectory_3d_figure",
    "trajectory_title",
]

DPI = 110  # a 12-inch-wide figure is 1,320 px: sharp in a browser, ~4x smaller than 150 dpi
ARM_COLORS = ("tab:blue", "tab:orange")
AXIS_COLORS = {"x": "tab:red", "y": "tab:green", "z": "tab:purple"}
STEADY_START = 1.0  # s, the start of the "steady" metrics


def new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _wrap(text: str, width_in: float, fontsize: float) -> str:
    """``text`` wrapped to ``width_in`` inches at ``fontsize`` points (without breaking run
    names at their hyphens)."""
    chars = max(30, int(width_in * 72 / (0.56 * fontsize)))
    return "\n".join(textwrap.wrap(text, width=chars, break_on_hyphens=False))


def suptitle(fig: Figure, title: str, fontsize: float, subtitle: str = "") -> None:
    """A short one-line ``title`` and, below it, ``subtitle`` wrapped to the figure's width."""
    width = fig.get_size_inches()[0]
    text = title if not subtitle else f"{title}\n{_wrap(subtitle, width, fontsize - 1)}"
    fig.suptitle(text, fontsize=fontsize, linespacing=1.35)


def save_figure(fig: Figure, path: str | os.PathLike[str], footer: str | None) -> Path:
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
    fig = new_figure(7, 3)
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
    return save_figure(fig, path, footer)


def trajectory_title(trajectory: str) -> str:
    return TRAJECTORY_TITLES.get(trajectory, trajectory)


def steps_axis(ax: Axes) -> None:
    ax.set_xlabel("environment steps")
    ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
    ax.grid(alpha=0.3)


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
        f"{trajectory_title(trajectory)}: target and tip paths",
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
    fig = new_figure(size[0], size[1] * len(rows) + 0.7)
    for sub, row in zip(_row_figures(fig, rows), rows, strict=True):
        if row.has_data:
            draw(sub, row)
        else:
            _no_row_data(sub, "no stored evaluation trajectory")
    suptitle(fig, title, 13, subtitle)
    return save_figure(fig, path, footer)


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
        f"{trajectory_title(trajectory)}: tracking error against time",
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
    fig = new_figure(12, 2.6 * len(trajectories) + 1.0)
    axes = fig.subplots(len(trajectories), 2, sharex=True, squeeze=False)
    for row, trajectory in enumerate(trajectories):
        df = moments[trajectory]
        peak_rows = (peaks or {}).get(trajectory)
        for arm in (0, 1):
            ax = axes[row, arm]
            name = f"{trajectory_title(trajectory)}, arm {arm + 1}"
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
    suptitle(fig, title, 12, "spatial RMS over the 20 elements against time")
    return save_figure(fig, path, footer)
