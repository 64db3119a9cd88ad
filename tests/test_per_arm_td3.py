"""TD3 with per-arm critic outputs (``algo.critic: per_arm``): buffer, critic update, CLI run."""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

pytest.importorskip("sbx", reason="sbx-rl (JAX) not installed")

import jax
import jax.numpy as jnp
from stable_baselines3.common.buffers import NStepReplayBuffer, ReplayBuffer

from softtrack.cli import app
from softtrack.env.vec_env import TrackingVecEnv
from softtrack.rl.factory import model_class
from softtrack.rl.variants.per_arm import PerArmTD3, RewardShareReplayBuffer
from softtrack.spec import load_spec
from softtrack.store.runs import RunStore

runner = CliRunner()


def _buffer(n_envs: int = 2) -> RewardShareReplayBuffer:
    venv = TrackingVecEnv(n_envs, episode_duration=0.01)
    return RewardShareReplayBuffer(
        100, venv.observation_space, venv.action_space, device="cpu", n_envs=n_envs
    )


def test_buffer_samples_the_shares_of_the_sampled_transitions() -> None:
    buffer = _buffer()
    obs = np.zeros((2, 81), np.float32)
    for step in range(20):
        ids = np.array([step * 2, step * 2 + 1], dtype=np.float32)
        obs[:, 0] = ids
        infos = [{"reward_shares": np.array([i, -3 * i], np.float32)} for i in ids]
        buffer.add(obs, obs, np.zeros((2, 24), np.float32), ids * 7, np.zeros(2), infos)
    sample = buffer.sample(64)
    rewards, first = sample.rewards.numpy(), sample.observations.numpy()[:, 0]
    assert rewards.shape == (64, 2) and sample.dones.shape == (64, 1)
    np.testing.assert_array_equal(rewards[:, 0], first)
    np.testing.assert_array_equal(rewards[:, 1], -3 * first)


def _fill_alike(buffers: list[Any], n_envs: int, steps: int, seed: int) -> None:
    """Add the same random transitions, with episode ends and time-outs, to every buffer."""
    rng = np.random.default_rng(seed)
    for step in range(steps):
        obs = rng.normal(size=(n_envs, 81)).astype(np.float32)
        obs[:, 0] = step
        next_obs = rng.normal(size=(n_envs, 81)).astype(np.float32)
        shares = rng.normal(size=(n_envs, 2)).astype(np.float32)
        done = rng.random(n_envs) < 0.15
        timeout = done & (rng.random(n_envs) < 0.5)
        infos = [
            {"reward_shares": shares[e], "TimeLimit.truncated": bool(timeout[e])}
            for e in range(n_envs)
        ]
        action = rng.uniform(-1, 1, (n_envs, 24)).astype(np.float32)
        for buffer in buffers:
            buffer.add(obs, next_obs, action, shares.sum(axis=1), done, infos)


@pytest.mark.parametrize(("capacity", "steps"), [(100, 40), (30, 47)])
def test_n_step_shares_sum_to_sb3s_n_step_return_of_the_summed_reward(
    capacity: int, steps: int
) -> None:
    venv = TrackingVecEnv(3, episode_duration=0.01)
    spaces_ = (venv.observation_space, venv.action_space)
    shares = RewardShareReplayBuffer(capacity, *spaces_, "cpu", n_envs=3, n_steps=3, gamma=0.9)
    summed = NStepReplayBuffer(capacity, *spaces_, "cpu", n_envs=3, n_steps=3, gamma=0.9)
    _fill_alike([shares, summed], n_envs=3, steps=steps, seed=capacity)
    np.random.seed(5)
    ours = shares.sample(256)
    np.random.seed(5)
    theirs = summed.sample(256)
    assert ours.rewards.shape == (256, 2) and ours.discounts.shape == (256, 1)
    np.testing.assert_allclose(
        ours.rewards.numpy().sum(axis=1), theirs.rewards.numpy()[:, 0], atol=1e-5
    )
    for field in ("observations", "actions", "next_observations", "dones", "discounts"):
        np.testing.assert_array_equal(getattr(ours, field).numpy(), getattr(theirs, field).numpy())
    assert (ours.discounts.numpy() < 0.9**2).any()  # some sequences run the full three steps


