"""``softtrack query``: DuckDB views over a small hand-made runs directory."""

from __future__ import annotations

import json
import statistics
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.store.query import (
    QueryError,
    ResultsDatabase,
    available_views,
    connect,
    format_result,
    query,
)
from softtrack.store.query_output import _significant
from softtrack.store.runs import RunInfo
from softtrack.store.tables import write_table

runner = CliRunner()

# eval_metrics rmse_3d of experiment exp-a: {(trajectory, arm): [seed 0, seed 1, seed 2]}
RMSE_A = {
    ("circle", 0): [0.10, 0.20, 0.60],
    ("circle", 1): [0.30, 0.30, 0.90],
    ("figure8", 0): [0.05, 0.15, 0.25],
    ("figure8", 1): [1.00, 2.00, 4.00],
}
RMSE_B = {
    ("circle", 0): [0.40],
    ("circle", 1): [0.50],
    ("figure8", 0): [0.70],
    ("figure8", 1): [0.80],
}


def _write_run(root: Path, dirname: str, run_id: str, name: str, seed: int, **extra: Any) -> Path:
    path = root / dirname
    (path / "tables").mkdir(parents=True)
    info = RunInfo(
        run_id=run_id,
        name=name,
        algo="td3",
        controller="centralized",
        seed=seed,
        status="completed",
        created="2026-01-01T10:00:00.000Z",
        total_timesteps=1000,
        global_step=1000,
        spec_hash="h-" + name,
        **extra,
    )
    (path / "run.json").write_text(info.model_dump_json(indent=2), encoding="utf-8")
    (path / "spec.yaml").write_text(f"name: {name}\ntraining:\n  final_stage_fraction: 0.2\n")
    return path


def _metrics(stored_id: str, cells: dict[tuple[str, int], list[float]], k: int) -> list[dict]:
    return [
        {"run_id": stored_id, "trajectory": traj, "arm": arm, "rmse_3d": values[k]}
        for (traj, arm), values in cells.items()
    ]


@pytest.fixture
def runs_dir(tmp_path: Path) -> Path:
    """exp-a seeds 0-2 and exp-b seed 0; directory names differ from the run ids, and the
    eval tables store the directory name as run_id (as the shipped runs do)."""
    root = tmp_path / "runs"
    for k in range(3):
        path = _write_run(
            root,
            f"a-seed{k}",
            f"01AAAAAAAAAAAAAAAAAAAAAAA{k}",
            "exp-a",
            k,
            started="2026-01-01T10:00:00.000Z",
            ended=f"2026-01-01T10:0{k + 1}:00.000Z",
            steps_per_second=100.0 * (k + 1),
        )
        write_table(path / "tables" / "eval_metrics.parquet", _metrics(path.name, RMSE_A, k))
        # train_episodes: centralized (no arm column) for seeds 0 and 1, with arm for seed 2
        rows = [
            {
                "run_id": f"01AAAAAAAAAAAAAAAAAAAAAAA{k}",
                "episode": i,
                "global_step": 100 * i,
                "return": float(i + k),
                "wall_time": 20.0 * i * (k + 1),
            }
            for i in range(1, 4)
        ]
        if k == 2:
            rows = [{**r, "arm": 1} for r in rows]
        write_table(path / "tables" / "train_episodes.parquet", rows)
    b = _write_run(
        root,
        "b-seed0",
        "01BBBBBBBBBBBBBBBBBBBBBBB0",
        "exp-b",
        0,
        sessions=[
            {"started": "2026-01-02T00:00:00Z", "ended": "2026-01-02T00:00:30Z"},
            {"started": "2026-01-02T01:00:00Z", "ended": "2026-01-02T01:01:00Z"},
        ],
        notes={"sweep": "sw1"},
    )
    write_table(b / "tables" / "eval_metrics.parquet", _metrics(b.name, RMSE_B, 0))
    # an old-format eval_moments (wide, float64) in exp-a seed 0, a new one (float32, without
    # run_id) in exp-b
    pq.write_table(
        pa.table(
            {
                "run_id": ["a-seed0"] * 2,
                "trajectory": ["circle"] * 2,
                "step": [1, 2],
                "t": [0.1, 0.2],
                "arm": [0, 0],
                "direction": [0, 0],
                "rms_moment": [1.0, 2.0],
                "max_abs_moment": [3.0, 4.0],
                "element_torques": pa.array([[1.0, -3.0], [2.0, 4.0]], pa.list_(pa.float32())),
            }
        ),
        root / "a-seed0" / "tables" / "eval_moments.parquet",
    )
    pq.write_table(
        pa.table(
            {
                "trajectory": ["circle"],
                "step": [1],
                "t": [0.1],
                "arm": [1],
                "direction": [2],
                "rms_moment": pa.array([5.5], pa.float32()),
            }
        ),
        b / "tables" / "eval_moments.parquet",
    )
    # leftovers that must be ignored: a writer's temporary file, an aborted run creation
    (b / "tables" / ".eval_metrics.tmp-0123abcd.parquet").write_bytes(b"partial")
    (b / "tables" / ".ghost.tmp-0123abcd.parquet").write_bytes(b"partial")
    (root / "aborted").mkdir()
    return root


