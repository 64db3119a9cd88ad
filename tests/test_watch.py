"""softtrack watch: what it shows, that it leaves the store untouched, and the live view driven
in a pseudo-terminal (refreshing as a run progresses, stopped cleanly by Ctrl-C)."""

from __future__ import annotations

import os
import pty
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.report.watch import sparkline
from softtrack.spec import ExperimentSpec
from softtrack.store.runs import RunStore
from softtrack.store.tables import write_table

runner = CliRunner()


def _spec(name: str) -> ExperimentSpec:
    return ExperimentSpec.model_validate(
        {"name": name, "seeds": [0], "training": {"total_timesteps": 100_000}}
    )


def _validation(store: RunStore, run_id: str, scores: list[float]) -> None:
    rows = [
        {
            "run_id": run_id,
            "global_step": 10_000 * (k + 1),
            "trajectory": "random",
            "episode": e,
            "arm": arm,
            "rmse_3d": score,
            "terminated": False,
        }
        for k, score in enumerate(scores)
        for e in range(2)
        for arm in range(2)
    ]
    write_table(store.get_run(run_id).table_path("validation"), rows)


@pytest.fixture
def store(tmp_path: Path) -> RunStore:
    store = RunStore(tmp_path / "runs")
    done = store.create_run(_spec("exp-done"), 0, ["softtrack", "train"])
    store.mark_running(done.run_id)
    store.heartbeat(done.run_id, 100_000, 2_000.0)
    store.mark_finished(done.run_id, "completed")
    _validation(store, done.run_id, [0.09, 0.06, 0.04, 0.05])
    live = store.create_run(_spec("exp-live"), 0, ["softtrack", "train"])
    store.mark_running(live.run_id)
    store.heartbeat(live.run_id, 25_000, 1_000.0)
    _validation(store, live.run_id, [0.2, 0.1])
    return store


def _files(root: Path) -> dict[str, int]:
    return {str(p.relative_to(root)): p.stat().st_mtime_ns for p in sorted(root.rglob("*"))}


def test_sparkline_scales_between_the_lowest_and_highest() -> None:
    assert sparkline([0.0, 0.5, 1.0]) == "▁▄█"
    assert sparkline([1.0, float("nan"), 1.0]) == "▁ ▁"
    assert sparkline([]) == ""


def test_once_shows_running_and_recent_runs_and_touches_nothing(store: RunStore) -> None:
    before = _files(store.root)
    result = runner.invoke(app, ["watch", "--once", "--runs-dir", str(store.root)])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    live = next(line for line in lines if "exp-live" in line)
    assert "running" in live and "25,000 (25 %)" in live and "1,000" in live
    assert "1m15s" in live  # 75,000 steps left at 1,000 steps/s
    assert "0.1000" in live and "▁" in live and "█" in live  # last and best, and the sparkline
    done = next(line for line in lines if "exp-done" in line)
    assert "completed" in done and "0.0500" in done and "0.0400" in done
    assert _files(store.root) == before  # no catalog, no entry removed, nothing rewritten


def test_a_selection_shows_only_those_runs(store: RunStore) -> None:
    result = runner.invoke(app, ["watch", "exp-done", "--once", "--runs-dir", str(store.root)])
    assert result.exit_code == 0
    assert "exp-done" in result.stdout and "exp-live" not in result.stdout


def test_live_view_in_a_terminal_refreshes_and_stops_on_ctrl_c(store: RunStore) -> None:
    live = next(r for r in store.list_runs() if r.info.name == "exp-live")
    leader, follower = pty.openpty()
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "softtrack.cli",
            "watch",
            "--interval",
            "0.3",
            "--runs-dir",
            str(store.root),
        ],
        stdin=follower,
        stdout=follower,
        stderr=follower,
        env={**os.environ, "COLUMNS": "160", "LINES": "40", "TERM": "xterm"},
        close_fds=True,
        # a terminal's Ctrl-C: a runner started in the background hands SIGINT down ignored
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    os.close(follower)
    seen = b""

    def read_until(needle: bytes, timeout: float) -> bool:
        nonlocal seen
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            ready, _, _ = select.select([leader], [], [], 0.2)
            if ready:
                try:
                    seen += os.read(leader, 65536)
                except OSError:
                    break
            if needle in seen:
                return True
        return False

    try:
        assert read_until(b"25,000", 60.0), seen[-2000:]
        store.heartbeat(live.run_id, 50_000, 1_000.0)
        assert read_until(b"50,000", 10.0), seen[-2000:]
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=10) == 0
    finally:
        if process.poll() is None:
            process.kill()
        os.close(leader)
