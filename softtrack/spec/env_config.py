"""The environment settings of a spec: ``env`` → :class:`~softtrack.env.config.TrackingConfig`.

The one translation from the spec's ``env`` section to the environment's configuration, used
by training (:mod:`softtrack.rl.factory`), validation, confirmation and evaluation. The
environment package knows nothing of specs; this module depends on it, not the reverse.
"""

from __future__ import annotations

from softtrack.env.config import TrackingConfig, make_config
from softtrack.env.reward import RewardConfig
from softtrack.spec.models import ExperimentSpec

__all__ = ["env_config"]


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
