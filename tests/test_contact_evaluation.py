"""Contact in evaluations and reports: per-step and per-episode tables, snapshots, the
report's contact section (a run trained and evaluated with contact on, viewpoints task)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.evaluation.metrics import contact_statistics
from softtrack.report.contact_section import centralized_vs_independent, contact_summary
from softtrack.report.data import group_runs, load_runs
from softtrack.store.runs import RunStore
from softtrack.store.tables import read_table

runner = CliRunner()


def test_contact_statistics() -> None:
    stats = contact_statistics([0.0, 0.002, np.nan, 0.0], [0.0, 30.0, 0.0, 10.0])
    assert stats == {
        "max_penetration": 0.002,
        "contact_steps": 2,
        "mean_contact_force": 10.0,
        "max_contact_force": 30.0,
    }
    ghost = contact_statistics([0.0, 0.05, 0.01], [0.0, 0.0, 0.0])  # contact off: overlaps
    assert ghost["contact_steps"] == 2 and ghost["max_penetration"] == 0.05


def _train_and_evaluate(tmp: Path, controller: str = "centralized") -> tuple[Path, str]:
    spec: dict[str, Any] = {
        "name": f"tiny-contact-{controller}",
        "seeds": [0],
        "controller": controller,
        "env": {
            "episode_duration": 0.1,
            "physics": {"contact_k": 1e6, "contact_nu": 600.0},
            "task": {"name": "viewpoints", "standoff": 0.1},
        },
        "algo": {
            "name": "td3",
            "device": "cpu",
            "batch_size": 16,
            "learning_starts": 50,
            "buffer_size": 2000,
            "policy_kwargs": {"net_arch": [16, 16]},
        },
        "training": {
            "total_timesteps": 200,
            "n_envs": 2,
            "checkpoint_interval": 0,
            "eval_duration": 0.4,
        },
    }
    path = tmp / f"contact-{controller}.yaml"
    path.write_text(yaml.safe_dump(spec), encoding="utf-8")
    runs = tmp / "runs"
    result = runner.invoke(app, ["train", str(path), "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    run_id = result.output.split()[0]
    result = runner.invoke(app, ["evaluate", run_id, "--runs-dir", str(runs)])
    assert result.exit_code == 0, result.output
    return runs, run_id


@pytest.fixture(scope="module")
def contact_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    return _train_and_evaluate(tmp_path_factory.mktemp("contact"))


def test_evaluation_tables_hold_contact(contact_run: tuple[Path, str]) -> None:
    runs, run_id = contact_run
    tables = runs / run_id / "tables"
    steps = read_table(tables / "eval_trajectories.parquet")
    assert {"clearance", "penetration", "contact_force"} <= set(steps.columns)
    assert np.isfinite(steps["clearance"]).all() and (steps["contact_force"] >= 0).all()
    arm0 = steps[steps.arm == 0]
    arm1 = steps[steps.arm == 1]
    # viewpoints: each arm's row holds its own point, 0.2 m apart along x
    assert np.allclose(arm1["target_x"].to_numpy() - arm0["target_x"].to_numpy(), 0.2, atol=1e-6)
    metrics = read_table(tables / "eval_metrics.parquet")
    for column in ("max_penetration", "contact_steps", "mean_contact_force", "max_contact_force"):
        assert column in metrics
    snapshots = read_table(tables / "eval_snapshots.parquet")
    assert set(snapshots["trajectory"]) == {"circle", "rectangle", "figure8"}
    assert snapshots.groupby("trajectory")["step"].nunique().eq(4).all()
    assert len(snapshots) == 3 * 4 * 2 * 21
    first = snapshots[(snapshots.step == snapshots.step.min()) & (snapshots.node == 0)]
    assert np.allclose(sorted(first["x"].unique()), [-0.1, 0.1])  # the clamped bases


def test_report_has_contact_section(contact_run: tuple[Path, str], tmp_path: Path) -> None:
    runs, run_id = contact_run
    groups = group_runs(load_runs([RunStore(runs).get_run(run_id)]))
    summary = contact_summary(groups)
    assert list(summary["task"]) == ["viewpoints"] and list(summary["contact"]) == ["on"]
    assert np.isnan(summary["floor"].iloc[0])  # no shared-target floor on viewpoints
    out = tmp_path / "report"
    result = runner.invoke(app, ["report", run_id, "--runs-dir", str(runs), "--out", str(out)])
    assert result.exit_code == 0, result.output
    text = (out / "index.md").read_text(encoding="utf-8")
    assert "### Contact between the arms" in text
    assert (out / "figures" / "contact_arms.png").stat().st_size > 10_000
    assert (out / "figures" / "contact_timeline.png").stat().st_size > 5_000


@pytest.mark.slow
def test_centralized_against_independent_rows(contact_run: tuple[Path, str]) -> None:
    runs, central_id = contact_run
    _, independent_id = _train_and_evaluate(runs.parent, "independent")
    store = RunStore(runs)
    groups = group_runs(load_runs([store.get_run(central_id), store.get_run(independent_id)]))
    rows = centralized_vs_independent(groups)
    assert [row[4] for row in rows] == ["circle", "figure8", "rectangle"]
    assert all(row[0] == "viewpoints" and row[3] == "1 / 1" for row in rows)
    assert all(cell.startswith(("+", "-")) for row in rows for cell in row[5:])
