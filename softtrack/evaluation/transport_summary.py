"""The one-line summary of a transport run over random-target episodes: the sphere's error,
the carried rate with its interval, how long and how firmly the sphere was held."""

from __future__ import annotations

import pandas as pd

from softtrack.evaluation.statistics import wilson_interval

__all__ = ["carried_summary"]


def carried_summary(rows: pd.DataFrame) -> str:
    """Transport over random-target episodes: the sphere's mean error, the *carried rate*
    (episodes carried to the end without a drop, with its 95 % Wilson interval), the mean time
    it was held before a drop or the end, the share of steps both arms touched it and the mean
    squeeze per arm: the line ``softtrack evaluate --random`` prints for a transport run.

    Args:
        rows: ``eval_random`` rows of one run (both arms' rows of each episode), with the
            transport columns (``dropped``, ``duration`` s, ``object_rmse_3d`` m,
            ``two_arm_contact``, ``object_force_mean`` N).
    """
    episodes = rows.drop_duplicates("episode")
    n = len(episodes)
    dropped = episodes["dropped"].astype(bool)
    carried = n - int(dropped.sum())
    low, high = wilson_interval(carried, n)
    held = episodes["duration"].astype(float)  # a dropped episode ends at its drop
    squeeze = rows.groupby("arm")["object_force_mean"].mean()
    return (
        f"sphere 3-D RMSE {episodes['object_rmse_3d'].mean():.4f} m (mean over {n} episode"
        f"{'s' if n != 1 else ''}); carried {carried} of {n} ({carried / n:.0%}, 95 % "
        f"[{low:.0%}, {high:.0%}]); held {held.mean():.1f} s on average (episodes of {held.max():.1f} s), "
        f"by both arms {episodes['two_arm_contact'].mean():.0%} of the steps; "
        "squeeze " + " / ".join(f"{v:.1f}" for v in squeeze) + " N (arm 1 / arm 2)"
    )
