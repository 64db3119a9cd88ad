"""Fault injection (``make faults``): each test injects one fault that once lost or corrupted
data, printed a traceback where one line belongs, or degraded the store, and checks that
softtrack now keeps every byte and says in one line what is wrong (docs/faults.md).

The marker's kind is what the fault did before the fix: ``lost``, ``traceback``, ``degraded``
(or ``held`` for the faults that already held, marked in their own modules). Disk faults are
injected by raising the operating system's error where softtrack writes; with root and mount
rights the same faults also run against a real full or read-only tmpfs.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.store import catalog
from softtrack.store.atomic import is_temp_file
from softtrack.store.catalog import read_catalog
from softtrack.store.runs import RunStore
from softtrack.store.tables import read_table

runner = CliRunner()
EVAL_DURATION = 0.2  # s: 100 control steps per trajectory


# ---- helpers --------------------------------------------------------------------------------
def _spec_data(**training: Any) -> dict[str, Any]:
    return {
        "name": "tiny",
        "seeds": [0],
        "env": {"episode_duration": 0.1},
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
            "heartbeat_interval": 0.5,
            "eval_duration": EVAL_DURATION,
            **training,
        },
    }


def _spec(tmp_path: Path, name: str = "tiny", **training: Any) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump({**_spec_data(**training), "name": name}), encoding="utf-8")
    return path


def _cli(*args: str) -> Any:
    return runner.invoke(app, list(args), env={"CI": "1"})


def _one_line(result: Any) -> str:
    """The command's one ``error:`` line on stderr (progress lines aside), checked to come
    without a traceback."""
    errors = [ln for ln in result.stderr.splitlines() if ln.startswith("error:")]
    assert "Traceback" not in result.output and len(errors) == 1, result.output
    return errors[0]


def _snapshot(root: Path) -> dict[str, str]:
    """Every file under ``root``: relative path → SHA-256."""
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name != "run.lock"
    }


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """A tiny trained and evaluated run (read-only for the tests: copy it first)."""
    tmp = tmp_path_factory.mktemp("faults")
    runs = tmp / "runs"
    result = _cli("train", str(_spec(tmp)), "--runs-dir", str(runs))
    assert result.exit_code == 0, result.output
    run_id = result.stdout.split()[0]
    result = _cli("evaluate", run_id, "--runs-dir", str(runs))
    assert result.exit_code == 0, result.output
    return runs, run_id


@pytest.fixture
def runs(trained: tuple[Path, str], tmp_path: Path) -> tuple[Path, str]:
    """A private copy of the trained run's runs directory."""
    source, run_id = trained
    copy = tmp_path / "runs"
    shutil.copytree(source, copy)
    return copy, run_id


def _raise_oserror(code: int, where: Path) -> Any:
    def fail(*_args: Any, **_kwargs: Any) -> None:
        raise OSError(code, os.strerror(code), str(where))

    return fail


# ---- 1. a query is read-only -----------------------------------------------------------------
@pytest.mark.faults("lost")
@pytest.mark.parametrize(
    "sql",
    [
        "COPY (SELECT * FROM eval_metrics WHERE false) TO '{run}/tables/eval_metrics.parquet'",
        "COPY (SELECT 'x') TO '{run}/run.json'",
        "ATTACH '{run}/new.db' AS extra",
        "INSTALL httpfs",
        "LOAD httpfs",
        "SELECT * FROM read_csv('/etc/passwd')",
        "SELECT * FROM read_parquet('{run}/tables/*.parquet')",
        "SET enable_external_access = true",
        "EXPORT DATABASE '{run}/dump'",
        "SELECT 1; COPY (SELECT 1) TO '{run}/x.csv'",
        "CREATE TABLE sneaky AS SELECT 1",
    ],
)
def test_query_cannot_write_read_outside_or_install(
    runs: tuple[Path, str], sql: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    root, run_id = runs
    run = root / run_id
    monkeypatch.setattr(catalog, "_RACY_S", 0.0)  # the copy's files count as settled at once
    read_catalog(root)  # the catalog a first read builds (a cache of the directories)
    before = _snapshot(root)
    result = _cli("query", sql.format(run=run), "--runs-dir", str(root))
    assert result.exit_code == 2
    assert _one_line(result).startswith("error: query: ")
    assert _snapshot(root) == before  # nothing written, nothing removed
    assert (
        _cli(
            "query", "SELECT count(*) AS n FROM eval_metrics", "--runs-dir", str(root)
        ).stdout.split()[-1]
        == "6"
    )  # the store still reads


# ---- 2. tune: a retry is its own trial's run ---------------------------------------------------
TUNE_PARAMS = {
    "params": {
        "algo.learning_rate": {"type": "float", "low": 1.0e-4, "high": 3.0e-3, "log": True},
        "algo.batch_size": {"type": "categorical", "choices": [8, 16]},
    },
}


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.slow
@pytest.mark.faults("lost")
def test_tune_killed_everywhere_then_rerun_keeps_every_trial_its_run(tmp_path: Path) -> None:
    import optuna

    from softtrack.spec import spec_hash
    from softtrack.tune.study import decode_params, default_storage, load_study, trial_spec

    data = _spec_data(
        total_timesteps=1600, n_envs=2, checkpoint_interval=200, validation_episodes=1
    )
    data["tune"] = TUNE_PARAMS
    spec = tmp_path / "tune.yaml"
    spec.write_text(yaml.safe_dump(data), encoding="utf-8")
    root = tmp_path / "runs"
    command = [
        sys.executable,
        "-m",
        "softtrack.cli",
        "tune",
        str(spec),
        "--trials",
        "3",
        "--study",
        "k",
        "--workers",
        "2",
        "--runs-dir",
        str(root),
    ]
    proc = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "CI": "1"},
        start_new_session=True,
    )
    deadline = time.monotonic() + 300
    workers: set[int] = set()
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        records = RunStore(root).list_runs() if root.is_dir() else []
        busy = [r for r in records if r.info.status == "running" and r.list_checkpoints()]
        if len(busy) >= 2:
            workers = {int(r.info.pid) for r in busy if r.info.pid}
            break
        time.sleep(0.05)
    assert workers, "two trials never trained at once"
    os.killpg(proc.pid, signal.SIGKILL)
    for pid in workers:
        if _alive(pid):
            os.kill(pid, signal.SIGKILL)
    proc.communicate(timeout=30)
    while any(_alive(pid) for pid in workers):
        time.sleep(0.05)

    result = subprocess.run(
        command, capture_output=True, text=True, timeout=900, env={**os.environ, "CI": "1"}
    )
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    ts = load_study(default_storage(root), "k")
    complete = [t for t in ts.study.get_trials() if t.state.name == "COMPLETE"]
    assert len(complete) == 3
    store = RunStore(root)
    for trial in ts.study.get_trials():
        if "run_id" not in trial.user_attrs or trial.state.name not in ("COMPLETE", "PRUNED"):
            continue
        record = store.get_run(trial.user_attrs["run_id"])
        values = decode_params(ts.tune, trial.params)
        assert set(values) == set(TUNE_PARAMS["params"])
        expected = trial_spec(ts, values, record.info.name)
        assert spec_hash(expected) == record.info.spec_hash, (trial.number, values)
        assert record.load_spec().algo.batch_size == values["algo.batch_size"]


