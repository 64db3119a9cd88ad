"""The independent baseline (one single-arm policy per arm) through ``softtrack train``."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from softtrack.api import validate_spec
from softtrack.cli import app
from softtrack.spec import parse_spec
from softtrack.store.runs import RunRecord, RunStore
from softtrack.store.status import complete_episodes, final_stage_return
from softtrack.store.tables import append_rows, read_table

runner = CliRunner()

EPISODE_STEPS = 50  # episode_duration 0.1 s / control step 2 ms
ROOT = Path(__file__).resolve().parents[1]


def _spec(tmp_path: Path, total: int, n_envs: int, normalize: bool = False) -> Path:
    data: dict[str, Any] = {
        "name": "tiny-independent",
        "controller": "independent",
        "seeds": [0],
        "env": {"episode_duration": 0.1},
        "algo": {
            "name": "td3",
            "device": "cpu",
            "batch_size": 16,
            "learning_starts": 50,
            "buffer_size": 5000,
            "normalize": normalize,
            "policy_kwargs": {"net_arch": [16, 16]},
        },
        "training": {
            "total_timesteps": total,
            "n_envs": n_envs,
            "checkpoint_interval": 200,
            "heartbeat_interval": 0.5,
        },
    }
    path = tmp_path / "independent.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _arm_dir(run_dir: Path, arm: int) -> Path:
    return run_dir / "models" / f"arm{arm}"


def _check_table(record: RunRecord, expected: list[int] | None = None) -> pd.DataFrame:
    """Both arms present, arm 0's rows first; per arm: episodes 0..n-1, steps non-decreasing
    and within the arm's steps; ``expected`` episodes per arm if given."""
    df = read_table(record.table_path("train_episodes"))
    assert df["arm"].dtype.kind == "i" and set(df["arm"]) <= {0, 1}
    assert (np.diff(df["arm"].to_numpy()) >= 0).all()  # arm 0, then arm 1
    assert (np.diff(df["wall_time"].to_numpy()) >= 0).all()  # one clock for the run
    whole = complete_episodes(df)  # not those a stop cut short at a resumed checkpoint
    assert (df["run_id"] == record.run_id).all() and (whole["length"] == EPISODE_STEPS).all()
    assert np.isfinite(df["return"]).all()
    arm_steps = record.info.arm_steps
    assert arm_steps is not None
    for arm in (0, 1):
        rows = df[df["arm"] == arm]
        assert list(rows["episode"]) == list(range(len(rows)))  # no gaps, no duplicates
        assert (np.diff(rows["global_step"].to_numpy()) >= 0).all()
        assert 0 < rows["global_step"].min() and rows["global_step"].max() <= arm_steps[arm]
        if expected is not None:
            assert len(complete_episodes(rows)) == expected[arm], (arm, len(rows), expected)
    return df


def _check_completed(
    record: RunRecord, budget: int, chunk: int, normalize: bool, without_state: int | None = None
) -> None:
    info = record.info
    assert info.status == "completed" and info.error is None
    assert info.arm_total_timesteps == budget and info.total_timesteps == 2 * budget
    assert info.arm_steps is not None and len(info.arm_steps) == 2
    assert all(budget <= s < budget + chunk for s in info.arm_steps)
    assert info.global_step == sum(info.arm_steps)
    assert not (record.path / "model.zip").exists()
    for arm in (0, 1):
        folder = _arm_dir(record.path, arm)
        assert (folder / "model.zip").is_file()
        assert (folder / "vecnormalize.pkl").is_file() == normalize
        if arm == without_state:
            continue
        state = json.loads((folder / "state.json").read_text())
        assert state["arm"] == arm and state["global_step"] == info.arm_steps[arm]