def test_views_and_their_columns(runs_dir: Path) -> None:
    views = {v.name: v for v in available_views(runs_dir)}
    assert list(views) == ["runs", "experiments", "eval_metrics", "eval_moments", "train_episodes"]
    assert views["eval_metrics"].runs == 4 and views["eval_moments"].runs == 2
    assert [c for c, _ in views["eval_metrics"].columns] == [
        "run_id",
        "trajectory",
        "arm",
        "rmse_3d",
    ]
    runs_columns = [c for c, _ in views["runs"].columns]
    for column in (
        "run_id",
        "dir",
        "name",
        "algo",
        "controller",
        "seed",
        "status",
        "total_timesteps",
        "global_step",
        "steps_per_second",
        "spec_hash",
        "git_commit",
        "created",
        "started",
        "ended",
        "host",
        "train_seconds",
    ):
        assert column in runs_columns
    con = connect(runs_dir)
    assert con.execute("SELECT count(*) FROM runs").fetchone() == (4,)


def test_runs_view(runs_dir: Path) -> None:
    df = query("SELECT * FROM runs ORDER BY run_id", runs_dir)
    assert list(df["dir"]) == ["a-seed0", "a-seed1", "a-seed2", "b-seed0"]
    assert list(df["name"]) == ["exp-a"] * 3 + ["exp-b"]
    # the training clock at the last logged episode (exp-b has no training episodes)
    assert list(df["train_seconds"][:3]) == [60.0, 120.0, 180.0]
    assert np.isnan(df["train_seconds"].iloc[3])
    assert list(df["final_stage_fraction"]) == [0.2] * 4
    assert df["sweep"].iloc[3] == "sw1"
    assert str(df["started"].iloc[0]) == "2026-01-01 10:00:00"
    exp = query("SELECT name, runs, seeds FROM experiments", runs_dir)
    assert list(exp["name"]) == ["exp-a", "exp-b"] and list(exp["runs"]) == [3, 1]
    assert list(exp["seeds"].iloc[0]) == [0, 1, 2]


def test_seed_mean_per_experiment_trajectory_and_arm(runs_dir: Path) -> None:
    df = query(
        "SELECT name, trajectory, arm, avg(rmse_3d) AS mean, stddev_samp(rmse_3d) AS std, "
        "count(*) AS n FROM eval_metrics JOIN runs USING (run_id) GROUP BY ALL ORDER BY ALL",
        runs_dir,
    )
    assert len(df) == 8
    for row in df.itertuples():
        values = (RMSE_A if row.name == "exp-a" else RMSE_B)[(row.trajectory, row.arm)]
        assert row.n == len(values)
        assert row.mean == pytest.approx(statistics.mean(values), rel=1e-12)
        if len(values) > 1:
            assert row.std == pytest.approx(statistics.stdev(values), rel=1e-12)
        else:
            assert row.std != row.std  # NULL (NaN): one seed has no sample std
    # hand-computed: exp-a figure8 arm 1 is 1, 2, 4 → mean 7/3, sample std sqrt(7/3)
    cell = df[(df["name"] == "exp-a") & (df["trajectory"] == "figure8") & (df["arm"] == 1)]
    assert cell["mean"].item() == pytest.approx(7 / 3)
    assert cell["std"].item() == pytest.approx((7 / 3) ** 0.5)


