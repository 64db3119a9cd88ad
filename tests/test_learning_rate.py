"""A learning rate that falls linearly over training (``algo.learning_rate_final``): the schedule,
the spec's checks, and sbx TD3's optimizers following it through training, saving and loading."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("sbx", reason="sbx-rl (JAX) not installed")

from softtrack.rl.callbacks import LearningRateDecay
from softtrack.rl.factory import build_model, make_vec_env, model_class
from softtrack.rl.learning_rate import learning_rate_at
from softtrack.spec.fields import SpecError
from softtrack.spec.spec_io import parse_spec, spec_hash

_SMALL: dict[str, dict[str, Any]] = {
    "training": {"n_envs": 2, "total_timesteps": 200},
    "algo": {"backend": "sbx", "learning_starts": 20, "buffer_size": 1000, "batch_size": 8},
}


def _spec(**algo: object):  # type: ignore[no-untyped-def]
    return parse_spec({**_SMALL, "algo": {**_SMALL["algo"], **algo}})


def test_the_rate_is_constant_then_falls_linearly_to_the_final_one() -> None:
    rates = [learning_rate_at(t, 1000, 1e-3, 1e-4, 0.5) for t in (0, 500, 750, 1000, 1200)]
    np.testing.assert_allclose(rates, [1e-3, 1e-3, 5.5e-4, 1e-4, 1e-4])
    assert learning_rate_at(0, 1000, 1e-3, 1e-4) == 1e-3
    assert learning_rate_at(250, 1000, 1e-3, 1e-4) == pytest.approx(7.75e-4)


def test_defaults_keep_every_hash() -> None:
    plain = _spec()
    assert spec_hash(plain) == spec_hash(_spec(learning_rate_decay_from=0.0))
    assert spec_hash(_spec(learning_rate_final=1e-4)) != spec_hash(plain)


@pytest.mark.parametrize(
    ("algo", "message"),
    [
        ({"name": "sac", "learning_rate_final": 1e-4}, "implemented for td3 and ddpg"),
        ({"backend": "sb3", "learning_rate_final": 1e-4}, "with backend sbx"),
        ({"learning_rate_decay_from": 0.5}, "set algo.learning_rate_final"),
        ({"learning_rate_final": 1e-4, "learning_rate_decay_from": 1.0}, "decay_from"),
    ],
)
def test_settings_it_cannot_run_with_are_rejected(algo: dict, message: str) -> None:
    with pytest.raises(SpecError, match=message):
        _spec(**algo)


def _rates(model: object) -> tuple[float, float]:
    policy = model.policy  # type: ignore[attr-defined]
    return tuple(  # type: ignore[return-value]
        float(state.opt_state.hyperparams["learning_rate"])
        for state in (policy.actor_state, policy.qf_state)
    )


def test_td3_trains_saves_and_loads_on_the_schedule(tmp_path: Path) -> None:
    spec = _spec(learning_rate=1e-3, learning_rate_final=1e-4, learning_rate_decay_from=0.5)
    env = make_vec_env(spec, seed=0)
    model = build_model(spec, env, seed=0)
    decay = LearningRateDecay(200, 1e-3, 1e-4, 0.5)
    model.learn(100, callback=decay)
    assert _rates(model) == pytest.approx((1e-3, 1e-3))  # the decay starts at 100 env steps
    model.learn(50, callback=decay, reset_num_timesteps=False)
    expected = learning_rate_at(150, 200, 1e-3, 1e-4, 0.5)  # after the last vector step
    assert _rates(model) == pytest.approx((expected, expected), rel=1e-5)
    model.save(tmp_path / "model.zip")
    loaded = model_class(spec).load(str(tmp_path / "model.zip"), env=env)
    assert _rates(loaded) == pytest.approx(_rates(model))
    loaded.learn(50, callback=LearningRateDecay(200, 1e-3, 1e-4, 0.5), reset_num_timesteps=False)
    assert _rates(loaded) == pytest.approx((1e-4, 1e-4))
    actions, _ = loaded.predict(env.reset(), deterministic=True)
    assert np.isfinite(actions).all()


def test_without_a_settable_optimizer_it_names_the_fix() -> None:
    spec = _spec()
    model = build_model(spec, make_vec_env(spec, seed=0), seed=0)
    with pytest.raises(ValueError, match="settable_adam"):
        model.learn(40, callback=LearningRateDecay(200, 1e-3, 1e-4, 0.0))


def test_softtrack_train_decays_the_rate_to_the_final_one(tmp_path: Path) -> None:
    """Through ``softtrack train``: the checkpoint at the decay's start still has lr₀, the
    finished model lr₁."""
    import yaml
    from typer.testing import CliRunner

    from softtrack.cli import app
    from softtrack.store.runs import RunStore

    data = {
        "algo": {
            **_SMALL["algo"],
            "learning_rate": 1e-3,
            "learning_rate_final": 1e-5,
            "learning_rate_decay_from": 0.5,
            "policy_kwargs": {"net_arch": [16, 16]},
        },
        "training": {"total_timesteps": 400, "n_envs": 2, "checkpoint_interval": 200},
        "seeds": [0],
    }
    spec = tmp_path / "decay.yaml"
    spec.write_text(yaml.safe_dump(data), encoding="utf-8")
    result = CliRunner().invoke(
        app, ["train", str(spec), "--runs-dir", str(tmp_path / "runs")], env={"CI": "1"}
    )
    assert result.exit_code == 0, result.output
    record = RunStore(tmp_path / "runs").get_run(result.stdout.strip())
    cls = model_class(record.load_spec())
    assert _rates(cls.load(str(record.model_path))) == pytest.approx((1e-5, 1e-5))
    first = sorted(record.list_checkpoints())[0]
    assert _rates(cls.load(str(first / "model.zip"))) == pytest.approx((1e-3, 1e-3))