def test_one_step_shares_sample_as_sb3s_one_step_buffer() -> None:
    venv = TrackingVecEnv(3, episode_duration=0.01)
    spaces_ = (venv.observation_space, venv.action_space)
    shares = RewardShareReplayBuffer(50, *spaces_, "cpu", n_envs=3)
    plain = ReplayBuffer(50, *spaces_, "cpu", n_envs=3)
    _fill_alike([shares, plain], n_envs=3, steps=70, seed=1)
    np.random.seed(2)
    ours = shares.sample(128)
    np.random.seed(2)
    theirs = plain.sample(128)
    np.testing.assert_allclose(
        ours.rewards.numpy().sum(axis=1), theirs.rewards.numpy()[:, 0], atol=1e-5
    )
    for field in ("observations", "actions", "next_observations", "dones"):
        np.testing.assert_array_equal(getattr(ours, field).numpy(), getattr(theirs, field).numpy())
    np.testing.assert_array_equal(ours.discounts.numpy(), np.float32(0.99))


def test_buffer_without_shares_in_the_infos_names_the_fix() -> None:
    buffer = _buffer()
    obs = np.zeros((2, 81), np.float32)
    with pytest.raises(ValueError, match=r"reward_shares=True"):
        buffer.add(obs, obs, np.zeros((2, 24), np.float32), np.zeros(2), np.zeros(2), [{}, {}])


def _model(per_arm_networks: bool) -> PerArmTD3:
    venv = TrackingVecEnv(2, reward_shares=True, episode_duration=0.01)
    return PerArmTD3(
        "MlpPolicy",
        venv,
        learning_rate=1e-2,
        learning_starts=10,
        policy_kwargs={"net_arch": [16, 16]},
        seed=0,
        per_arm_networks=per_arm_networks,
    )


def _perturbed(params: Any, arm_axis: int, arm: int) -> Any:
    """``params`` with 1 added to every weight of arm ``arm``'s networks (stacked on an axis)."""

    def bump(leaf: jax.Array) -> jax.Array:
        index = (slice(None),) * arm_axis + (arm,)
        return leaf.at[index].add(1.0)

    return jax.tree_util.tree_map(bump, params)


def test_per_arm_networks_give_each_arm_its_own_actions_and_q_values() -> None:
    model = _model(per_arm_networks=True)
    rng = np.random.default_rng(1)
    obs = jnp.asarray(rng.normal(size=(5, 81)), jnp.float32)
    actions = jnp.asarray(rng.uniform(-1, 1, (5, 24)), jnp.float32)
    actor, qf = model.policy.actor_state, model.policy.qf_state
    base_actions = np.asarray(actor.apply_fn(actor.params, obs))
    base_q = np.asarray(qf.apply_fn(qf.params, obs, actions))
    assert base_actions.shape == (5, 24) and base_q.shape == (2, 5, 2)
    for arm in (0, 1):
        mine = slice(12 * arm, 12 * arm + 12)
        others = slice(12 * (1 - arm), 12 * (1 - arm) + 12)
        moved = np.asarray(actor.apply_fn(_perturbed(actor.params, 0, arm), obs))
        assert not np.allclose(moved[:, mine], base_actions[:, mine])
        np.testing.assert_array_equal(moved[:, others], base_actions[:, others])
        # the critics are stacked twin-major: network c·2 + arm
        for twin in (0, 1):
            moved_q = np.asarray(
                qf.apply_fn(_perturbed(qf.params, 0, 2 * twin + arm), obs, actions)
            )
            assert not np.allclose(moved_q[twin, :, arm], base_q[twin, :, arm])
            unchanged = np.ones((2, 2), bool)
            unchanged[twin, arm] = False
            np.testing.assert_array_equal(
                moved_q.transpose(0, 2, 1)[unchanged], base_q.transpose(0, 2, 1)[unchanged]
            )


@pytest.mark.parametrize("per_arm_networks", [False, True])
def test_each_critic_output_learns_its_own_arms_reward(per_arm_networks: bool) -> None:
    model = _model(per_arm_networks)
    qf_state, key = model.policy.qf_state, model.key
    rng = np.random.default_rng(0)
    obs = jnp.asarray(rng.normal(size=(32, 81)), jnp.float32)
    actions = jnp.asarray(rng.uniform(-1, 1, (32, 24)), jnp.float32)
    rewards = jnp.tile(jnp.array([[1.0, -2.0]]), (32, 1))
    terminal = jnp.ones(32)  # no bootstrap: the target is the reward itself
    for _ in range(300):
        qf_state, _, key = PerArmTD3.update_critic(
            model.policy.actor_state,
            qf_state,
            obs,
            actions,
            obs,
            rewards,
            terminal,
            jnp.full(32, 0.99),
            0.2,
            0.5,
            key,
        )
    q = np.asarray(qf_state.apply_fn(qf_state.params, obs, actions))
    assert q.shape == (2, 32, 2)  # (twin critics, batch, arms)
    np.testing.assert_allclose(q[..., 0], 1.0, atol=0.05)
    np.testing.assert_allclose(q[..., 1], -2.0, atol=0.05)


