"""Rewrite the evaluation tables of runs made by earlier versions in the current format.

Earlier versions stored every element torque at every step in ``eval_moments`` (about 7 MB a
run) and positions as float64 in ``eval_trajectories``. The current format (see
:mod:`softtrack.evaluation.run_evaluation`) keeps the summaries of docs/environment.md by default:

* ``eval_moments``: the per-step spatial RMS per arm and direction, float32;
* ``eval_moment_peaks``: each element's largest absolute torque over the episode;
* ``eval_trajectories``: positions as float32;
* ``eval_metrics``: the ``peak_moment`` column (the arm's largest absolute element torque over
  the episode), where it predates that column, from ``eval_moment_peaks``. The other torque
  and clearance columns need the episode again (``softtrack evaluate``).

The conversion reads only the stored tables (no episode is run again), so the summaries equal
those a fresh evaluation of the same episodes stores. Each table is replaced atomically; a
run already in the current format is left untouched.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from softtrack.store.tables import element_peaks_frame, read_table, write_table

__all__ = ["upgrade_run_tables"]

_OLD_MOMENT_COLUMNS = ("max_abs_moment", "element_torques")
_POSITION_COLUMNS = tuple(f"{kind}_{axis}" for kind in ("tip", "target") for axis in "xyz")


def upgrade_run_tables(
    run_dir: str | os.PathLike[str], keep_full_moments: bool = False
) -> list[str]:
    """Rewrite ``run_dir``'s evaluation tables in the current format (module docstring).

    Args:
        run_dir: a run directory (``tables/`` inside it).
        keep_full_moments: keep the old per-element torque history as
            ``eval_element_moments`` (what ``softtrack evaluate --full-moments`` stores).

    Returns:
        The names of the tables written, in writing order (empty if none needed it).
    """
    tables = Path(run_dir) / "tables"
    written = []
    moments_path = tables / "eval_moments.parquet"
    if moments_path.is_file():
        old = read_table(moments_path)
        if "element_torques" in old.columns:
            written += _split_moments(tables, old, keep_full_moments)
    trajectories_path = tables / "eval_trajectories.parquet"
    if trajectories_path.is_file():
        frame = read_table(trajectories_path)
        if any(frame[c].dtype != np.float32 for c in _POSITION_COLUMNS if c in frame.columns):
            write_table(trajectories_path, _narrow(frame, _POSITION_COLUMNS))
            written.append("eval_trajectories")
    if _add_peak_moment(tables):
        written.append("eval_metrics")
    return written


def _add_peak_moment(tables: Path) -> bool:
    """Add ``peak_moment`` (N·m) to an ``eval_metrics`` without it, per trajectory and arm the
    maximum of ``eval_moment_peaks`` over elements and directions; False when there is nothing
    to add (column present, a table missing, or a trajectory or arm without peaks)."""
    metrics_path = tables / "eval_metrics.parquet"
    peaks_path = tables / "eval_moment_peaks.parquet"
    if not (metrics_path.is_file() and peaks_path.is_file()):
        return False
    metrics = read_table(metrics_path)
    if "peak_moment" in metrics.columns:
        return False
    peaks = read_table(peaks_path)
    peak = peaks.groupby(["trajectory", "arm"])["peak_abs_moment"].max()
    keys = list(zip(metrics["trajectory"].astype(str), metrics["arm"].astype(int), strict=True))
    if not all(key in peak.index for key in keys):
        return False
    metrics["peak_moment"] = [float(peak[key]) for key in keys]
    write_table(metrics_path, metrics)
    return True


def _split_moments(tables: Path, old: pd.DataFrame, keep_full: bool) -> list[str]:
    """Peaks per element from the stored element torques, then the per-step RMS table."""
    peaks = []
    for (run_id, trajectory), rows in old.groupby(["run_id", "trajectory"], sort=False):
        n_arms, n_dirs = int(rows["arm"].max()) + 1, int(rows["direction"].max()) + 1
        torques = np.stack(rows["element_torques"].to_numpy()).astype(np.float32)
        index = rows["arm"].to_numpy() * n_dirs + rows["direction"].to_numpy()
        per_channel = np.zeros((n_arms * n_dirs, torques.shape[1]), dtype=np.float32)
        np.maximum.at(per_channel, index, np.abs(torques))
        peaks.append(
            element_peaks_frame(
                str(run_id), str(trajectory), per_channel.reshape(n_arms, n_dirs, -1)
            )
        )
    written = []
    if keep_full:
        full = old.drop(columns=[c for c in ("rms_moment", "max_abs_moment") if c in old.columns])
        write_table(tables / "eval_element_moments.parquet", _narrow(full, ()))
        written.append("eval_element_moments")
    write_table(tables / "eval_moment_peaks.parquet", pd.concat(peaks, ignore_index=True))
    summary = old.drop(columns=[c for c in _OLD_MOMENT_COLUMNS if c in old.columns])
    write_table(tables / "eval_moments.parquet", _narrow(summary, ("rms_moment",)))
    return [*written, "eval_moment_peaks", "eval_moments"]


def _narrow(frame: pd.DataFrame, float_columns: tuple[str, ...]) -> pd.DataFrame:
    """``float_columns`` as float32 and the integer index columns as int32, as fresh tables
    store them."""
    frame = frame.copy()
    for column in float_columns:
        if column in frame.columns:
            frame[column] = frame[column].astype(np.float32)
    for column in ("step", "arm", "direction", "element"):
        if column in frame.columns:
            frame[column] = frame[column].astype(np.int32)
    return frame
