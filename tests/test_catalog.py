"""The catalog of a runs directory: equal to the directories after every kind of change,
rebuilt when missing or tampered with, never corrupted by concurrent writers killed at random."""

from __future__ import annotations

import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.spec import ExperimentSpec
from softtrack.store import catalog
from softtrack.store.catalog import FORMAT_VERSION, catalog_path, read_catalog
from softtrack.store.catalog_format import CATALOG_DIR, file_stamp
from softtrack.store.catalog_rows import run_row
from softtrack.store.run_summaries import run_listing
from softtrack.store.runs import RunStore
from softtrack.store.tables import append_rows, write_table

runner = CliRunner()
REPO = Path(__file__).resolve().parents[1]


def _spec(name: str = "exp") -> ExperimentSpec:
    return ExperimentSpec.model_validate(
        {"name": name, "seeds": [0], "training": {"total_timesteps": 100_000}}
    )


def _make_run(store: RunStore, name: str = "exp", seed: int = 0, episodes: int = 3) -> Path:
    record = store.create_run(_spec(name), seed, ["softtrack", "train"])
    rows = [
        {
            "run_id": record.run_id,
            "episode": i,
            "global_step": 100 * (i + 1),
            "return": float(i),
            "length": 100,
            "wall_time": 1.0 + i,
        }
        for i in range(episodes)
    ]
    append_rows(record.table_path("train_episodes"), rows)
    write_table(
        record.table_path("eval_metrics"),
        [
            {"run_id": record.run_id, "trajectory": "circle", "arm": a, "rmse_3d": 0.1}
            for a in (0, 1)
        ],
    )
    return record.path


