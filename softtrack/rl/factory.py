"""Build the Stable-Baselines3 algorithm, its environment and its exploration noise from a spec.

The core algorithms are SB3's or SBX's TD3, DDPG, SAC, PPO and TQC (sb3-contrib's for SB3),
and SBX's CrossQ (:func:`algo_class`). A research
variant that the spec enables (:mod:`softtrack.rl.variants`) may replace the algorithm class,
add constructor arguments (e.g. its replay buffer class) and environment arguments; the factory
asks the variants' registry for them and names no variant itself. The environment settings come
from :func:`softtrack.spec.env_config.env_config`.

The training environment is ``VecMonitor(TrackingVecEnv(n_envs, config))`` (plus
``VecNormalize`` when ``algo.normalize`` is set): all ``n_envs`` environments advance in one
engine call, and ``VecMonitor`` adds ``info["episode"] = {"r", "l", "t"}`` when an episode
ends, which :mod:`softtrack.rl.callbacks` logs.
"""

from __future__ import annotations

import importlib.util
import warnings
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from softtrack.rl import variants
from softtrack.rl.learning_rate import settable_adam
from softtrack.spec import ExperimentSpec, SpecError
from softtrack.spec.env_config import env_config

__all__ = [
    "ALGO_NAMES",
    "algo_class",
    "build_model",
    "check_supported",
    "load_model",
    "make_action_noise",
    "make_vec_env",
    "model_class",
]

ALGO_NAMES = ("td3", "ddpg", "sac", "tqc", "crossq", "ppo")


def installed(module: str) -> bool:
    """Whether ``module`` can be imported here (without importing it)."""
    return importlib.util.find_spec(module) is not None


def check_supported(spec: ExperimentSpec, file: str = "spec") -> None:
    """Raise :class:`SpecError` for spec settings ``softtrack train`` cannot run here."""
    if spec.algo.backend == "sbx":
        try:
            import sbx  # noqa: F401
        except ImportError:
            raise SpecError(
                file,
                "algo.backend 'sbx' needs the JAX backend (sbx-rl, a dependency of softtrack), "
                "which is not installed",
                "reinstall softtrack (pip install -c constraints.txt -e .) or use "
                "algo.backend: sb3",
                field="algo.backend",
            ) from None
    if spec.training.tensorboard and not installed("tensorboard"):
        raise SpecError(
            file,
            "training.tensorboard needs the tensorboard package, which is not installed",
            "pip install 'softtrack[tensorboard]' (or -c constraints.txt tensorboard) or set "
            "training.tensorboard: false",
            field="training.tensorboard",
        )
    if spec.algo.backend == "sb3" and spec.algo.name == "tqc":
        try:
            import sb3_contrib  # noqa: F401
        except ImportError:
            raise SpecError(
                file,
                "algo.name 'tqc' with backend sb3 needs sb3-contrib, which is not installed",
                "pip install -c constraints.txt -e . or use algo.backend: sbx",
                field="algo.name",
            ) from None


