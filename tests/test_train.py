"""``softtrack train`` end to end with tiny budgets: tables, interrupt and resume, SIGKILL."""

from __future__ import annotations

import importlib.util
import json
import os
import re
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

from softtrack.cli import app
from softtrack.store.runs import RunStore
from softtrack.store.status import complete_episodes
from softtrack.store.tables import read_table

runner = CliRunner()

EPISODE_STEPS = 50  # episode_duration 0.1 s / control step 2 ms


def _spec(tmp_path: Path, algo: str = "td3", backend: str = "sb3", **training: Any) -> Path:
    algo_section: dict[str, Any] = {
        "name": algo,
        "backend": backend,
        "device": "cpu",
        "batch_size": 16,
        "policy_kwargs": {"net_arch": [16, 16]},
    }
    if algo == "ppo":
        algo_section.update(n_steps=64, batch_size=32, n_epochs=2)
    else:
        algo_section.update(learning_starts=50, buffer_size=5000)
    data = {
        "name": f"tiny-{algo}",
        "seeds": [0],
        "env": {"episode_duration": 0.1},
        "algo": algo_section,
        "training": {
            "total_timesteps": 400,
            "n_envs": 2,
            "checkpoint_interval": 200,
            "heartbeat_interval": 0.5,
            **training,
        },
    }
    path = tmp_path / f"{algo}.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _episodes(run_dir: Path) -> pd.DataFrame:
    return read_table(run_dir / "tables" / "train_episodes.parquet")


def _check_episodes(df: pd.DataFrame, run_id: str, final_step: int) -> None:
    assert list(df["episode"]) == list(range(len(df)))  # no gaps, no duplicates
    assert (np.diff(df["global_step"].to_numpy()) >= 0).all()
    assert 0 < df["global_step"].min() and df["global_step"].max() <= final_step
    assert np.isfinite(df["return"]).all()
    whole = complete_episodes(df)
    assert (whole["length"] == EPISODE_STEPS).all()
    cut = df.drop(whole.index)  # episodes a stop cut short at the checkpoint resumed from
    assert ((0 < cut["length"]) & (cut["length"] < EPISODE_STEPS)).all()
    assert (df["run_id"] == run_id).all()
    assert (np.diff(df["wall_time"].to_numpy()) >= 0).all()


SBX_TD3 = pytest.param(
    "td3",
    "sbx",
    marks=pytest.mark.skipif(
        importlib.util.find_spec("sbx") is None, reason="sbx-rl (JAX) not installed"
    ),
)