# ---- 3, 4. a full or read-only disk: one line, the run resumable ------------------------------
@pytest.mark.faults("traceback")
def test_disk_full_during_train_marks_the_run_interrupted(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import softtrack.rl.callbacks as callbacks

    root = tmp_path / "runs"
    spec = _spec(tmp_path, total_timesteps=400, checkpoint_interval=200)
    monkeypatch.setattr(
        callbacks, "atomic_dir", _raise_oserror(errno.ENOSPC, root / "x" / "checkpoints" / ".tmp")
    )
    result = _cli("train", str(spec), "--runs-dir", str(root))
    assert result.exit_code not in (0, 2) and result.exit_code < 128
    err = _one_line(result)
    assert "no space left on the device" in err and "--resume" in err and "free" in err
    (record,) = RunStore(root).list_runs()
    assert record.info.status == "interrupted" and "no space left" in str(record.info.error)
    monkeypatch.undo()  # space is back: the run resumes and finishes
    result = _cli("train", "--resume", record.run_id, "--runs-dir", str(root))
    assert result.exit_code == 0, result.output
    assert RunStore(root).get_run(record.run_id).info.status == "completed"


@pytest.mark.faults("traceback")
@pytest.mark.parametrize(
    "code, words", [(errno.ENOSPC, "no space left"), (errno.EROFS, "read-only file system")]
)
def test_disk_faults_during_evaluate_are_one_line_and_keep_the_tables(
    runs: tuple[Path, str], monkeypatch: pytest.MonkeyPatch, code: int, words: str
) -> None:
    import softtrack.store.tables as tables

    root, run_id = runs
    before = _snapshot(root / run_id / "tables")
    monkeypatch.setattr(
        tables,
        "_write_parquet",
        _raise_oserror(code, root / run_id / "tables" / ".x.tmp-1-a.parquet"),
    )
    result = _cli("evaluate", run_id, "--runs-dir", str(root))
    assert result.exit_code == 2
    err = _one_line(result)
    assert words in err and str(root / run_id / "tables") in err
    assert _snapshot(root / run_id / "tables") == before


@pytest.mark.faults("traceback")
def test_read_only_runs_directory_train_and_report_are_one_line(
    runs: tuple[Path, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import softtrack.store.ids as ids

    root, run_id = runs
    monkeypatch.setattr(ids.os, "mkdir", _raise_oserror(errno.EROFS, root / "new"))
    result = _cli("train", str(_spec(tmp_path)), "--runs-dir", str(root))
    assert result.exit_code == 2 and "read-only file system" in _one_line(result)
    monkeypatch.undo()
    import softtrack.store.tables as tables

    for table in (root / run_id / "tables").glob("eval_*.parquet"):
        table.unlink()  # an unevaluated run: report must evaluate (and write) it
    monkeypatch.setattr(
        tables,
        "_write_parquet",
        _raise_oserror(errno.EROFS, root / run_id / "tables" / ".t.parquet"),
    )
    result = _cli("report", run_id, "--runs-dir", str(root), "--out", str(tmp_path / "rep"))
    assert result.exit_code == 2 and "read-only file system" in _one_line(result)


def _can_mount() -> bool:
    if os.geteuid() != 0 or not sys.platform.startswith("linux") or shutil.which("mount") is None:
        return False
    probe = Path(f"/tmp/softtrack-mount-probe-{os.getpid()}")
    probe.mkdir(exist_ok=True)
    ok = (
        subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(probe)], capture_output=True
        ).returncode
        == 0
    )
    if ok:
        subprocess.run(["umount", str(probe)], capture_output=True)
    probe.rmdir()
    return ok


@pytest.fixture
def tmpfs(tmp_path: Path) -> Iterator[Any]:
    """``mount(size_kb, read_only=False) -> Path``: a real tmpfs (root with mount rights only)."""
    if not _can_mount():
        pytest.skip("needs root and mount rights for a real tmpfs (the injected variants run)")
    mounted: list[Path] = []

    def mount(size_kb: int, read_only: bool = False) -> Path:
        point = tmp_path / f"mnt{len(mounted)}"
        point.mkdir()
        options = f"size={size_kb}k" + (",ro" if read_only else "")
        subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(point)], check=True)
        mounted.append(point)
        return point

    yield mount
    for point in mounted:
        subprocess.run(["umount", "-l", str(point)], capture_output=True)


