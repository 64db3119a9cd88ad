"""Metrics of a transport episode (docs/environment.md, "Transport"): the study's tracking
metrics applied to the carried sphere, the drop, and the arms' hold on the sphere.

Pure NumPy. The names are ``eval_metrics`` columns, absent (NULL) for the other tasks.
"""

from __future__ import annotations

import numpy as np

__all__ = ["TRANSPORT_ARM_STATISTICS", "TRANSPORT_STATISTICS", "transport_statistics"]

#: Columns of the whole scene (the same in both arms' rows).
TRANSPORT_STATISTICS = (
    "object_rmse_3d",
    "object_rmse_x",
    "object_rmse_y",
    "object_rmse_z",
    "object_mae_x",
    "object_mae_y",
    "object_mae_z",
    "object_mean_spatial_error",
    "object_max_error",
    "dropped",
    "drop_time",
    "two_arm_contact",
)
#: Columns of each arm's row.
TRANSPORT_ARM_STATISTICS = ("object_contact", "object_force_mean", "object_force_max")


def transport_statistics(
    object_position: np.ndarray,
    goal: np.ndarray,
    force: np.ndarray,
    touching: np.ndarray,
    dropped: bool,
    t: np.ndarray,
) -> tuple[dict[str, float | bool], list[dict[str, float]]]:
    """The transport metrics of one episode.

    Args:
        object_position: (N, 3) the sphere's centre after each control step, m.
        goal: (N, 3) its goal at the same instants, m.
        force: (N, A) each arm's contact force on the sphere, mean over the control step, N.
        touching: (N, A) bool, each arm touched the sphere during the control step.
        dropped: the episode ended with a drop (its last step).
        t: (N,) time after each control step, s.

    Returns:
        (scene, arms): ``object_*`` = :func:`tracking_metrics` of the sphere against its goal
        (m), ``dropped``, ``drop_time`` (s; NaN without a drop) and ``two_arm_contact`` (the
        fraction of steps both arms touched the sphere); per arm ``object_contact`` (the
        fraction of steps it touched it) and ``object_force_mean``, ``object_force_max`` (N).
    """
    from softtrack.evaluation.metrics import tracking_metrics  # numba: not for its constants

    metrics = tracking_metrics(object_position, goal)
    scene: dict[str, float | bool] = {f"object_{key}": value for key, value in metrics.items()}
    scene["dropped"] = bool(dropped)
    scene["drop_time"] = float(t[-1]) if dropped and len(t) else float("nan")
    held = np.asarray(touching, dtype=bool)
    scene["two_arm_contact"] = float(held.all(axis=1).mean()) if len(held) else 0.0
    forces = np.asarray(force, dtype=np.float64)
    arms = [
        {
            "object_contact": float(held[:, arm].mean()) if len(held) else 0.0,
            "object_force_mean": float(forces[:, arm].mean()) if len(forces) else 0.0,
            "object_force_max": float(forces[:, arm].max()) if len(forces) else 0.0,
        }
        for arm in range(held.shape[1])
    ]
    return scene, arms
