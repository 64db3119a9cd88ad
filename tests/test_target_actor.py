"""``algo.act_with_target_actor``: validation, evaluation and export act with TD3's target actor."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from softtrack.rl.target_actor import act_with_target_actor, acting_with_target_actor
from softtrack.spec import SpecError, parse_spec, spec_hash


def _tiny_td3(backend: str) -> Any:
    """A TD3 on Pendulum after 60 steps, its actor away from its average (tau 0.05)."""
    import gymnasium as gym

    if backend == "sbx":
        from sbx import TD3
    else:
        from stable_baselines3 import TD3
    device = {"device": "cpu"} if backend == "sb3" else {}
    model = TD3(
        "MlpPolicy",
        gym.make("Pendulum-v1"),
        learning_starts=20,
        seed=0,
        tau=0.05,
        policy_kwargs={"net_arch": [8]},
        **device,
    )
    model.learn(60)
    return model


@pytest.mark.parametrize("backend", ["sbx", "sb3"])
def test_a_training_model_acts_with_its_target_actor_inside_and_its_own_after(
    backend: str,
) -> None:
    model = _tiny_td3(backend)
    obs = np.linspace(-1, 1, 3, dtype=np.float32)[None, :]
    own = model.predict(obs, deterministic=True)[0]
    with acting_with_target_actor(model):
        target = model.predict(obs, deterministic=True)[0]
    assert not np.allclose(own, target)
    assert np.array_equal(model.predict(obs, deterministic=True)[0], own)
    with acting_with_target_actor(model, enabled=False):
        assert np.array_equal(model.predict(obs, deterministic=True)[0], own)
    act_with_target_actor(model)
    assert np.array_equal(model.predict(obs, deterministic=True)[0], target)


def test_an_exported_sbx_model_keeps_the_target_actor_it_acts_with(tmp_path: Path) -> None:
    from sbx import TD3

    from softtrack.rl.policy_export import strip_training_state

    model = _tiny_td3("sbx")
    obs = np.linspace(-1, 1, 3, dtype=np.float32)[None, :]
    with acting_with_target_actor(model):
        target = model.predict(obs, deterministic=True)[0]
    act_with_target_actor(model)
    strip_training_state(model)
    model.save(tmp_path / "model.zip")
    exported = TD3.load(tmp_path / "model.zip", device="cpu")
    act_with_target_actor(exported)  # nothing to swap: it acts with the average already
    assert np.array_equal(exported.predict(obs, deterministic=True)[0], target)


def test_only_td3_and_ddpg_have_a_target_actor_and_the_default_keeps_every_hash() -> None:
    with pytest.raises(SpecError, match="ppo has no target actor") as error:
        parse_spec({"algo": {"name": "ppo", "act_with_target_actor": True}})
    assert "act_with_target_actor" in str(error.value)
    spec = parse_spec({"algo": {"name": "td3"}})
    assert spec_hash(spec) == spec_hash(parse_spec({"algo": {"act_with_target_actor": False}}))
    assert spec_hash(spec) != spec_hash(parse_spec({"algo": {"act_with_target_actor": True}}))