@pytest.mark.slow
@pytest.mark.faults("traceback")
def test_a_really_full_disk_during_train(tmp_path: Path, tmpfs: Any) -> None:
    disk = tmpfs(600)  # room for the run, not for a checkpoint with its replay buffer
    root = disk / "runs"
    spec = _spec(tmp_path, total_timesteps=400, checkpoint_interval=200)
    command = [sys.executable, "-m", "softtrack.cli", "train", str(spec), "--runs-dir", str(root)]
    result = subprocess.run(
        command, capture_output=True, text=True, timeout=300, env={**os.environ, "CI": "1"}
    )
    assert result.returncode not in (0, 2), result.stderr
    lines = [ln for ln in result.stderr.splitlines() if ln.startswith("error:")]
    assert "Traceback" not in result.stderr and len(lines) == 1, result.stderr
    assert "no space left" in lines[0] and str(root) in lines[0]
    (record,) = RunStore(root).list_runs()
    assert record.info.status == "interrupted"
    assert not [p for p in root.rglob("*") if is_temp_file(p)]


@pytest.mark.slow
@pytest.mark.faults("traceback")
def test_a_really_read_only_runs_directory(
    runs: tuple[Path, str], tmp_path: Path, tmpfs: Any
) -> None:
    root, run_id = runs
    ro = tmpfs(4096)
    shutil.copytree(root, ro / "runs")
    subprocess.run(["mount", "-o", "remount,ro", str(ro)], check=True)
    for args in (["evaluate", run_id], ["train", str(_spec(tmp_path))]):
        result = subprocess.run(
            [sys.executable, "-m", "softtrack.cli", *args, "--runs-dir", str(ro / "runs")],
            capture_output=True,
            text=True,
            timeout=300,
            env={**os.environ, "CI": "1"},
        )
        assert result.returncode == 2, result.stderr
        assert "Traceback" not in result.stderr
        assert "read-only file system" in result.stderr.strip().splitlines()[-1]


