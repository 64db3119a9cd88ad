"""``softtrack sweep`` / ``resume`` with tiny budgets: grid expansion, the local pool, faults
(kill -9 of a worker, SIGTERM of the sweep, a job that raises, a corrupt checkpoint), lost
runs, two sweeps in one runs directory, and the SLURM path through submitit's local executor."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.executors.dispatch import ExecOptions, execute, select_resumable_runs
from softtrack.executors.sweep import expand_grid, parse_grid, parse_seeds, split_values
from softtrack.spec import SpecError, load_spec
from softtrack.store.run_summaries import list_run_summaries
from softtrack.store.runs import RunStore
from softtrack.store.status import effective_status
from softtrack.store.tables import read_table

runner = CliRunner()


def _spec(tmp_path: Path, name: str = "tiny", **training: Any) -> Path:
    data = {
        "name": name,
        "seeds": [0],
        "env": {"episode_duration": 0.1},
        "algo": {
            "name": "td3",
            "device": "cpu",
            "batch_size": 16,
            "learning_starts": 50,
            "buffer_size": 5000,
            "policy_kwargs": {"net_arch": [16, 16]},
        },
        "training": {
            "total_timesteps": 200,
            "n_envs": 2,
            "checkpoint_interval": 0,
            "heartbeat_interval": 0.5,
            **training,
        },
    }
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _check_contiguous(record: Any) -> None:
    df = read_table(record.table_path("train_episodes"))
    assert list(df["episode"]) == list(range(len(df)))  # no gaps, no duplicates
    assert (np.diff(df["global_step"].to_numpy()) >= 0).all()
    assert df["global_step"].max() <= record.info.global_step


def _sweep_proc(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "softtrack.cli", "sweep", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "CI": "1"},
        start_new_session=True,
    )


def _wait(predicate: Any, proc: subprocess.Popen[str] | None = None, timeout: float = 90) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc is not None:
            assert proc.poll() is None, proc.communicate()
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    if proc is not None:
        proc.kill()
    raise AssertionError("timed out")


def _checkpointed(runs_dir: Path) -> Any:
    for record in RunStore(runs_dir).list_runs():
        if record.info.status == "running" and record.list_checkpoints():
            return record
    return None


# ---- grid expansion (no training) -----------------------------------------------------------
def test_split_and_parse() -> None:
    assert split_values("[16,16],[64, 64]") == ["[16,16]", "[64, 64]"]
    assert split_values("td3,ddpg,ppo") == ["td3", "ddpg", "ppo"]
    assert parse_grid(["algo.name=td3,ddpg"]) == [("algo.name", ["td3", "ddpg"])]
    assert parse_seeds("0,2-4") == [0, 2, 3, 4] and parse_seeds(None) is None
    for bad in (["algo.name"], ["algo.name="], ["seeds=0,1"], ["a=1", "a=2"]):
        with pytest.raises(SpecError):
            parse_grid(bad)
    with pytest.raises(SpecError):
        parse_seeds("zero")


def test_expand_grid(tmp_path: Path) -> None:
    spec = _spec(tmp_path)
    points = expand_grid(
        [str(spec)],
        parse_grid(["algo.name=td3,ddpg", "algo.learning_rate=0.001,0.0003"]),
        seeds=[0, 1],
    )
    assert len(points) == 4 and all(p.spec.seeds == [0, 1] for p in points)
    assert [p.spec.name for p in points] == [
        "tiny-td3-0.001",
        "tiny-td3-0.0003",
        "tiny-ddpg-0.001",
        "tiny-ddpg-0.0003",
    ]
    assert points[3].spec.algo.name == "ddpg" and points[3].spec.algo.learning_rate == 0.0003
    assert points[3].grid == {"algo.name": "ddpg", "algo.learning_rate": "0.0003"}
    # any spec field, including nested lists
    points = expand_grid([str(spec)], parse_grid(["algo.policy_kwargs.net_arch=[8,8],[32]"]))
    assert [p.spec.algo.policy_kwargs.net_arch for p in points] == [[8, 8], [32]]


@pytest.mark.parametrize(
    "args",
    [
        ["--grid", "algo.name=td3,bogus"],
        ["--grid", "training.bogus=1,2"],
        ["--grid", "algo.name"],
        ["--seeds", "x"],
        ["--set", "training.total_timesteps=-1"],
    ],
)
def test_sweep_user_errors_write_nothing(tmp_path: Path, args: list[str]) -> None:
    runs_dir = tmp_path / "runs"
    result = runner.invoke(app, ["sweep", str(_spec(tmp_path)), *args, "--runs-dir", str(runs_dir)])
    assert result.exit_code == 2, result.output
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert not runs_dir.exists() or not any(runs_dir.iterdir())


# ---- lost runs ------------------------------------------------------------------------------
def test_lost_run_is_shown_and_selected(tmp_path: Path) -> None:
    spec = load_spec(_spec(tmp_path))
    store = RunStore(tmp_path / "runs")
    record = store.create_run(spec, 0)
    store.mark_running(record.run_id)
    assert effective_status(store.get_run(record.run_id)) == "running"  # our own pid
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    store.update_run(record.run_id, pid=dead.pid)
    record = store.get_run(record.run_id)
    assert record.info.status == "running" and effective_status(record) == "lost"
    rows = list_run_summaries(store.root)
    assert rows[0]["status"] == "lost" and rows[0]["stored_status"] == "running"
    assert "lost" in runner.invoke(app, ["runs", "--runs-dir", str(store.root)]).stdout
    assert [r.run_id for r in select_resumable_runs(store, ["tiny"])] == [record.run_id]
    assert store.get_run(record.run_id).info.status == "running"  # display only


# ---- the local pool -------------------------------------------------------------------------
#: Imported by a worker's interpreter at start (``PYTHONPATH``): the worker whose command line
#: names ``SOFTTRACK_TEST_BUG_RUN`` raises at its first checkpoint, as a bug in softtrack would.
_BUG_AT_CHECKPOINT = """
import os, sys
bad = os.environ.get("SOFTTRACK_TEST_BUG_RUN")
if bad and bad in sys.argv:
    import softtrack.rl.callbacks as callbacks
    import softtrack.rl.policy_training as policy_training

    def save_checkpoint(*args, **kwargs):
        raise ZeroDivisionError("a bug at the first checkpoint")

    callbacks.save_checkpoint = policy_training.save_checkpoint = save_checkpoint
