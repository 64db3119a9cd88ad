"""Evaluation episodes run together (softtrack.evaluation.episodes.run_episodes): a batch gives
each episode the numbers it has alone, for every task, with early ends, and for the policies
that accept batches."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import pytest

from softtrack.env.core import TrackingCore
from softtrack.env.settings import TrackingConfig, make_config
from softtrack.evaluation import (
    Episode,
    accepts_batches,
    independent_policy,
    iter_episodes,
    run_episode,
    run_episodes,
)
from softtrack.rl.factory import build_model, make_vec_env
from softtrack.rl.policy import deterministic_policy
from softtrack.spec import ExperimentSpec

SEEDS = [11, 12, 13]


def _linear_policy(obs_dim: int, act_dim: int, scale: float = 0.3) -> Callable[..., np.ndarray]:
    """A fixed random tanh-linear policy, row by row the same for a batch."""
    weights = np.random.default_rng(5).normal(scale=scale, size=(obs_dim, act_dim))

    def act(observation: np.ndarray) -> np.ndarray:
        # an explicit sum, not a matrix product: BLAS may round a batch differently
        products = np.asarray(observation, dtype=np.float64)[..., :, None] * weights
        return np.tanh(products.sum(axis=-2))

    act.accepts_batches = True  # type: ignore[attr-defined]
    return act


def _same(alone: Episode, together: Episode) -> None:
    for field in dataclasses.fields(Episode):
        a, b = getattr(alone, field.name), getattr(together, field.name)
        if field.name == "planning_time":
            assert a is None and b is None
        elif isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=field.name)
        else:
            assert a == b, field.name


def _check(policy: Callable[..., np.ndarray], config: TrackingConfig, trajectory: str) -> None:
    together = run_episodes(policy, config, trajectory, 0.4, SEEDS)
    assert len(together) == len(SEEDS)
    for seed, episode in zip(SEEDS, together, strict=True):
        _same(run_episode(policy, config, trajectory, 0.4, seed), episode)


@pytest.mark.parametrize(
    "settings",
    [
        {},
        {"contact_k": 1e6, "contact_nu": 600.0},
        {"task": "viewpoints", "contact_k": 1e6, "contact_nu": 600.0},
        {"realism": {"obs_noise_node_position": 0.002, "youngs_modulus_scale": [0.8, 1.2]}},
    ],
    ids=["shared", "contact", "viewpoints", "noise-and-model-error"],
)
def test_a_batch_of_episodes_equals_each_episode_alone(settings: dict) -> None:
    config = make_config(**settings)
    _check(_linear_policy(81, 24), config, "random")


@pytest.mark.parametrize("task", ["shared", "transport"])
def test_episodes_of_different_targets_in_one_batch_equal_each_alone(task: str) -> None:
    """Validation's batch: random-target episodes beside the three trajectories, each episode
    the numbers it has alone (the mixed targets move each environment as its own mode)."""
    settings = {"task": "transport", "sphere": {}, "contact_k": 1e6, "contact_nu": 600.0}
    config = make_config(**(settings if task == "transport" else {}))
    policy = _linear_policy(TrackingCore(1, config).obs_dim, 24, scale=0.1)
    names = ["random", "circle", "random", "rectangle", "figure8"]
    seeds = [21, 0, 22, 0, 0]
    together = run_episodes(policy, config, names, 0.3, seeds)
    assert [e.trajectory for e in together] == names
    for name, seed, episode in zip(names, seeds, together, strict=True):
        _same(run_episode(policy, config, name, 0.3, seed), episode)
    with pytest.raises(ValueError, match="2 trajectories for 3 seeds"):
        run_episodes(policy, config, ["circle", "random"], 0.3, [1, 2, 3])


def test_episodes_that_end_early_stop_recording_in_the_batch() -> None:
    """The transport task's zero action lets the sphere go: every episode ends at its drop,
    the batch's as the lone ones'."""
    config = make_config(
        task="transport", sphere={}, contact_k=1e6, contact_nu=600.0, drop_grace=0.05
    )
    policy = _linear_policy(TrackingCore(1, config).obs_dim, 24, scale=0.0)
    together = run_episodes(policy, config, "circle", 1.0, SEEDS)
    assert all(e.dropped and e.terminated and len(e.t) < 500 for e in together)
    for seed, episode in zip(SEEDS, together, strict=True):
        _same(run_episode(policy, config, "circle", 1.0, seed), episode)


def test_an_sbx_policy_and_its_independent_pair_run_in_batches() -> None:
    """Trained policies see one observation at a time: a batch of episodes equals each alone."""
    pytest.importorskip("sbx")
    spec = ExperimentSpec.model_validate(
        {
            "name": "batch-test",
            "algo": {"name": "td3", "backend": "sbx", "policy_kwargs": {"net_arch": [16, 16]}},
        }
    )
    model = build_model(spec, make_vec_env(spec), seed=0)
    policy = deterministic_policy(model)
    assert not accepts_batches(policy)
    _check(policy, make_config(), "circle")
    _check(policy, make_config(), "random")

    arm_spec = spec.model_copy(update={"controller": "independent"})
    arm_model = build_model(arm_spec, make_vec_env(arm_spec, arm=0), seed=0)
    pair = independent_policy([deterministic_policy(arm_model)] * 2)
    assert not accepts_batches(pair)
    _check(pair, make_config(), "random")
    assert accepts_batches(independent_policy([_linear_policy(44, 12)] * 2))


def test_a_planner_runs_one_episode_at_a_time() -> None:
    inner = _linear_policy(81, 24)
    starts: list[int] = []

    def planner(observation: np.ndarray) -> np.ndarray:
        return inner(observation)

    planner.start_episode = lambda core: starts.append(core.n_envs)  # type: ignore[attr-defined]
    config = make_config()
    episodes = list(iter_episodes(planner, config, "random", 0.1, SEEDS))
    assert len(episodes) == 3 and starts == [1, 1, 1]
    assert all(e.planning_time is not None for e in episodes)
    with pytest.raises(ValueError, match="one episode at a time"):
        run_episodes(planner, config, "random", 0.1, SEEDS)
    with pytest.raises(ValueError, match="at least one seed"):
        run_episodes(inner, config, "random", 0.1, [])
    batched = list(iter_episodes(inner, config, "random", 0.1, SEEDS, batch=2))
    for seed, together in zip(SEEDS, batched, strict=True):
        _same(run_episode(inner, config, "random", 0.1, seed), together)
