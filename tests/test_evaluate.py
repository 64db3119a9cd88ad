"""``softtrack evaluate`` and ``softtrack report`` on tiny trained runs: tables, metrics
recomputed from the stored trajectories, copied run directories, errors."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.metrics import tracking_metrics
from softtrack.store.runs import RunStore
from softtrack.store.tables import read_table

runner = CliRunner()
EVAL_DURATION = 0.4  # s: 200 control steps per trajectory keeps the test fast


def _train_tiny(tmp_path: Path, controller: str = "centralized") -> tuple[Path, str]:
    spec: dict[str, Any] = {
        "name": f"tiny-{controller}",
        "controller": controller,
        "seeds": [0],
        "env": {"episode_duration": 0.1},
        "algo": {"name": "td3", "device": "cpu", "batch_size": 16, "learning_starts": 50,
                 "buffer_size": 2000, "policy_kwargs": {"net_arch": [16, 16]}},
        "training": {"total_timesteps": 200, "n_envs": 2, "checkpoint_interval": 0,
                     "eval_duration": EVAL_DURATION},
    }
    path = tmp_path / f"{controller}.yaml"
    path.write_text(yaml.safe_dump(spec), encoding="utf-8")
    runs = tmp_path / "runs"
    result = runner.invoke(app, ["train", str(path), "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    run_id = result.output.split()[0]
    return runs, run_id


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    return _train_tiny(tmp_path_factory.mktemp("eval"))


def test_evaluate_writes_tables_and_metrics_match_trajectories(trained: tuple[Path, str]) -> None:
    runs, run_id = trained
    result = runner.invoke(app, ["evaluate", run_id, "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    assert result.output.count("3-D RMSE arm 1 / arm 2") == 3
    tables = runs / run_id / "tables"
    trajectories = read_table(tables / "eval_trajectories.parquet")
    metrics = read_table(tables / "eval_metrics.parquet")
    moments = read_table(tables / "eval_moments.parquet")
    n_steps = round(EVAL_DURATION / 0.002)
    assert sorted(metrics["trajectory"].unique()) == ["circle", "figure8", "rectangle"]
    assert len(trajectories) == 3 * 2 * n_steps
    assert len(moments) == 3 * 2 * 2 * n_steps
    assert len(moments["element_torques"].iloc[0]) == 20
    for (trajectory, arm), rows in trajectories.groupby(["trajectory", "arm"]):
        rows = rows.sort_values("step")
        assert rows["t"].iloc[0] == pytest.approx(0.002) and len(rows) == n_steps
        tip = rows[["tip_x", "tip_y", "tip_z"]].to_numpy()
        target = rows[["target_x", "target_y", "target_z"]].to_numpy()
        recomputed = tracking_metrics(tip, target)
        stored = metrics[(metrics["trajectory"] == trajectory) & (metrics["arm"] == arm)].iloc[0]
        for key, value in recomputed.items():
            assert stored[key] == pytest.approx(value, rel=1e-12, abs=1e-15), key
    # the moment statistics agree with the stored element torques
    torques = np.stack(moments["element_torques"].to_numpy()).astype(np.float64)
    assert np.allclose(np.sqrt((torques**2).mean(axis=1)), moments["rms_moment"], rtol=1e-6)
    assert np.allclose(np.abs(torques).max(axis=1), moments["max_abs_moment"], rtol=1e-6)


def test_evaluate_one_trajectory_keeps_the_others(trained: tuple[Path, str]) -> None:
    runs, run_id = trained
    assert runner.invoke(app, ["evaluate", run_id, "--runs-dir", str(runs)]).exit_code == 0
    before = read_table(runs / run_id / "tables" / "eval_metrics.parquet")
    result = runner.invoke(app, ["evaluate", run_id, "-t", "circle", "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    after = read_table(runs / run_id / "tables" / "eval_metrics.parquet")
    assert len(after) == len(before) == 6
    key = ["trajectory", "arm"]
    merged = before.sort_values(key).reset_index(drop=True)
    # deterministic policy and physics: re-evaluating gives the same numbers
    assert np.allclose(after.sort_values(key)["rmse_3d"].to_numpy(), merged["rmse_3d"].to_numpy())


def test_a_copied_run_directory_evaluates(trained: tuple[Path, str], tmp_path: Path) -> None:
    runs, run_id = trained
    copy = tmp_path / "elsewhere" / run_id
    shutil.copytree(runs / run_id, copy)
    shutil.rmtree(copy / "tables", ignore_errors=True)
    result = runner.invoke(app, ["evaluate", str(copy), "-t", "figure8"])
    assert result.exit_code == 0, result.output
    assert (copy / "tables" / "eval_metrics.parquet").is_file()


def test_report_evaluates_runs_without_evaluation(trained: tuple[Path, str], tmp_path: Path) -> None:
    runs, run_id = trained
    fresh = tmp_path / "runs"
    shutil.copytree(runs / run_id, fresh / run_id)
    shutil.rmtree(fresh / run_id / "tables" / "eval_metrics.parquet", ignore_errors=True)
    (fresh / run_id / "tables" / "eval_metrics.parquet").unlink(missing_ok=True)
    out = tmp_path / "report"
    result = runner.invoke(app, ["report", run_id, "--runs-dir", str(fresh), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert (fresh / run_id / "tables" / "eval_metrics.parquet").is_file()
    index = (out / "index.md").read_text(encoding="utf-8")
    assert "0.065" in index  # the study's circle value beside the measured one
    assert (out / "figures" / "training_curves.png").is_file()


def test_independent_run_evaluates_with_one_policy_per_arm(tmp_path: Path) -> None:
    runs, run_id = _train_tiny(tmp_path, controller="independent")
    result = runner.invoke(app, ["evaluate", run_id, "-t", "rectangle", "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    metrics = read_table(runs / run_id / "tables" / "eval_metrics.parquet")
    assert sorted(metrics["arm"]) == [0, 1]


@pytest.mark.parametrize(
    "args, message",
    [
        (["evaluate", "NOSUCHRUN"], "no run"),
        (["evaluate", "X", "-t", "spiral"], "spiral"),
        (["report", "nothing-here"], ""),
    ],
)
def test_user_errors_exit_2(tmp_path: Path, args: list[str], message: str) -> None:
    runs = tmp_path / "runs"
    runs.mkdir()
    extra = ["--out", str(tmp_path / "r")] if args[0] == "report" else []
    result = runner.invoke(app, [*args, "--runs-dir", str(runs), *extra])
    assert result.exit_code == 2, result.output
    assert message in result.output
    assert not (tmp_path / "r").exists()


def test_unfinished_run_has_no_model(tmp_path: Path) -> None:
    runs = tmp_path / "runs"
    from softtrack.spec import ExperimentSpec

    record = RunStore(runs).create_run(ExperimentSpec(name="unfinished"), 0)
    result = runner.invoke(app, ["evaluate", record.run_id, "--runs-dir", str(runs)])
    assert result.exit_code == 2
    assert "no trained model" in result.output
    assert not (record.path / "tables" / "eval_metrics.parquet").exists()
