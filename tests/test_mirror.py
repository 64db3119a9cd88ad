"""Mirror-image transitions (``algo.mirror_replay``): the maps, the engine's equivariance under
them, the replay buffer that stores both, and a training run with it."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.env import DualArmTrackingEnv
from softtrack.env.vec_env import TrackingVecEnv
from softtrack.rl.variants.mirror import MirrorReplayBuffer, mirror_action, mirror_observation
from softtrack.store.runs import RunStore

runner = CliRunner()


def test_mirror_maps_swap_the_arms_and_negate_x() -> None:
    obs = np.arange(81, dtype=np.float32)[None]
    mirrored = mirror_observation(obs)[0]
    np.testing.assert_array_equal(mirrored[0:11], -obs[0, 37:48])  # arm 2's node x, negated
    np.testing.assert_array_equal(mirrored[11:34], obs[0, 48:71])  # its y, z and tip speed
    assert mirrored[34] == -obs[0, 71] and mirrored[71] == -obs[0, 34]
    np.testing.assert_array_equal(mirrored[74:81], [-74, 75, 76, 77, -78, 79, 80])
    action = np.arange(24, dtype=np.float32)
    np.testing.assert_array_equal(
        mirror_action(action),
        np.r_[-np.arange(12, 18), np.arange(18, 24), -np.arange(0, 6), np.arange(6, 12)],
    )
    rng = np.random.default_rng(0)
    obs, action = rng.normal(size=(5, 81)), rng.normal(size=(3, 5, 24))
    np.testing.assert_array_equal(mirror_observation(mirror_observation(obs)), obs)
    np.testing.assert_array_equal(mirror_action(mirror_action(action)), action)
    with pytest.raises(ValueError, match="81"):
        mirror_observation(np.zeros(44))
    with pytest.raises(ValueError, match="24"):
        mirror_action(np.zeros(12))


@pytest.mark.parametrize("target", [(0.2, 0.7, 0.1), (-0.35, 0.5, -0.2)])
def test_the_engine_is_mirror_equivariant_bit_for_bit(target: tuple[float, float, float]) -> None:
    """Full-range random actions coil the arms; the mirrored scene still matches exactly."""
    env = DualArmTrackingEnv(target="fixed", fixed_position=target)
    twin = DualArmTrackingEnv(target="fixed", fixed_position=(-target[0], *target[1:]))
    obs, _ = env.reset(seed=0)
    twin_obs, _ = twin.reset(seed=0)
    np.testing.assert_array_equal(mirror_observation(obs), twin_obs)
    actions = np.random.default_rng(1).uniform(-1, 1, (300, 24)).astype(np.float32)
    for action in actions:
        obs, reward, *_ = env.step(action)
        twin_obs, twin_reward, *_ = twin.step(mirror_action(action))
        np.testing.assert_array_equal(mirror_observation(obs), twin_obs)
        assert reward == twin_reward
    assert np.abs(obs[0:11] + obs[37:48]).max() > 0.1  # the arms did not move symmetrically


def test_buffer_stores_each_transition_and_its_mirror_image() -> None:
    venv = TrackingVecEnv(2, episode_duration=0.01)
    buffer = MirrorReplayBuffer(
        40, venv.observation_space, venv.action_space, device="cpu", n_envs=2
    )
    rng = np.random.default_rng(2)
    obs, next_obs = rng.normal(size=(2, 2, 81)).astype(np.float32)
    action = rng.uniform(-1, 1, (2, 24)).astype(np.float32)
    reward, done = np.array([0.5, -1.0], np.float32), np.array([0.0, 1.0], np.float32)
    buffer.add(obs, next_obs, action, reward, done, [{}, {"TimeLimit.truncated": True}])
    assert buffer.pos == 2
    np.testing.assert_array_equal(buffer.observations[0], obs)
    np.testing.assert_array_equal(buffer.observations[1], mirror_observation(obs))
    np.testing.assert_array_equal(buffer.next_observations[1], mirror_observation(next_obs))
    np.testing.assert_array_equal(buffer.actions[1], mirror_action(action))
    np.testing.assert_array_equal(buffer.rewards[1], reward)
    np.testing.assert_array_equal(buffer.dones[1], done)
    np.testing.assert_array_equal(buffer.timeouts[1], [False, True])


@pytest.mark.parametrize("backend", ["sb3", "sbx"])
def test_train_a_mirror_replay_run(tmp_path: Path, backend: str) -> None:
    if backend == "sbx":
        pytest.importorskip("sbx", reason="sbx-rl (JAX) not installed")
    data = {
        "name": "tiny-mirror",
        "seeds": [0],
        "env": {"episode_duration": 0.1},
        "algo": {
            "name": "td3",
            "backend": backend,
            "batch_size": 16,
            "learning_starts": 50,
            "buffer_size": 5000,
            "mirror_replay": True,
            "policy_kwargs": {"net_arch": [16, 16]},
        },
        "training": {"total_timesteps": 400, "n_envs": 2, "checkpoint_interval": 200},
    }
    spec = tmp_path / "mirror.yaml"
    spec.write_text(yaml.safe_dump(data), encoding="utf-8")
    runs_dir = tmp_path / "runs"
    result = runner.invoke(app, ["train", str(spec), "--runs-dir", str(runs_dir)], env={"CI": "1"})
    assert result.exit_code == 0, result.output
    record = RunStore(runs_dir).get_run(result.stdout.strip())
    assert record.info.status == "completed"

    checkpoint = record.list_checkpoints()[0]
    with (checkpoint / "replay_buffer.pkl").open("rb") as handle:
        buffer = pickle.load(handle)
    assert isinstance(buffer, MirrorReplayBuffer)
    # two slots per vector step; SB3 checkpoints before storing its 100th (200 env steps / 2 envs)
    assert buffer.pos == 2 * 99
    stored = buffer.observations[: buffer.pos]
    np.testing.assert_array_equal(stored[1::2], mirror_observation(stored[0::2]))
    np.testing.assert_array_equal(
        buffer.actions[1 : buffer.pos : 2], mirror_action(buffer.actions[0 : buffer.pos : 2])
    )