"""


def test_sweep_failing_job_and_siblings(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A job that raises mid-training (a bug) is recorded as failed with its traceback; one
    whose checkpoint directory is a file is interrupted with one line and resumable once it is
    moved away; their sibling completes; `runs --failed` shows the failed one."""
    spec = load_spec(_spec(tmp_path, checkpoint_interval=100))
    store = RunStore(tmp_path / "runs")
    records = [store.create_run(spec, s) for s in (0, 1, 2)]
    bad, blocked = records[1], records[2]
    inject = tmp_path / "inject"
    inject.mkdir()
    (inject / "sitecustomize.py").write_text(_BUG_AT_CHECKPOINT)
    path = os.pathsep.join(p for p in (str(inject), os.environ.get("PYTHONPATH", "")) if p)
    monkeypatch.setenv("PYTHONPATH", path)
    monkeypatch.setenv("SOFTTRACK_TEST_BUG_RUN", bad.run_id)
    (blocked.path / "checkpoints").rmdir()
    (blocked.path / "checkpoints").write_text("not a directory")  # the first checkpoint fails
    lines: list[str] = []
    outcome = execute(
        store, [r.run_id for r in records], ExecOptions(workers=2), "S", on_progress=lines.append
    )
    assert outcome.statuses == {
        records[0].run_id: "completed",
        bad.run_id: "failed",
        blocked.run_id: "interrupted",
    }
    assert sorted(outcome.missing) == sorted(
        [(bad.run_id, "failed"), (blocked.run_id, "interrupted")]
    )
    assert outcome.exit_code == 1
    assert lines and "3 runs" in lines[-1] and "1 completed" in lines[-1]
    info = store.get_run(bad.run_id).info
    assert info.error and "ZeroDivisionError" in info.error
    assert "Traceback" in (info.traceback or "")
    assert "killed_by_signal" not in info.notes
    blocked_info = store.get_run(blocked.run_id).info
    assert "is a file where softtrack needs a directory" in (blocked_info.error or "")
    assert "\n" not in (blocked_info.error or "") and not blocked_info.traceback
    result = runner.invoke(app, ["runs", "--failed", "--runs-dir", str(store.root)])
    assert result.exit_code == 0 and bad.run_id in result.stdout
    assert "Traceback" in result.stdout and records[0].run_id not in result.stdout
    # a failed-by-exception run is not resumed by experiment name; the blocked one is, once
    # the file is moved away
    assert select_resumable_runs(store, ["tiny"]) == []
    (blocked.path / "checkpoints").unlink()
    (blocked.path / "checkpoints").mkdir()
    assert [r.run_id for r in select_resumable_runs(store, ["tiny"])] == [blocked.run_id]