def test_run_id_comes_from_run_json(runs_dir: Path) -> None:
    ids = query("SELECT DISTINCT run_id FROM eval_metrics ORDER BY 1", runs_dir)["run_id"]
    assert list(ids) == [f"01AAAAAAAAAAAAAAAAAAAAAAA{k}" for k in range(3)] + [
        "01BBBBBBBBBBBBBBBBBBBBBBB0"
    ]
    # the new eval_moments file has no run_id column: it still gets its run's id
    df = query("SELECT run_id, rms_moment FROM eval_moments WHERE arm = 1", runs_dir)
    assert list(df["run_id"]) == ["01BBBBBBBBBBBBBBBBBBBBBBB0"]


def test_union_by_name_across_schemas(runs_dir: Path) -> None:
    moments = query("SELECT * FROM eval_moments ORDER BY arm, step", runs_dir)
    assert list(moments.columns) == [
        "run_id",
        "trajectory",
        "step",
        "t",
        "arm",
        "direction",
        "rms_moment",
        "max_abs_moment",
        "element_torques",
    ]
    assert list(moments["rms_moment"]) == [1.0, 2.0, 5.5]
    assert moments["max_abs_moment"].isna().tolist() == [False, False, True]
    episodes = query(
        "SELECT run_id, count(*) AS n, count(arm) AS with_arm, sum(return) AS total "
        "FROM train_episodes GROUP BY run_id ORDER BY run_id",
        runs_dir,
    )
    assert list(episodes["n"]) == [3, 3, 3] and list(episodes["with_arm"]) == [0, 0, 3]
    assert list(episodes["total"]) == [6.0, 9.0, 12.0]


def test_cli_formats(runs_dir: Path) -> None:
    sql = (
        "SELECT name, trajectory, arm, avg(rmse_3d) AS rmse FROM eval_metrics "
        "JOIN runs USING (run_id) WHERE trajectory = 'circle' GROUP BY ALL ORDER BY ALL"
    )
    base = ["query", sql, "--runs-dir", str(runs_dir)]

    result = runner.invoke(app, [*base, "--format", "csv"])
    assert result.exit_code == 0, result.output
    assert result.stdout.splitlines() == [
        "name,trajectory,arm,rmse",
        "exp-a,circle,0,0.3",
        "exp-a,circle,1,0.5",
        "exp-b,circle,0,0.4",
        "exp-b,circle,1,0.5",
    ]

    result = runner.invoke(app, [*base, "--format", "json"])
    assert result.exit_code == 0, result.output
    records = json.loads(result.stdout)
    assert [r["name"] for r in records] == ["exp-a", "exp-a", "exp-b", "exp-b"]
    assert records[1]["arm"] == 1 and records[1]["rmse"] == pytest.approx(0.5)

    result = runner.invoke(app, base)
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert lines[0].split() == ["name", "trajectory", "arm", "rmse"]
    assert lines[1].split() == ["exp-a", "circle", "0", "0.3"]
    assert len({len(line) for line in lines}) == 1  # aligned (numbers right-justified)
    assert not lines[1].startswith("0")  # no index column


def test_table_format_nulls_and_lists() -> None:
    import pandas as pd

    df = pd.DataFrame({"a": [1.5, float("nan")], "b": [None, "x"], "c": [[1, 2], None]})
    assert format_result(df).splitlines() == ["  a  b  c", "1.5     [1, 2]", "     x"]


def test_floats_print_as_numpy_would_without_numpy() -> None:
    """Six significant digits, positional: NumPy's format_float_positional, which the
    output module no longer imports (ties, tiny and huge values, negative zero)."""
    rng = np.random.default_rng(0)
    values = [0.0, -0.0, 0.1 + 0.2, 1e-300, 1e300, 123456789.0, 999999.5, 0.0001234565, 5e-324]
    values += [float(v) for v in rng.uniform(-1, 1, 2000) * 10.0 ** rng.integers(-12, 12, 2000)]
    values += [
        round(float(v), int(d))
        for v, d in zip(rng.uniform(0, 100, 2000), rng.integers(0, 9, 2000), strict=True)
    ]
    values += [
        float(f"{int(m)}5e{int(e)}")
        for m, e in zip(rng.integers(1, 999999, 2000), rng.integers(-10, 5, 2000), strict=True)
    ]
    for value in values:
        expected = np.format_float_positional(
            value, precision=6, unique=True, fractional=False, trim="-"
        )
        assert _significant(value) == expected, value