def _spec(tmp_path: Path, per_arm_networks: bool = False, actor_observation: str = "full") -> Path:
    data = {
        "name": "tiny-per-arm",
        "seeds": [0],
        "env": {"episode_duration": 0.1},
        "algo": {
            "name": "td3",
            "backend": "sbx",
            "critic": "per_arm",
            "batch_size": 16,
            "learning_starts": 50,
            "buffer_size": 5000,
            "gradient_steps": 2,
            "policy_kwargs": {"net_arch": [16, 16]},
            "per_arm_networks": per_arm_networks,
            "actor_observation": actor_observation,
        },
        "training": {"total_timesteps": 400, "n_envs": 2, "checkpoint_interval": 200},
    }
    path = tmp_path / "per-arm.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("per_arm_networks", "actor_observation"),
    [(False, "full"), (True, "full"), (True, "own_arm")],
)
def test_train_checkpoint_and_evaluate_a_per_arm_run(
    tmp_path: Path, per_arm_networks: bool, actor_observation: str
) -> None:
    runs_dir = tmp_path / "runs"
    spec = _spec(tmp_path, per_arm_networks, actor_observation)
    result = runner.invoke(app, ["train", str(spec), "--runs-dir", str(runs_dir)], env={"CI": "1"})
    assert result.exit_code == 0, result.output
    run_id = result.stdout.strip()
    record = RunStore(runs_dir).get_run(run_id)
    assert record.info.status == "completed"

    model = model_class(record.load_spec()).load(str(record.model_path))
    assert isinstance(model, PerArmTD3) and model.n_reward_shares == 2
    assert model.policy.per_arm_networks == per_arm_networks
    assert model.policy.actor_observation == actor_observation
    obs = np.zeros((1, 81), np.float32)
    assert model.policy.qf_state.apply_fn(
        model.policy.qf_state.params, obs, np.zeros((1, 24), np.float32)
    ).shape == (2, 1, 2)

    checkpoint = record.list_checkpoints()[0]
    with (checkpoint / "replay_buffer.pkl").open("rb") as handle:
        buffer = pickle.load(handle)
    assert isinstance(buffer, RewardShareReplayBuffer)
    stored = buffer.reward_shares[: buffer.pos]
    np.testing.assert_allclose(stored.sum(axis=-1), buffer.rewards[: buffer.pos], atol=1e-4)
    assert (stored[..., 0] != stored[..., 1]).any()

    evaluated = runner.invoke(
        app, ["evaluate", run_id, "--runs-dir", str(runs_dir), "--trajectory", "circle"]
    )
    assert evaluated.exit_code == 0, evaluated.output
    assert "circle" in evaluated.stdout


SHIPPED = Path(__file__).resolve().parents[1] / "models" / "td3-sbx-per-arm-4e6-seed0"


@pytest.mark.skipif(not SHIPPED.is_dir(), reason="shipped per-arm model not in this checkout")
def test_a_model_saved_before_per_arm_networks_loads_as_one_network() -> None:
    model = model_class(load_spec(SHIPPED / "spec.yaml")).load(str(SHIPPED / "model.zip"))
    assert model.policy.per_arm_networks is False
    assert model.policy.actor_observation == "full"
    action, _ = model.predict(np.zeros((1, 81), np.float32), deterministic=True)
    assert action.shape == (1, 24) and np.isfinite(action).all()


def test_own_arm_actors_see_only_their_arm_and_the_target() -> None:
    venv = TrackingVecEnv(2, reward_shares=True, episode_duration=0.01)
    model = PerArmTD3(
        "MlpPolicy",
        venv,
        learning_starts=10,
        policy_kwargs={"net_arch": [16, 16]},
        seed=0,
        per_arm_networks=True,
        actor_observation="own_arm",
    )
    actor = model.policy.actor_state
    rng = np.random.default_rng(2)
    obs = rng.normal(size=(4, 81)).astype(np.float32)
    base = np.asarray(actor.apply_fn(actor.params, obs))
    assert base.shape == (4, 24)
    for arm in (0, 1):
        mine, others = slice(12 * arm, 12 * arm + 12), slice(12 - 12 * arm, 24 - 12 * arm)
        moved_obs = obs.copy()
        moved_obs[:, 37 * arm : 37 * (arm + 1)] += 1.0  # this arm's block only
        moved = np.asarray(actor.apply_fn(actor.params, moved_obs))
        assert not np.allclose(moved[:, mine], base[:, mine])
        np.testing.assert_array_equal(moved[:, others], base[:, others])
    moved_obs = obs.copy()
    moved_obs[:, -7:] += 1.0  # the target moves every arm's actions
    moved = np.asarray(actor.apply_fn(actor.params, moved_obs))
    assert not np.allclose(moved[:, :12], base[:, :12])
    assert not np.allclose(moved[:, 12:], base[:, 12:])