def test_train_prints_progress_lines_into_a_log(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from softtrack.rl import callbacks

    monkeypatch.setattr(callbacks, "PROGRESS_LINE_INTERVAL_S", 0.0)
    spec = _spec(tmp_path)
    result = runner.invoke(
        app, ["train", str(spec), "--runs-dir", str(tmp_path / "runs")], env={"CI": "1"}
    )
    assert result.exit_code == 0, result.output
    run_id = result.stdout.strip()
    lines = [line for line in result.stderr.splitlines() if line.startswith(run_id[-8:])]
    assert re.fullmatch(
        r"\S+ finished: 400/400 steps \(100\.0%\) in 0:\d\d min, [\d,]+ steps/s", lines.pop()
    )
    steps = [int(re.match(r"\S+ ([\d,]+)/400 steps", line)[1].replace(",", "")) for line in lines]
    assert len(steps) >= 10 and steps == sorted(steps) and steps[-1] <= 400
    assert all("steps/s" in line for line in lines[1:])
    assert any(
        re.search(r"the last 20 episodes -?[\d,]+\.\d\d, \d+:\d\d min left$", line)
        for line in lines
    )


def test_a_training_log_gets_a_line_every_5_percent_and_a_final_line(tmp_path: Path) -> None:
    """stderr is not a terminal (a log file): whole lines at every 5 % of the budget, however
    short the run, and a final line with 100 %, the steps, the elapsed time and steps/s."""
    from softtrack.rl import callbacks

    assert callbacks.PROGRESS_LINE_INTERVAL_S >= 60  # the time-based lines alone: none here
    spec = _spec(tmp_path)
    result = runner.invoke(
        app, ["train", str(spec), "--runs-dir", str(tmp_path / "runs")], env={"CI": "1"}
    )
    assert result.exit_code == 0, result.output
    run_id = result.stdout.strip()
    lines = [line for line in result.stderr.splitlines() if line.startswith(run_id[-8:])]
    assert "\r" not in result.stderr  # whole lines, no bar
    final = lines.pop()
    match = re.fullmatch(
        r"\S+ finished: 400/400 steps \(100\.0%\) in (\d+):(\d\d) min, ([\d,]+) steps/s", final
    )
    assert match, final
    assert int(match[3].replace(",", "")) > 0
    percents = [float(re.search(r"\(([\d.]+)%\)", line)[1]) for line in lines]
    assert len(percents) >= 15 and percents == sorted(percents) and percents[-1] < 100
    assert all(
        b - a <= 10 for a, b in zip([0.0, *percents], percents, strict=False)
    )  # none skipped
    assert len(lines) <= 20  # one per 5 %, not one per step


def test_final_progress_line_format() -> None:
    from softtrack.rl.callbacks import final_progress_line

    assert final_progress_line("5JP1EEN4", 100_000, 100_000, 349.4, 286.2) == (
        "5JP1EEN4 finished: 100,000/100,000 steps (100.0%) in 5:49 min, 286 steps/s"
    )
    assert final_progress_line("x arm1", 61_000, 100_000, 7_384.0, None) == (
        "x arm1 stopped: 61,000/100,000 steps (61.0%) in 2:03:04 h"
    )


def test_progress_line_format() -> None:
    from softtrack.rl.callbacks import progress_line

    line = progress_line("5JP1EEN4", 2_650_720, 4_000_000, 378.1, 14169.214)
    assert line == (
        "5JP1EEN4 2,650,720/4,000,000 steps (66.3%), 378 steps/s, "
        "mean return of the last 20 episodes 14,169.21, 59:29 min left"
    )
    # a short run's time left in seconds, not "0:00 h"
    assert progress_line("x", 30_000, 40_000, 500.0, None).endswith(", 0:20 min left")
    assert progress_line("x", 0, 4_000_000, 378.1, None).endswith(", 2:56:19 h left")
    assert progress_line("x arm1", 0, 10, None, float("nan")) == "x arm1 0/10 steps (0.0%)"
    assert progress_line("x", 5_000, 1_500_000, 1_812.4, None, updates_start=10_000) == (
        "x 5,000/1,500,000 steps (0.3%), 1,812 steps/s, updates start at 10,000 steps"
    )


def test_the_time_left_counts_from_the_first_update(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """1,000 env steps without updates in 1 s, then 1,000 with updates in 10 s: the lines
    give no time left before the updates, then the updating rate (100 steps/s, not the
    session's 182) and the time left at that rate; the final line keeps the session's rate."""
    from types import SimpleNamespace

    from softtrack.rl import callbacks

    clock = {"now": 0.0}
    monkeypatch.setattr(callbacks.time, "monotonic", lambda: clock["now"])
    monkeypatch.setenv("CI", "1")
    model = SimpleNamespace(
        num_timesteps=0, learning_starts=1_000, get_env=lambda: None, logger=None
    )
    record = SimpleNamespace(run_id="01ABCDEFGH12345678")
    episodes = SimpleNamespace(recent_return=None)
    monitor = callbacks.ProgressMonitor(
        store=None,  # type: ignore[arg-type]
        record=record,  # type: ignore[arg-type]
        episodes=episodes,  # type: ignore[arg-type]
        total_timesteps=11_000,
        heartbeat_interval=1e9,
        stop_requested=lambda: False,
        line_interval=0.0,
    )
    monitor.init_callback(model)  # type: ignore[arg-type]
    monitor.on_training_start({}, {})
    for step, now in ((500, 0.5), (999, 0.999), (1_000, 1.009), (2_000, 11.009)):
        model.num_timesteps, clock["now"] = step, now
        monitor.on_step()
    monitor.close()
    lines = capsys.readouterr().err.splitlines()
    assert (
        lines[0] == "12345678 500/11,000 steps (4.5%), 1,000 steps/s, updates start at 1,000 steps"
    )
    assert lines[2] == "12345678 1,000/11,000 steps (9.1%), 100 steps/s, 1:40 min left"
    assert lines[3] == "12345678 2,000/11,000 steps (18.2%), 100 steps/s, 1:30 min left"
    assert lines[4] == "12345678 stopped: 2,000/11,000 steps (18.2%) in 0:11 min, 182 steps/s"


@pytest.mark.parametrize(
    "algo, backend", [("td3", "sb3"), ("ddpg", "sb3"), ("ppo", "sb3"), SBX_TD3]
)
def test_train_end_to_end(tmp_path: Path, algo: str, backend: str) -> None:
    spec = _spec(tmp_path, algo, backend)
    runs_dir = tmp_path / "runs"
    result = runner.invoke(
        app,
        ["train", str(spec), "--runs-dir", str(runs_dir), "--set", "training.total_timesteps=256"],
        env={"CI": "1"},
    )
    assert result.exit_code == 0, result.output
    run_id = result.stdout.strip()
    record = RunStore(runs_dir).get_run(run_id)
    info = record.info
    assert info.status == "completed" and info.error is None
    assert info.global_step >= 256 and info.steps_per_second and info.steps_per_second > 0
    assert record.model_path.is_file()
    checkpoints = record.list_checkpoints()
    assert len(checkpoints) == 1  # at step 200 (keep_checkpoints 2, only one interval crossed)
    state = json.loads((checkpoints[0] / "state.json").read_text())
    assert state["global_step"] == int(checkpoints[0].name.split("-")[1])
    assert (checkpoints[0] / "model.zip").is_file()
    assert (checkpoints[0] / "replay_buffer.pkl").is_file() == (algo != "ppo")
    df = _episodes(record.path)
    assert len(df) >= 2 * (256 // (2 * EPISODE_STEPS))
    _check_episodes(df, run_id, info.global_step)

    listing = runner.invoke(app, ["runs", "--runs-dir", str(runs_dir), "--format", "json"])
    rows = json.loads(listing.stdout)
    assert [(r["run_id"], r["algo"], r["status"]) for r in rows] == [(run_id, algo, "completed")]


def test_train_several_seeds_and_runs_listing(tmp_path: Path) -> None:
    spec = _spec(tmp_path, "td3", total_timesteps=120, checkpoint_interval=0)
    runs_dir = tmp_path / "runs"
    result = runner.invoke(
        app,
        ["train", str(spec), "--runs-dir", str(runs_dir), "--set", "seeds=[3, 4]"],
        env={"CI": "1"},
    )
    assert result.exit_code == 0, result.output
    ids = result.stdout.split()
    assert len(ids) == 2
    result = runner.invoke(
        app, ["train", str(spec), "--runs-dir", str(runs_dir), "--seed", "9"], env={"CI": "1"}
    )
    assert result.exit_code == 0, result.output
    ids += result.stdout.split()
    rows = json.loads(
        runner.invoke(app, ["runs", "--runs-dir", str(runs_dir), "-f", "json"]).stdout
    )
    assert [(r["run_id"], r["seed"], r["status"]) for r in rows] == [
        (ids[0], 3, "completed"),
        (ids[1], 4, "completed"),
        (ids[2], 9, "completed"),
    ]
    table = runner.invoke(app, ["runs", "--runs-dir", str(runs_dir)]).stdout.splitlines()
    assert len(table) == 4 and all("completed" in line for line in table[1:])
    for run_id in ids:
        assert not RunStore(runs_dir).get_run(run_id).list_checkpoints()


@pytest.mark.parametrize(
    "args",
    [
        ["train", "{tmp}/absent.yaml"],
        ["train", "{spec}", "--set", "training.bogus=1"],
        ["train", "{spec}", "--set", "algo.name=dqn"],
        ["train", "--resume", "01ABSENT"],
        ["train"],
        ["train", "{spec}", "--resume", "01ABSENT"],
    ],
)
def test_train_user_errors(tmp_path: Path, args: list[str]) -> None:
    spec = _spec(tmp_path)
    runs_dir = tmp_path / "runs"
    args = [a.format(tmp=tmp_path, spec=spec) for a in args]
    result = runner.invoke(app, [*args, "--runs-dir", str(runs_dir)])
    assert result.exit_code == 2, result.output
    assert result.stdout == ""
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert not runs_dir.exists() or not any(runs_dir.iterdir())


def test_resume_completed_run_is_an_error(tmp_path: Path) -> None:
    spec = _spec(tmp_path, total_timesteps=100, checkpoint_interval=0)
    runs_dir = tmp_path / "runs"
    run_id = runner.invoke(app, ["train", str(spec), "--runs-dir", str(runs_dir)]).stdout.strip()
    result = runner.invoke(app, ["train", "--resume", run_id, "--runs-dir", str(runs_dir)])
    assert result.exit_code == 2 and "already completed" in result.stderr
    assert result.stdout == ""


# ---- interrupt and resume -------------------------------------------------------------------
def _start(spec: Path, runs_dir: Path) -> subprocess.Popen[str]:
    env = {**os.environ, "CI": "1"}
    return subprocess.Popen(
        [sys.executable, "-m", "softtrack.cli", "train", str(spec), "--runs-dir", str(runs_dir)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )


def _wait_for_checkpoint(proc: subprocess.Popen[str], runs_dir: Path, timeout: float = 180) -> Path:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        records = RunStore(runs_dir).list_runs()
        if records and records[0].list_checkpoints():
            return records[0].path
        time.sleep(0.02)
    proc.kill()
    raise AssertionError("no checkpoint appeared")


def _interrupt(spec: Path, runs_dir: Path) -> tuple[Path, str, str]:
    """Start training ``spec``, SIGINT it after its first checkpoint; (run dir, stdout, stderr)
    of the process, which exited with 130."""
    proc = _start(spec, runs_dir)
    run_dir = _wait_for_checkpoint(proc, runs_dir)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    return run_dir, out, err


def _latest_step(run_dir: Path) -> int:
    steps = [
        int(p.name.split("-")[1])
        for p in (run_dir / "checkpoints").iterdir()
        if p.name.startswith("step-")
    ]
    return max(steps)


def _expected_episodes(split: int, total: int, n_envs: int) -> int:
    """Episodes of n_envs synchronous envs trained to ``split``, then resumed (envs reset)."""
    period = n_envs * EPISODE_STEPS
    return n_envs * (split // period + (total - split) // period)


def _resume_and_check(
    runs_dir: Path,
    run_id: str,
    split: int,
    total: int,
    n_envs: int,
    chunk: int,
    first_session: str = "interrupted",
) -> None:
    """Resume to completion; the run ends within one collection ``chunk`` past ``total``
    (PPO collects whole rollouts of n_steps·n_envs); run.json lists both training sessions,
    the first ended with status ``first_session``."""
    result = runner.invoke(
        app, ["train", "--resume", run_id[:10], "--runs-dir", str(runs_dir)], env={"CI": "1"}
    )
    assert result.exit_code == 0, result.output
    assert result.stdout.strip() == run_id
    record = RunStore(runs_dir).get_run(run_id)
    final = record.info.global_step
    assert record.info.status == "completed" and total <= final < total + chunk
    df = _episodes(record.path)
    _check_episodes(df, run_id, final)
    assert len(complete_episodes(df)) == _expected_episodes(split, final, n_envs)
    under_way = n_envs if (split // n_envs) % EPISODE_STEPS else 0  # at the checkpoint
    assert len(df) - len(complete_episodes(df)) == under_way
    assert record.model_path.is_file()
    sessions = record.info.sessions
    assert [s["status"] for s in sessions] == [first_session, "completed"]
    assert sessions[1]["end_step"] == final
    if first_session == "interrupted":  # (a killed one's end_step is its last heartbeat's)
        assert sessions[0]["end_step"] == split
    assert sessions[0]["ended"] <= sessions[1]["started"] <= sessions[1]["ended"]


@pytest.mark.faults("held")
@pytest.mark.parametrize("algo, backend", [("td3", "sb3"), ("ppo", "sb3"), SBX_TD3])
def test_interrupt_and_resume(tmp_path: Path, algo: str, backend: str) -> None:
    total, n_envs = 2400, 4
    spec = _spec(
        tmp_path, algo, backend, total_timesteps=total, n_envs=n_envs, checkpoint_interval=200
    )
    runs_dir = tmp_path / "runs"
    run_dir, out, err = _interrupt(spec, runs_dir)
    run_id = out.strip()
    assert run_id == run_dir.name
    assert "--resume" in err and "Traceback" not in err
    record = RunStore(runs_dir).get_run(run_id)
    assert record.info.status == "interrupted"
    split = _latest_step(run_dir)
    assert 0 < split < total and record.info.global_step == split
    assert record.list_checkpoints()
    df = _episodes(run_dir) if (run_dir / "tables" / "train_episodes.parquet").exists() else None
    if df is not None:
        _check_episodes(df, run_id, split)
    chunk = 64 * n_envs if algo == "ppo" else n_envs
    _resume_and_check(runs_dir, run_id, split, total, n_envs, chunk)


@pytest.mark.faults("held")
def test_sigkill_then_resume(tmp_path: Path) -> None:
    total, n_envs = 2400, 4
    spec = _spec(tmp_path, "td3", total_timesteps=total, n_envs=n_envs, checkpoint_interval=200)
    runs_dir = tmp_path / "runs"
    proc = _start(spec, runs_dir)
    run_dir = _wait_for_checkpoint(proc, runs_dir)
    time.sleep(0.3)
    proc.kill()  # SIGKILL
    proc.communicate(timeout=30)
    record = RunStore(runs_dir).get_run(run_dir.name)
    assert record.info.status == "running"  # nobody could mark it
    for table in (run_dir / "tables").glob("*.parquet"):
        pd.read_parquet(table)  # every finished table is readable
    split = _latest_step(run_dir)
    # a corrupt newer checkpoint is skipped: resume falls back to the last good one
    bad = run_dir / "checkpoints" / f"step-{split + 4:012d}"
    bad.mkdir()
    (bad / "state.json").write_text("{not json")
    (bad / "model.zip").write_bytes(b"garbage")
    _resume_and_check(runs_dir, run_dir.name, split, total, n_envs, n_envs, "lost")


@pytest.mark.parametrize("algo, backend", [("td3", "sb3"), SBX_TD3])
def test_same_seed_trains_the_same_run(tmp_path: Path, algo: str, backend: str) -> None:
    """Two trainings of one spec and seed, learning from step 50, give the same episode returns."""
    spec = _spec(tmp_path, algo, backend)
    returns = []
    for name in ("a", "b", "c"):
        seed = "1" if name == "c" else "0"
        result = runner.invoke(
            app,
            ["train", str(spec), "--runs-dir", str(tmp_path / name), "--seed", seed],
            env={"CI": "1"},
        )
        assert result.exit_code == 0, result.output
        record = RunStore(tmp_path / name).get_run(result.stdout.strip())
        returns.append(_episodes(record.path)["return"].to_numpy())
    np.testing.assert_array_equal(returns[0], returns[1])
    assert not np.array_equal(returns[0], returns[2])  # another seed, another run


def test_quickstart_reports_the_shipped_policy_as_it_just_measured_it(tmp_path: Path) -> None:
    """The shipped run's stored evaluation (another CPU: here a made-up 9.8765 m) is not what
    the quickstart's report shows: it shows the evaluation the quickstart just printed, made
    in a copy of the shipped run in the runs directory; the shipped directory is only read."""
    from softtrack.store.tables import write_table

    spec = _spec(tmp_path, total_timesteps=200, checkpoint_interval=0, eval_duration=0.2)
    trained = tmp_path / "trained"
    result = runner.invoke(app, ["train", str(spec), "--runs-dir", str(trained)], env={"CI": "1"})
    assert result.exit_code == 0, result.output
    shipped = tmp_path / "models" / "shipped-td3"
    result = runner.invoke(
        app, ["export", result.stdout.strip(), str(shipped), "--runs-dir", str(trained)]
    )
    assert result.exit_code == 0, result.output
    assert runner.invoke(app, ["evaluate", str(shipped), "--in-place"]).exit_code == 0
    stored = shipped / "tables" / "eval_metrics.parquet"
    write_table(stored, read_table(stored).assign(rmse_3d=9.8765))
    before = {p: p.read_bytes() for p in shipped.rglob("*") if p.is_file()}

    runs, out = tmp_path / "runs", tmp_path / "report"
    tiny = [
        "--set",
        "training.total_timesteps=200",
        "--set",
        "training.n_envs=2",
        "--set",
        "training.checkpoint_interval=0",
        "--set",
        "training.eval_duration=0.2",
        "--set",
        "env.episode_duration=0.1",
        "--set",
        "algo.learning_starts=50",
        "--set",
        "algo.batch_size=16",
        "--set",
        "algo.buffer_size=2000",
        "--set",
        "algo.policy_kwargs.net_arch=[16, 16]",
    ]
    result = runner.invoke(
        app,
        [
            "quickstart",
            *tiny,
            "--runs-dir",
            str(runs),
            "--out",
            str(out),
            "--pretrained",
            str(shipped),
        ],
        env={"CI": "1"},
    )
    assert result.exit_code == 0, result.output
    assert {p: p.read_bytes() for p in shipped.rglob("*") if p.is_file()} == before
    printed = {
        line.split()[1]: re.search(r"arm 1 / arm 2: ([\d.]+) / ([\d.]+) m", line).groups()
        for line in result.stdout.splitlines()
        if line.startswith("shipped-td3 ")
    }
    assert sorted(printed) == ["circle", "figure8", "rectangle"]
    live = read_table(runs / "shipped-td3" / "tables" / "eval_metrics.parquet")
    assert (live["rmse_3d"] < 9).all()
    index = (out / "index.md").read_text(encoding="utf-8")
    assert "9.8765" not in index
    section = index.split("### TD3 [tiny-td3]", 1)[1].split("\n### ", 1)[0]
    for name, trajectory in (
        ("circle", "circle"),
        ("rectangle", "rectangle"),
        ("figure-eight", "figure8"),
    ):
        for arm, value in enumerate(printed[trajectory]):
            start = f"| {name} | arm {arm + 1} |"
            row = next(r for r in section.splitlines() if r.startswith(start))
            assert f"| {value} |" in row, (row, value)


def test_tensorboard_logs_into_the_run_and_keeps_the_spec_hash(tmp_path: Path) -> None:
    """``training.tensorboard: true`` writes SB3's scalars to ``<run>/tb/`` (the episode
    return among them), and a spec differs from its hash only in where it logs."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    from softtrack.spec import load_spec, spec_hash

    spec = _spec(tmp_path, tensorboard=True)
    result = runner.invoke(app, ["train", str(spec), "--runs-dir", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    run_dir = tmp_path / "runs" / result.stdout.strip()
    events = sorted((run_dir / "tb").rglob("events.out.tfevents.*"))
    assert events, sorted(p.name for p in run_dir.iterdir())
    accumulator = EventAccumulator(str(events[0].parent))
    accumulator.Reload()
    assert "rollout/ep_rew_mean" in accumulator.Tags()["scalars"]
    (tmp_path / "plain").mkdir()
    plain = _spec(tmp_path / "plain")
    assert spec_hash(load_spec(spec)) == spec_hash(load_spec(plain))


def test_tensorboard_without_the_package_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from softtrack.rl import factory

    monkeypatch.setattr(factory, "installed", lambda module: module != "tensorboard")
    spec = _spec(tmp_path, tensorboard=True)
    result = runner.invoke(app, ["train", str(spec), "--runs-dir", str(tmp_path / "runs")])
    assert result.exit_code == 2
    assert "training.tensorboard needs the tensorboard package" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "runs").exists() or not any((tmp_path / "runs").iterdir())
