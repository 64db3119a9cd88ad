"""The files of ``softtrack workspace --out``: the held region, the floors and the figure of a
measured workspace (:mod:`softtrack.evaluation.workspace`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from softtrack.env.settings import TrackingConfig
from softtrack.store.atomic import atomic_write_text
from softtrack.store.tables import write_table

if TYPE_CHECKING:
    from softtrack.evaluation.workspace import WorkspaceResult

__all__ = ["write_workspace_files"]


def write_workspace_files(
    out: Path, name: str, config: TrackingConfig, results: Sequence[WorkspaceResult], seed: int
) -> None:
    """Write ``softtrack workspace --out``'s files into ``out`` (created): ``held.parquet``
    (every held rest position, m, with its torque per control unit), ``floors.csv`` (each
    path's floor, m, per scale), ``boundary.csv`` (the held region per height) and
    ``workspace.png`` (:func:`~softtrack.report.workspace_figure.workspace_figure`); ``name``
    titles the figure, ``seed`` (of the search) is in its caption."""
    # matplotlib: loaded when the files are written, not with the API
    from softtrack.report.workspace_figure import workspace_figure

    out.mkdir(parents=True, exist_ok=True)
    held = pd.concat(
        [
            pd.DataFrame(r.held, columns=["x", "y", "z"]).assign(torque_scale=r.torque_scale)
            for r in results
        ],
        ignore_index=True,
    )
    write_table(out / "held.parquet", held)
    floors = pd.concat([r.floors.assign(torque_scale=r.torque_scale) for r in results])
    atomic_write_text(out / "floors.csv", floors.to_csv(index=False))
    boundary = pd.concat([r.boundary.assign(torque_scale=r.torque_scale) for r in results])
    atomic_write_text(out / "boundary.csv", boundary.to_csv(index=False))
    workspace_figure(
        config,
        results,
        out / "workspace.png",
        f"Where two arms can hold the sphere: {name}",
        f"softtrack workspace, search seed {seed}",
    )
