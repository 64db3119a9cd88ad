"""Observation vector of the tracking environment (``docs/environment.md``, "Observation").

Layout for A arms (A·37 + 7 values; 81 for two arms, 44 for one):

====================  =========================================================
per arm a (37 values)  x of nodes 0, 2, …, 20, then y of them, then z (33 values),
                       tip speed ‖v_tip‖ (m/s), tip velocity direction (3)
last 7                 target centre (3), target speed, target velocity direction (3)
====================  =========================================================

Directions are zeros where the speed is exactly 0.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from softtrack.env.observation_layout import (
    TARGET_SIZE,
    arm_view_columns,
    observation_labels,
    observation_size,
    sampled_node_count,
)

__all__ = ["arm_view_columns", "build_observation", "observation_labels", "observation_size"]


def build_observation(
    nodes: np.ndarray,
    tip_velocity: np.ndarray,
    target_position: np.ndarray,
    target_velocity: np.ndarray,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Observations of a batch of environments.

    Args:
        nodes: (n, A, 3, n_nodes) node positions of A arms, m (coordinate-major, as the
            simulator stores them); n_nodes must be odd (21 by default).
        tip_velocity: (n, A, 3) velocity of each arm's last node, m/s.
        target_position: (n, 3) target centre, m.
        target_velocity: (n, 3) target velocity, m/s.
        out: optional preallocated float32 (n, A·(3·⌈n_nodes/2⌉+4)+7) array to fill.

    Returns:
        float32 (n, 37·A + 7) observations in the layout of the module docstring.
    """
    nodes = np.asarray(nodes)
    tip_velocity = np.asarray(tip_velocity, dtype=float)
    target_position = np.asarray(target_position)
    target_velocity = np.asarray(target_velocity, dtype=float)
    if nodes.ndim != 4 or nodes.shape[2] != 3:
        raise ValueError(f"nodes must have shape (n, A, 3, n_nodes), got {nodes.shape}")
    n, n_arms, _, n_nodes = nodes.shape
    m = sampled_node_count(n_nodes)
    if tip_velocity.shape != (n, n_arms, 3):
        raise ValueError(f"tip_velocity must have shape {(n, n_arms, 3)}, got {tip_velocity.shape}")
    if target_position.shape != (n, 3) or target_velocity.shape != (n, 3):
        raise ValueError(
            f"target_position and target_velocity must have shape {(n, 3)}, got "
            f"{target_position.shape} and {target_velocity.shape}"
        )
    per_arm = 3 * m + 4
    size = n_arms * per_arm + TARGET_SIZE
    if out is None:
        out = np.empty((n, size), dtype=np.float32)
    elif out.shape != (n, size) or out.dtype != np.float32:
        raise ValueError(f"out must be a float32 array of shape {(n, size)}")
    _fill_observation(
        np.ascontiguousarray(nodes, dtype=np.float64),
        np.ascontiguousarray(tip_velocity),
        np.ascontiguousarray(target_position, dtype=np.float64),
        np.ascontiguousarray(target_velocity),
        out,
    )
    return out


@njit(cache=True)
def _speed_direction_into(vx: float, vy: float, vz: float, out: np.ndarray, i: int, j: int) -> None:
    """Write ‖v‖ and v/‖v‖ (zeros when ‖v‖ = 0) into out[i, j:j+4]."""
    speed = math.sqrt(vx * vx + vy * vy + vz * vz)
    out[i, j] = speed
    if speed > 0.0:
        out[i, j + 1] = vx / speed
        out[i, j + 2] = vy / speed
        out[i, j + 3] = vz / speed
    else:
        out[i, j + 1] = 0.0
        out[i, j + 2] = 0.0
        out[i, j + 3] = 0.0


@njit(cache=True)
def _fill_observation(nodes, tip_velocity, target_position, target_velocity, out):
    """The layout of the module docstring, written into ``out`` (n, A·37+7) in one pass."""
    n, n_arms, _, n_nodes = nodes.shape
    m = (n_nodes + 1) // 2
    per_arm = 3 * m + 4
    for i in range(n):
        for a in range(n_arms):
            base = a * per_arm
            for c in range(3):
                for k in range(m):
                    out[i, base + c * m + k] = nodes[i, a, c, 2 * k]
            _speed_direction_into(
                tip_velocity[i, a, 0],
                tip_velocity[i, a, 1],
                tip_velocity[i, a, 2],
                out,
                i,
                base + 3 * m,
            )
        tail = n_arms * per_arm
        for c in range(3):
            out[i, tail + c] = target_position[i, c]
        _speed_direction_into(
            target_velocity[i, 0], target_velocity[i, 1], target_velocity[i, 2], out, i, tail + 3
        )