@pytest.mark.parametrize("normalize", [False, True])
def test_independent_end_to_end(tmp_path: Path, normalize: bool) -> None:
    budget, n_envs = 300, 2  # episodes end at steps 100, 200, 300 (final stage: 300)
    spec = _spec(tmp_path, budget, n_envs, normalize)
    runs_dir = tmp_path / "runs"
    result = runner.invoke(app, ["train", str(spec), "--runs-dir", str(runs_dir)], env={"CI": "1"})
    assert result.exit_code == 0, result.output
    run_id = result.stdout.strip()
    record = RunStore(runs_dir).get_run(run_id)
    _check_completed(record, budget, n_envs, normalize)
    assert record.info.controller == "independent"
    for arm in (0, 1):  # one checkpoint per arm (at step 200), under the arm's directory
        checkpoints = sorted((_arm_dir(record.path, arm) / "checkpoints").iterdir())
        assert [p.name for p in checkpoints] == [f"step-{200:012d}"]
        assert (checkpoints[0] / "replay_buffer.pkl").is_file()
    assert not record.list_checkpoints()  # nothing in the run's own checkpoints/
    per_arm = n_envs * (budget // (n_envs * EPISODE_STEPS))
    _check_table(record, [per_arm, per_arm])

    # the saved policies are single-arm ones (44 → 12) and drive both arms together
    from softtrack.rl.factory import algo_class
    from softtrack.rl.policy import load_policy

    model = algo_class("td3").load(str(_arm_dir(record.path, 1) / "model.zip"), device="cpu")
    assert model.observation_space.shape == (44,) and model.action_space.shape == (12,)
    policy = load_policy(record, record.load_spec())
    assert np.asarray(policy(np.zeros(81, dtype=np.float32))).shape == (24,)

    rows = json.loads(
        runner.invoke(app, ["runs", "--runs-dir", str(runs_dir), "-f", "json"]).stdout
    )
    assert [(r["run_id"], r["controller"], r["status"]) for r in rows] == [
        (run_id, "independent", "completed")
    ]
    assert rows[0]["global_step"] == record.info.global_step
    assert rows[0]["total_timesteps"] == 2 * budget
    assert rows[0]["final_return"] is not None and rows[0]["final_return_episodes"] > 0
    table = runner.invoke(app, ["runs", "--runs-dir", str(runs_dir)]).stdout
    assert f"{record.info.global_step}/{2 * budget}" in table


# ---- interrupt and resume -------------------------------------------------------------------
def _start(spec: Path, runs_dir: Path) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "softtrack.cli", "train", str(spec), "--runs-dir", str(runs_dir)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "CI": "1"},
        cwd=ROOT,
    )


def _wait_for_arm_checkpoint(
    proc: subprocess.Popen[str], runs_dir: Path, arm: int, timeout: float = 120
) -> Path:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        records = RunStore(runs_dir).list_runs()
        if records and records[0].policy_dir(arm).list_checkpoints():
            return records[0].path
        time.sleep(0.02)
    proc.kill()
    raise AssertionError(f"no checkpoint of arm {arm} appeared")


