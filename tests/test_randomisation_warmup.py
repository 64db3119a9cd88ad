"""The domain-randomisation curriculum: ``RealismModel.strength`` and
``training.randomisation_warmup_steps`` (:class:`softtrack.rl.callbacks.RandomisationWarmup`);
training with either curriculum (the transport goal's: tests/test_goal_warmup.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from stable_baselines3 import TD3
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

from softtrack import api
from softtrack.env import TrackingCore, make_config
from softtrack.env.vec_env import TrackingVecEnv
from softtrack.rl import policy_training
from softtrack.rl.callbacks import GoalMotionWarmup, RandomisationWarmup
from softtrack.spec import SpecError, parse_spec, spec_hash
from softtrack.spec.spec_io import _FIELDS_ADDED_LATER

RANGES = {
    "youngs_modulus_scale": [0.6, 1.3],
    "damping_scale": [0.8, 1.25],
    "torque_scale_factor": [0.85, 1.15],
    "density_scale": 1.1,
}
NOISE = {"obs_noise_node_position": 0.005, "obs_noise_speed": 0.02}
DR = {**RANGES, **NOISE, "action_delay": 1, "action_delay_max": 5}


def _core(strength: float, n_envs: int = 8, seed: int = 4) -> TrackingCore:
    core = TrackingCore(n_envs, make_config(realism=DR))
    core.realism.strength = strength
    core.reset(np.arange(n_envs), [np.random.default_rng(seed + i) for i in range(n_envs)])
    return core


def test_strength_narrows_the_ranges_towards_one_with_the_same_draws() -> None:
    full, quarter, none = _core(1.0), _core(0.25), _core(0.0)
    f = full.engine.factors
    assert np.all((f[:, 0] >= 0.6) & (f[:, 0] <= 1.3)) and len(set(f[:, 0].tolist())) == 8
    ranged = [0, 3, 4]  # E, damping, actuator gain
    np.testing.assert_allclose(
        quarter.engine.factors[:, ranged], 1 + 0.25 * (f[:, ranged] - 1), rtol=1e-12
    )
    np.testing.assert_array_equal(none.engine.factors[:, ranged], 1.0)
    for core in (full, quarter, none):  # a fixed factor is the plant: never ramped
        np.testing.assert_array_equal(core.engine.factors[:, 1], 1.1)


def test_strength_narrows_the_delay_range_from_the_fixed_delay() -> None:
    assert set(_core(0.0, n_envs=32).realism.action_delays.tolist()) == {1}
    half = set(_core(0.5, n_envs=32).realism.action_delays.tolist())
    assert half <= {1, 2, 3} and len(half) > 1  # 1 + round(0.5·4) = 3 at most
    assert max(_core(1.0, n_envs=32).realism.action_delays.tolist()) == 5


def test_strength_scales_the_noise_with_the_same_draws() -> None:
    errors = {}
    for strength in (1.0, 0.5, 0.0):
        core = _core(strength, n_envs=2)
        seen = core.step(np.full((2, 24), 0.3)).observation
        errors[strength] = seen - core.observe()
    assert np.abs(errors[1.0]).max() > 1e-3
    np.testing.assert_allclose(errors[0.5], 0.5 * errors[1.0], atol=1e-6)  # float32 reading
    np.testing.assert_array_equal(errors[0.0], 0.0)


@pytest.mark.parametrize("value", [-0.1, 1.5, float("nan")])
def test_strength_outside_zero_to_one_is_an_error(value: float) -> None:
    core = TrackingCore(1, make_config(realism=DR))
    with pytest.raises(ValueError, match="must lie in"):
        core.realism.strength = value


class _Recorder(BaseCallback):
    """The strength and each (re)started episode's delay seen before every env step."""

    def __init__(self, core: TrackingCore) -> None:
        super().__init__()
        self.core = core
        self.rows: list[tuple[int, float, int]] = []

    def _on_step(self) -> bool:
        self.rows.append(
            (
                self.num_timesteps,
                self.core.realism.strength,
                int(self.core.realism.action_delays.max()),
            )
        )
        return True


def test_warmup_ramps_the_training_environments_through_their_wrappers() -> None:
    venv = TrackingVecEnv(2, make_config(realism=DR, episode_duration=0.02))
    env = VecNormalize(VecMonitor(venv))
    warmup = RandomisationWarmup(200, env)
    assert venv.core.realism.strength == 0.0  # before the model's first reset
    env.seed(0)
    model = TD3("MlpPolicy", env, learning_starts=1000, policy_kwargs={"net_arch": [8]}, seed=0)
    recorder = _Recorder(venv.core)
    model.learn(300, callback=[warmup, recorder])
    steps, strengths, delays = (np.array(column) for column in zip(*recorder.rows, strict=True))
    np.testing.assert_allclose(strengths, np.minimum(1.0, steps / 200))
    # 10-step episodes restart every 20 env steps: those begun at strength ≤ 0.09 (steps 0 and
    # 20) have the delay 1 + round(≤ 0.36 · 4) = 1; at full strength it is drawn from 1 … 5
    assert delays[steps < 40].max() == 1
    assert delays[steps > 220].max() >= 4
    # a resumed run starts at its step count's strength
    RandomisationWarmup(200, env, step=50)
    assert venv.core.realism.strength == 0.25