def _without_stamps(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    out = []
    for row in rows:
        row = {k: v for k, v in row.items() if k != "stamp"}
        if row.get("tables"):  # per-file stamps too
            row["tables"] = [item[:4] for item in json.loads(row["tables"])]
        out.append(row)
    return out


def _truth(root: Path) -> list[dict[str, Any]]:
    """Every run's row read from its directory now (what the catalog must equal)."""
    rows = []
    for path in sorted(root.iterdir()):
        if path.name == CATALOG_DIR:
            continue
        found = run_row(path)
        if found is not None:
            rows.append(found.row)
    return _without_stamps(rows)


def _assert_current(root: Path) -> catalog.CatalogSnapshot:
    snapshot = read_catalog(root)
    assert _without_stamps(snapshot.rows()) == _truth(root)
    return snapshot


@pytest.fixture
def store(tmp_path: Path) -> RunStore:
    store = RunStore(tmp_path / "runs")
    for seed in range(3):
        _make_run(store, "exp-a", seed)
    _make_run(store, "exp-b", 0)
    return store


def test_writers_keep_the_catalog_current_without_reading_the_runs(store: RunStore) -> None:
    first = _assert_current(store.root)
    assert first.table.num_rows == 4
    assert catalog_path(store.root).is_file()
    assert first.reread == 0  # every row came from the entries the writers left
    assert not list((store.root / CATALOG_DIR / "entries").iterdir())  # merged and removed
    path = _make_run(store, "exp-c")
    store.heartbeat(path.name, 500)
    append_rows(path / "tables" / "train_episodes.parquet", [{"episode": 9, "return": 5.0}])
    snapshot = _assert_current(store.root)
    assert snapshot.reread == 0 and snapshot.notices == []
    assert _assert_current(store.root).reread == 0


def test_changes_behind_softtracks_back_are_read_again(store: RunStore) -> None:
    _assert_current(store.root)
    runs = sorted(p for p in store.root.iterdir() if p.name != CATALOG_DIR)
    shutil.copytree(runs[0], store.root / "copied-run")  # added by hand
    shutil.rmtree(runs[1])  # deleted by hand
    info = json.loads((runs[2] / "run.json").read_text())
    (runs[2] / "run.json").write_text(json.dumps({**info, "status": "failed"}))  # edited in place
    time.sleep(catalog._RACY_S + 0.1)  # the edits are no longer too fresh to trust
    snapshot = _assert_current(store.root)
    assert snapshot.reread == 2
    assert snapshot.notices == [
        f"catalog of {store.root}: run directories 1 added, 1 changed, 1 removed outside "
        "softtrack; read from the directories"
    ]
    assert _assert_current(store.root).notices == []  # said once: the catalog is current now


def test_a_table_rewritten_in_place_is_seen_by_query(store: RunStore) -> None:
    _assert_current(store.root)
    run = next(p for p in sorted(store.root.iterdir()) if p.name != CATALOG_DIR)
    metrics = run / "tables" / "eval_metrics.parquet"
    size = metrics.stat().st_size
    time.sleep(0.05)  # past the file system's clock tick
    with open(metrics, "r+b") as fh:  # same inode, same directory: no stamp of the run moves
        fh.write(b"x" * size)
    result = runner.invoke(
        app, ["query", "SELECT count(*) FROM eval_metrics", "--runs-dir", str(store.root)]
    )
    assert result.exit_code == 2 and str(metrics) in result.stderr
    assert "not readable Parquet" in result.stderr


@pytest.mark.faults("held")
@pytest.mark.parametrize("damage", ["garbage", "edited", "directory", "empty"])
def test_a_damaged_catalog_is_rebuilt_with_one_line(store: RunStore, damage: str) -> None:
    _assert_current(store.root)
    path = catalog_path(store.root)
    if damage == "garbage":
        path.write_bytes(b"\x00not an arrow file")
    elif damage == "empty":
        path.write_bytes(b"")
    elif damage == "directory":
        path.unlink()
        path.mkdir()
    else:  # a hand edit that keeps the file valid: a value changed, the digest kept
        table = pq.read_table(path)
        names = table.column("name").to_pylist()
        names[0] = "tampered"
        table = table.set_column(table.schema.get_field_index("name"), "name", pa.array(names))
        pq.write_table(table, path)
    result = runner.invoke(app, ["runs", "--runs-dir", str(store.root)])
    assert result.exit_code == 0, result.output
    notes = [line for line in result.stderr.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "rebuilt from 4 run directories" in notes[0]
    assert "tampered" not in result.stdout and result.stdout.count("exp-a") == 3
    if damage != "directory":
        assert _assert_current(store.root).notices == []


def test_an_unchanged_catalog_leaves_its_rows_in_the_file(store: RunStore) -> None:
    _assert_current(store.root)
    snapshot = read_catalog(store.root)
    assert snapshot.file == catalog_path(store.root) and snapshot.notices == []
    assert snapshot.columns(["name"], start=3) == {"name": ["exp-b"]}
    assert snapshot.table.column("name").to_pylist() == ["exp-a"] * 3 + ["exp-b"]
    _make_run(store, "exp-c")  # a change: the rows are merged in memory and written back
    changed = read_catalog(store.root)
    assert changed.file is None and changed.columns(["name"])["name"][-1] == "exp-c"
    assert _assert_current(store.root).file == catalog_path(store.root)


def test_a_format_1_catalog_is_converted_without_reading_the_runs(store: RunStore) -> None:
    _assert_current(store.root)
    path = catalog_path(store.root)
    table = pq.read_table(path)
    meta = dict(table.schema.metadata)
    meta[b"softtrack_catalog_version"] = b"1"
    older = path.with_name("catalog.arrow")
    with pa.OSFile(str(older), "wb") as sink:
        with pa.ipc.new_file(sink, table.schema.with_metadata(meta)) as writer:
            writer.write_table(table)
    path.unlink()
    (path.parent / "verified").write_text(file_stamp(str(older)))

    def no_run_read(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("a run was read from its directory")

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(
            catalog, "_reread", lambda root, names, *a: [] if not names else no_run_read()
        )
        snapshot = read_catalog(store.root)
    assert snapshot.notices == [] and snapshot.n_rows == 4
    assert path.is_file() and not older.exists()
    assert _assert_current(store.root).notices == []


@pytest.mark.faults("held")
def test_a_newer_catalog_is_left_alone(store: RunStore) -> None:
    _assert_current(store.root)
    path = catalog_path(store.root)
    table = pq.read_table(path)
    meta = dict(table.schema.metadata)
    meta[b"softtrack_catalog_version"] = str(FORMAT_VERSION + 1).encode()
    pq.write_table(table.replace_schema_metadata(meta), path)
    before = path.read_bytes()
    _make_run(store, "exp-new")  # a writer of this version leaves no entry for it
    listing = run_listing(store.root)
    assert [s["name"] for s in listing.summaries].count("exp-new") == 1
    assert len(listing.notices) == 1 and "newer softtrack" in listing.notices[0]
    assert path.read_bytes() == before
    assert not (store.root / CATALOG_DIR / "entries").exists() or not any(
        (store.root / CATALOG_DIR / "entries").iterdir()
    )


@pytest.mark.faults("held")
def test_a_read_only_runs_directory_is_answered_from_the_directories(
    store: RunStore, monkeypatch: pytest.MonkeyPatch
) -> None:
    shutil.rmtree(store.root / CATALOG_DIR)

    def read_only(*args: Any, **kwargs: Any) -> None:
        raise OSError(30, "Read-only file system")

    monkeypatch.setattr(catalog.Path, "mkdir", read_only)
    result = runner.invoke(app, ["runs", "--runs-dir", str(store.root)])
    assert result.exit_code == 0, result.output
    assert result.stdout.count("exp-a") == 3
    notes = [line for line in result.stderr.splitlines() if line.startswith("note:")]
    assert any("cannot be written" in note for note in notes), notes
    assert not (store.root / CATALOG_DIR).exists()


def test_deleting_the_catalog_loses_nothing(store: RunStore) -> None:
    rows = _without_stamps(read_catalog(store.root).rows())
    shutil.rmtree(store.root / CATALOG_DIR)
    again = read_catalog(store.root)
    assert _without_stamps(again.rows()) == rows
    assert again.notices == [f"catalog of {store.root} built from 4 run directories"]


def test_runs_limit_shows_the_runs_created_last(store: RunStore) -> None:
    result = runner.invoke(app, ["runs", "--runs-dir", str(store.root), "--limit", "1"])
    assert result.exit_code == 0, result.output
    assert result.stdout.count("\n") == 2 and "exp-b" in result.stdout
    assert "(the 1 run created last of 4; --limit 0 lists all)" in result.stderr


# ---- concurrency ----------------------------------------------------------------------------
_WRITER = """
import random, sys
from pathlib import Path
from softtrack.spec import ExperimentSpec
from softtrack.store.runs import RunStore
from softtrack.store.tables import append_rows
root, seed = sys.argv[1], int(sys.argv[2])
store, rng = RunStore(root), random.Random(seed)
spec = ExperimentSpec.model_validate(
    {"name": f"exp-{seed % 4}", "seeds": [seed], "training": {"total_timesteps": 100_000}}
)
record = store.create_run(spec, seed, ["softtrack", "train"])
for i in range(20):  # a training process in miniature: episodes, heartbeats, the end
    append_rows(record.table_path("train_episodes"), [{"run_id": record.run_id, "episode": i, "global_step": 100 * i,
                "return": rng.random(), "length": 100, "wall_time": 1.0 + i}])
    store.heartbeat(record.run_id, 100 * i)
store.mark_finished(record.run_id, "completed")
"""
_READER = """
import sys
from pathlib import Path
from softtrack.store.catalog import read_catalog
for _ in range(30):
    read_catalog(Path(sys.argv[1]))
"""


def _python(code: str, *args: str) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.Popen([sys.executable, "-c", code, *args], env=env)


@pytest.mark.slow  # 34 processes importing softtrack: a minute of one core
@pytest.mark.faults("held")
def test_32_concurrent_writers_killed_at_random_never_corrupt_it(tmp_path: Path) -> None:
    root = tmp_path / "runs"
    _make_run(RunStore(root), "seed-run")
    writers = [_python(_WRITER, str(root), str(seed)) for seed in range(32)]
    readers = [_python(_READER, str(root)) for _ in range(2)]
    deadline = time.monotonic() + 120  # until half of them are writing their runs
    while len(list(root.glob("*/run.json"))) < 17 and time.monotonic() < deadline:
        time.sleep(0.05)
    killed = set(random.Random(0).sample(range(32), 8))
    for index in sorted(killed):
        writers[index].send_signal(signal.SIGKILL)
    for proc in writers + readers:
        proc.wait(timeout=300)
    survivors = [p for i, p in enumerate(writers) if i not in killed]
    assert all(p.returncode == 0 for p in survivors + readers)
    time.sleep(catalog._RACY_S + 0.1)  # the last writes are no longer too fresh to trust
    snapshot = _assert_current(root)
    assert not any("edited" in note or "unreadable" in note for note in snapshot.notices)
    finished = [r for r in snapshot.rows() if r["status"] == "completed"]
    assert len(finished) >= len(survivors)
    again = read_catalog(root)  # the merged file itself reads back, digest and all
    assert again.notices == [] and again.reread == 0


# ---- the consolidated table copies ------------------------------------------------------------
def _rmse_sum(root: Path) -> float:
    result = runner.invoke(
        app,
        [
            "query",
            "SELECT sum(rmse_3d) AS s FROM eval_metrics",
            "--runs-dir",
            str(root),
            "-f",
            "csv",
        ],
    )
    assert result.exit_code == 0, result.output
    return float(result.stdout.splitlines()[1])


def test_a_query_reads_the_table_copy_and_sees_every_change(store: RunStore) -> None:
    copy = store.root / CATALOG_DIR / "tables" / "eval_metrics.parquet"
    assert _rmse_sum(store.root) == pytest.approx(0.8)  # 4 runs x 2 arms x 0.1
    assert copy.is_file()  # written by the first query
    run = next(p for p in sorted(store.root.iterdir()) if p.name != CATALOG_DIR)
    write_table(  # one run evaluated again
        run / "tables" / "eval_metrics.parquet",
        [{"run_id": "x", "trajectory": "circle", "arm": a, "rmse_3d": 1.0} for a in (0, 1)],
    )
    assert _rmse_sum(store.root) == pytest.approx(2.6)
    shutil.rmtree(run)  # one run deleted
    assert _rmse_sum(store.root) == pytest.approx(0.6)
    copy.write_bytes(copy.read_bytes()[:-20] + b"x" * 20)  # the copy damaged: ignored, rewritten
    assert _rmse_sum(store.root) == pytest.approx(0.6)
    shutil.rmtree(store.root / CATALOG_DIR)  # the cache deleted: nothing lost
    assert _rmse_sum(store.root) == pytest.approx(0.6)
