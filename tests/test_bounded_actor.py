"""TD3 with the actor's pre-activation penalty (``algo.actor_preactivation_penalty``): the
loss it adds, its effect on saturation, the spec's checks, a CLI run and its inference copy."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

pytest.importorskip("sbx", reason="sbx-rl (JAX) not installed")

import jax
import jax.numpy as jnp
from sbx import TD3

from softtrack.cli import app
from softtrack.env.vec_env import TrackingVecEnv
from softtrack.rl import variants
from softtrack.rl.factory import model_class
from softtrack.rl.variants.bounded_actor import PenalisedActor, PreactivationPenaltyTD3
from softtrack.spec import SpecError, load_spec, parse_spec
from softtrack.store.runs import RunStore

runner = CliRunner()


def _model(penalty: float) -> PreactivationPenaltyTD3:
    venv = TrackingVecEnv(1, episode_duration=0.01)
    return PreactivationPenaltyTD3(
        "MlpPolicy",
        venv,
        learning_rate=1e-2,
        learning_starts=10,
        policy_kwargs={"net_arch": [16, 16]},
        seed=0,
        preactivation_penalty=penalty,
    )


def _preactivations(model: TD3, obs: jnp.ndarray) -> np.ndarray:
    actions = model.policy.actor_state.apply_fn(model.policy.actor_state.params, obs)
    return np.arctanh(np.clip(np.asarray(actions, np.float64), -1 + 1e-12, 1 - 1e-12))


def test_the_actor_loss_adds_lambda_times_the_mean_square_preactivation() -> None:
    model = _model(0.5)
    obs = jnp.asarray(np.random.default_rng(0).normal(size=(64, 81)), jnp.float32)
    state, qf, key = model.policy.actor_state, model.policy.qf_state, model.key
    _, _, penalised, _ = PreactivationPenaltyTD3.update_actor(state, qf, obs, key)
    _, _, plain, _ = TD3.update_actor(state, qf, obs, key)
    u = _preactivations(model, obs)
    np.testing.assert_allclose(float(penalised) - float(plain), 0.5 * np.mean(u**2), rtol=1e-3)


def test_the_penalty_pulls_saturated_actions_back() -> None:
    """Scaled-up output weights saturate most actions; the penalty alone (a critic that
    prefers nothing) brings the pre-activations back, where SBX's TD3 leaves them."""
    obs = jnp.asarray(np.random.default_rng(1).normal(size=(64, 81)), jnp.float32)
    saturated = {}
    for penalty in (0.0, 1.0):
        model = _model(penalty)
        state = model.policy.actor_state
        params = state.params
        last = sorted(params["params"])[-1]
        params["params"][last]["kernel"] = params["params"][last]["kernel"] * 200.0
        state = state.replace(params=params)
        qf = model.policy.qf_state
        zero_q = qf.replace(params=jax.tree_util.tree_map(jnp.zeros_like, qf.params))
        key = model.key
        update = PreactivationPenaltyTD3.update_actor if penalty else TD3.update_actor
        for _ in range(100):
            state, _, _, key = update(state, zero_q, obs, key)
        actions = np.asarray(state.apply_fn(state.params, obs))
        saturated[penalty] = float(np.mean(np.abs(actions) >= 0.99))
    assert saturated[0.0] > 0.5
    assert saturated[1.0] < 0.05


def test_the_registry_builds_it_with_the_spec_weight() -> None:
    spec = parse_spec({"algo": {"backend": "sbx", "actor_preactivation_penalty": 0.1}})
    assert [v.name for v in variants.active_variants(spec)] == ["actor_preactivation_penalty"]
    assert model_class(spec) is PreactivationPenaltyTD3
    assert variants.model_kwargs(spec) == {"preactivation_penalty": 0.1}


@pytest.mark.parametrize(
    "algo",
    [
        {"backend": "sb3"},
        {"backend": "sbx", "name": "sac"},
        {"backend": "sbx", "critic": "per_arm"},
    ],
)
def test_the_spec_names_what_the_penalty_cannot_run_with(algo: dict[str, str]) -> None:
    with pytest.raises(SpecError, match="actor_preactivation_penalty"):
        parse_spec({"algo": {**algo, "actor_preactivation_penalty": 0.1}})


def test_a_negative_weight_is_a_spec_error() -> None:
    with pytest.raises(SpecError, match="actor_preactivation_penalty"):
        parse_spec({"algo": {"backend": "sbx", "actor_preactivation_penalty": -1}})


def test_train_evaluate_and_export_a_run(tmp_path: Path) -> None:
    data = {
        "name": "tiny-bounded",
        "seeds": [0],
        "env": {"episode_duration": 0.1},
        "algo": {
            "name": "td3",
            "backend": "sbx",
            "batch_size": 16,
            "learning_starts": 50,
            "buffer_size": 5000,
            "policy_kwargs": {"net_arch": [16, 16]},
            "actor_preactivation_penalty": 0.1,
        },
        "training": {"total_timesteps": 300, "n_envs": 2, "checkpoint_interval": 150},
    }
    spec_path = tmp_path / "bounded.yaml"
    spec_path.write_text(yaml.safe_dump(data), encoding="utf-8")
    runs_dir = tmp_path / "runs"
    result = runner.invoke(
        app, ["train", str(spec_path), "--runs-dir", str(runs_dir)], env={"CI": "1"}
    )
    assert result.exit_code == 0, result.output
    run_id = result.stdout.strip()
    record = RunStore(runs_dir).get_run(run_id)
    model = model_class(load_spec(spec_path)).load(str(record.model_path))
    assert isinstance(model, PreactivationPenaltyTD3) and model.preactivation_penalty == 0.1
    actor = model.policy.actor_state.apply_fn.__self__  # resumes with the saved penalty
    assert isinstance(actor, PenalisedActor) and actor.preactivation_penalty == 0.1

    evaluated = runner.invoke(
        app, ["evaluate", run_id, "--runs-dir", str(runs_dir), "--trajectory", "circle"]
    )
    assert evaluated.exit_code == 0, evaluated.output
    exported = runner.invoke(
        app, ["export", run_id, str(tmp_path / "export"), "--runs-dir", str(runs_dir)]
    )
    assert exported.exit_code == 0, exported.output
    plain = TD3.load(str(tmp_path / "export" / "model.zip"), device="cpu")
    assert "softtrack" not in repr(plain.policy.actor_state.apply_fn)
    obs = np.zeros((3, 81), np.float32)
    np.testing.assert_array_equal(
        plain.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0]
    )
