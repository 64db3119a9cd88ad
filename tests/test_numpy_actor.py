"""``softtrack.rl.numpy_actor``: validation's NumPy copy of a trained sbx TD3/DDPG, SAC/TQC or CrossQ actor
acts as the model's own ``predict`` does, to float32 rounding, and declines every other actor."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from softtrack.rl.factory import build_model, make_vec_env, model_class
from softtrack.rl.numpy_actor import numpy_actor
from softtrack.rl.policy import deterministic_policy, model_paths
from softtrack.rl.target_actor import acting_with_target_actor
from softtrack.spec.spec_io import parse_spec
from softtrack.store.runs import RunStore

MODELS = Path(__file__).resolve().parents[1] / "models"


def _model(run: str) -> object:
    record = RunStore(MODELS).get_run(run)
    spec = record.load_spec()
    return model_class(spec).load(str(model_paths(record, spec)[0]), device="cpu")


@pytest.mark.parametrize(
    "run",
    [
        "td3-sbx-128-mirror-tta-3e6-seed0",
        "ddpg-sbx-1e6-seed0",
        "td3-sbx-1e7-seed0",
        "sac-sbx-128-mirror-fast-1e6-seed0",
    ],
)
def test_the_numpy_actor_acts_as_the_model_does(run: str) -> None:
    model = _model(run)
    act = numpy_actor(model)
    assert act is not None and getattr(act, "accepts_batches", False)
    reference = deterministic_policy(model, batches=True)
    observations = np.random.default_rng(0).normal(size=(32, 81))
    batch = act(observations)
    assert batch.shape == (32, 24) and batch.dtype == np.float64
    np.testing.assert_allclose(batch, reference(observations), rtol=0, atol=2e-5)
    one_row = act(observations[3])  # float32 rounding differs from the batch's in the last bits
    np.testing.assert_allclose(one_row, batch[3], rtol=0, atol=1e-5)
    assert np.abs(batch).max() <= 1.0  # the action space's bounds


def test_the_numpy_actor_takes_the_weights_the_model_acts_with_now() -> None:
    """Inside ``acting_with_target_actor`` (validation's context) a training model's copy is
    its target actor's; outside, its own actor's."""
    model = _model("td3-sbx-128-mirror-tta-3e6-seed0")
    policy = model.policy  # type: ignore[attr-defined]
    params = policy.actor_state.params
    shifted = {"params": {k: {**v, "bias": v["bias"] + 0.5} for k, v in params["params"].items()}}
    policy.actor_state = policy.actor_state.replace(target_params=shifted)
    x = np.random.default_rng(1).normal(size=(4, 81))
    own = numpy_actor(model)
    with acting_with_target_actor(model):
        target = numpy_actor(model)
        reference = deterministic_policy(model, batches=True)(x)
    assert own is not None and target is not None
    np.testing.assert_allclose(target(x), reference, atol=2e-5)
    assert np.abs(own(x) - target(x)).max() > 1e-2


def _tiny_trained_model(algo: str, **algo_fields: object) -> Any:
    """An sbx ``algo`` model of a 2-env spec (``algo_fields`` added to its ``algo``) after 64
    env steps of learning: weights, and CrossQ's running statistics, away from their start."""
    algo_spec = {
        "name": algo,
        "backend": "sbx",
        "learning_starts": 20,
        "buffer_size": 1000,
        "batch_size": 8,
        **algo_fields,
    }
    spec = parse_spec({"training": {"n_envs": 2, "total_timesteps": 200}, "algo": algo_spec})
    model = build_model(spec, make_vec_env(spec, seed=0), seed=0)
    model.learn(64)
    return model


@pytest.mark.parametrize("batch_norm", [True, False])
def test_a_crossq_actor_acts_as_the_model_does(batch_norm: bool) -> None:
    """CrossQ's batch renormalisations, with running statistics far from 0 and 1, fold into
    its dense layers; its deterministic action is the Gaussian mean's tanh."""
    import jax

    model = _tiny_trained_model(
        "crossq",
        policy_delay=3,
        policy_kwargs={"net_arch": [16, 16], "batch_norm_actor": batch_norm},
    )
    policy = model.policy
    rng = np.random.default_rng(3)
    stats = jax.tree_util.tree_map(
        lambda leaf: (
            rng.uniform(0.5, 2.0, np.shape(leaf)).astype(np.float32) if np.ndim(leaf) else leaf
        ),
        jax.device_get(policy.actor_state.batch_stats),
    )
    policy.actor_state = policy.actor_state.replace(batch_stats=stats)
    act = numpy_actor(model)
    assert act is not None
    observations = rng.normal(size=(32, 81))
    reference = deterministic_policy(model, batches=True)(observations)
    np.testing.assert_allclose(act(observations), reference, rtol=0, atol=2e-5)
    assert np.abs(reference).max() > 0.05  # the actions are not all near zero


def test_a_tqc_actor_acts_as_the_model_does() -> None:
    """TQC's actor is SAC's: its log-std head does not act, the mean's tanh does."""
    model = _tiny_trained_model("tqc", policy_kwargs={"net_arch": [16, 16]})
    act = numpy_actor(model)
    assert act is not None
    observations = np.random.default_rng(4).normal(size=(32, 81))
    reference = deterministic_policy(model, batches=True)(observations)
    np.testing.assert_allclose(act(observations), reference, rtol=0, atol=2e-5)
    assert np.abs(reference).max() > 0.05


def test_other_actors_are_declined() -> None:
    assert numpy_actor(_model("ppo-sbx-4e6-seed0")) is None
    assert numpy_actor(object()) is None
