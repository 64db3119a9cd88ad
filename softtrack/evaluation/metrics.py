"""Tracking-accuracy and actuation metrics of docs/environment.md: pure NumPy, no state.

With e(t) = tip(t) − target(t) of one arm over the N control steps of an episode:

* axis RMSE sqrt(mean_t e_a²) and axis MAE mean_t |e_a| for a ∈ {x, y, z};
* spatial error d(t) = ‖e(t)‖, its mean, its maximum, and the 3-D RMSE sqrt(mean_t d²);
* for the torques of one arm and direction: the spatial RMS over the elements at each step,
  and the largest absolute element torque over the episode;
* for the actions of one arm (clipped to [−1, 1] as the environment applies them): the
  fraction saturated (|a| ≥ 0.99), the mean absolute change per control step and the RMS —
  high saturation with large changes marks a "bang-bang" policy.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "ACTION_STATISTICS",
    "AXES",
    "SATURATION_THRESHOLD",
    "action_statistics",
    "moment_peak",
    "moment_rms",
    "tracking_errors",
    "tracking_metrics",
]

AXES = ("x", "y", "z")
#: Keys of :func:`action_statistics`, also the ``eval_metrics`` columns (absent in tables
#: written before they were added).
ACTION_STATISTICS = ("action_saturation", "action_change", "action_rms")
SATURATION_THRESHOLD = 0.99  # |a| at or above this counts as saturated


def tracking_errors(tip: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Error vectors e = tip − target: (N, 3) m from tip (N, 3) m and target (N, 3) m."""
    tip = np.asarray(tip, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    if tip.shape != target.shape or tip.ndim != 2 or tip.shape[1] != 3:
        raise ValueError(f"tip and target must both have shape (N, 3); got {tip.shape}, {target.shape}")
    if tip.shape[0] == 0:
        raise ValueError("at least one time step is needed")
    return tip - target


def tracking_metrics(tip: np.ndarray, target: np.ndarray) -> dict[str, float]:
    """All tracking metrics of one arm over one episode.

    Args:
        tip: (N, 3) tip positions, m.
        target: (N, 3) target centre positions at the same instants, m.

    Returns:
        ``rmse_x``, ``rmse_y``, ``rmse_z``, ``mae_x``, ``mae_y``, ``mae_z``,
        ``mean_spatial_error``, ``rmse_3d``, ``max_error`` — all in m.
    """
    e = tracking_errors(tip, target)
    d = np.sqrt(np.sum(e * e, axis=1))
    metrics: dict[str, float] = {}
    for i, axis in enumerate(AXES):
        metrics[f"rmse_{axis}"] = float(np.sqrt(np.mean(e[:, i] ** 2)))
    for i, axis in enumerate(AXES):
        metrics[f"mae_{axis}"] = float(np.mean(np.abs(e[:, i])))
    metrics["mean_spatial_error"] = float(np.mean(d))
    metrics["rmse_3d"] = float(np.sqrt(np.mean(d * d)))
    metrics["max_error"] = float(np.max(d))
    return metrics


def moment_rms(element_torques: np.ndarray) -> np.ndarray:
    """Spatial RMS over the elements: (..., n_elem) N·m → (...) N·m."""
    torques = np.asarray(element_torques, dtype=np.float64)
    return np.sqrt(np.mean(torques * torques, axis=-1))


def moment_peak(element_torques: np.ndarray) -> np.ndarray:
    """Largest absolute torque over steps and elements: (N, ..., n_elem) N·m → (...) N·m."""
    torques = np.abs(np.asarray(element_torques, dtype=np.float64))
    return torques.max(axis=(0, -1))


def action_statistics(actions: np.ndarray) -> dict[str, float]:
    """How hard and how jerkily one arm is driven over one episode.

    The actions are clipped to [−1, 1] first, as the environment applies them.

    Args:
        actions: (N, M) one arm's actions at the N control steps, N ≥ 1 (M = 12 for an arm:
            6 normal, then 6 binormal control points), before clipping.

    Returns:
        ``action_saturation``: fraction of the N·M values with |a| ≥ 0.99 (0..1);
        ``action_change``: mean over steps k ≥ 1 and the M values of |a_k − a_{k−1}| (0..2;
        0 when N = 1);
        ``action_rms``: sqrt(mean a²) over the N·M values (0..1).
    """
    a = np.asarray(actions, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] == 0:
        raise ValueError(f"actions must have shape (N, M) with M ≥ 1; got {a.shape}")
    if a.shape[0] == 0:
        raise ValueError("at least one time step is needed")
    a = np.clip(a, -1.0, 1.0)
    change = float(np.mean(np.abs(np.diff(a, axis=0)))) if a.shape[0] > 1 else 0.0
    return {
        "action_saturation": float(np.mean(np.abs(a) >= SATURATION_THRESHOLD)),
        "action_change": change,
        "action_rms": float(np.sqrt(np.mean(a * a))),
    }
