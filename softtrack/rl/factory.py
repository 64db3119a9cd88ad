"""Build the Stable-Baselines3 algorithm, its environment and its exploration noise from a spec.

The training environment is ``VecMonitor(TrackingVecEnv(n_envs, config))`` (plus
``VecNormalize`` when ``algo.normalize`` is set): all ``n_envs`` environments advance in one
engine call, and ``VecMonitor`` adds ``info["episode"] = {"r", "l", "t"}`` when an episode
ends, which :mod:`softtrack.rl.callbacks` logs.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from softtrack.env.config import TrackingConfig, make_config
from softtrack.env.reward import RewardConfig
from softtrack.spec import ExperimentSpec, SpecError

__all__ = [
    "ALGO_NAMES",
    "algo_class",
    "build_model",
    "check_supported",
    "env_config",
    "load_model",
    "make_action_noise",
    "make_vec_env",
    "model_class",
]

ALGO_NAMES = ("td3", "ddpg", "sac", "ppo")


def check_supported(spec: ExperimentSpec, file: str = "spec") -> None:
    """Raise :class:`SpecError` for spec settings ``softtrack train`` cannot run here."""
    if spec.algo.backend == "sbx":
        try:
            import sbx  # noqa: F401
        except ImportError:
            raise SpecError(
                file,
                "algo.backend 'sbx' needs the JAX backend, which is not installed",
                "pip install -c constraints.txt -e '.[sbx]' or use algo.backend: sb3",
                field="algo.backend",
            ) from None


def env_config(spec: ExperimentSpec, arm: int | None = None) -> TrackingConfig:
    """The :class:`TrackingConfig` of the spec's training environment.

    Args:
        arm: ``None`` for the dual-arm scene; 0 or 1 for the single-arm scene of that arm
            (its base from ``env.physics.base_positions``, the single-arm reward of SPEC §3
            with the spec's ``nonfinite_reward``).
    """
    env = spec.env
    sim = env.sim_kwargs()
    target = env.target_kwargs()
    name = target.pop("name")
    if arm is None:
        return make_config(
            n_arms=2,
            target=name,
            episode_duration=env.episode_duration,
            **sim,
            **target,
            **env.reward_kwargs(),
        )
    sim["base_positions"] = (tuple(sim["base_positions"][arm]),)
    single = RewardConfig.single_arm()
    reward = RewardConfig(
        arm_weights=single.arm_weights,
        bonus_thresholds=single.bonus_thresholds,
        bonus_values=single.bonus_values,
        cooperative_bonus=single.cooperative_bonus,
        nonfinite_reward=env.reward.nonfinite_reward,
    )
    return make_config(
        n_arms=1,
        arm=arm,
        target=name,
        reward=reward,
        episode_duration=env.episode_duration,
        **sim,
        **target,
    )


def make_vec_env(
    spec: ExperimentSpec,
    seed: int | None = None,
    arm: int | None = None,
    *,
    normalize: bool | None = None,
) -> Any:
    """``VecMonitor(TrackingVecEnv(training.n_envs, env_config(spec, arm)))``, seeded.

    With ``algo.critic: per_arm`` every step's info also holds the per-arm reward shares.

    With ``normalize`` (default ``algo.normalize``) the result is wrapped in a fresh
    ``VecNormalize`` (observations, and rewards with ``algo.normalize_reward``); pass
    ``normalize=False`` to wrap a saved one with ``VecNormalize.load`` instead.
    """
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from softtrack.env.vec_env import TrackingVecEnv

    with warnings.catch_warnings():  # TrackingVecEnv has no render mode; SB3 warns about it
        warnings.filterwarnings("ignore", message=".*render_mode.*")
        venv: Any = VecMonitor(
            TrackingVecEnv(
                spec.training.n_envs,
                env_config(spec, arm),
                reward_shares=spec.algo.critic == "per_arm",
            )
        )
    if seed is not None:
        venv.seed(int(seed))
    if spec.algo.normalize if normalize is None else normalize:
        venv = VecNormalize(
            venv, norm_obs=True, norm_reward=spec.algo.normalize_reward, gamma=spec.algo.gamma
        )
    return venv


def make_action_noise(spec: ExperimentSpec, action_dim: int, n_envs: int) -> Any:
    """Exploration noise from ``algo.noise_type`` / ``algo.noise_std`` (off-policy only).

    Returns ``None`` for PPO, ``noise_type: null`` or ``noise_std: 0``; otherwise a
    ``VectorizedActionNoise`` over ``n_envs`` copies of ``NormalActionNoise`` or
    ``OrnsteinUhlenbeckActionNoise`` with mean 0 and std ``noise_std`` on every action.
    """
    from stable_baselines3.common.noise import (
        NormalActionNoise,
        OrnsteinUhlenbeckActionNoise,
        VectorizedActionNoise,
    )

    algo = spec.algo
    if not algo.is_off_policy or algo.noise_type is None or algo.noise_std == 0:
        return None
    mean = np.zeros(action_dim)
    sigma = algo.noise_std * np.ones(action_dim)
    base: Any
    if algo.noise_type == "normal":
        base = NormalActionNoise(mean, sigma)
    else:
        base = OrnsteinUhlenbeckActionNoise(mean, sigma)
    return VectorizedActionNoise(base, n_envs)


def algo_class(name: str, backend: str = "sb3", critic: str = "joint") -> Any:
    """The algorithm class of a name (td3, ddpg, sac, ppo) in a backend (sb3 or sbx).

    ``critic="per_arm"`` (td3 with sbx only) gives :class:`softtrack.rl.per_arm_td3.PerArmTD3`.
    """
    if critic == "per_arm":
        from softtrack.rl.per_arm_td3 import PerArmTD3

        return PerArmTD3
    if backend == "sbx":
        import sbx as library
    else:
        import stable_baselines3 as library
    return {"td3": library.TD3, "ddpg": library.DDPG, "sac": library.SAC, "ppo": library.PPO}[name]


def model_class(spec: ExperimentSpec) -> Any:
    """The algorithm class that trains and loads the models of ``spec`` (:func:`algo_class`)."""
    return algo_class(spec.algo.name, spec.algo.backend, spec.algo.critic)


def _set_threads(spec: ExperimentSpec) -> None:
    import torch

    torch.set_num_threads(spec.training.torch_threads)


def build_model(spec: ExperimentSpec, env: Any, seed: int) -> Any:
    """A fresh SB3 model for ``env`` with the spec's hyperparameters and ``seed``."""
    _set_threads(spec)
    kwargs = spec.algo.sb3_kwargs()
    noise = make_action_noise(spec, int(np.prod(env.action_space.shape)), env.num_envs)
    if noise is not None:
        kwargs["action_noise"] = noise
    if spec.algo.mirror_replay:
        from softtrack.rl.mirror import MirrorReplayBuffer

        kwargs["replay_buffer_class"] = MirrorReplayBuffer
    return model_class(spec)(
        env=env, seed=int(seed), verbose=0, **kwargs
    )


def load_model(spec: ExperimentSpec, path: str | Path, env: Any) -> Any:
    """Load a saved model (``model.zip``) onto ``env``; ``num_timesteps`` is restored."""
    _set_threads(spec)
    device = spec.algo.device if spec.algo.backend == "sb3" else "auto"
    return model_class(spec).load(str(path), env=env, device=device)
