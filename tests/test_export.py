"""Exported runs: model.zip is the policy, inference-only, loadable with the plain library."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.rl.policy import model_paths
from softtrack.store.runs import RunStore

runner = CliRunner()
pytest.importorskip("sbx")


def _train_sbx(tmp_path: Path) -> tuple[Path, str]:
    spec: dict[str, Any] = {
        "name": "tiny-sbx",
        "seeds": [0],
        "env": {"episode_duration": 0.1},
        "algo": {
            "name": "td3",
            "backend": "sbx",
            "batch_size": 16,
            "learning_starts": 50,
            "buffer_size": 2000,
            "policy_kwargs": {"net_arch": [16, 16]},
        },
        "training": {
            "total_timesteps": 300,
            "n_envs": 2,
            "checkpoint_interval": 100,
            "eval_duration": 0.1,
            "validation_episodes": 1,
            "final_policy": "best_validated",
        },
    }
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(spec), encoding="utf-8")
    runs = tmp_path / "runs"
    result = runner.invoke(app, ["train", str(path), "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    return runs, result.output.split()[0]


@pytest.fixture(scope="module")
def sbx_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    return _train_sbx(tmp_path_factory.mktemp("export"))


def _actions(model_file: Path, observations: np.ndarray) -> np.ndarray:
    import sbx

    model = sbx.TD3.load(str(model_file), device="cpu")
    actions, _ = model.predict(observations, deterministic=True)
    return np.asarray(actions)


def test_exported_policy_loads_with_plain_sbx_and_acts_as_the_run(
    sbx_run: tuple[Path, str], tmp_path: Path
) -> None:
    runs, run_id = sbx_run
    record = RunStore(runs).get_run(run_id)
    dest = tmp_path / "models" / "tiny-sbx-seed0"
    result = runner.invoke(app, ["export", run_id, str(dest), "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    manifest = json.loads((dest / "policy.json").read_text())
    assert manifest["model"] == "best"
    policy_file = model_paths(record, record.load_spec())[0]
    observations = np.random.default_rng(0).normal(size=(32, 81)).astype(np.float32)
    assert np.array_equal(
        _actions(dest / "model.zip", observations), _actions(policy_file, observations)
    )
    assert (dest / "model.zip").stat().st_size < 0.6 * policy_file.stat().st_size
    last = dest / "other_models" / "last" / "model.zip"
    assert np.array_equal(
        _actions(last, observations), _actions(record.path / "model.zip", observations)
    )


def test_policy_only_export_leaves_out_the_other_model(
    sbx_run: tuple[Path, str], tmp_path: Path
) -> None:
    runs, run_id = sbx_run
    full, lean = tmp_path / "a" / "full", tmp_path / "b" / "lean"  # one run per directory
    for dest, extra in ((full, []), (lean, ["--policy-only"])):
        result = runner.invoke(app, ["export", run_id, str(dest), "--runs-dir", str(runs), *extra])
        assert result.exit_code == 0, result.output
    assert (full / "other_models" / "last" / "model.zip").is_file()
    assert not (lean / "other_models").exists()
    manifest = json.loads((lean / "policy.json").read_text())
    assert manifest["model"] == "best" and manifest["other_models"] == {}
    observations = np.random.default_rng(1).normal(size=(8, 81)).astype(np.float32)
    assert np.array_equal(
        _actions(lean / "model.zip", observations), _actions(full / "model.zip", observations)
    )
    result = runner.invoke(app, ["evaluate", str(lean), "-t", "circle", "--in-place"])
    assert result.exit_code == 0, result.output
    result = runner.invoke(app, ["evaluate", str(lean), "-t", "circle", "--model", "last"])
    assert result.exit_code == 2
    assert "exported with its policy only (no last model" in result.output
    assert "train --resume" not in result.output


def test_upgrade_relayouts_an_old_export_in_place(
    sbx_run: tuple[Path, str], tmp_path: Path
) -> None:
    runs, run_id = sbx_run
    old = tmp_path / "models" / "tiny-sbx-seed0"  # the earlier export: a copy, checkpoints left out
    shutil.copytree(runs / run_id, old, ignore=shutil.ignore_patterns("checkpoints", "run.lock"))
    before = runner.invoke(app, ["evaluate", str(old), "-t", "circle", "--in-place"])
    assert before.exit_code == 0, before.output
    result = runner.invoke(app, ["upgrade", str(old)])
    assert result.exit_code == 0, result.output
    assert "models" in result.output
    assert (old / "policy.json").is_file() and not (old / "best").exists()
    after = runner.invoke(app, ["evaluate", str(old), "-t", "circle", "--in-place"])
    assert after.exit_code == 0, after.output
    assert after.output == before.output  # the same policy, the same episode
    again = runner.invoke(app, ["upgrade", str(old)])
    assert again.exit_code == 0 and "already current" in again.output


def test_exported_policy_in_plain_gymnasium_tracks_as_softtrack_evaluate(
    sbx_run: tuple[Path, str], tmp_path: Path
) -> None:
    import gymnasium as gym

    import softtrack.env  # noqa: F401
    from softtrack import api
    from softtrack.spec.env_config import env_config, env_kwargs

    runs, run_id = sbx_run
    dest = tmp_path / "exported"
    assert runner.invoke(app, ["export", run_id, str(dest), "--runs-dir", str(runs)]).exit_code == 0
    spec = RunStore(runs).get_run(run_id).load_spec()
    for arm, env_id in (
        (None, "softtrack/DualArmTracking-v0"),
        (1, "softtrack/SingleArmTracking-v0"),
    ):
        assert gym.make(env_id, **env_kwargs(spec, arm)).unwrapped.config == env_config(spec, arm)
    import sbx

    model = sbx.TD3.load(str(dest / "model.zip"), device="cpu")
    env = gym.make(
        "softtrack/DualArmTracking-v0",
        **{**env_kwargs(spec), "target": "circle", "episode_duration": 0.1},
    )
    observation, _ = env.reset(seed=0)
    squared, steps, done = np.zeros(2), 0, False
    while not done:
        observation, _, terminated, truncated, info = env.step(
            model.predict(observation, deterministic=True)[0]
        )
        squared += np.asarray(info["distances"]) ** 2
        steps, done = steps + 1, terminated or truncated
    expected = api.evaluate([str(dest)], ["circle"], write=False).sort_values("arm")
    np.testing.assert_allclose(np.sqrt(squared / steps), expected["rmse_3d"], rtol=1e-12)


def test_a_stored_model_zip_is_deflated_to_the_same_bytes(tmp_path: Path) -> None:
    """Stable-Baselines3 stores its members uncompressed; ``deflate_model_zip`` (export and
    ``softtrack upgrade``) rewrites them deflated: the same names, dates and bytes once read,
    a smaller file, and a second call changes nothing."""
    import zipfile

    from softtrack.store.model_zip import deflate_model_zip, is_deflated

    path = tmp_path / "model.zip"
    data = {
        "data": b'{"params": "' + b"QUJD" * 20_000 + b'"}',
        "_stable_baselines3_version": b"2.9",
    }
    with zipfile.ZipFile(path, "w") as archive:  # ZIP_STORED, as the libraries write it
        for name, payload in data.items():
            archive.writestr(zipfile.ZipInfo(name, date_time=(2026, 12, 4, 10, 14, 0)), payload)
    before = path.stat().st_size
    assert not is_deflated(path)
    assert deflate_model_zip(path) and is_deflated(path)
    assert path.stat().st_size < before / 10
    with zipfile.ZipFile(path) as archive:
        assert {i.filename: archive.read(i) for i in archive.infolist()} == data
        assert {i.date_time for i in archive.infolist()} == {(2026, 12, 4, 10, 14, 0)}
    assert not deflate_model_zip(path)
    assert [p.name for p in tmp_path.iterdir()] == ["model.zip"]  # no temporary left
