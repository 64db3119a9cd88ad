"""Mirror-image transitions of the dual-arm scene, for a replay buffer that stores both.

The default scene is symmetric under the reflection x → −x: the bases sit at x = ∓0.1, both
rest along +y with d₁ = +z and d₂ = +x, and the reward weights both arms alike. Reflecting a
state swaps the arms and negates every x coordinate; reflecting an action swaps the arms'
blocks and negates the normal values (a couple about d₁ = +z is a pseudovector, so its mirror
image turns the other way) while the binormal values (couples about +x) stay. The engine is
equivariant under this map bit for bit (``tests/test_mirror.py``), so every transition
(s, a, r, s') the environment produces has a twin (m(s), m(a), r, m(s')) that it would have
produced from the mirrored state: ``algo.mirror_replay`` stores both, so that what one arm
learns the other can use (:class:`MirrorReplayBuffer`, the replay buffer class that the
variants' registry, :mod:`softtrack.rl.variants`, gives the algorithm).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from stable_baselines3.common.buffers import NStepReplayBuffer, ReplayBuffer

__all__ = ["MirrorNStepReplayBuffer", "MirrorReplayBuffer", "mirror_action", "mirror_observation"]

ARM_OBS = 37  # per arm: x, y, z of 11 nodes, tip speed, tip velocity direction (3)
POINT_OBS = 7  # a point's position (3), speed, velocity direction (3): target, sphere, goal
OBS_DIM = 2 * ARM_OBS + POINT_OBS  # 81; the transport task's 88 holds two points
ACTION_DIM = 24
_ARM_X = np.r_[0:11, 34]  # node x coordinates and the x of the tip velocity direction
_POINT_X = np.array([0, 4])  # a point's x and the x of its velocity direction


def mirror_observation(obs: np.ndarray) -> np.ndarray:
    """The observation of the mirror-image scene (x → −x, arms swapped).

    Args:
        obs: (..., 81) dual-arm observations (docs/environment.md layout), or (..., 88) of
            the transport task (the sphere's block, then the goal's).

    Returns:
        An array of the same shape and dtype: arm 2's block mirrored in arm 1's place, arm
        1's in arm 2's, and each point's x position and x velocity direction negated.
    """
    obs = np.asarray(obs)
    points, rest = divmod(obs.shape[-1] - 2 * ARM_OBS, POINT_OBS)
    if rest or points not in (1, 2):
        raise ValueError(
            f"expected dual-arm observations of {OBS_DIM} (or, transport, "
            f"{OBS_DIM + POINT_OBS}) values, got {obs.shape}"
        )
    arm1 = obs[..., :ARM_OBS].copy()
    arm2 = obs[..., ARM_OBS : 2 * ARM_OBS].copy()
    tail = obs[..., 2 * ARM_OBS :].copy()
    for block in (arm1, arm2):
        block[..., _ARM_X] *= -1
    for point in range(points):
        tail[..., POINT_OBS * point + _POINT_X] *= -1
    return np.concatenate([arm2, arm1, tail], axis=-1)


def mirror_action(action: np.ndarray) -> np.ndarray:
    """The action of the mirror-image scene: arms swapped, normal values negated.

    Args:
        action: (..., 24) control values, [arm1 normal(6), arm1 binormal(6), arm2 normal(6),
            arm2 binormal(6)].

    Returns:
        (..., 24) array of the same dtype.
    """
    action = np.asarray(action)
    if action.shape[-1] != ACTION_DIM:
        raise ValueError(f"expected dual-arm actions of {ACTION_DIM} values, got {action.shape}")
    blocks = action.reshape(*action.shape[:-1], 2, 2, 6)[..., ::-1, :, :].copy()
    blocks[..., 0, :] *= -1
    return blocks.reshape(action.shape)


class MirrorReplayBuffer(ReplayBuffer):
    """An SB3 replay buffer that stores every transition and its mirror image.

    Each :meth:`add` takes two slots, so a buffer of ``buffer_size`` transitions holds the
    last ``buffer_size / 2`` environment steps. Rewards and episode ends are unchanged by the
    reflection (the reward is symmetric in the arms when their weights are equal, which the
    spec checks).
    """

    def add(
        self,
        obs: np.ndarray,
        next_obs: np.ndarray,
        action: np.ndarray,
        reward: np.ndarray,
        done: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        """Store (obs, action, reward, next_obs) and its mirror image; shapes (n_envs, ...)."""
        super().add(obs, next_obs, action, reward, done, infos)
        super().add(
            mirror_observation(obs),
            mirror_observation(next_obs),
            mirror_action(action),
            reward,
            done,
            infos,
        )


class MirrorNStepReplayBuffer(NStepReplayBuffer):
    """SB3's n-step replay buffer (``algo.n_step_returns``) that also stores every
    transition's mirror image: the mirror images of the n_envs environments are n_envs more
    columns, so each column holds one (real or mirrored) episode in order, as n-step returns
    need. Capacity: ``buffer_size`` transitions, i.e. the last ``buffer_size / 2`` environment
    steps, as :class:`MirrorReplayBuffer`.

    Args:
        buffer_size, observation_space, action_space, device: as SB3's buffers.
        n_envs: the training environments (the buffer keeps 2·n_envs columns).
        **kwargs: ``n_steps``, ``gamma`` and the rest of SB3's ``NStepReplayBuffer``.
    """

    def __init__(
        self,
        buffer_size: int,
        observation_space: Any,
        action_space: Any,
        device: Any = "auto",
        n_envs: int = 1,
        **kwargs: Any,
    ) -> None:
        super().__init__(
            buffer_size, observation_space, action_space, device, n_envs=2 * n_envs, **kwargs
        )

    def add(
        self,
        obs: np.ndarray,
        next_obs: np.ndarray,
        action: np.ndarray,
        reward: np.ndarray,
        done: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        """Store the (n_envs, ...) transitions in the first n_envs columns and their mirror
        images in the others, at one position."""
        super().add(
            np.concatenate([obs, mirror_observation(obs)]),
            np.concatenate([next_obs, mirror_observation(next_obs)]),
            np.concatenate([action, mirror_action(action)]),
            np.concatenate([reward, reward]),
            np.concatenate([done, done]),
            [*infos, *infos],
        )
