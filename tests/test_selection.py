"""Run selection means the same in every command: a run directory, a spec file, an experiment
name, or a run id (or unique prefix); commands that work on one run say so, in one line, when
an item names several."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.spec import load_spec
from softtrack.store.runs import RunStore, RunStoreError
from softtrack.store.selection import EmptySelectionError, select_one_run, select_runs

runner = CliRunner()


def _spec_file(tmp_path: Path, name: str) -> Path:
    data = {"name": name, "training": {"total_timesteps": 1000}, "algo": {"learning_starts": 10}}
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


@pytest.fixture
def store(tmp_path: Path) -> RunStore:
    store = RunStore(tmp_path / "runs")
    two = load_spec(_spec_file(tmp_path, "two"))
    one = load_spec(_spec_file(tmp_path, "one"))
    store.create_run(two, seed=0)
    store.create_run(two, seed=1)
    store.create_run(one, seed=0)
    return store


def test_every_kind_of_item_selects_the_same_runs(store: RunStore, tmp_path: Path) -> None:
    two = [r for r in store.list_runs() if r.info.name == "two"]
    ids = sorted(r.run_id for r in two)
    assert sorted(r.run_id for r in select_runs(store, ["two"])) == ids
    assert sorted(r.run_id for r in select_runs(store, [str(tmp_path / "two.yaml")])) == ids
    assert [r.run_id for r in select_runs(store, [ids[0][:12]])] == [ids[0]]
    elsewhere = tmp_path / "copied" / "two-seed0"
    shutil.copytree(two[0].path, elsewhere)
    (found,) = select_runs(store, [str(elsewhere)])
    assert found.path == elsewhere.resolve()


def test_one_run_commands_take_one_run(store: RunStore) -> None:
    one = select_one_run("one", store.root)
    assert one.info.name == "one"
    with pytest.raises(RunStoreError, match=r"'two' names 2 runs .* give its run id or run dir"):
        select_one_run("two", store.root)
    with pytest.raises(EmptySelectionError, match="neither an experiment name"):
        select_one_run("three", store.root)


def test_export_of_an_experiment_of_several_runs_is_one_line(
    store: RunStore, tmp_path: Path
) -> None:
    result = runner.invoke(
        app, ["export", "two", str(tmp_path / "out"), "--runs-dir", str(store.root)]
    )
    assert result.exit_code == 2
    assert result.output.count("\n") == 1 and "'two' names 2 runs" in result.output
    assert not (tmp_path / "out").exists()
