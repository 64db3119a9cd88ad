"""Tracking-accuracy and actuation metrics of SPEC §5: pure NumPy, no state.

With e(t) = tip(t) − target(t) of one arm over the N control steps of an episode:

* axis RMSE sqrt(mean_t e_a²) and axis MAE mean_t |e_a| for a ∈ {x, y, z};
* spatial error d(t) = ‖e(t)‖, its mean, its maximum, and the 3-D RMSE sqrt(mean_t d²);
* for the torques of one arm and direction: the spatial RMS over the elements at each step,
  and the largest absolute element torque over the episode.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "AXES",
    "moment_peak",
    "moment_rms",
    "tracking_errors",
    "tracking_metrics",
]

AXES = ("x", "y", "z")


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
