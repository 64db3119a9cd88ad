"""The environment settings of a spec: ``env`` → :class:`~softtrack.env.settings.TrackingConfig`.

The one translation from the spec's ``env`` section to the environment's configuration, used
by training (:mod:`softtrack.rl.factory`), validation, confirmation and evaluation. The
environment package knows nothing of specs; this module depends on it, not the reverse.
"""

from __future__ import annotations

from typing import Any

from softtrack.env.reward import RewardConfig
from softtrack.env.settings import TrackingConfig, make_config
from softtrack.spec.models import ExperimentSpec

__all__ = ["env_config", "env_kwargs"]


def env_kwargs(spec: ExperimentSpec, arm: int | None = None) -> dict[str, Any]:
    """The spec's training environment as keyword arguments of the registered Gymnasium
    environments, so a policy can be driven with plain ``gymnasium.make``::

        gym.make("softtrack/DualArmTracking-v0", **{**env_kwargs(spec), "target": "circle"})
        gym.make("softtrack/SingleArmTracking-v0", **env_kwargs(spec, arm=1))

    Args:
        arm: ``None`` for the dual-arm scene; 0 or 1 for the single-arm scene of that arm
            (its base from ``env.physics.base_positions``, the independent baseline's
            single-arm reward with the spec's ``nonfinite_reward``, and no contact: there
            is no other arm); the result then holds ``arm``.
    """
    env = spec.env
    sim = env.sim_kwargs()
    target = env.target_kwargs()
    common = {"target": target.pop("name"), "episode_duration": env.episode_duration, **target}
    if env.task.name == "viewpoints":  # only then, so a default spec's kwargs stay as they were
        common.update(task=env.task.name, standoff=env.task.standoff)
    elif env.task.name == "transport":
        common.update(task=env.task.name, **env.task.model_dump(exclude={"name", "standoff"}))
    if env.realism.active:  # only then, so the kwargs of a default spec stay as they were
        common["realism"] = env.realism.realism_kwargs()
    if arm is None:
        return {**common, **sim, **env.reward_kwargs()}
    sim["base_positions"] = (tuple(sim["base_positions"][arm]),)
    # alone in its scene the arm has nothing to touch: an independent policy learns without
    # the other arm, and meets it (and the contact) only in the dual-arm evaluation
    sim["contact_k"] = sim["contact_nu"] = 0.0
    single = RewardConfig.single_arm()
    reward = RewardConfig(
        arm_weights=single.arm_weights,
        bonus_thresholds=single.bonus_thresholds,
        bonus_values=single.bonus_values,
        cooperative_bonus=single.cooperative_bonus,
        nonfinite_reward=env.reward.nonfinite_reward,
        action_rate_penalty=env.reward.action_rate_penalty,
        action_penalty=env.reward.action_penalty,
    )
    return {"arm": arm, "reward": reward, **common, **sim}


def env_config(spec: ExperimentSpec, arm: int | None = None) -> TrackingConfig:
    """The :class:`TrackingConfig` of the spec's training environment (:func:`env_kwargs`)."""
    return make_config(n_arms=2 if arm is None else 1, **env_kwargs(spec, arm))
