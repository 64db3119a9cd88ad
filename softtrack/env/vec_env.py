"""A Stable-Baselines3 ``VecEnv`` that steps N tracking environments in one engine call."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

from softtrack.env.core import TrackingCore
from softtrack.env.render import core_frame
from softtrack.env.reward import reward_shares
from softtrack.env.settings import TrackingConfig, make_config
from softtrack.viz.scene import SceneRenderer

__all__ = ["REWARD_SHARES_KEY", "TrackingVecEnv"]

REWARD_SHARES_KEY = "reward_shares"  # info key of the per-arm reward shares


class TrackingVecEnv(VecEnv):
    """N dual-arm (or single-arm) tracking environments advanced together.

    Behaves like SB3's ``DummyVecEnv`` over N ``DualArmTrackingEnv``: ``reset()`` seeds
    environment i with ``seed + i`` after :meth:`seed`, finished episodes are reset
    automatically (continuing each environment's random stream), and the info of a finished
    episode holds ``terminal_observation`` and ``TimeLimit.truncated``. The physics of all N
    environments is one compiled engine call per step.

    Args:
        n_envs: number of environments.
        config: a :class:`TrackingConfig`; if omitted, built from ``env_kwargs``.
        full_info: include the documented per-step info keys (tip positions, target, distances,
            torques, time) in every info dict; off saves time during training. With model
            error (``env.realism``), ``parameters`` (the episode's factors) is in the reset
            infos and in the info of every finished episode either way.
        reward_shares: add ``info["reward_shares"]``, the (A,) float32 per-arm split of the
            reward (:func:`softtrack.env.reward.reward_shares`; in the transport task
            :meth:`softtrack.env.transport_env.TransportModel.reward_shares`), for per-arm critics.
        **env_kwargs: keyword arguments of :func:`make_config` (e.g. ``target="circle"``).
    """

    #: read by VecEnv.__init__ via get_attr; ``"rgb_array"``: :meth:`get_images` draws
    render_mode: str | None = None

    def __init__(
        self,
        n_envs: int,
        config: TrackingConfig | None = None,
        *,
        full_info: bool = False,
        reward_shares: bool = False,
        render_mode: str | None = None,
        **env_kwargs: Any,
    ) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ValueError(
                f"render_mode={render_mode!r} is not supported; use 'rgb_array' or leave it out"
            )
        self.render_mode = render_mode
        self._renderer: SceneRenderer | None = None
        self.config = config if config is not None else make_config(**env_kwargs)
        self.core = TrackingCore(n_envs, self.config)
        self.full_info = full_info
        self.with_reward_shares = reward_shares
        observation_space = gym.spaces.Box(-np.inf, np.inf, (self.core.obs_dim,), dtype=np.float32)
        action_space = gym.spaces.Box(-1.0, 1.0, (self.core.action_dim,), dtype=np.float32)
        super().__init__(n_envs, observation_space, action_space)
        self._actions: np.ndarray | None = None
        self._rngs: list[np.random.Generator | None] = [None] * n_envs

    def _rng_for(self, i: int, seed: int | None) -> np.random.Generator:
        if seed is not None or self._rngs[i] is None:
            self._rngs[i], _ = seeding.np_random(seed)
        rng = self._rngs[i]
        assert rng is not None
        return rng

    def reset(self) -> VecEnvObs:
        rngs = [self._rng_for(i, self._seeds[i]) for i in range(self.num_envs)]
        obs = self.core.reset(np.arange(self.num_envs), rngs)
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        if self.core.model_error:  # each episode's model-error factors, also without full_info
            for i, info in enumerate(self.reset_infos):
                info["parameters"] = self.core.parameters(i)
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        assert self._actions is not None, "step_async must be called before step_wait"
        result = self.core.step(self._actions.reshape(self.num_envs, -1))
        obs = result.observation
        dones = result.terminated | result.truncated
        if self.full_info:
            infos = [self.core.info(i, result.distances) for i in range(self.num_envs)]
        else:
            infos = [{} for _ in range(self.num_envs)]
        if self.with_reward_shares:
            if result.touching is not None and self.core.transport is not None:
                shares = self.core.transport.reward_shares(result.reward, result.touching)
            else:
                shares = reward_shares(result.distances, result.reward, self.config.reward)
            for info, share in zip(infos, shares.astype(np.float32), strict=True):
                info[REWARD_SHARES_KEY] = share
        finished = np.flatnonzero(dones)
        if finished.size:
            for i in finished.tolist():
                infos[i]["terminal_observation"] = obs[i].copy()
                infos[i]["TimeLimit.truncated"] = bool(result.truncated[i])
                if self.core.model_error:  # the factors of the episode that just ended
                    infos[i]["parameters"] = self.core.parameters(i)
            rngs = [self._rng_for(i, None) for i in finished.tolist()]
            obs[finished] = self.core.reset(finished, rngs)
        return obs, result.reward.astype(np.float32), dones, infos

    def close(self) -> None:
        return None

    # ---- attribute access, as DummyVecEnv offers it over its single envs ----------------
    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self, attr_name) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        setattr(self, attr_name, value)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        method = getattr(self, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        """Each environment's frame now ((480, 640, 3) uint8) with ``render_mode="rgb_array"``,
        else ``None`` each."""
        if self.render_mode != "rgb_array":
            return [None for _ in range(self.num_envs)]
        if self._renderer is None:
            self._renderer = SceneRenderer()
        return [self._renderer.render(core_frame(self.core, i)) for i in range(self.num_envs)]