@pytest.mark.faults("held")
def test_kill9_worker_then_resume(tmp_path: Path) -> None:
    spec = _spec(tmp_path, total_timesteps=2400, n_envs=4, checkpoint_interval=200)
    runs_dir = tmp_path / "runs"
    proc = _sweep_proc(str(spec), "--runs-dir", str(runs_dir), "--workers", "1")
    record = _wait(lambda: _checkpointed(runs_dir), proc)
    time.sleep(0.3)
    os.kill(record.info.pid, signal.SIGKILL)  # the worker, not the sweep
    _out, err = proc.communicate(timeout=60)
    assert proc.returncode == 1, err
    info = RunStore(runs_dir).get_run(record.run_id).info
    assert info.status == "failed" and info.notes["killed_by_signal"] == signal.SIGKILL
    assert "missing: " + record.run_id in err
    result = runner.invoke(app, ["resume", "tiny", "--runs-dir", str(runs_dir)])
    assert result.exit_code == 0, result.output
    assert result.stdout.split() == [record.run_id]
    record = RunStore(runs_dir).get_run(record.run_id)
    assert record.info.status == "completed" and 2400 <= record.info.global_step < 2404
    _check_contiguous(record)
    result = runner.invoke(app, ["resume", "tiny", "--runs-dir", str(runs_dir)])
    assert result.exit_code == 0 and "nothing to resume" in result.stderr


@pytest.mark.faults("held")
def test_sigterm_sweep_then_resume_with_corrupt_checkpoint(tmp_path: Path) -> None:
    spec = _spec(tmp_path, total_timesteps=2400, n_envs=4, checkpoint_interval=200)
    runs_dir = tmp_path / "runs"
    proc = _sweep_proc(str(spec), "--runs-dir", str(runs_dir), "--workers", "1", "--seeds", "0,1")
    record = _wait(lambda: _checkpointed(runs_dir), proc)
    _wait(lambda: len(RunStore(runs_dir).get_run(record.run_id).list_checkpoints()) >= 2, proc)
    proc.send_signal(signal.SIGTERM)
    _out, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, err
    sweep_id = err.split()[1].rstrip(":")
    statuses = sorted(r.info.status for r in RunStore(runs_dir).list_runs())
    assert statuses == ["interrupted", "queued"]
    # the newest checkpoint is corrupt: resume says so and falls back to the previous one
    record = RunStore(runs_dir).get_run(record.run_id)
    newest, previous = record.list_checkpoints()[-1], record.list_checkpoints()[-2]
    (newest / "model.zip").write_bytes(b"truncated")
    result = runner.invoke(app, ["resume", sweep_id, "--runs-dir", str(runs_dir)])
    assert result.exit_code == 0, result.output
    log = record.log_path.read_text()
    assert f"{newest}: corrupt checkpoint" in log and f"falling back to {previous.name}" in log
    for r in RunStore(runs_dir).list_runs():
        assert r.info.status == "completed" and r.info.global_step >= 2400
        _check_contiguous(r)


def test_two_sweeps_share_a_runs_dir(tmp_path: Path) -> None:
    runs_dir = tmp_path / "runs"
    procs = [
        _sweep_proc(
            str(_spec(tmp_path, name)),
            "--runs-dir",
            str(runs_dir),
            "--workers",
            "1",
            "--seeds",
            "0,1",
        )
        for name in ("one", "two")
    ]
    results = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], results
    records = RunStore(runs_dir).list_runs()
    assert len(records) == 4 and all(r.info.status == "completed" for r in records)
    sweeps = {r.info.notes["sweep"] for r in records}
    assert len(sweeps) == 2
    for out, err in results:
        assert "2/2 runs completed" in err and len(out.split()) == 2


