"""Tracking-accuracy and actuation metrics of docs/environment.md: pure NumPy, no state.

With e(t) = tip(t) − target(t) of one arm over the N control steps of an episode:

* axis RMSE sqrt(mean_t e_a²) and axis MAE mean_t |e_a| for a ∈ {x, y, z};
* spatial error d(t) = ‖e(t)‖, its mean, its maximum, and the 3-D RMSE sqrt(mean_t d²);
* for the torques of one arm and direction: the spatial RMS over the elements at each step,
  and the largest absolute element torque over the episode;
* for the actions of one arm (clipped to [−1, 1] as the environment applies them): the
  fraction saturated (|a| ≥ 0.99), the mean absolute change per control step and the RMS —
  high saturation with large changes marks a "bang-bang" policy;
* for the element torques of one arm: the RMS of their rate of change (N·m/s, smoothness) and
  their largest absolute value (N·m);
* for the two arms of a scene: the surface clearance (smallest node-to-node distance of their
  centrelines minus both radii, m) at each step, its minimum over the episode and the number
  of steps below the collision test's margin (inter-arm safety); the deepest overlap of
  their surfaces, the steps on which they touch and the contact force between them (contact).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

__all__ = [
    "ACTION_STATISTICS",
    "AXES",
    "CONTACT_STATISTICS",
    "SAFETY_STATISTICS",
    "SATURATION_THRESHOLD",
    "TORQUE_STATISTICS",
    "action_statistics",
    "arm_clearance",
    "contact_statistics",
    "moment_peak",
    "moment_rms",
    "safety_statistics",
    "torque_statistics",
    "tracking_errors",
    "tracking_metrics",
]

AXES = ("x", "y", "z")
#: Keys of :func:`action_statistics`, also the ``eval_metrics`` columns (absent in tables
#: written before they were added).
ACTION_STATISTICS = ("action_saturation", "action_change", "action_rms")
SATURATION_THRESHOLD = 0.99  # |a| at or above this counts as saturated
#: Keys of :func:`torque_statistics` and :func:`safety_statistics`, also ``eval_metrics``
#: columns (absent in tables written before they were added).
TORQUE_STATISTICS = ("torque_rate_rms", "peak_moment")
SAFETY_STATISTICS = ("min_arm_distance", "collision_steps")
#: Keys of :func:`contact_statistics`, ``eval_metrics`` columns since contact was added.
CONTACT_STATISTICS = ("max_penetration", "contact_steps", "mean_contact_force", "max_contact_force")


def tracking_errors(tip: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Error vectors e = tip − target: (N, 3) m from tip (N, 3) m and target (N, 3) m."""
    tip = np.asarray(tip, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    if tip.shape != target.shape or tip.ndim != 2 or tip.shape[1] != 3:
        raise ValueError(
            f"tip and target must both have shape (N, 3); got {tip.shape}, {target.shape}"
        )
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


def torque_statistics(element_torques: np.ndarray, t: np.ndarray) -> dict[str, float]:
    """How smoothly and how hard one arm's element torques are driven over one episode.

    Args:
        element_torques: (N, ..., n_elem) the arm's element torques at the N control steps,
            N·m (e.g. (N, 2, n_elem): normal and binormal), N ≥ 1.
        t: (N,) the times of those steps, s, increasing.

    Returns:
        ``torque_rate_rms``: sqrt(mean (Δτ/Δt)²) over the steps k ≥ 1 and every element and
        direction, with Δτ = τ_k − τ_{k−1} and Δt = t_k − t_{k−1} (the control step), N·m/s
        (0 when N = 1);
        ``peak_moment``: the largest |τ| over steps, elements and directions, N·m (the maximum
        of the arm's ``eval_moment_peaks`` rows, :func:`moment_peak`).
    """
    torques = np.asarray(element_torques, dtype=np.float64)
    times = np.asarray(t, dtype=np.float64)
    if torques.ndim < 2 or torques.shape[0] != times.shape[0] or times.ndim != 1:
        raise ValueError(
            f"element_torques must have shape (N, ..., n_elem) and t shape (N,); got "
            f"{torques.shape}, {times.shape}"
        )
    if times.shape[0] == 0:
        raise ValueError("at least one time step is needed")
    if times.shape[0] > 1:
        dt = np.diff(times).reshape((-1,) + (1,) * (torques.ndim - 1))
        rate = np.diff(torques, axis=0) / dt
        rate_rms = float(np.sqrt(np.mean(rate * rate)))
    else:
        rate_rms = 0.0
    return {"torque_rate_rms": rate_rms, "peak_moment": float(np.max(moment_peak(torques)))}


def arm_clearance(nodes: np.ndarray, radius: float | np.ndarray) -> np.ndarray | float:
    """Surface clearance between the arms of a scene, m.

    Args:
        nodes: (..., A, 3, n_nodes) centreline node positions of the A arms, m (e.g. the
            engine's ``position`` of one environment, (A, 3, n_nodes)).
        radius: each arm's radius r, m: one for every scene, or (...) one per scene.

    Returns:
        (...) (a float for one scene) the smallest distance between a node of one arm and a
        node of another, minus 2·r (negative: the surfaces overlap); NaN with fewer than two
        arms or a non-finite node. The reward's collision test
        (:func:`softtrack.env.reward.collision_penalty`) compares the same clearance, with r
        its ``arm_radius``, against ``collision_margin``.
    """
    x = np.asarray(nodes, dtype=np.float64)
    if x.ndim < 3 or x.shape[-2] != 3:
        raise ValueError(f"nodes must have shape (..., A, 3, n_nodes); got {x.shape}")
    batch = x.shape[:-3]
    if x.shape[-3] < 2:
        return np.full(batch, np.nan)[()]
    if x.ndim == 3:  # one scene (run_episode's call at every step): no batch to reshape
        return np.float64(math.sqrt(_scene_min_distance2(x)) - 2.0 * float(radius))
    flat = np.ascontiguousarray(x.reshape((-1, *x.shape[-3:])))
    radii = np.asarray(radius, dtype=np.float64)
    return (np.sqrt(_min_node_distance2(flat)).reshape(batch) - 2.0 * radii)[()]


@njit(cache=True)
def _min_node_distance2(x):  # pragma: no cover - compiled
    """(B, A, 3, n) nodes → (B,) smallest squared distance between nodes of different arms
    (NaN where a node is not finite)."""
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = _scene_min_distance2(x[i])
    return out


@njit(cache=True)
def _scene_min_distance2(x):  # pragma: no cover - compiled
    """(A, 3, n) nodes of one scene → smallest squared distance between nodes of different
    arms, or NaN."""
    n_arms, _, n_nodes = x.shape
    best = np.inf
    for a in range(n_arms - 1):
        for b in range(a + 1, n_arms):
            for j in range(n_nodes):
                for k in range(n_nodes):
                    dx = x[a, 0, j] - x[b, 0, k]
                    dy = x[a, 1, j] - x[b, 1, k]
                    dz = x[a, 2, j] - x[b, 2, k]
                    d2 = dx * dx + dy * dy + dz * dz
                    if math.isnan(d2):
                        return math.nan
                    if d2 < best:
                        best = d2
    return best


def contact_statistics(penetration: ArrayLike, contact_force: ArrayLike) -> dict[str, float | int]:
    """Contact between the arms over one episode.

    Args:
        penetration: (N,) the overlap of the arms' surfaces at each control step, m (NaN
            where undefined: one arm).
        contact_force: (N,) the total contact force between the arms at each step, N.

    Returns:
        ``max_penetration``: the deepest overlap, m (NaN if none is defined);
        ``contact_steps``: the number of steps on which the arms touch (a contact force,
        or without contact modelled, an overlap);
        ``mean_contact_force``, ``max_contact_force``: over all steps, N.
    """
    depth = np.asarray(penetration, dtype=np.float64).reshape(-1)
    force = np.asarray(contact_force, dtype=np.float64).reshape(-1)
    finite = depth[np.isfinite(depth)]
    touching = (force > 0) | (np.nan_to_num(depth, nan=0.0) > 0)
    return {
        "max_penetration": float(finite.max()) if finite.size else float("nan"),
        "contact_steps": int(np.count_nonzero(touching)),
        "mean_contact_force": float(force.mean()) if force.size else 0.0,
        "max_contact_force": float(force.max()) if force.size else 0.0,
    }


def safety_statistics(clearance: ArrayLike, margin: float = 0.0) -> dict[str, float | int]:
    """Inter-arm safety over one episode from the clearance at each step.

    Args:
        clearance: (N,) surface clearance between the arms after each control step, m
            (:func:`arm_clearance`; NaN where undefined: one arm, non-finite state).
        margin: the collision test's margin (``reward.collision_margin``), m ≥ 0.

    Returns:
        ``min_arm_distance``: the smallest finite clearance, m (NaN if none is finite, e.g.
        a single-arm scene);
        ``collision_steps``: the number of steps with clearance < margin (with margin 0:
        steps in contact), those on which the reward's collision penalty applies.
    """
    c = np.asarray(clearance, dtype=np.float64).reshape(-1)
    finite = c[np.isfinite(c)]
    return {
        "min_arm_distance": float(finite.min()) if finite.size else float("nan"),
        "collision_steps": int(np.count_nonzero(finite < float(margin))),
    }
