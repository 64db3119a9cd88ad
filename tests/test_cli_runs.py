"""``softtrack runs`` over several fake runs, as a table and as JSON."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.spec import parse_spec
from softtrack.store.run_summaries import list_run_summaries
from softtrack.store.runs import RunStore
from softtrack.store.status import final_stage_return
from softtrack.store.tables import append_rows

runner = CliRunner()


@pytest.fixture
def runs_dir(tmp_path: Path) -> Path:
    """Three runs: completed with episodes, running without final-stage episodes, queued."""
    root = tmp_path / "runs"
    store = RunStore(root)
    td3 = parse_spec(
        {
            "name": "td3-small",
            "training": {"total_timesteps": 1000},
            "algo": {"learning_starts": 10},
        }
    )
    ppo = parse_spec(
        {
            "name": "ppo-small",
            "controller": "independent",
            "algo": {"name": "ppo", "n_steps": 64, "batch_size": 32},
            "training": {"total_timesteps": 2000},
        }
    )

    done = store.create_run(td3, seed=0)
    store.mark_running(done.run_id)
    # episodes end at steps 100, 200, ..., 1000; the last 10 % of 1000 steps is (900, 1000]
    append_rows(
        done.table_path("train_episodes"),
        [
            {
                "run_id": done.run_id,
                "episode": i,
                "global_step": 100 * (i + 1),
                "return": float(i),
                "length": 100,
                "wall_time": 0.1 * i,
            }
            for i in range(10)
        ],
    )
    store.mark_finished(done.run_id, "completed", global_step=1000, steps_per_second=500.0)

    running = store.create_run(td3, seed=1)
    store.mark_running(running.run_id)
    append_rows(
        running.table_path("train_episodes"),
        [
            {
                "run_id": running.run_id,
                "episode": 0,
                "global_step": 300,
                "return": -5.0,
                "length": 100,
                "wall_time": 1.0,
            }
        ],
    )
    store.heartbeat(running.run_id, global_step=250)

    store.create_run(ppo, seed=7)
    return root


def test_final_stage_return(runs_dir: Path) -> None:
    records = RunStore(runs_dir).list_runs()
    assert final_stage_return(records[0]) == (9.0, 1, 1000)  # only the episode ending at 1000
    assert final_stage_return(records[0], fraction=0.3) == (8.0, 3, 1000)  # 800, 900, 1000
    assert final_stage_return(records[1]) == (None, 0, 300)
    assert final_stage_return(records[2]) == (None, 0, 0)


def test_runs_json(runs_dir: Path) -> None:
    result = runner.invoke(app, ["runs", "--runs-dir", str(runs_dir), "--format", "json"])
    assert result.exit_code == 0, result.output
    rows = json.loads(result.stdout)
    assert [(r["name"], r["algo"], r["controller"], r["seed"], r["status"]) for r in rows] == [
        ("td3-small", "td3", "centralized", 0, "completed"),
        ("td3-small", "td3", "centralized", 1, "running"),
        ("ppo-small", "ppo", "independent", 7, "queued"),
    ]
    assert [r["final_return"] for r in rows] == [9.0, None, None]
    assert [r["global_step"] for r in rows] == [1000, 300, 0]  # the table's steps count too
    assert [r["total_timesteps"] for r in rows] == [1000, 1000, 4000]  # independent: 2 arms
    assert rows[0]["started"] and rows[0]["ended"] and rows[1]["ended"] is None
    assert rows[0]["steps_per_second"] == 500.0
    assert rows[0]["run_id"] < rows[1]["run_id"] < rows[2]["run_id"]
    assert not any(r["stale"] for r in rows)


def test_runs_table(runs_dir: Path) -> None:
    result = runner.invoke(app, ["runs", "--runs-dir", str(runs_dir)])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert len(lines) == 4
    assert lines[0].split()[:6] == ["ID", "NAME", "ALGO", "CONTROLLER", "SEED", "STATUS"]
    ids = [r.run_id for r in RunStore(runs_dir).list_runs()]
    for line, run_id in zip(lines[1:], ids, strict=False):
        assert line.startswith(run_id)
    assert "completed" in lines[1] and "1000/1000" in lines[1] and "9.00" in lines[1]
    assert "running" in lines[2] and "300/1000" in lines[2]
    assert "queued" in lines[3] and "0/4000" in lines[3] and "independent" in lines[3]
    today = datetime.now(UTC).strftime("%Y-%m-%d")
    assert today in lines[1]


def test_runs_dir_from_environment(runs_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SOFTTRACK_RUNS_DIR", str(runs_dir))
    result = runner.invoke(app, ["runs", "-f", "json"])
    assert result.exit_code == 0 and len(json.loads(result.stdout)) == 3


def test_stale_running_run(runs_dir: Path) -> None:
    store = RunStore(runs_dir)
    running = store.list_runs()[1]
    store.update_run(running.run_id, heartbeat=datetime.now(UTC) - timedelta(hours=1))
    rows = list_run_summaries(runs_dir)
    assert [r["stale"] for r in rows] == [False, True, False]
    # a stale heartbeat and nobody holding the run's lock: shown as lost, run.json unchanged
    assert [r["status"] for r in rows] == ["completed", "lost", "queued"]
    assert rows[1]["stored_status"] == "running"
    assert store.get_run(running.run_id).info.status == "running"
    result = runner.invoke(app, ["runs", "--runs-dir", str(runs_dir)])
    assert " lost " in result.stdout


def test_no_runs(tmp_path: Path) -> None:
    result = runner.invoke(app, ["runs", "--runs-dir", str(tmp_path / "absent")])
    assert result.exit_code == 0
    assert "no runs in" in result.stderr and result.stdout == ""
    result = runner.invoke(app, ["runs", "--runs-dir", str(tmp_path), "--format", "json"])
    assert result.exit_code == 0 and json.loads(result.stdout) == []


def test_bad_format_is_a_usage_error(runs_dir: Path) -> None:
    result = runner.invoke(app, ["runs", "--runs-dir", str(runs_dir), "--format", "xml"])
    assert result.exit_code == 2


def test_report_without_a_selection_is_a_one_line_error(runs_dir: Path) -> None:
    """Like every other command: one line saying what to give, exit code 2, no usage box."""
    result = runner.invoke(
        app, ["report", "--runs-dir", str(runs_dir), "--out", str(runs_dir.parent / "report")]
    )
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: nothing selected: give one or more experiment names")
    assert f"softtrack runs --runs-dir {runs_dir}" in lines[0]
    assert "Usage" not in result.output and "╭" not in result.output
    assert not (runs_dir.parent / "report").exists()


def test_copy_run_takes_a_shipped_run_without_its_evaluation(
    runs_dir: Path, tmp_path: Path
) -> None:
    """The quickstart evaluates the shipped policy in a copy inside the runs directory, so its
    report shows that evaluation; the shipped directory is only read."""
    from softtrack import api
    from softtrack.store.runs import RunStoreError

    shipped_store = RunStore(tmp_path / "models")
    spec = parse_spec(
        {"name": "shipped", "algo": {"learning_starts": 10}, "training": {"total_timesteps": 1000}}
    )
    record = shipped_store.create_run(spec, seed=0)
    record.model_path.write_bytes(b"a trained model")
    for name in ("train_episodes", "eval_metrics", "eval_moments"):
        append_rows(
            record.table_path(name),
            [{"run_id": record.run_id, "trajectory": "circle", "rmse_3d": 0.0492}],
        )
    (record.path / "checkpoints").mkdir(exist_ok=True)
    (record.path / "checkpoints" / "state.json").write_text("{}")
    before = {p: p.read_bytes() for p in record.path.rglob("*") if p.is_file()}

    copy = api.copy_run(record.path, runs_dir=runs_dir)
    assert copy == runs_dir / record.run_id
    assert (copy / "model.zip").read_bytes() == b"a trained model"
    assert sorted(p.name for p in (copy / "tables").iterdir()) == ["train_episodes.parquet"]
    assert not (copy / "checkpoints").exists()
    assert RunStore(runs_dir).get_run(record.run_id).info.name == "shipped"
    # a second quickstart reuses the copy and drops the evaluation it stored meanwhile
    append_rows(copy / "tables" / "eval_metrics.parquet", [{"rmse_3d": 0.0471}])
    assert api.copy_run(record.path, runs_dir=runs_dir) == copy
    assert not (copy / "tables" / "eval_metrics.parquet").exists()
    assert {p: p.read_bytes() for p in record.path.rglob("*") if p.is_file()} == before
    # another run under that id, or the shipped directory itself: an error, nothing written
    (copy / "model.zip").write_bytes(b"another model")
    with pytest.raises(RunStoreError, match="already holds another run"):
        api.copy_run(record.path, runs_dir=runs_dir)
    with pytest.raises(RunStoreError, match="holds the run to copy itself"):
        api.copy_run(record.path, runs_dir=tmp_path / "models")
    assert {p: p.read_bytes() for p in record.path.rglob("*") if p.is_file()} == before


@pytest.mark.faults("degraded")
def test_an_infinite_return_is_named_not_dropped(runs_dir: Path) -> None:
    """A diverged episode's ``-inf`` return in the final stage makes the final-stage return
    ``-inf`` (it vanished from the mean before); JSON writes it as a string, not null."""
    record = RunStore(runs_dir).list_runs()[0]
    append_rows(
        record.table_path("train_episodes"),
        [
            {
                "run_id": record.run_id,
                "episode": 10,
                "global_step": 1000,
                "return": float("-inf"),
                "length": 100,
                "wall_time": 1.0,
            }
        ],
    )
    assert final_stage_return(record) == (float("-inf"), 2, 1000)
    table = runner.invoke(app, ["runs", "--runs-dir", str(runs_dir)])
    assert table.exit_code == 0 and " -inf " in table.stdout
    result = runner.invoke(app, ["runs", "--runs-dir", str(runs_dir), "--format", "json"])
    assert result.exit_code == 0 and json.loads(result.stdout)[0]["final_return"] == "-inf"


def test_training_names_each_of_the_first_non_finite_returns(
    runs_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from softtrack.rl.callbacks import NON_FINITE_WARNINGS, EpisodeLogger, TrainingClock

    record = RunStore(runs_dir).list_runs()[0]
    logger = EpisodeLogger(record, TrainingClock(), next_episode=10, flush_interval=1e9)
    logger.num_timesteps = 1100
    returns = [1.0, float("inf"), float("nan"), float("-inf"), float("inf"), 2.0]
    logger.locals = {"infos": [{"episode": {"r": r, "l": 100}} for r in returns]}
    logger._on_step()
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == NON_FINITE_WARNINGS == 3 and logger.non_finite == 4
    assert "episode 11 " in lines[0] and "a return of inf" in lines[0]
    assert "later ones are stored without a line" in lines[-1]
    assert [row["return"] for row in logger.pending][1] == float("inf")