def _expected_episodes(split: int, total: int, n_envs: int) -> int:
    """Episodes of n_envs synchronous envs trained to ``split``, then resumed (envs reset)."""
    period = n_envs * EPISODE_STEPS
    return n_envs * (split // period + (total - split) // period)


@pytest.mark.parametrize(
    ("arm", "signum"),
    [(0, signal.SIGINT), (1, signal.SIGTERM), (1, signal.SIGKILL)],
    ids=["arm0-sigint", "arm1-sigterm", "arm1-sigkill"],
)
def test_independent_interrupt_and_resume(tmp_path: Path, arm: int, signum: int) -> None:
    budget, n_envs = 2400, 4
    spec = _spec(tmp_path, budget, n_envs)
    runs_dir = tmp_path / "runs"
    proc = _start(spec, runs_dir)
    run_dir = _wait_for_arm_checkpoint(proc, runs_dir, arm)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=60)
    record = RunStore(runs_dir).get_run(run_dir.name)
    split = max(int(p.name.split("-")[1]) for p in record.policy_dir(arm).list_checkpoints())
    assert 0 < split < budget
    if signum == signal.SIGKILL:
        assert proc.returncode == -signal.SIGKILL
        assert record.info.status == "running"  # nobody could mark it
    else:
        assert proc.returncode == 128 + signum, err
        assert out.strip() == run_dir.name
        assert "--resume" in err and "Traceback" not in err
        assert record.info.status == "interrupted"
        expected_steps = [budget, split] if arm == 1 else [split, 0]
        assert record.info.arm_steps == expected_steps
        assert record.info.global_step == sum(expected_steps)
    assert _arm_dir(run_dir, 0).joinpath("model.zip").is_file() == (arm == 1)
    assert not _arm_dir(run_dir, 1).joinpath("model.zip").exists()

    result = runner.invoke(
        app, ["train", "--resume", run_dir.name[:10], "--runs-dir", str(runs_dir)], env={"CI": "1"}
    )
    assert result.exit_code == 0, result.output
    assert result.stdout.strip() == run_dir.name
    record = RunStore(runs_dir).get_run(run_dir.name)
    _check_completed(record, budget, n_envs, normalize=False)
    full = n_envs * (budget // (n_envs * EPISODE_STEPS))
    expected = [full, full]
    expected[arm] = _expected_episodes(split, record.info.arm_steps[arm], n_envs)  # type: ignore[index]
    _check_table(record, expected)
    result = runner.invoke(app, ["train", "--resume", run_dir.name, "--runs-dir", str(runs_dir)])
    assert result.exit_code == 2 and "already completed" in result.stderr


def test_resume_skips_finished_arm_and_restarts_arm_without_checkpoint(tmp_path: Path) -> None:
    """As after a stop between the arms: arm 0 finished, arm 1 never checkpointed."""
    budget, n_envs = 300, 2
    runs_dir = tmp_path / "runs"
    args = ["train", str(_spec(tmp_path, budget, n_envs)), "--runs-dir", str(runs_dir)]
    run_id = runner.invoke(app, args, env={"CI": "1"}).stdout.strip()
    store = RunStore(runs_dir)
    before = read_table(store.get_run(run_id).table_path("train_episodes"))
    arm0_model = _arm_dir(store.get_run(run_id).path, 0) / "model.zip"
    arm0_bytes = arm0_model.read_bytes()
    shutil.rmtree(_arm_dir(store.get_run(run_id).path, 1))
    (_arm_dir(store.get_run(run_id).path, 0) / "state.json").unlink()  # falls back to the table
    store.update_run(run_id, status="interrupted", global_step=budget, arm_steps=[budget, 0])

    result = runner.invoke(app, ["train", "--resume", run_id, "--runs-dir", str(runs_dir)])
    assert result.exit_code == 0, result.output
    record = store.get_run(run_id)
    assert arm0_model.read_bytes() == arm0_bytes  # arm 0 was not trained again
    _check_completed(record, budget, n_envs, normalize=False, without_state=0)
    after = _check_table(record, [6, 6])
    pd.testing.assert_frame_equal(
        after[after["arm"] == 0].reset_index(drop=True),
        before[before["arm"] == 0].reset_index(drop=True),
    )


# ---- final-stage return ---------------------------------------------------------------------
def _rows(run_id: str, arm: int | None, returns: list[float], step: int) -> list[dict[str, Any]]:
    rows = []
    for i, ret in enumerate(returns):
        row: dict[str, Any] = {
            "run_id": run_id,
            "episode": i,
            "global_step": step * (i + 1),
            "return": ret,
            "length": step,
            "wall_time": float(i),
        }
        if arm is not None:
            row["arm"] = arm
        rows.append(row)
    return rows


def test_final_stage_return_per_arm(tmp_path: Path) -> None:
    store = RunStore(tmp_path / "runs")
    data: dict[str, Any] = {"training": {"total_timesteps": 1000}, "algo": {"learning_starts": 10}}
    spec = parse_spec({**data, "controller": "independent"})
    record = store.create_run(spec, seed=0)
    path = record.table_path("train_episodes")
    # arm 0: episodes end at 100..1000 (final stage (900, 1000]: return 9); arm 1: at 200..1000
    append_rows(path, _rows(record.run_id, 0, [float(i) for i in range(10)], 100))
    append_rows(path, _rows(record.run_id, 1, [10.0, 20.0, 30.0, 40.0, 51.0], 200))
    assert final_stage_return(record) == ((9.0 + 51.0) / 2, 2, 2000)
    # fraction 0.3: arm 0 steps 800, 900, 1000 (mean 8); arm 1 steps 800, 1000 (mean 45.5)
    assert final_stage_return(record, fraction=0.3) == ((8.0 + 45.5) / 2, 5, 2000)

    # a centralized table with arm = -1 (or without the column) is one policy's
    centralized = store.create_run(parse_spec(data), seed=1)
    rows = _rows(centralized.run_id, -1, [float(i) for i in range(10)], 100)
    append_rows(centralized.table_path("train_episodes"), rows)
    assert final_stage_return(centralized) == (9.0, 1, 1000)


def test_independent_experiment_validates() -> None:
    spec = validate_spec(ROOT / "experiments" / "study" / "independent-td3-64-1e7.yaml")
    assert spec.controller == "independent" and spec.algo.name == "td3"
    from softtrack.rl.factory import check_supported
    from softtrack.spec.env_config import env_config

    check_supported(spec)
    for arm in (0, 1):
        config = env_config(spec, arm)
        assert config.n_arms == 1