def test_cli_views(runs_dir: Path) -> None:
    result = runner.invoke(app, ["query", "--views", "--runs-dir", str(runs_dir)])
    assert result.exit_code == 0, result.output
    assert "eval_moments (2 runs)" in result.stdout and "element_torques FLOAT[]" in result.stdout


@pytest.mark.parametrize(
    ("sql", "expected"),
    [
        ("SELEC name FROM runs", "syntax error"),
        ("SELECT * FROM eval_moment_peaks", "no view eval_moment_peaks"),
        ("SELECT nope FROM runs", '"nope" not found'),
    ],
)
def test_bad_sql_is_one_line_and_exit_2(runs_dir: Path, sql: str, expected: str) -> None:
    result = runner.invoke(app, ["query", sql, "--runs-dir", str(runs_dir)])
    assert result.exit_code == 2
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: query: ") and expected in lines[0]
    assert "Traceback" not in result.output
    if "no view" in expected:
        assert "available views: runs, experiments, eval_metrics" in lines[0]


def test_missing_and_empty_runs_dir(tmp_path: Path) -> None:
    result = runner.invoke(app, ["query", "SELECT 1", "--runs-dir", str(tmp_path / "absent")])
    assert result.exit_code == 2
    assert len(result.stderr.splitlines()) == 1 and "does not exist" in result.stderr
    result = runner.invoke(app, ["query", "SELECT 1", "--runs-dir", str(tmp_path)])
    assert result.exit_code == 2 and "holds no runs" in result.stderr
    with pytest.raises(QueryError, match="--runs-dir"):
        query("SELECT 1", tmp_path / "absent")


@pytest.mark.faults("held")
def test_corrupt_parquet_file(runs_dir: Path) -> None:
    bad = runs_dir / "a-seed1" / "tables" / "train_episodes.parquet"
    bad.write_bytes(b"not parquet at all")
    result = runner.invoke(
        app, ["query", "SELECT count(*) FROM train_episodes", "--runs-dir", str(runs_dir)]
    )
    assert result.exit_code == 2 and len(result.stderr.splitlines()) == 1
    assert str(bad) in result.stderr and "not readable Parquet" in result.stderr
    # the other views still work
    with ResultsDatabase(runs_dir) as db:
        assert db.query("SELECT count(*) AS n FROM eval_metrics")["n"].item() == 16
        assert [v.error is not None for v in db.views() if v.name == "train_episodes"] == [True]


def test_a_huge_table_result_shows_its_first_rows_and_counts_the_rest() -> None:
    """Bounded memory: ``--format table`` prints the first rows and counts the others in
    batches; CSV streams every row."""
    import duckdb

    from softtrack.store.query_output import write_cursor

    connection = duckdb.connect()
    chunks: list[str] = []
    cursor = connection.execute("SELECT range AS i, range * 2 AS j FROM range(25000)")
    assert write_cursor(cursor, "table", chunks.append, batch_rows=1000, table_rows=100) == 25000
    text = "".join(chunks)
    assert len(text.splitlines()) == 1 + 100 + 1  # header, 100 rows, the count
    assert text.splitlines()[-1].startswith("… 24,900 more rows not shown")
    chunks.clear()
    cursor = connection.execute("SELECT range AS i FROM range(25000)")
    assert write_cursor(cursor, "csv", chunks.append, batch_rows=1000) == 25000
    assert len("".join(chunks).splitlines()) == 25001
    chunks.clear()
    cursor = connection.execute("SELECT range AS i FROM range(5)")
    write_cursor(cursor, "table", chunks.append, table_rows=100)
    assert "more rows" not in "".join(chunks)


@pytest.mark.faults("degraded")
@pytest.mark.parametrize("table", ["train_episodes", "eval_metrics"])
def test_one_query_reads_one_version_of_a_table_replaced_meanwhile(
    runs_dir: Path, table: str
) -> None:
    """A writer renames a new version over a table between two reads of one query (a view
    read twice): both reads see the version current when the view was made; the links that
    pin it are gone once the query closes."""
    run_dir = runs_dir / "a-seed1"
    snapshots = runs_dir / ".softtrack-catalog" / "snapshots"
    sql = f"SELECT count(*) AS n FROM {table}"
    with ResultsDatabase(runs_dir) as db:
        before = db.query(sql)["n"].item()
        rows = pq.read_table(run_dir / "tables" / f"{table}.parquet").to_pylist()
        write_table(run_dir / "tables" / f"{table}.parquet", rows + rows)  # temp + rename
        assert db.query(sql)["n"].item() == before
        assert any(snapshots.iterdir())
    assert not any(snapshots.iterdir())
    with ResultsDatabase(runs_dir) as db:  # a new query sees the new version
        assert db.query(sql)["n"].item() == before + len(rows)