# ---- 5, 6. hostile specs -------------------------------------------------------------------
def _alias_bomb(levels: int) -> str:
    lines = ['a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for k in range(1, levels):
        prev, cur = chr(ord("a") + k - 1), chr(ord("a") + k)
        lines.append(f"{cur}: &{cur} [" + ", ".join([f"*{prev}"] * 9) + "]")
    return "\n".join(lines) + "\n"


@pytest.mark.faults("traceback")
@pytest.mark.parametrize(
    "text, words",
    [
        (_alias_bomb(9), "expands to more than"),
        (_alias_bomb(7), "expands to more than"),
        ("name: x\nseeds: " + "[" * 20000 + "\n", "nests lists/mappings more than"),
        ("name: x\nseeds: " + "[" * 20000 + "]" * 20000 + "\n", "nests lists/mappings more than"),
    ],
)
def test_yaml_bombs_and_deep_nesting_are_rejected_fast(
    tmp_path: Path, text: str, words: str
) -> None:
    path = tmp_path / "bomb.yaml"
    path.write_text(text, encoding="utf-8")
    start = time.monotonic()
    result = _cli("validate", str(path))
    assert time.monotonic() - start < 10
    assert result.exit_code == 2 and words in _one_line(result)


@pytest.mark.faults("traceback")
def test_an_override_bomb_is_rejected(tmp_path: Path) -> None:
    result = _cli("validate", str(_spec(tmp_path)), "--set", "seeds=" + "[" * 5000)
    assert result.exit_code == 2 and "nests" in _one_line(result)


@pytest.mark.faults("degraded")
def test_integers_beyond_64_bits_are_refused(tmp_path: Path) -> None:
    spec = _spec(tmp_path)
    result = _cli(
        "train",
        str(spec),
        "--set",
        "training.total_timesteps=9223372036854775808",
        "--runs-dir",
        str(tmp_path / "runs"),
    )
    assert result.exit_code == 2 and "64-bit" in _one_line(result)
    assert not (tmp_path / "runs").exists()


@pytest.mark.faults("degraded")
def test_a_run_json_beyond_64_bits_is_listed_unreadable_and_queries_work(
    runs: tuple[Path, str], tmp_path: Path
) -> None:
    root, run_id = runs
    shutil.copytree(root / run_id, root / "huge")
    data = json.loads((root / "huge" / "run.json").read_text())
    data.update(run_id="01HUGEHUGEHUGEHUGEHUGEHUGE", total_timesteps=2**63)
    (root / "huge" / "run.json").write_text(json.dumps(data))
    result = _cli("query", "SELECT count(*) AS n FROM runs", "--runs-dir", str(root))
    assert result.exit_code == 0 and result.stdout.split()[-1] == "1"
    assert "huge" in result.stderr and "left out" in result.stderr
    listing = _cli("runs", "--runs-dir", str(root)).stdout
    assert "huge: unreadable" in listing


# ---- 7, 8. evaluation tables: all or none, no temporaries -------------------------------------
@pytest.mark.faults("degraded")
def test_evaluate_with_a_corrupt_table_changes_no_table(runs: tuple[Path, str]) -> None:
    root, run_id = runs
    tables = root / run_id / "tables"
    (tables / "eval_metrics.parquet").write_bytes(b"PAR1 garbage")
    before = _snapshot(tables)
    result = _cli("evaluate", run_id, "--runs-dir", str(root))
    assert result.exit_code == 2 and "eval_metrics.parquet" in _one_line(result)
    assert _snapshot(tables) == before


_SLOW_WRITER = """
import signal, sys, time
from pathlib import Path
import pandas as pd
import softtrack.cli as cli
import softtrack.store.tables as tables
signal.signal(signal.SIGTERM, cli.exit_on_sigterm)
write = tables._write_parquet
def slow(table, path):
    write(table, path)
    print("written", flush=True)
    time.sleep(60)
tables._write_parquet = slow
tables.write_tables({Path(sys.argv[1]): pd.DataFrame({"a": [1.0, 2.0]})})
"""


@pytest.mark.faults("degraded")
def test_sigterm_during_a_table_write_leaves_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "tables" / "eval_metrics.parquet"
    proc = subprocess.Popen(
        [sys.executable, "-c", _SLOW_WRITER, str(target)], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None and proc.stdout.readline().strip() == "written"
    assert [p for p in target.parent.iterdir() if is_temp_file(p)]  # mid-write
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=30) == 128 + signal.SIGTERM
    assert list(target.parent.iterdir()) == []  # no temporary, no half table


@pytest.mark.faults("degraded")
def test_a_killed_writers_temporary_is_swept_by_the_next_evaluation(runs: tuple[Path, str]) -> None:
    root, run_id = runs
    tables = root / run_id / "tables"
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = [
        tables / f".eval_metrics.tmp-{dead.pid}-deadbeef.parquet",
        tables / ".eval_trajectories.tmp-cafebabe.parquet",
    ]  # an older version's name
    for path in stale:
        path.write_bytes(b"half")
    result = _cli("evaluate", run_id, "--runs-dir", str(root))
    assert result.exit_code == 0, result.output
    assert not [p for p in tables.iterdir() if is_temp_file(p)]


# ---- 9, 10, 11. missing files, runs found by id ----------------------------------------------
@pytest.mark.faults("degraded")
@pytest.mark.parametrize("damage", ["missing", "truncated"])
def test_a_run_without_a_readable_run_json_is_listed_and_named(
    runs: tuple[Path, str], damage: str
) -> None:
    root, run_id = runs
    path = root / run_id / "run.json"
    if damage == "missing":
        path.unlink()
    else:
        path.write_text(path.read_text()[:40])
    listing = _cli("runs", "--runs-dir", str(root))
    assert listing.exit_code == 0
    assert f"{run_id}: unreadable:" in listing.stdout and "run.json" in listing.stdout
    rows = json.loads(_cli("runs", "--runs-dir", str(root), "--format", "json").stdout)
    assert [r["status"] for r in rows] == ["unreadable"]
    result = _cli("evaluate", str(root / run_id))
    assert result.exit_code == 2 and "run.json" in _one_line(result)
    result = _cli("evaluate", run_id, "--runs-dir", str(root))
    assert result.exit_code == 2 and "run.json" in _one_line(result)
    result = _cli("resume", "--runs-dir", str(root))
    assert run_id in result.stderr and "run.json" in result.stderr


def _interrupted_run(tmp_path: Path) -> tuple[Path, str]:
    """A run stopped by SIGINT after its first checkpoint (mid-episode)."""
    spec = _spec(tmp_path, total_timesteps=2000, checkpoint_interval=200, n_envs=2)
    root = tmp_path / "runs"
    proc = subprocess.Popen(
        [sys.executable, "-m", "softtrack.cli", "train", str(spec), "--runs-dir", str(root)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "CI": "1"},
    )
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        records = RunStore(root).list_runs() if root.is_dir() else []
        if records and records[0].list_checkpoints():
            break
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.02)
    time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    return root, out.strip()


@pytest.mark.faults("lost")
@pytest.mark.parametrize("damage", ["missing", "latin-1"])
def test_resume_with_a_broken_spec_keeps_the_status(tmp_path: Path, damage: str) -> None:
    root, run_id = _interrupted_run(tmp_path)
    spec = root / run_id / "spec.yaml"
    original = spec.read_bytes()
    if damage == "missing":
        spec.unlink()
    else:
        spec.write_bytes(original + "# caf\xe9\n".encode("latin-1"))
    for args in (["train", "--resume", run_id], ["resume", run_id]):
        result = _cli(*args, "--runs-dir", str(root))
        assert result.exit_code == 2 and "spec.yaml" in _one_line(result), result.output
        assert RunStore(root).get_run(run_id).info.status == "interrupted"
    result = _cli("resume", "--runs-dir", str(root))  # all: it is named, not failed
    assert "spec.yaml" in result.stderr
    assert RunStore(root).get_run(run_id).info.status == "interrupted"
    spec.write_bytes(original)
    result = _cli("train", "--resume", run_id, "--runs-dir", str(root))
    assert result.exit_code == 0, result.output
    assert RunStore(root).get_run(run_id).info.status == "completed"


@pytest.mark.faults("degraded")
def test_evaluate_finds_a_run_by_its_id_in_a_directory_named_otherwise(
    runs: tuple[Path, str],
) -> None:
    root, run_id = runs
    (root / run_id).rename(root / "td3-tiny-seed0")
    result = _cli("evaluate", run_id, "--runs-dir", str(root), "--trajectory", "circle")
    assert result.exit_code == 0, result.output
    assert (root / "td3-tiny-seed0" / "tables" / "eval_metrics.parquet").is_file()


