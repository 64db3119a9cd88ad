"""``softtrack sync mlflow``: what it writes, read back with the real MLflow client; idempotent."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.spec import ExperimentSpec
from softtrack.store.runs import RunStore
from softtrack.store.tables import append_rows, write_table

mlflow = pytest.importorskip(
    "mlflow", reason="MLflow is an optional dependency (softtrack[mlflow])"
)

runner = CliRunner()
EPISODES = 5


def _make_run(store: RunStore, name: str, seed: int, *, independent: bool = False) -> Path:
    spec = ExperimentSpec.model_validate(
        {
            "name": name,
            "seeds": [seed],
            "training": {"total_timesteps": 100_000},
            "controller": "independent" if independent else "centralized",
        }
    )
    record = store.create_run(spec, seed, ["softtrack", "train"])
    arms = (0, 1) if independent else (None,)
    rows = [
        {
            "run_id": record.run_id,
            "episode": i,
            "global_step": 1000 * (i + 1),
            "return": float(i),
            "length": 500,
            "wall_time": 2.0 * i,
            **({} if arm is None else {"arm": arm}),
        }
        for arm in arms
        for i in range(EPISODES)
    ]
    append_rows(record.table_path("train_episodes"), rows)
    write_table(
        record.table_path("eval_metrics"),
        [
            {"run_id": record.run_id, "trajectory": t, "arm": a, "rmse_3d": 0.05 + 0.01 * a}
            for t in ("circle", "figure8")
            for a in (0, 1)
        ],
    )
    write_table(
        record.table_path("validation"),
        [
            {
                "global_step": s,
                "wall_time": 1.0,
                "trajectory": "circle",
                "episode": 0,
                "arm": a,
                "rmse_3d": 0.2 / s * 1000,
            }
            for s in (1000, 2000)
            for a in (0, 1)
        ],
    )
    if independent:
        for arm in (0, 1):
            (record.path / "models" / f"arm{arm}").mkdir(parents=True)
            (record.path / "models" / f"arm{arm}" / "model.zip").write_bytes(b"policy")
    else:
        (record.path / "model.zip").write_bytes(b"policy")
    store.mark_finished(record.run_id, "completed")
    return record.path


def _active_runs(client: mlflow.MlflowClient) -> list:
    experiments = client.search_experiments()
    return client.search_runs([e.experiment_id for e in experiments])


def test_sync_writes_what_mlflow_reads_back_and_is_idempotent(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)  # MLflow's artifacts go beside its database
    store = RunStore(tmp_path / "runs")
    central = _make_run(store, "central", 0)
    _make_run(store, "central", 1)
    _make_run(store, "indep", 0, independent=True)
    uri = f"sqlite:///{tmp_path / 'mlflow.db'}"
    args = ["sync", "mlflow", "--runs-dir", str(store.root), "--tracking-uri", uri]

    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "3 runs created, 0 replaced" in result.stdout

    client = mlflow.MlflowClient(tracking_uri=uri)
    assert {e.name for e in client.search_experiments()} >= {"central", "indep"}
    runs = _active_runs(client)
    assert len(runs) == 3
    by_dir = {r.data.tags["softtrack.dir"]: r for r in runs}
    first = by_dir[central.name]
    assert first.info.status == "FINISHED"
    assert first.data.params["training.total_timesteps"] == "100000"
    assert first.data.params["name"] == "central"
    assert first.data.metrics["eval/circle/arm1/rmse_3d"] == pytest.approx(0.06)
    assert first.data.metrics["eval/rmse_3d"] == pytest.approx(0.055)
    history = client.get_metric_history(first.info.run_id, "train/return")
    assert [(m.step, m.value) for m in history] == [(1000 * (i + 1), float(i)) for i in range(5)]
    validation = client.get_metric_history(first.info.run_id, "validation/circle/rmse_3d")
    assert [m.step for m in validation] == [1000, 2000]
    artifacts = {a.path for a in client.list_artifacts(first.info.run_id)}
    assert {"spec.yaml", "run.json", "summary.md", "policy"} <= artifacts
    assert [a.path for a in client.list_artifacts(first.info.run_id, "policy")] == [
        "policy/model.zip"
    ]
    indep = next(r for r in runs if r.data.tags["softtrack.controller"] == "independent")
    assert len(client.get_metric_history(indep.info.run_id, "train/return/arm1")) == EPISODES
    policy = {a.path for a in client.list_artifacts(indep.info.run_id, "policy/arm1")}
    assert policy == {"policy/arm1/model.zip"}

    again = runner.invoke(app, args)  # nothing changed: nothing added
    assert again.exit_code == 0, again.output
    assert "0 runs created, 0 replaced (changed since the last sync), 3 unchanged" in again.stdout
    assert len(_active_runs(client)) == 3
    assert len(client.get_metric_history(first.info.run_id, "train/return")) == EPISODES

    append_rows(  # trained further: the run is replaced, not duplicated
        central / "tables" / "train_episodes.parquet",
        [{"episode": 9, "global_step": 9000, "return": 9.0, "length": 500, "wall_time": 20.0}],
    )
    third = runner.invoke(app, [*args[:2], "central", *args[2:]])
    assert third.exit_code == 0, third.output
    assert "0 runs created, 1 replaced" in third.stdout and "1 unchanged" in third.stdout
    runs = _active_runs(client)
    assert len(runs) == 3
    replaced = next(r for r in runs if r.data.tags["softtrack.dir"] == central.name)
    assert len(client.get_metric_history(replaced.info.run_id, "train/return")) == EPISODES + 1


def test_sync_without_mlflow_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import builtins

    store = RunStore(tmp_path / "runs")
    _make_run(store, "central", 0)
    real_import = builtins.__import__

    def no_mlflow(name: str, *args: object, **kwargs: object) -> object:
        if name == "mlflow" or name.startswith("mlflow."):
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_mlflow)
    result = runner.invoke(app, ["sync", "mlflow", "--runs-dir", str(store.root)])
    assert result.exit_code == 2
    assert result.stderr.strip().splitlines() == [
        "error: sync mlflow: MLflow is not installed; install it with "
        "`pip install 'softtrack[mlflow]'` (mlflow-skinny)"
    ]
