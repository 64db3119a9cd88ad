"""The run store: ULIDs, atomic writes (also under SIGKILL), Parquet tables, run.json."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from pydantic import ValidationError

from softtrack.spec import ExperimentSpec, load_spec, parse_spec, spec_hash
from softtrack.store import ids
from softtrack.store.atomic import (
    atomic_dir,
    atomic_path,
    atomic_write_bytes,
    atomic_write_json,
    atomic_write_text,
    is_temp_file,
    remove_temp_files,
)
from softtrack.store.ids import create_unique_dir, id_timestamp, is_valid_id, new_id
from softtrack.store.provenance import cpu_description, usable_cores
from softtrack.store.runs import RunNotFoundError, RunStore, resolve_runs_dir
from softtrack.store.tables import (
    TableNotFoundError,
    append_rows,
    list_tables,
    read_table,
    write_table,
)

REPO = Path(__file__).resolve().parents[1]


def _python(code: str, **kwargs) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(code)],
        env=env,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        **kwargs,
    )


def _wait_for_line(proc: subprocess.Popen, expected: str, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if line.strip() == expected:
            return
        if not line and proc.poll() is not None:
            raise AssertionError(f"child exited early: {proc.stderr.read()}")
    raise AssertionError(f"child did not print {expected!r} in time")


# ---- ids ----------------------------------------------------------------------------------
def test_ids_are_ulids_unique_and_sorted() -> None:
    made = [new_id() for _ in range(5000)]
    assert len(set(made)) == len(made)
    assert made == sorted(made)  # monotonic within a process, even within one millisecond
    assert all(len(i) == 26 and is_valid_id(i) for i in made)
    assert not set("ILOU") & set("".join(made))
    assert abs(id_timestamp(made[0]) - datetime.now(UTC)) < timedelta(seconds=5)


def test_ids_sort_by_time() -> None:
    earlier, later = new_id(1_700_000_000_000), new_id(1_700_000_000_001)
    assert earlier < later
    assert id_timestamp(earlier) == datetime.fromtimestamp(1_700_000_000, tz=UTC)
    assert new_id(2**48 - 1).startswith("7ZZZZZZZZZ")
    with pytest.raises(ValueError):
        new_id(2**48)


def test_create_unique_dir_retries_on_collision(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    taken = new_id()
    (tmp_path / taken).mkdir()
    sequence = iter([taken, taken, "01ARZ3NDEKTSV4RRFFQ69G5FAV"])
    monkeypatch.setattr(ids, "new_id", lambda: next(sequence))
    run_id, path = create_unique_dir(tmp_path)
    assert run_id == "01ARZ3NDEKTSV4RRFFQ69G5FAV" and path.is_dir()


@pytest.mark.faults("held")
def test_concurrent_creation_from_several_processes(tmp_path: Path) -> None:
    code = f"""
        from softtrack.store.ids import create_unique_dir
        for _ in range(40):
            print(create_unique_dir({str(tmp_path)!r})[0])
    """
    procs = [_python(code) for _ in range(4)]
    outputs = [p.communicate(timeout=60) for p in procs]
    assert all(p.returncode == 0 for p in procs), outputs
    made = [line for out, _ in outputs for line in out.split()]
    assert len(made) == 160 and len(set(made)) == 160
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(made)


# ---- atomic writes ------------------------------------------------------------------------
def test_atomic_writes(tmp_path: Path) -> None:
    atomic_write_bytes(tmp_path / "a.bin", b"\x00\x01")
    atomic_write_text(tmp_path / "sub" / "b.txt", "héllo")
    atomic_write_json(tmp_path / "c.json", {"x": [1, 2.5, None]})
    assert (tmp_path / "a.bin").read_bytes() == b"\x00\x01"
    assert (tmp_path / "sub" / "b.txt").read_text(encoding="utf-8") == "héllo"
    assert json.loads((tmp_path / "c.json").read_text()) == {"x": [1, 2.5, None]}
    with pytest.raises(ValueError):
        atomic_write_json(tmp_path / "c.json", {"x": float("nan")})
    assert json.loads((tmp_path / "c.json").read_text()) == {"x": [1, 2.5, None]}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.bin", "c.json", "sub"]


def test_failed_write_leaves_old_file_and_no_temp(tmp_path: Path) -> None:
    target = tmp_path / "model.zip"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".zip" and is_temp_file(tmp)
        tmp.write_bytes(b"half-writ")
        raise RuntimeError("killed mid-way")
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["model.zip"]


def test_atomic_dir(tmp_path: Path) -> None:
    target = tmp_path / "checkpoints" / "step-000000000100"
    with pytest.raises(RuntimeError), atomic_dir(target) as tmp:
        (tmp / "model.zip").write_bytes(b"m")
        raise RuntimeError
    assert not target.exists() and list((tmp_path / "checkpoints").iterdir()) == []
    with atomic_dir(target) as tmp:
        (tmp / "model.zip").write_bytes(b"m")
        (tmp / "replay_buffer.pkl").write_bytes(b"r")
    assert sorted(p.name for p in target.iterdir()) == ["model.zip", "replay_buffer.pkl"]
    with pytest.raises(FileExistsError), atomic_dir(target):
        pass


@pytest.mark.faults("held")
def test_sigkill_during_write_keeps_old_file(tmp_path: Path) -> None:
    target = tmp_path / "run.json"
    atomic_write_json(target, {"status": "old"})
    proc = _python(f"""
        import time
        from softtrack.store.atomic import atomic_path
        with atomic_path({str(target)!r}) as tmp:
            with open(tmp, "w") as fh:
                fh.write('{{"status": "ne')
                fh.flush()
                print("ready", flush=True)
                time.sleep(60)
    """)
    _wait_for_line(proc, "ready")
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert json.loads(target.read_text()) == {"status": "old"}
    leftovers = [p for p in tmp_path.iterdir() if p != target]
    assert len(leftovers) == 1 and is_temp_file(leftovers[0])
    assert remove_temp_files(tmp_path) == leftovers
    assert list(tmp_path.iterdir()) == [target]


# ---- tables -------------------------------------------------------------------------------
def test_append_read_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "tables" / "episodes.parquet"
    assert append_rows(path, [{"episode": 0, "global_step": 5000, "return": -10.5}]) == 1
    assert append_rows(path, []) == 1
    assert (
        append_rows(
            path,
            [
                {"episode": 1, "global_step": 10000, "return": np.float32(-3.25)},
                {"episode": 2, "global_step": np.int64(15000), "return": -1, "note": "x"},
            ],
        )
        == 3
    )
    df = read_table(path)
    assert list(df.columns) == ["episode", "global_step", "return", "note"]
    assert df["episode"].tolist() == [0, 1, 2]
    assert df["global_step"].tolist() == [5000, 10000, 15000]
    assert df["return"].tolist() == [-10.5, -3.25, -1.0]
    assert pd.isna(df["note"][0]) and df["note"][2] == "x"
    assert read_table(path, ["return"]).shape == (3, 1)
    assert pd.read_parquet(path).shape == (3, 4)  # an ordinary Parquet file
    assert list_tables(path.parent) == {"episodes": path}


def test_write_table_and_missing_table(tmp_path: Path) -> None:
    path = tmp_path / "metrics.parquet"
    with pytest.raises(TableNotFoundError, match=r"metrics.parquet"):
        read_table(path)
    assert read_table(path, ["a"], missing_ok=True).columns.tolist() == ["a"]
    df = pd.DataFrame({"a": [1.0, 2.0], "b": ["x", "y"]}, index=[10, 11])
    write_table(path, df)
    pd.testing.assert_frame_equal(read_table(path), df.reset_index(drop=True))
    write_table(path, [{"a": 3.0}])
    assert read_table(path)["a"].tolist() == [3.0]


def test_read_ignores_stray_temp_files(tmp_path: Path) -> None:
    path = tmp_path / "episodes.parquet"
    append_rows(path, [{"episode": 0, "return": 1.0}])
    stray = tmp_path / ".episodes.tmp-deadbeef.parquet"
    stray.write_bytes(b"PAR1 half-written garbage")
    assert read_table(path)["return"].tolist() == [1.0]
    assert list_tables(tmp_path) == {"episodes": path}
    live = tmp_path / f".episodes.tmp-{os.getppid()}-0badf00d.parquet"
    live.write_bytes(b"PAR1 a live writer's file")
    append_rows(path, [{"episode": 1, "return": 2.0}])
    assert read_table(path)["return"].tolist() == [1.0, 2.0]
    assert not stray.exists()  # a dead writer's leftover is swept by the next write
    assert live.exists()  # a live process's temporary file is left alone


@pytest.mark.faults("held")
def test_sigkill_during_appends_leaves_readable_table(tmp_path: Path) -> None:
    path = tmp_path / "appended.parquet"
    proc = _python(f"""
        from softtrack.store.tables import append_rows
        batch = 0
        while True:
            append_rows({str(path)!r}, [{{"batch": batch, "row": i, "return": float(i)}} for i in range(50)])
            batch += 1
            if batch == 3:
                print("ready", flush=True)
    """)
    _wait_for_line(proc, "ready")
    time.sleep(0.3)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    df = read_table(path)
    assert len(df) >= 150 and len(df) % 50 == 0  # whole appends only
    assert df["batch"].tolist() == sorted(df["batch"].tolist())
    assert df.groupby("batch").size().eq(50).all()


# ---- runs ---------------------------------------------------------------------------------
@pytest.fixture
def spec() -> ExperimentSpec:
    return parse_spec(
        {"name": "unit", "training": {"total_timesteps": 1000}, "algo": {"learning_starts": 10}}
    )


def test_a_prefix_selects_by_run_id_not_by_a_named_directory(
    tmp_path: Path, spec: ExperimentSpec
) -> None:
    """``models/<name>-seed0`` is selected by its whole name or its run id's prefix; a prefix
    of its name (``td3-sbx-64`` of ``td3-sbx-64-tuned-seed0``) selects nothing."""
    store = RunStore(tmp_path / "runs")
    record = store.create_run(spec, seed=0)
    named = record.path.rename(tmp_path / "runs" / "td3-sbx-64-tuned-seed0")
    assert store.get_run(named.name).run_id == named.name
    assert store.get_run(record.run_id[:10]).path == named
    with pytest.raises(RunNotFoundError, match="no run 'td3-sbx-64'"):
        store.get_run("td3-sbx-64")


def test_create_run(tmp_path: Path, spec: ExperimentSpec) -> None:
    store = RunStore(tmp_path / "runs")
    record = store.create_run(spec, seed=1, command=["softtrack", "train", "x.yaml"])
    assert is_valid_id(record.run_id) and record.path == tmp_path / "runs" / record.run_id
    assert sorted(p.name for p in record.path.iterdir()) == [
        "checkpoints",
        "run.json",
        "spec.yaml",
        "tables",
    ]
    assert load_spec(record.spec_path) == spec.with_seed(1)
    data = json.loads(record.run_json_path.read_text())
    assert data["status"] == "queued" and data["seed"] == 1 and data["run_id"] == record.run_id
    assert data["spec_hash"] == spec_hash(spec)
    assert data["command"] == ["softtrack", "train", "x.yaml"]
    assert data["versions"]["numpy"] == np.__version__ and "python" in data["versions"]
    assert data["created"].endswith("Z") and data["started"] is None
    assert data["cpu"] == cpu_description()
    assert {
        "git_commit",
        "git_dirty",
        "steps_per_second",
        "global_step",
        "error",
        "heartbeat",
        "ended",
    } <= set(data)
    assert record.table_path("train_episodes") == record.path / "tables" / "train_episodes.parquet"
    assert record.checkpoint_dir(100).name == "step-000000000100"


def test_update_get_list(tmp_path: Path, spec: ExperimentSpec) -> None:
    store = RunStore(tmp_path)
    a = store.create_run(spec, 0)
    b = store.create_run(spec, 1)
    (tmp_path / "01ZZZZZZZZZZZZZZZZZZZZZZZZ").mkdir()  # aborted creation: no run.json
    (tmp_path / ".01ZZ.tmp-0000").mkdir()
    assert [r.run_id for r in store.list_runs()] == [a.run_id, b.run_id]
    store.mark_running(a.run_id)
    store.heartbeat(a.run_id, global_step=500, steps_per_second=1234.5)
    done = store.mark_finished(a.run_id, "failed", error="boom\nsecond line")
    assert done.info.status == "failed" and done.info.error == "boom second line"
    got = store.get_run(a.run_id)
    assert got.info.global_step == 500 and got.info.steps_per_second == 1234.5
    assert got.info.started and got.info.ended and got.info.heartbeat
    assert store.get_run(a.run_id.lower()[:20]).run_id == a.run_id  # unique prefix, any case
    when = datetime(2025, 1, 2, 3, 4, 5, tzinfo=UTC)
    assert store.update_run(b.run_id, started=when).info.started == "2025-01-02T03:04:05.000Z"
    with pytest.raises(TypeError, match="statuss"):
        store.update_run(b.run_id, statuss="running")
    with pytest.raises(ValidationError):
        store.update_run(b.run_id, status="exploded")
    assert store.get_run(b.run_id).info.status == "queued"


def test_sessions_record_each_training_process(tmp_path: Path, spec: ExperimentSpec) -> None:
    store = RunStore(tmp_path)
    run = store.create_run(spec, 0)
    assert run.info.sessions == []
    store.mark_running(run.run_id)
    store.heartbeat(run.run_id, global_step=300, steps_per_second=100.0)
    store.mark_finished(run.run_id, "interrupted", global_step=400)
    store.mark_running(run.run_id)
    open_session = store.get_run(run.run_id).info.sessions[-1]
    assert "ended" not in open_session and open_session["pid"] == os.getpid()
    store.mark_finished(run.run_id, "completed", global_step=1000, steps_per_second=250.0)
    first, second = store.get_run(run.run_id).info.sessions
    assert (first["end_step"], first["status"], first["steps_per_second"]) == (
        400,
        "interrupted",
        100.0,
    )
    assert (second["end_step"], second["status"], second["steps_per_second"]) == (
        1000,
        "completed",
        250.0,
    )
    for session in (first, second):
        assert session["git_commit"] == run.info.git_commit and session["cpu"] == run.info.cpu
        assert session["started"] <= session["ended"]
    store.mark_finished(run.run_id, "failed", error="late")  # no open session: none changed
    assert store.get_run(run.run_id).info.sessions == [first, second]


def test_run_not_found_message(tmp_path: Path, spec: ExperimentSpec) -> None:
    store = RunStore(tmp_path)
    with pytest.raises(RunNotFoundError) as info:
        store.get_run("01NOPE")
    message = str(info.value)
    assert str(tmp_path) in message and "softtrack runs" in message and "\n" not in message
    store.create_run(spec, 0)
    store.create_run(spec, 1)
    with pytest.raises(RunNotFoundError, match="matches 2 runs"):
        store.get_run("0")
    with pytest.raises(RunNotFoundError, match="no runs directory"):
        RunStore(tmp_path / "absent").get_run("x")


def test_resolve_runs_dir(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("SOFTTRACK_RUNS_DIR", raising=False)
    assert resolve_runs_dir(None) == Path("runs")
    monkeypatch.setenv("SOFTTRACK_RUNS_DIR", "/data/runs")
    assert resolve_runs_dir(None) == Path("/data/runs")
    assert resolve_runs_dir("elsewhere") == Path("elsewhere")


def test_cpu_description_reads_model_cores_and_widest_extension(tmp_path: Path) -> None:
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text(
        "processor\t: 0\nmodel name\t: Test CPU 9000\nflags\t\t: fpu sse4_2 avx avx2 fma\n\n"
        "processor\t: 1\nmodel name\t: Test CPU 9000\nflags\t\t: fpu sse4_2 avx avx2 fma\n"
    )
    cores = usable_cores()
    suffix = "s" if cores != 1 else ""
    assert cpu_description(str(cpuinfo)) == f"Test CPU 9000, {cores} core{suffix}, avx2"
    described = cpu_description(str(tmp_path / "missing"))
    assert described.endswith(f"{cores} core{suffix}") and not described.startswith(",")