# ---- SLURM through submitit's local executor ------------------------------------------------
def test_slurm_executor_via_submitit_local(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("submitit")
    monkeypatch.setenv("SOFTTRACK_SUBMITIT_CLUSTER", "local")
    runs_dir = tmp_path / "runs"
    result = runner.invoke(
        app,
        [
            "sweep",
            str(_spec(tmp_path)),
            "--executor",
            "slurm",
            "--seeds",
            "0,1",
            "--time",
            "5",
            "--runs-dir",
            str(runs_dir),
        ],
    )
    assert result.exit_code == 0, result.output
    records = RunStore(runs_dir).list_runs()
    assert len(records) == 2 and all(r.info.status == "completed" for r in records)
    assert (runs_dir / ".submitit").is_dir()


def test_slurm_preemption_requeues_and_resumes(tmp_path: Path) -> None:
    """submitit's local executor sends the preemption signal; the job checkpoints, is
    requeued and resumes the run from its checkpoint."""
    pytest.importorskip("submitit")
    from softtrack.executors.base import Job
    from softtrack.executors.slurm import SlurmOptions, submit_jobs

    spec = load_spec(_spec(tmp_path, total_timesteps=6000, n_envs=4, checkpoint_interval=200))
    store = RunStore(tmp_path / "runs")
    record = store.create_run(spec, 0)
    (_job,) = submit_jobs(
        [Job(str(store.root), record.run_id)],
        SlurmOptions(folder=str(tmp_path / "slurm"), time_min=10, cluster="local"),
    )
    _wait(lambda: store.get_run(record.run_id).list_checkpoints(), timeout=120)
    worker = store.get_run(record.run_id).info.pid
    stat = Path(f"/proc/{worker}/stat").read_text()
    job_pid = int(stat.rsplit(")", 1)[1].split()[1])  # the submitit task running RunJob
    os.kill(job_pid, signal.SIGUSR2)  # what SLURM sends before preemption/time-out
    _wait(lambda: store.get_run(record.run_id).info.status == "interrupted", timeout=60)
    _wait(lambda: store.get_run(record.run_id).info.status == "completed", timeout=180)
    record = store.get_run(record.run_id)
    assert record.info.global_step >= 6000
    _check_contiguous(record)
    assert json.loads(record.run_json_path.read_text())["status"] == "completed"


@pytest.mark.faults("degraded")
def test_ctrl_c_while_a_large_sweep_makes_its_runs_keeps_them_queued(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C while the runs of a large sweep are made (before, nothing was printed for
    minutes and the user never saw the sweep id): progress lines, then one line with the
    sweep id and the counts, exit 130; the runs made are queued with the sweep's id and
    `resume SWEEP_ID` selects every one of them."""
    from softtrack.executors import sweep_creation

    monkeypatch.setattr(sweep_creation, "PROGRESS_INTERVAL_S", 0.0)
    made = 0
    create = RunStore.create_run

    def create_then_interrupt(self: RunStore, *args: Any, **kwargs: Any) -> Any:
        nonlocal made
        made += 1
        if made == 3:
            os.kill(os.getpid(), signal.SIGINT)
        return create(self, *args, **kwargs)

    monkeypatch.setattr(RunStore, "create_run", create_then_interrupt)
    runs = tmp_path / "runs"
    result = runner.invoke(
        app, ["sweep", str(_spec(tmp_path)), "--seeds", "0-49", "--runs-dir", str(runs)]
    )
    assert result.exit_code == 130, result.output
    assert "making runs: 1/50" in result.stderr
    last = result.stderr.strip().splitlines()[-1]
    assert "3 of 50 made and queued" in last and "the other 47 were not made" in last
    sweep_id = last.split()[1].rstrip(":")
    store = RunStore(runs)
    records = store.list_runs()
    assert len(records) == 3 and {r.info.status for r in records} == {"queued"}
    assert len(select_resumable_runs(store, [sweep_id])) == 3
