"""Reward of the tracking environment (``docs/environment.md``, "Reward" and the safety penalty).

With dᵢ the distance of arm i's tip to the target centre (m):

    r = −Σᵢ wᵢ·dᵢ² + Σᵢ Σ_k b_k·1(dᵢ ≤ θ_k) + b_coop·1(all dᵢ ≤ θ_coop)

(the cooperative term only with two or more arms). Optionally, −c_col when the closest pair
of nodes of the two arms is nearer than 2·arm_radius + margin, and action penalties for smooth
actuation (:func:`action_penalty`): −c_rate·mean((aₜ − aₜ₋₁)²) − c_act·mean(aₜ²) over the
clipped action's values.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from softtrack.env.reward_config import RewardConfig

__all__ = [
    "RewardConfig",
    "action_penalty",
    "collision_penalty",
    "reward_shares",
    "tip_distances",
    "tracking_reward",
]


def tip_distances(tips: np.ndarray, target_position: np.ndarray) -> np.ndarray:
    """Distances dᵢ = ‖tipᵢ − target‖, (n, A) m, of tips (n, A, 3) m and targets (n, 3) m."""
    e = np.asarray(tips, dtype=float) - np.asarray(target_position, dtype=float)[:, None, :]
    x, y, z = e[..., 0], e[..., 1], e[..., 2]
    return np.sqrt(x * x + y * y + z * z)


def tracking_reward(distances: np.ndarray, config: RewardConfig) -> np.ndarray:
    """Tracking reward of a batch of environments.

    Args:
        distances: (n, A) tip-to-target distances dᵢ, m; A must equal ``len(arm_weights)``.
        config: the reward settings.

    Returns:
        (n,) float64 rewards; ``config.nonfinite_reward`` for a row with a NaN or inf distance.
    """
    d = np.asarray(distances, dtype=float)
    if d.ndim != 2 or d.shape[1] != len(config.arm_weights):
        raise ValueError(
            f"distances must have shape (n, {len(config.arm_weights)}) to match arm_weights, "
            f"got {d.shape}"
        )
    cooperative = config.cooperative_bonus if d.shape[1] >= 2 else 0.0
    return _tracking_reward(
        np.ascontiguousarray(d),
        np.asarray(config.arm_weights, dtype=np.float64),
        np.asarray(config.bonus_thresholds, dtype=np.float64),
        np.asarray(config.bonus_values, dtype=np.float64),
        float(config.cooperative_threshold),
        float(cooperative),
        float(config.nonfinite_reward),
    )


@njit(cache=True)
def _tracking_reward(d, weights, thresholds, values, coop_threshold, coop_bonus, nonfinite):
    """The reward of the module docstring for distances d (n, A), one pass per environment."""
    n, n_arms = d.shape
    reward = np.empty(n)
    for i in range(n):
        r = 0.0
        all_close = True
        for a in range(n_arms):
            di = d[i, a]
            r -= weights[a] * di * di
            for k in range(thresholds.shape[0]):
                if di <= thresholds[k]:
                    r += values[k]
            if not di <= coop_threshold:
                all_close = False
        if coop_bonus != 0.0 and all_close:
            r += coop_bonus
        reward[i] = r if math.isfinite(r) else nonfinite
    return reward


def action_penalty(actions: np.ndarray, previous: np.ndarray, config: RewardConfig) -> np.ndarray:
    """The action penalties of a batch of control steps, to add to the reward (≤ 0).

    Args:
        actions: (n, D) clipped control values of this step, in [−1, 1].
        previous: (n, D) those of the previous step (zeros after a reset).
        config: ``action_rate_penalty`` c_rate and ``action_penalty`` c_act.

    Returns:
        (n,) −c_rate·mean_d((aₜ − aₜ₋₁)²) − c_act·mean_d(aₜ²).
    """
    a = np.asarray(actions, dtype=float)
    penalty = np.zeros(a.shape[0])
    if config.action_rate_penalty:
        change = a - np.asarray(previous, dtype=float)
        penalty -= config.action_rate_penalty * np.mean(change * change, axis=1)
    if config.action_penalty:
        penalty -= config.action_penalty * np.mean(a * a, axis=1)
    return penalty


def reward_shares(distances: np.ndarray, rewards: np.ndarray, config: RewardConfig) -> np.ndarray:
    """Split each step's reward into one share per arm; the shares sum to the reward.

    Arm i's share is its own terms, −wᵢ·dᵢ² + Σ_k b_k·1(dᵢ ≤ θ_k), plus 1/A of the cooperative
    bonus; whatever else the reward holds (the collision penalty, the non-finite reward of a
    terminated step) is split equally between the A arms.

    Args:
        distances: (n, A) tip-to-target distances dᵢ, m.
        rewards: (n,) the rewards of these steps (:func:`tracking_reward` plus penalties).
        config: the reward settings that produced ``rewards``.

    Returns:
        (n, A) float64 shares, each row summing to its reward.
    """
    d = np.asarray(distances, dtype=float)
    total = np.asarray(rewards, dtype=float)
    n_arms = d.shape[1]
    with np.errstate(invalid="ignore"):
        shares = -np.asarray(config.arm_weights, dtype=float) * d * d
        for threshold, value in zip(config.bonus_thresholds, config.bonus_values, strict=True):
            shares += value * (d <= threshold)
        if n_arms >= 2 and config.cooperative_bonus:
            together = (d <= config.cooperative_threshold).all(axis=1, keepdims=True)
            shares += config.cooperative_bonus / n_arms * together
    shares[~np.isfinite(shares).all(axis=1)] = 0.0
    shares += ((total - shares.sum(axis=1)) / n_arms)[:, None]
    return shares


def collision_penalty(nodes: np.ndarray, config: RewardConfig) -> np.ndarray:
    """Inter-arm safety penalty.

    Args:
        nodes: (n, 2, 3, n_nodes) node positions of the two arms, m.
        config: the reward settings (``collision_penalty``, ``collision_margin``, ``arm_radius``).

    Returns:
        (n,) float64: −collision_penalty where the smallest distance between any node of arm 1
        and any node of arm 2 is < 2·arm_radius + collision_margin, else 0 (zeros at once when
        collision_penalty is 0). Non-finite nodes give 0 (the episode terminates anyway).
    """
    n = np.shape(nodes)[0]
    if config.collision_penalty == 0:
        return np.zeros(n)
    nodes = np.asarray(nodes, dtype=float)
    if nodes.ndim != 4 or nodes.shape[1] != 2 or nodes.shape[2] != 3:
        raise ValueError(f"nodes must have shape (n, 2, 3, n_nodes), got {nodes.shape}")
    diff = nodes[:, 0, :, :, None] - nodes[:, 1, :, None, :]  # (n, 3, n_nodes, n_nodes)
    np.multiply(diff, diff, out=diff)
    dist2 = diff[:, 0] + diff[:, 1]  # (n, node of arm 1, node of arm 2), m²
    dist2 += diff[:, 2]
    min_dist2 = dist2.reshape(n, -1).min(axis=1)
    clearance = 2.0 * config.arm_radius + config.collision_margin
    return np.where(min_dist2 < clearance * clearance, -float(config.collision_penalty), 0.0)