def test_links_left_by_a_killed_query_are_removed_by_the_next(runs_dir: Path) -> None:
    snapshots = runs_dir / ".softtrack-catalog" / "snapshots"
    left = snapshots / "999999999-deadbeef"  # no such process
    left.mkdir(parents=True)
    (left / "0.eval_metrics.parquet").write_bytes(b"x")
    query("SELECT count(*) FROM eval_metrics", runs_dir)
    assert not left.exists()


def test_where_no_link_can_be_made_the_files_are_read_in_place(
    runs_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A read-only runs directory (or one on another file system) refuses the links: the
    query reads the files themselves and leaves no snapshot directory behind."""
    import errno
    import os

    def refuse(*_args: object, **_kwargs: object) -> None:
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(os, "link", refuse)
    assert query("SELECT count(*) AS n FROM eval_metrics", runs_dir)["n"].item() == 16
    snapshots = runs_dir / ".softtrack-catalog" / "snapshots"
    assert not snapshots.exists() or not any(snapshots.iterdir())


@pytest.mark.faults("degraded")
def test_too_few_file_descriptors_name_the_limit_not_a_table(tmp_path: Path) -> None:
    """Under ``ulimit -n 8`` a query over 40 runs' files blamed a healthy table ("unreadable:
    move it away"); now one line names the limit, exit 1 (the machine's limit)."""
    import resource
    import subprocess
    import sys

    root = tmp_path / "runs"
    for k in range(40):
        path = _write_run(root, f"r{k}", f"01CCCCCCCCCCCCCCCCCCCCCC{k:02d}", "exp-c", k)
        write_table(path / "tables" / "eval_metrics.parquet", _metrics(path.name, RMSE_B, 0))
    before = {p: p.read_bytes() for p in root.rglob("*.parquet")}

    def few_files() -> None:
        resource.setrlimit(resource.RLIMIT_NOFILE, (8, 8))

    result = subprocess.run(
        [
            str(Path(sys.executable).parent / "softtrack"),
            "query",
            "SELECT count(*) FROM eval_metrics",
            "--runs-dir",
            str(root),
        ],
        capture_output=True,
        text=True,
        preexec_fn=few_files,
        timeout=120,
    )
    assert result.returncode == 1, result.stderr
    assert result.stderr.count("\n") == 1 and "ulimit -n" in result.stderr
    assert "move it away" not in result.stderr
    assert all(p.read_bytes() == data for p, data in before.items())


@pytest.mark.faults("traceback")
@pytest.mark.parametrize("signum", [2, 15])
def test_a_signal_mid_query_stops_it_with_one_line(runs_dir: Path, signum: int) -> None:
    """SIGTERM (or Ctrl-C) while DuckDB computes: a "RuntimeError: Query interrupted"
    traceback before (DuckDB turns the signal into its own error), and about one signal in
    five was lost (the query ran on); one line, 128 + signal."""
    import signal
    import subprocess
    import sys
    import time

    command = str(Path(sys.executable).parent / "softtrack")
    sql = "SELECT sum(range) + (SELECT count(*) FROM eval_metrics) FROM range(100000000000)"
    process = subprocess.Popen(
        [command, "query", sql, "--runs-dir", str(runs_dir)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as from a shell
    )
    snapshots = runs_dir / ".softtrack-catalog" / "snapshots"
    deadline = time.monotonic() + 60
    while not list(snapshots.glob(f"{process.pid}-*")) and time.monotonic() < deadline:
        time.sleep(0.1)  # the query pins its files right before DuckDB runs it
    assert process.poll() is None and time.monotonic() < deadline
    time.sleep(1.0)
    process.send_signal(signum)
    try:
        _, stderr = process.communicate(timeout=30)
    finally:
        process.kill()
    assert process.returncode == 128 + signum, stderr
    assert stderr.strip() == f"stopped by {signal.Signals(signum).name}"