# ---- 12. resume keeps the history ------------------------------------------------------------
@pytest.mark.faults("degraded")
def test_resume_keeps_started_the_killed_sessions_step_and_every_env_step(tmp_path: Path) -> None:
    spec = _spec(tmp_path, total_timesteps=2000, checkpoint_interval=220, n_envs=2)
    root = tmp_path / "runs"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "softtrack.cli",
            "train",
            str(spec),
            "--runs-dir",
            os.path.abspath(root),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "CI": "1"},
    )
    deadline = time.monotonic() + 180
    record = None
    while time.monotonic() < deadline and record is None:
        records = RunStore(root).list_runs() if root.is_dir() else []
        if records and records[0].list_checkpoints():
            record = records[0]
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.02)
    assert record is not None
    proc.kill()  # SIGKILL: the session is never closed by its process
    proc.communicate(timeout=30)
    checkpoint = int(RunStore(root).get_run(record.run_id).list_checkpoints()[-1].name[5:])
    started = RunStore(root).get_run(record.run_id).info.started
    result = _cli("train", "--resume", record.run_id, "--runs-dir", str(root))
    assert result.exit_code == 0, result.output
    info = RunStore(root).get_run(record.run_id).info
    assert info.started == started  # the first start, not the resume's
    lost, _done = info.sessions
    assert lost["status"] == "lost" and lost["end_step"] >= checkpoint > 0
    runs_dir_arg = info.command[info.command.index("--runs-dir") + 1]
    assert not os.path.isabs(runs_dir_arg)
    assert os.path.normpath(Path.cwd() / runs_dir_arg) == os.path.abspath(root)
    episodes = read_table(record.table_path("train_episodes"))
    truncated = episodes[episodes["truncated"].fillna(False).astype(bool)]
    assert len(truncated) == 2  # the two envs' episodes under way at the 220-step checkpoint
    assert (truncated["global_step"] == checkpoint).all() and (truncated["length"] < 50).all()
    assert list(episodes["episode"]) == list(range(len(episodes)))
    # every env step up to the checkpoint lies in one episode row (whole or truncated)
    before = episodes[episodes["global_step"] <= checkpoint]
    assert int(before["length"].sum()) == checkpoint


@pytest.mark.faults("lost")
@pytest.mark.parametrize("damage", ["a file", "missing"])
def test_resume_without_its_checkpoints_refuses_and_changes_nothing(
    tmp_path: Path, damage: str
) -> None:
    """Resuming a run whose ``checkpoints`` became a file marked it failed and cut its
    ``train_episodes``; with ``checkpoints/`` gone it silently started again at step 0. Now
    both refuse in one line and every file stays as it was."""
    root, run_id = _interrupted_run(tmp_path)
    checkpoints = root / run_id / "checkpoints"
    shutil.rmtree(checkpoints)
    if damage == "a file":
        checkpoints.write_text("not a directory")
    before = _snapshot(root / run_id)
    for args in (["train", "--resume", run_id], ["resume", run_id]):
        result = _cli(*args, "--runs-dir", str(root))
        assert result.exit_code == 2, result.output
        line = _one_line(result)
        assert "checkpoints" in line and "cannot resume" in line, line
        assert _snapshot(root / run_id) == before
    assert RunStore(root).get_run(run_id).info.status == "interrupted"


@pytest.mark.faults("traceback")
@pytest.mark.parametrize("dt", ["1e-300", "5e-9"])
def test_a_meaningless_time_step_is_refused_at_validation(tmp_path: Path, dt: str) -> None:
    """``dt = 1e-300`` passed validation and training, then evaluate ended in a traceback (an
    episode of 1e301 steps); every command that reads the spec now refuses it in one line."""
    spec = _spec(tmp_path)
    runs = tmp_path / "runs"
    for command in (["validate", str(spec)], ["train", str(spec), "--runs-dir", str(runs)]):
        result = _cli(*command, "--set", f"env.physics.dt={dt}")
        assert result.exit_code == 2, result.output
        line = _one_line(result)
        assert "env.physics.dt" in line and "integration steps" in line, line
    assert not runs.exists()


@pytest.mark.faults("traceback")
def test_export_destinations_that_cannot_hold_the_run_are_one_line(
    runs: tuple[Path, str], tmp_path: Path
) -> None:
    """``export`` onto a path under a file gave a traceback, and into a directory already
    holding the run made its id appear twice there (``compare`` counted it twice)."""
    root, run_id = runs
    before = _snapshot(root / run_id)
    afile = tmp_path / "afile"
    afile.write_text("x")
    cases = {
        str(afile / "sub"): "is a file, not a directory",
        str(root / "second-copy"): f"already holds run {run_id}",
        str(root / run_id / "inside"): "inside the run directory",
    }
    for dest, words in cases.items():
        result = _cli("export", run_id, dest, "--runs-dir", str(root))
        assert result.exit_code == 2 and words in _one_line(result), result.output
    assert _snapshot(root / run_id) == before and not (root / "second-copy").exists()


