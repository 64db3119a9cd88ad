"""Learner options for the time-to-accuracy search (issue 40): n-step returns
(``algo.n_step_returns``) and layer-normalised critics (``algo.policy_kwargs.layer_norm``)."""

from __future__ import annotations

import numpy as np
import pytest
from stable_baselines3.common.buffers import NStepReplayBuffer

from softtrack.rl.factory import build_model, make_vec_env
from softtrack.rl.variants.per_arm import RewardShareReplayBuffer
from softtrack.spec.fields import SpecError
from softtrack.spec.spec_io import parse_spec, spec_hash

_SMALL = {
    "training": {"n_envs": 2, "total_timesteps": 200},
    "algo": {"backend": "sbx", "learning_starts": 20, "buffer_size": 1000, "batch_size": 8},
}


def _spec(**algo: object):  # type: ignore[no-untyped-def]
    return parse_spec({**_SMALL, "algo": {**_SMALL["algo"], **algo}})


def test_defaults_keep_every_hash_and_pass_nothing_new() -> None:
    plain = _spec()
    explicit = _spec(n_step_returns=1, policy_kwargs={"layer_norm": False})
    assert spec_hash(plain) == spec_hash(explicit)
    kwargs = plain.algo.sb3_kwargs(resolve_activation=False)
    assert "n_steps" not in kwargs and "layer_norm" not in kwargs["policy_kwargs"]
    assert spec_hash(_spec(n_step_returns=3)) != spec_hash(plain)


def test_n_step_returns_build_sb3s_n_step_buffer() -> None:
    spec = _spec(n_step_returns=3, policy_kwargs={"layer_norm": True})
    kwargs = spec.algo.sb3_kwargs(resolve_activation=False)
    assert kwargs["n_steps"] == 3 and kwargs["policy_kwargs"]["layer_norm"] is True
    env = make_vec_env(spec, seed=0)
    model = build_model(spec, env, seed=0)
    assert isinstance(model.replay_buffer, NStepReplayBuffer)
    assert model.replay_buffer.n_steps == 3
    critic_params = model.policy.qf_state.params["params"]
    assert any("LayerNorm" in name for name in _names(critic_params))
    model.learn(64)  # trains through the n-step samples
    actions, _ = model.predict(env.reset(), deterministic=True)
    assert np.isfinite(actions).all()


def test_per_arm_critics_learn_n_step_returns_of_each_share() -> None:
    spec = _spec(
        n_step_returns=3,
        critic="per_arm",
        per_arm_networks=True,
        actor_observation="own_arm",
    )
    env = make_vec_env(spec, seed=0)
    model = build_model(spec, env, seed=0)
    assert isinstance(model.replay_buffer, RewardShareReplayBuffer)
    assert (model.replay_buffer.n_steps, model.replay_buffer.gamma) == (3, spec.algo.gamma)
    model.learn(64)  # trains through the n-step samples
    actions, _ = model.predict(env.reset(), deterministic=True)
    assert np.isfinite(actions).all()


def _names(tree: object, prefix: str = "") -> list[str]:
    if not isinstance(tree, dict):
        return [prefix]
    return [n for key, value in tree.items() for n in _names(value, f"{prefix}/{key}")]


@pytest.mark.parametrize(
    ("algo", "message"),
    [
        ({"name": "ppo", "n_step_returns": 3}, "n_step_returns 3 applies to the off-policy"),
        ({"backend": "sb3", "policy_kwargs": {"layer_norm": True}}, "layer_norm is implemented"),
        ({"n_step_returns": 0}, "n_step_returns"),
    ],
)
def test_unsupported_settings_are_rejected(algo: dict, message: str) -> None:
    with pytest.raises(SpecError, match=message):
        _spec(**algo)


def _ppo(log_std_init: float):  # type: ignore[no-untyped-def]
    algo = {"name": "ppo", "device": "cpu", "n_steps": 16, "batch_size": 16}
    algo["policy_kwargs"] = {"log_std_init": log_std_init}
    return parse_spec({"training": {"n_envs": 2, "total_timesteps": 200}, "algo": algo})


def test_ppo_log_std_init_reaches_the_policy() -> None:
    spec = _ppo(-4.0)
    assert spec.algo.sb3_kwargs(resolve_activation=False)["policy_kwargs"]["log_std_init"] == -4.0
    assert spec_hash(spec) != spec_hash(_ppo(0.0))
    model = build_model(spec, make_vec_env(spec, seed=0), seed=0)
    np.testing.assert_allclose(model.policy.log_std.detach().numpy(), -4.0)


def test_mirror_images_are_n_step_columns_of_their_own() -> None:
    """With mirror replay, n-step returns run along each environment's episode and, in their
    own columns, along its mirror image: the sampled n-step rewards of a mirrored column equal
    the real column's, and its observations are the mirror images."""
    from softtrack.rl.variants.mirror import MirrorNStepReplayBuffer, mirror_observation

    spec = _spec(n_step_returns=3, mirror_replay=True)
    env = make_vec_env(spec, seed=0)
    model = build_model(spec, env, seed=0)
    buffer = model.replay_buffer
    assert isinstance(buffer, MirrorNStepReplayBuffer)
    assert buffer.n_envs == 4 and buffer.n_steps == 3
    model.learn(60)
    stored = buffer.pos
    np.testing.assert_array_equal(buffer.rewards[:stored, :2], buffer.rewards[:stored, 2:])
    np.testing.assert_allclose(
        buffer.observations[:stored, 2:], mirror_observation(buffer.observations[:stored, :2])
    )
    np.random.seed(0)
    samples = buffer.sample(32)
    assert samples.discounts is not None
    assert np.isfinite(samples.rewards.numpy()).all()
