"""Observation vector of the tracking environment (``SPEC.md`` §3, "Observation").

Layout for A arms (A·37 + 7 values; 81 for two arms, 44 for one):

====================  =========================================================
per arm a (37 values)  x of nodes 0, 2, …, 20, then y of them, then z (33 values),
                       tip speed ‖v_tip‖ (m/s), tip velocity direction (3)
last 7                 target centre (3), target speed, target velocity direction (3)
====================  =========================================================

Directions are zeros where the speed is exactly 0.
"""

from __future__ import annotations

import numpy as np

__all__ = ["build_observation", "observation_labels", "observation_size"]

_TARGET_SIZE = 7


def _n_sampled_nodes(n_nodes: int) -> int:
    if n_nodes < 1 or n_nodes % 2 == 0:
        raise ValueError(
            f"n_nodes={n_nodes} must be odd so that the sampled nodes 0, 2, …, n_nodes−1 "
            "end at the tip (use an even number of elements)"
        )
    return (n_nodes + 1) // 2


def observation_size(n_arms: int, n_nodes: int = 21) -> int:
    """Length of the observation: n_arms·(3·⌈n_nodes/2⌉ + 4) + 7 (81 for the default 2 arms)."""
    return n_arms * (3 * _n_sampled_nodes(n_nodes) + 4) + _TARGET_SIZE


def observation_labels(n_arms: int, n_nodes: int = 21) -> list[str]:
    """A name for every observation index, e.g. ``arm1.node4.y``, ``arm2.tip_dir.z``,
    ``target.speed`` (arms are numbered from 1, nodes by their index along the rod)."""
    if n_arms < 1:
        raise ValueError(f"n_arms={n_arms} must be ≥ 1")
    nodes = range(0, n_nodes, 2)
    _n_sampled_nodes(n_nodes)
    labels: list[str] = []
    for arm in range(1, n_arms + 1):
        for axis in "xyz":
            labels += [f"arm{arm}.node{k}.{axis}" for k in nodes]
        labels.append(f"arm{arm}.tip_speed")
        labels += [f"arm{arm}.tip_dir.{axis}" for axis in "xyz"]
    labels += [f"target.pos.{axis}" for axis in "xyz"]
    labels.append("target.speed")
    labels += [f"target.dir.{axis}" for axis in "xyz"]
    return labels


def _speed_and_direction(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """‖v‖ (...,) and v/‖v‖ (..., 3) (zeros where ‖v‖ = 0) of velocities v (..., 3)."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    speed = np.sqrt(x * x + y * y + z * z)
    direction = np.zeros_like(v)
    np.divide(v, speed[..., None], out=direction, where=speed[..., None] > 0)
    return speed, direction


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
    m = _n_sampled_nodes(n_nodes)
    if tip_velocity.shape != (n, n_arms, 3):
        raise ValueError(f"tip_velocity must have shape {(n, n_arms, 3)}, got {tip_velocity.shape}")
    if target_position.shape != (n, 3) or target_velocity.shape != (n, 3):
        raise ValueError(
            f"target_position and target_velocity must have shape {(n, 3)}, got "
            f"{target_position.shape} and {target_velocity.shape}"
        )
    per_arm = 3 * m + 4
    size = n_arms * per_arm + _TARGET_SIZE
    if out is None:
        out = np.empty((n, size), dtype=np.float32)
    elif out.shape != (n, size) or out.dtype != np.float32:
        raise ValueError(f"out must be a float32 array of shape {(n, size)}")
    speed, direction = _speed_and_direction(tip_velocity)
    for a in range(n_arms):  # A ≤ 2: a loop over arms, not over environments
        base = a * per_arm
        out[:, base : base + 3 * m] = nodes[:, a, :, ::2].reshape(n, 3 * m)
        out[:, base + 3 * m] = speed[:, a]
        out[:, base + 3 * m + 1 : base + per_arm] = direction[:, a]
    tail = out[:, n_arms * per_arm :]
    tail[:, 0:3] = target_position
    speed, direction = _speed_and_direction(target_velocity)
    tail[:, 3] = speed
    tail[:, 4:7] = direction
    return out