@pytest.mark.faults("lost")
def test_a_killed_exports_copy_is_removed_and_a_racing_export_is_one_line(
    runs: tuple[Path, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A killed export left its whole temporary copy behind for good; the next export to that
    destination removes it. Two exports to one destination: the second says so in one line
    and keeps nothing, the first's copy stays whole."""
    from softtrack.store import run_export

    root, run_id = runs
    out = tmp_path / "out"
    out.mkdir()
    dead = out / ".mine.tmp-999999-0badf00d"  # a temporary of a writer that is gone
    (dead / "tables").mkdir(parents=True)
    (dead / "model.zip").write_bytes(b"0" * 1000)
    result = _cli("export", run_id, str(out / "mine"), "--runs-dir", str(root))
    assert result.exit_code == 0, result.output
    assert not dead.exists() and sorted(p.name for p in out.iterdir()) == ["mine"]

    copy = run_export._copy_run
    race = tmp_path / "race"
    race.mkdir()
    monkeypatch.setattr(  # another export takes the name while this one copies
        run_export,
        "_copy_run",
        lambda *args: (copy(*args), shutil.copytree(out / "mine", race / "second")),
    )
    result = _cli("export", run_id, str(race / "second"), "--runs-dir", str(root))
    assert result.exit_code == 2 and "created by another process" in _one_line(result)
    assert sorted(p.name for p in race.iterdir()) == ["second"]  # no temporary left
    assert (race / "second" / "run.json").is_file()  # the other export's copy, whole


def _damage_metrics(path: Path, damage: str) -> None:
    import pandas as pd

    rows = pd.read_parquet(path)
    path.unlink()
    if damage == "numbers as text":
        rows.assign(rmse_3d=rows["rmse_3d"].astype(str)).to_parquet(path)
    elif damage == "a column missing":
        rows.drop(columns=["arm"]).to_parquet(path)
    else:  # a directory where the table belongs
        path.mkdir()
        rows.to_parquet(path / "part-0.parquet")


@pytest.mark.faults("traceback")
@pytest.mark.parametrize("damage", ["numbers as text", "a column missing", "a directory"])
def test_a_table_of_another_shape_is_named_in_one_line(
    runs: tuple[Path, str], tmp_path: Path, damage: str
) -> None:
    """A table with the wrong columns, numbers stored as text, or a directory in its place
    gave tracebacks in ``evaluate``, ``report`` and ``compare``. Now ``compare`` refuses in one
    line naming the file (a seed left out would change every interval), ``report`` leaves the
    table out with a warning naming it, and ``evaluate`` refuses before writing anything."""
    root, run_id = runs
    second = root / "second"
    shutil.copytree(root / run_id, second)
    table = root / run_id / "tables" / "eval_metrics.parquet"
    _damage_metrics(table, damage)
    before = _snapshot(root / run_id)
    result = _cli("compare", run_id, str(second), "--runs-dir", str(root))
    assert result.exit_code == 2 and str(table) in _one_line(result), result.output
    result = _cli("report", run_id, "--runs-dir", str(root), "--out", str(tmp_path / "rep"))
    assert result.exit_code == 0, result.output
    warnings = [ln for ln in result.stderr.splitlines() if ln.startswith("warning:")]
    assert "Traceback" not in result.output and any(str(table) in w for w in warnings)
    result = _cli("evaluate", run_id, "-t", "circle", "--runs-dir", str(root))
    assert result.exit_code == 2 and str(table) in _one_line(result), result.output
    assert _snapshot(root / run_id) == before


@pytest.mark.faults("degraded")
def test_a_truncated_model_is_not_exported(runs: tuple[Path, str], tmp_path: Path) -> None:
    """A truncated ``model.zip`` was exported without a word (a shipped run that cannot load)."""
    root, run_id = runs
    model = root / run_id / "model.zip"
    model.write_bytes(model.read_bytes()[: model.stat().st_size // 2])
    result = _cli("export", run_id, str(tmp_path / "out" / "x"), "--runs-dir", str(root))
    assert result.exit_code == 2 and "model.zip" in _one_line(result), result.output
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


@pytest.mark.faults("lost")
def test_evaluating_a_shipped_runs_last_model_writes_into_its_copy(
    runs: tuple[Path, str], tmp_path: Path
) -> None:
    """``evaluate --model last`` of a shipped run whose last model is its policy stored its
    results into the shipped run itself (the read-only copy rule applied to ``policy`` only)."""
    from softtrack.store.run_export import mark_read_only

    root, run_id = runs
    shipped = root / run_id
    mark_read_only(shipped)
    before = _snapshot(shipped)
    mine = tmp_path / "mine"
    result = _cli(
        "evaluate", str(shipped), "-t", "circle", "--model", "last", "--runs-dir", str(mine)
    )
    assert result.exit_code == 0, result.output
    assert _snapshot(shipped) == before
    assert (mine / run_id / "tables" / "eval_metrics.parquet").is_file()


@pytest.mark.faults("degraded")
def test_a_run_name_edited_into_a_newline_and_markup_is_an_unreadable_run(
    runs: tuple[Path, str], tmp_path: Path
) -> None:
    """A run.json ``name`` edited to hold a newline and HTML broke the runs table and the
    report's headings; such a run is now listed unreadable, with the field named."""
    root, run_id = runs
    path = root / run_id / "run.json"
    data = json.loads(path.read_text())
    data["name"] = "evil\n<b>x</b>|y"
    path.write_text(json.dumps(data))
    result = _cli("runs", "--runs-dir", str(root))
    assert result.exit_code == 0 and "evil\n<b>" not in result.stdout  # no raw newline
    assert "unreadable" in result.stdout and "'evil\\n<b>x</b>|y'" in result.stdout
    result = _cli("report", run_id, "--runs-dir", str(root), "--out", str(tmp_path / "rep"))
    assert result.exit_code == 2 and "name: String should match pattern" in _one_line(result)
    assert not (tmp_path / "rep").exists()


@pytest.mark.faults("lost")
def test_ctrl_c_during_many_random_episodes_keeps_the_finished_ones(
    runs: tuple[Path, str],
) -> None:
    """``evaluate --random 100000`` printed nothing for minutes and Ctrl-C discarded every
    finished episode. Now a line every 5 % (and at least every 30 s) says how far it is, and
    an interruption stores the episodes done so far (0 … k−1) before it stops: SIGTERM here
    (exit 143; Ctrl-C takes the same path, but a test runner started in the background hands
    SIGINT down ignored)."""
    root, run_id = runs
    proc = subprocess.Popen(
        [
            *(sys.executable, "-m", "softtrack.cli", "evaluate", run_id),
            *("-t", "none", "--random", "400", "--runs-dir", str(root)),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "CI": "1"},
    )
    assert proc.stderr is not None
    for line in proc.stderr:  # the first progress line: some episodes are done
        if "random targets:" in line:
            break
    proc.send_signal(signal.SIGTERM)
    _out, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    rows = read_table(root / run_id / "tables" / "eval_random.parquet")
    episodes = sorted(set(rows["episode"]))
    assert 1 <= len(episodes) < 400 and episodes == list(range(len(episodes)))
    assert f"stopped by SIGTERM: kept the {len(episodes)} finished episodes of 400" in err, err


@pytest.mark.faults("traceback")
def test_an_address_space_limit_too_small_for_jax_is_one_line(runs: tuple[Path, str]) -> None:
    """Under ``ulimit -v`` evaluate died with a traceback, blamed the model, or hung in XLA's
    allocator ignoring SIGTERM; now it stops at once with one line naming the limit, exit 1
    (a machine limit, not the user's input)."""
    import resource

    root, run_id = runs

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2_000_000 * 1024, resource.RLIM_INFINITY))

    started = time.monotonic()
    proc = subprocess.run(
        [
            *(sys.executable, "-m", "softtrack.cli", "evaluate", run_id),
            *("-t", "circle", "--runs-dir", str(root)),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=limit,
        env={**os.environ, "CI": "1"},
    )
    assert proc.returncode == 1, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and "ulimit -v" in lines[0] and "Traceback" not in proc.stderr
    assert time.monotonic() - started < 60


def test_evaluate_and_export_take_the_run_lock_the_trainers_take(
    runs: tuple[Path, str], tmp_path: Path
) -> None:
    """While another process holds a run (training it), evaluating into it and exporting it
    are one line naming the holder, exit 2, nothing changed; listing it needs no lock."""
    root, run_id = runs
    run_dir = next(p for p in root.iterdir() if (p / "run.json").is_file())
    before = _snapshot(run_dir)
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\n"
            "from softtrack.store.runs import RunStore, run_lock\n"
            "record = RunStore(sys.argv[1]).get_run(sys.argv[2])\n"
            "with run_lock(record, sys.argv[3]):\n"
            "    print('held', flush=True)\n"
            "    time.sleep(60)\n",
            str(root),
            run_id,
            "trained",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        result = _cli("evaluate", run_id, "-t", "circle", "--runs-dir", str(root))
        line = _one_line(result)
        assert result.exit_code == 2 and "is being trained by another process" in line, line
        assert f"pid {holder.pid}" in line
        result = _cli("export", run_id, str(tmp_path / "out"), "--runs-dir", str(root))
        assert result.exit_code == 2 and "being trained" in _one_line(result)
        assert not (tmp_path / "out").exists()
        result = _cli("runs", "--runs-dir", str(root))  # reading the store needs no lock
        assert result.exit_code == 0 and run_id in result.output, result.output
    finally:
        holder.kill()
        holder.wait()
    assert _snapshot(run_dir) == before
    # the lock is free again: evaluation and export go through
    assert _cli("evaluate", run_id, "-t", "circle", "--runs-dir", str(root)).exit_code == 0
    assert _cli("export", run_id, str(tmp_path / "out"), "--runs-dir", str(root)).exit_code == 0


@pytest.mark.faults("traceback")
@pytest.mark.parametrize("where", ["runs dir", "under it"])
def test_train_into_a_runs_directory_that_is_a_file_is_one_line(tmp_path: Path, where: str) -> None:
    blocker = tmp_path / "runs"
    blocker.write_text("not a directory")
    runs_dir = blocker if where == "runs dir" else blocker / "sub"
    result = _cli("train", str(_spec(tmp_path)), "--runs-dir", str(runs_dir))
    assert result.exit_code == 2
    line = _one_line(result)
    assert f"{blocker} is a file where softtrack needs a directory" in line
    assert blocker.read_text() == "not a directory"
    result = _cli("runs", "--runs-dir", str(blocker))
    assert result.exit_code == 2 and "is not a directory" in _one_line(result)


@pytest.mark.faults("traceback")
@pytest.mark.parametrize("command", ["evaluate", "report"])
def test_a_run_whose_tables_are_a_file_is_refused_before_any_episode(
    runs: tuple[Path, str], tmp_path: Path, command: str
) -> None:
    """Before: `report` evaluated every trajectory, then a traceback (FileExistsError)."""
    root, run_id = runs
    tables = next(root.glob("*/tables"))
    shutil.rmtree(tables)
    tables.write_text("a file")
    before = _snapshot(root)
    args = [run_id, "--runs-dir", str(root)]
    if command == "report":
        args += ["--out", str(tmp_path / "report")]
    result = _cli(command, *args)
    assert result.exit_code == 2
    assert "is a file where the run's tables directory belongs" in _one_line(result)
    assert "3-D RMSE" not in result.output  # no episode ran

    def run_files(snapshot: dict[str, str]) -> dict[str, str]:  # the catalog is a cache
        return {k: v for k, v in snapshot.items() if not k.startswith(".softtrack-catalog")}

    assert run_files(_snapshot(root)) == run_files(before)


# ---- the hostile sweep of session 26 (tests/hostile_sweep.py): each fault it found ------------
@pytest.mark.faults("traceback")
def test_a_file_size_limit_is_one_line_and_exit_1(
    runs: tuple[Path, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Under ``ulimit -f`` the table write fails with EFBIG: it was a traceback; now one line
    naming the limit, exit 1 (a machine limit), and the stored tables unchanged."""
    from softtrack.store.disk import machine_limit

    root, run_id = runs
    before = _snapshot(root / run_id / "tables")
    monkeypatch.setattr(
        "softtrack.store.tables.pq.write_table",
        lambda *a, **k: (_ for _ in ()).throw(OSError(errno.EFBIG, "File too large")),
    )
    result = _cli("evaluate", run_id, "-t", "circle", "--runs-dir", str(root))
    line = _one_line(result)
    assert result.exit_code == 1 and "file-size limit" in line and "ulimit -f" in line, line
    assert _snapshot(root / run_id / "tables") == before
    assert machine_limit(OSError("[errno 27] Error writing bytes to file")) is not None


@pytest.mark.faults("degraded")
@pytest.mark.parametrize("kind", ["a directory", "a FIFO", "too large"])
def test_a_run_record_of_the_wrong_kind_or_size_is_named(runs: tuple[Path, str], kind: str) -> None:
    """A run.json that is a directory or a FIFO was listed as "missing"; a 200-MB one was read
    whole (2.2 GB of memory). Now the listing names what it is, and a record is read only up
    to 4 MB."""
    root, run_id = runs
    record = root / run_id / "run.json"
    record.unlink()
    if kind == "a directory":
        record.mkdir()
    elif kind == "a FIFO":
        os.mkfifo(record)
    else:
        record.write_text('{"pad": "' + "x" * 5_000_000 + '"}')
    result = _cli("runs", "--runs-dir", str(root))
    assert result.exit_code == 0 and "Traceback" not in result.output
    expected = "larger than 4,000,000 bytes" if kind == "too large" else f"run.json is {kind}"
    assert expected in result.stdout, result.stdout
    assert "xxxxxxxxxx" not in result.output


@pytest.mark.faults("degraded")
@pytest.mark.parametrize(
    "change, words",
    [
        ({"format_version": 99}, "a newer softtrack wrote it"),
        ({"total_timesteps": -5}, "total_timesteps"),
        ({"global_step": -1}, "global_step"),
    ],
    ids=["newer format", "negative budget", "negative step"],
)
def test_a_run_record_out_of_its_range_is_unreadable(
    runs: tuple[Path, str], change: dict[str, int], words: str
) -> None:
    """A run.json of a newer layout was evaluated as if it were this one's, and negative
    counters were listed as progress; now such a record is unreadable, named in one line,
    and nothing is written."""
    root, run_id = runs
    record = root / run_id / "run.json"
    record.write_text(json.dumps({**json.loads(record.read_text()), **change}))
    before = _snapshot(root / run_id)
    result = _cli("evaluate", run_id, "-t", "circle", "--runs-dir", str(root))
    line = _one_line(result)
    assert result.exit_code == 2 and words in line and "Value error" not in line, line
    assert _snapshot(root / run_id) == before


@pytest.mark.faults("degraded")
def test_control_characters_in_a_run_directory_name_are_escaped(runs: tuple[Path, str]) -> None:
    """A run directory renamed to hold an escape sequence and a newline broke the listing's
    lines and drove the terminal; now they are printed as escapes."""
    root, run_id = runs
    (root / run_id / "run.json").write_text("{")
    (root / run_id).rename(root / "x\x1b[31mred\nline")
    result = _cli("runs", "--runs-dir", str(root))
    assert result.exit_code == 0
    assert "\x1b" not in result.output and "x\\x1b[31mred\\nline: unreadable" in result.stdout


@pytest.mark.faults("degraded")
def test_a_runs_directory_that_is_a_run_says_so(runs: tuple[Path, str]) -> None:
    root, run_id = runs
    result = _cli("runs", "--runs-dir", str(root / run_id))
    assert result.exit_code == 0
    assert f"is a run itself; its runs directory is {root}" in result.stderr, result.stderr


@pytest.mark.faults("degraded")
def test_compare_refuses_a_controller_named_twice(runs: tuple[Path, str]) -> None:
    """``compare A A`` compared a controller with itself (P = 0.50 of nothing)."""
    root, _run_id = runs
    result = _cli("compare", "tiny", "tiny", "--runs-dir", str(root))
    line = _one_line(result)
    assert result.exit_code == 2 and "both select run" in line, line


@pytest.mark.faults("degraded")
def test_a_target_period_below_two_control_steps_is_refused(tmp_path: Path) -> None:
    """``env.target.period: 1e-300`` passed validation (the sampled path cannot go round)."""
    result = _cli("validate", str(_spec(tmp_path)), "--set", "env.target.period=1e-300")
    line = _one_line(result)
    assert result.exit_code == 2 and "shorter than two control steps" in line, line


@pytest.mark.faults("degraded")
@pytest.mark.parametrize(
    "command, blocker",
    [
        (["compare", "a", "b", "--figure", "{out}", "--runs-dir", "none"], "directory"),
        (["animate", "x", "-o", "{out}", "--runs-dir", "none"], "directory"),
        (["animate", "x", "--strip", "{out}/s.png", "--runs-dir", "none"], "file"),
        (["workspace", "x.yaml", "--out", "{out}"], "file"),
        (["workspace", "x.yaml", "--out", "{out}/sub"], "file"),
    ],
    ids=[
        "figure onto a directory",
        "animation onto a directory",
        "strip under a file",
        "workspace onto a file",
        "workspace under a file",
    ],
)
def test_an_output_path_that_cannot_be_written_is_refused_before_any_work(
    tmp_path: Path, command: list[str], blocker: str
) -> None:
    """An output onto a directory (or under a file) was found only when written: after the
    replays (animate, 30 s), after minutes of search (workspace, then a traceback), or named as
    softtrack's own temporary (compare). Now it is one line naming the user's path, at once."""
    out = tmp_path / "out.png"
    if blocker == "directory":
        out.mkdir()
    else:
        out.write_text("x")
    args = [a.replace("{out}", str(out)) for a in command]
    result = _cli(*args)
    line = _one_line(result)
    assert result.exit_code == 2 and str(out) in line and ".tmp" not in line, line