def test_warmup_needs_realism_and_a_positive_length() -> None:
    with pytest.raises(ValueError, match=r"needs env.realism"):
        RandomisationWarmup(10, VecMonitor(TrackingVecEnv(1, make_config())))
    with pytest.raises(ValueError, match="must be > 0"):
        RandomisationWarmup(0, TrackingVecEnv(1, make_config(realism=DR)))


def _spec(realism: dict | None = None, **training: object) -> dict:
    return {
        "env": {"realism": realism or {"youngs_modulus_scale": [0.7, 1.3]}},
        "algo": {"learning_starts": 100},
        "training": {"total_timesteps": 1000, **training},
    }


def test_spec_field_is_hash_neutral_off_and_checked_on() -> None:
    assert _FIELDS_ADDED_LATER[("training", "randomisation_warmup_steps")] == 0
    assert spec_hash(parse_spec(_spec())) == spec_hash(
        parse_spec(_spec(randomisation_warmup_steps=0))
    )
    assert spec_hash(parse_spec(_spec(randomisation_warmup_steps=500))) != spec_hash(
        parse_spec(_spec())
    )
    with pytest.raises(SpecError, match="randomisation_warmup_steps 2000 > total_timesteps"):
        parse_spec(_spec(randomisation_warmup_steps=2000))
    fixed_only = {"action_delay": 2, "action_delay_max": 2, "youngs_modulus_scale": 0.7}
    with pytest.raises(SpecError, match="has none"):
        parse_spec(_spec(fixed_only, randomisation_warmup_steps=10))
    for random in (
        {"obs_noise_direction": 0.01},
        {"obs_drop_probability": 0.1},
        {"action_delay_max": 1},
    ):
        parse_spec(_spec(random, randomisation_warmup_steps=10))


CURRICULA = {
    "randomisation": (
        RandomisationWarmup,
        {"realism": {"youngs_modulus_scale": [0.9, 1.1]}},
        lambda warmup: warmup.realism.strength,
    ),
    "goal": (
        GoalMotionWarmup,
        {
            "physics": {"contact_k": 1e6, "contact_nu": 600.0, "sphere": {}},
            "task": {"name": "transport"},
        },
        lambda warmup: warmup.transport.goal_motion,
    ),
}


@pytest.mark.parametrize("curriculum", sorted(CURRICULA))
def test_training_a_spec_with_a_warmup_ramps_its_environments(
    curriculum: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``training.randomisation_warmup_steps`` and ``training.goal_warmup_steps``: a trained
    spec's callback follows min(1, step / N) at every env step."""
    base, env, strength = CURRICULA[curriculum]
    made: list[Any] = []

    class Recorded(base):  # type: ignore[misc, valid-type]
        def __init__(self, warmup_steps: int, env: object, step: int = 0) -> None:
            super().__init__(warmup_steps, env, step)
            self.seen: list[tuple[int, float]] = []
            made.append(self)

        def _on_step(self) -> bool:
            result = super()._on_step()
            self.seen.append((self.num_timesteps, strength(self)))
            return result

    monkeypatch.setattr(policy_training, base.__name__, Recorded)
    spec = {
        "name": "tiny-warmup",
        "seeds": [0],
        "env": {"episode_duration": 0.1, **env},
        "algo": {
            "name": "td3",
            "backend": "sb3",
            "device": "cpu",
            "batch_size": 16,
            "learning_starts": 50,
            "buffer_size": 5000,
            "policy_kwargs": {"net_arch": [16, 16]},
        },
        "training": {
            "total_timesteps": 400,
            "n_envs": 2,
            "checkpoint_interval": 0,
            f"{curriculum}_warmup_steps": 200,
        },
    }
    path = tmp_path / "warmup.yaml"
    path.write_text(yaml.safe_dump(spec), encoding="utf-8")
    [outcome] = api.train(path, runs_dir=tmp_path / "runs", show_progress=False)
    assert outcome.status == "completed" and len(made) == 1
    steps, strengths = (np.array(column) for column in zip(*made[0].seen, strict=True))
    assert made[0].warmup_steps == 200 and steps[-1] == 400
    np.testing.assert_allclose(strengths, np.minimum(1.0, steps / 200))
