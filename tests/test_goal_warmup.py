"""The transport curriculum: ``TransportModel.goal_motion`` and ``training.goal_warmup_steps``
(:class:`softtrack.rl.callbacks.GoalMotionWarmup`; training with it:
tests/test_randomisation_warmup.py)."""

from __future__ import annotations

import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

from softtrack.env import TrackingCore, make_config
from softtrack.env.vec_env import TrackingVecEnv
from softtrack.rl.callbacks import GoalMotionWarmup
from softtrack.spec import SpecError, parse_spec, spec_hash
from softtrack.spec.spec_io import _FIELDS_ADDED_LATER

TRANSPORT = {"task": "transport", "sphere": {}, "contact_k": 1e6, "contact_nu": 600.0}
SQUEEZE = np.zeros(24)
SQUEEZE[0:6], SQUEEZE[12:18] = -0.03, 0.03


def _goals(motion: float, steps: int = 700) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Goals and goal velocities after 1 … ``steps`` control steps (circle, 1-s approach) at
    ``motion``, and the sphere's start."""
    core = TrackingCore(1, make_config(target="circle", approach=1.0, **TRANSPORT))
    assert core.transport is not None
    core.transport.goal_motion = motion
    core.reset([0], [np.random.default_rng(0)])
    goals, velocities = [], []
    for _ in range(steps):
        core.step(SQUEEZE[None])
        goals.append(core.transport.goal_position[0].copy())
        velocities.append(core.transport.goal_velocity[0].copy())
    return np.array(goals), np.array(velocities), np.asarray(core.transport.start)


def test_goal_motion_scales_the_goal_about_the_spheres_start() -> None:
    """m = 0 keeps the goal (and its velocity) at the start; m = 0.5 halves every offset from
    it and every velocity, through the approach and on the path; m = 1 is the task."""
    full, full_velocity, start = _goals(1.0)
    still, still_velocity, _ = _goals(0.0)
    half, half_velocity, _ = _goals(0.5)
    np.testing.assert_array_equal(still, np.broadcast_to(start, still.shape))
    np.testing.assert_array_equal(still_velocity, 0.0)
    np.testing.assert_allclose(half - start, 0.5 * (full - start), atol=1e-12)
    np.testing.assert_allclose(half_velocity, 0.5 * full_velocity, atol=1e-12)
    assert np.linalg.norm(full[-1] - start) > 0.3  # on the circle, far from the start


def test_goal_ahead_follows_the_scaled_goal() -> None:
    core = TrackingCore(1, make_config(target="circle", approach=0.5, **TRANSPORT))
    assert core.transport is not None
    core.transport.goal_motion = 0.25
    core.reset([0], [np.random.default_rng(0)])
    for _ in range(200):
        core.step(SQUEEZE[None])
    ahead = core.transport.goal_ahead(int(core.step_count[0]), core.targets, 0, np.arange(1, 101))
    reached = []
    for _ in range(100):
        core.step(SQUEEZE[None])
        reached.append(core.transport.goal_position[0].copy())
    np.testing.assert_allclose(ahead, np.array(reached), atol=1e-12)


def test_warmup_ramps_the_training_environments_through_their_wrappers() -> None:
    venv = TrackingVecEnv(2, make_config(episode_duration=0.02, **TRANSPORT))
    env = VecNormalize(VecMonitor(venv))
    warmup = GoalMotionWarmup(200, env)
    assert venv.core.transport is not None and venv.core.transport.goal_motion == 0.0
    GoalMotionWarmup(200, env, step=50)  # a resumed run starts at its step count's motion
    assert venv.core.transport.goal_motion == 0.25
    warmup.num_timesteps = 300
    warmup._on_step()
    assert venv.core.transport.goal_motion == 1.0


def test_warmup_needs_the_transport_task_and_a_positive_length() -> None:
    with pytest.raises(ValueError, match="needs the transport task"):
        GoalMotionWarmup(10, VecMonitor(TrackingVecEnv(1, make_config())))
    with pytest.raises(ValueError, match="must be > 0"):
        GoalMotionWarmup(0, TrackingVecEnv(1, make_config(**TRANSPORT)))


def _spec(task: str = "transport", **training: object) -> dict:
    env: dict = {"task": {"name": task}}
    if task == "transport":
        env["physics"] = {"contact_k": 1e6, "contact_nu": 600.0, "sphere": {}}
    return {
        "env": env,
        "algo": {"learning_starts": 100},
        "training": {"total_timesteps": 1000, **training},
    }


def test_spec_field_is_hash_neutral_off_and_checked_on() -> None:
    assert _FIELDS_ADDED_LATER[("training", "goal_warmup_steps")] == 0
    assert spec_hash(parse_spec(_spec())) == spec_hash(parse_spec(_spec(goal_warmup_steps=0)))
    assert spec_hash(parse_spec(_spec(goal_warmup_steps=500))) != spec_hash(parse_spec(_spec()))
    with pytest.raises(SpecError, match="goal_warmup_steps 2000 > total_timesteps 1000"):
        parse_spec(_spec(goal_warmup_steps=2000))
    with pytest.raises(SpecError, match=r"env\.task\.name is 'shared'"):
        parse_spec(_spec("shared", goal_warmup_steps=10))
