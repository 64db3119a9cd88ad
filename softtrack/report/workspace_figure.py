"""The transport workspace's figure: where the sphere can be held, the paths, their floors."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from softtrack.env.settings import TrackingConfig
from softtrack.evaluation.workspace import WorkspaceResult, path_points
from softtrack.report.figures import new_figure, save_figure, suptitle

__all__ = ["workspace_figure"]

_PATH_COLOURS = {"circle": "tab:blue", "rectangle": "tab:orange", "figure8": "tab:green"}


def workspace_figure(
    config: TrackingConfig,
    results: Sequence[WorkspaceResult],
    path: str | os.PathLike[str],
    title: str,
    footer: str | None = None,
) -> Path:
    """Two views per actuation scale (a row each): from above (x–z) and from the side (x–y),
    the held rest positions (dots, coloured by height), the arms' bases, the sphere's start
    and each path with its floor in the legend. Returns the PNG's path."""
    fig = new_figure(11.0, 4.6 * len(results) + 0.8)
    rows = fig.subfigures(len(results), 1, squeeze=False)[:, 0]
    heights = np.concatenate([r.held[:, 1] for r in results if len(r.held)] or [np.zeros(1)])
    for row, result in zip(rows, results, strict=True):
        top, side = row.subplots(1, 2)
        held = result.held
        floors = dict(zip(result.floors["path"], result.floors["floor"], strict=True))
        row.suptitle(
            f"{result.torque_scale:g} N·m per control unit: {len(held):,} of "
            f"{result.samples:,} samples held the sphere at rest",
            fontsize=10,
        )
        scatter = None
        for ax, (a, b), names in (
            (top, (0, 2), ("x (m)", "z (m)")),
            (side, (0, 1), ("x (m)", "y (m)")),
        ):
            if len(held):
                scatter = ax.scatter(
                    held[:, a],
                    held[:, b],
                    c=held[:, 1],
                    s=6,
                    cmap="viridis",
                    vmin=float(heights.min()),
                    vmax=float(heights.max()),
                    alpha=0.7,
                    lw=0,
                )
            for name in result.floors["path"]:
                points = path_points(config, name, 400)
                closed = np.vstack([points, points[:1]])
                ax.plot(
                    closed[:, a],
                    closed[:, b],
                    "--",
                    color=_PATH_COLOURS.get(name, "grey"),
                    lw=1.2,
                    label=f"{name}: floor {floors[name]:.3f} m",
                )
            assert config.sim.sphere is not None
            start = np.asarray(config.sim.sphere.center)
            ax.plot(start[a], start[b], "k+", ms=10, mew=2, label="sphere's start")
            bases = np.asarray(config.sim.base_positions)
            ax.plot(bases[:, a], bases[:, b], "ks", ms=5, label="arm bases")
            ax.set_xlabel(names[0])
            ax.set_ylabel(names[1])
            ax.set_aspect("equal", adjustable="datalim")
            ax.grid(alpha=0.3)
        top.set_title("from above", fontsize=9)
        side.set_title("from the side (the arms grow along +y)", fontsize=9)
        side.legend(fontsize=7, loc="lower right")
        if scatter is not None:
            row.colorbar(scatter, ax=[top, side], shrink=0.8, label="held at height y (m)")
    suptitle(fig, title, 12)
    return save_figure(fig, path, footer)
