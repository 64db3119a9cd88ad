"""Where each value sits in the observation vector (the layout of
:mod:`softtrack.env.observation`, without its numba kernels): sizes, the columns one arm
sees, and a name for every index."""

from __future__ import annotations

import numpy as np

__all__ = [
    "TARGET_SIZE",
    "arm_view_columns",
    "observation_labels",
    "observation_size",
    "sampled_node_count",
]

#: Values of the target block (centre, speed, velocity direction).
TARGET_SIZE = 7


def sampled_node_count(n_nodes: int) -> int:
    """Nodes an arm's block samples (0, 2, …, n_nodes − 1): (n_nodes + 1) / 2."""
    if n_nodes < 1 or n_nodes % 2 == 0:
        raise ValueError(
            f"n_nodes={n_nodes} must be odd so that the sampled nodes 0, 2, …, n_nodes−1 "
            "end at the tip (use an even number of elements)"
        )
    return (n_nodes + 1) // 2


def observation_size(n_arms: int, n_nodes: int = 21) -> int:
    """Length of the observation: n_arms·(3·⌈n_nodes/2⌉ + 4) + 7 (81 for the default 2 arms)."""
    return n_arms * (3 * sampled_node_count(n_nodes) + 4) + TARGET_SIZE


def arm_view_columns(arm: int, n_arms: int, observation_dim: int) -> np.ndarray:
    """Indices of what one arm sees on its own: its 37-value block, then the points' blocks
    (the target's 7; in the transport task the sphere's and the goal's, 14).

    That is the single-arm observation (44 values for 21 nodes) inside the A-arm one.

    Args:
        arm: the arm, 0 … n_arms − 1.
        n_arms: A, arms in the observation.
        observation_dim: length of the A-arm observation (81 for two arms, 88 in transport).

    Returns:
        (observation_dim − (A − 1)·block,) int64 column indices, block = the per-arm length.
    """
    for points in (1, 2):  # an arm block is 3·m + 4 ≡ 1 (mod 3): one count fits (A ≤ 2)
        tail = points * TARGET_SIZE
        block, rest = divmod(observation_dim - tail, n_arms)
        if not rest and block > 4 and block % 3 == 1 and 0 <= arm < n_arms:
            points_columns = np.arange(observation_dim - tail, observation_dim)
            return np.concatenate([np.arange(block * arm, block * (arm + 1)), points_columns])
    raise ValueError(f"no arm {arm} in a {observation_dim}-value observation of {n_arms} arms")


def observation_labels(n_arms: int, n_nodes: int = 21) -> list[str]:
    """A name for every observation index, e.g. ``arm1.node4.y``, ``arm2.tip_dir.z``,
    ``target.speed`` (arms are numbered from 1, nodes by their index along the rod)."""
    if n_arms < 1:
        raise ValueError(f"n_arms={n_arms} must be ≥ 1")
    nodes = range(0, n_nodes, 2)
    sampled_node_count(n_nodes)
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