def make_vec_env(
    spec: ExperimentSpec,
    seed: int | None = None,
    arm: int | None = None,
    *,
    normalize: bool | None = None,
) -> Any:
    """``VecMonitor(TrackingVecEnv(training.n_envs, env_config(spec, arm)))``, seeded.

    An enabled variant may add arguments of ``TrackingVecEnv``
    (:func:`softtrack.rl.variants.vec_env_kwargs`; with ``algo.critic: per_arm`` every step's
    info also holds the per-arm reward shares).

    With ``normalize`` (default ``algo.normalize``) the result is wrapped in a fresh
    ``VecNormalize`` (observations, and rewards with ``algo.normalize_reward``); pass
    ``normalize=False`` to wrap a saved one with ``VecNormalize.load`` instead.
    """
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    # here, not at the top: stable-baselines3 and torch load when an environment is built
    from softtrack.env.vec_env import TrackingVecEnv

    with warnings.catch_warnings():  # TrackingVecEnv has no render mode; SB3 warns about it
        warnings.filterwarnings("ignore", message=".*render_mode.*")
        venv: Any = VecMonitor(
            TrackingVecEnv(
                spec.training.n_envs,
                env_config(spec, arm),
                **variants.vec_env_kwargs(spec),
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

    Returns ``None`` for PPO, for the algorithms that explore by sampling their stochastic
    policy (SAC, TQC, CrossQ: ``noise_type`` does not apply), ``noise_type: null`` or
    ``noise_std: 0``; otherwise a
    ``VectorizedActionNoise`` over ``n_envs`` copies of ``NormalActionNoise`` or
    ``OrnsteinUhlenbeckActionNoise`` with mean 0 and std ``noise_std`` on every action.
    """
    from stable_baselines3.common.noise import (
        NormalActionNoise,
        OrnsteinUhlenbeckActionNoise,
        VectorizedActionNoise,
    )

    algo = spec.algo
    if (
        not algo.is_off_policy
        or algo.explores_by_entropy
        or algo.noise_type is None
        or algo.noise_std == 0
    ):
        return None
    mean = np.zeros(action_dim)
    sigma = algo.noise_std * np.ones(action_dim)
    base: Any
    if algo.noise_type == "normal":
        base = NormalActionNoise(mean, sigma)
    else:
        base = OrnsteinUhlenbeckActionNoise(mean, sigma)
    return VectorizedActionNoise(base, n_envs)


def algo_class(name: str, backend: str = "sb3") -> Any:
    """The core algorithm class of a name (td3, ddpg, sac, tqc, crossq, ppo) in a backend (sb3
    or sbx): ``sbx.<ALGO>``, else ``stable_baselines3.<ALGO>`` or, for tqc,
    ``sb3_contrib.TQC``; crossq exists in sbx only (``KeyError`` for sb3, which the spec
    rejects)."""
    library: ModuleType
    if backend == "sbx":
        import sbx as library

        if name == "crossq":
            return library.CrossQ
    elif name == "tqc":
        import sb3_contrib as library
    else:
        import stable_baselines3 as library
    return getattr(
        library, {"td3": "TD3", "ddpg": "DDPG", "sac": "SAC", "tqc": "TQC", "ppo": "PPO"}[name]
    )


def model_class(spec: ExperimentSpec) -> Any:
    """The algorithm class that trains and loads the models of ``spec``: an enabled variant's
    (:func:`softtrack.rl.variants.model_class_override`), else the core :func:`algo_class`."""
    override = variants.model_class_override(spec)
    return override if override is not None else algo_class(spec.algo.name, spec.algo.backend)


def _set_threads(spec: ExperimentSpec) -> None:
    import torch

    torch.set_num_threads(spec.training.torch_threads)


def build_model(
    spec: ExperimentSpec, env: Any, seed: int, tensorboard_dir: Path | None = None
) -> Any:
    """A fresh SB3 model for ``env`` with the spec's hyperparameters and ``seed``, logging to
    TensorBoard in ``tensorboard_dir`` when given."""
    _set_threads(spec)
    kwargs = spec.algo.sb3_kwargs()
    if tensorboard_dir is not None:
        kwargs["tensorboard_log"] = str(tensorboard_dir)
    noise = make_action_noise(spec, int(np.prod(env.action_space.shape)), env.num_envs)
    if noise is not None:
        kwargs["action_noise"] = noise
    kwargs.update(variants.model_kwargs(spec))
    if spec.algo.learning_rate_final is not None:
        kwargs["policy_kwargs"] = {
            **kwargs.get("policy_kwargs", {}),
            "optimizer_class": settable_adam,
        }
    return model_class(spec)(env=env, seed=int(seed), verbose=0, **kwargs)


def load_model(spec: ExperimentSpec, path: str | Path, env: Any) -> Any:
    """Load a saved model (``model.zip``) onto ``env``; ``num_timesteps`` is restored."""
    _set_threads(spec)
    device = spec.algo.device if spec.algo.backend == "sb3" else "auto"
    return model_class(spec).load(str(path), env=env, device=device)
