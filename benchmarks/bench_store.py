"""The results store at scale: every read command and a write, on synthetic stores of 1,000,
10,000 and 100,000 runs, with this checkout's code and (``--before REF``) an earlier commit's.

Each store is made of copies of a shipped run (``models/td3-sbx-128-mirror-tta-3e6-seed1``:
``train_episodes``, ``validation``, ``eval_metrics``, ``eval_random``, ``eval_snapshots`` and
``eval_moment_peaks``, 210 kB a run), ten seeds per experiment name; a store of 100,000 runs
or more (``--lean-from``) has ``run.json`` and ``eval_metrics`` only. Every command runs as a
user runs it (``softtrack ...`` in a fresh process, the file cache warm after one untimed
call); the figures are medians of ``--repeats`` calls, with the peak memory (max RSS) of the
slowest. The code before runs from a ``git worktree`` of REF (its commands that take longer
than ``--timeout`` are reported as ``>T``); the write is one run's ``train_episodes`` append
and evaluation tables (``write_tables``) in one process, median of 20, catalog update included
after. Run on one core:

    taskset -c 0 .venv/bin/python benchmarks/bench_store.py --before 08895e6

Prints one table per store size: command, seconds before, seconds after, the ratio and the
peak memory after; and the first-use cost (the catalog built from the run directories).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TEMPLATE = REPO / "models" / "td3-sbx-128-mirror-tta-3e6-seed1"
FULL_TABLES = (
    "train_episodes",
    "validation",
    "eval_metrics",
    "eval_random",
    "eval_snapshots",
    "eval_moment_peaks",
)
LEAN_TABLES = ("eval_metrics",)
SEEDS_PER_EXPERIMENT = 10

_WRITE_SCRIPT = """
import statistics, sys, time
from pathlib import Path
import pandas as pd
from softtrack.store.tables import append_rows, read_table, write_tables
run = Path(sys.argv[1])
template = Path(sys.argv[2])
metrics = read_table(template / "tables" / "eval_metrics.parquet")
peaks = read_table(template / "tables" / "eval_moment_peaks.parquet")
times = []
for i in range(21):
    start = time.perf_counter()
    append_rows(run / "tables" / "train_episodes.parquet",
                [{"run_id": "x", "episode": 10_000 + i, "global_step": 10_000_000 + i,
                  "return": -1.0, "length": 500, "wall_time": 1.0}])
    write_tables({run / "tables" / "eval_metrics.parquet": metrics,
                  run / "tables" / "eval_moment_peaks.parquet": peaks})
    times.append(time.perf_counter() - start)
print(statistics.median(times[1:]))
"""


@dataclass(frozen=True)
class Timing:
    seconds: float | None  # None: ran past the time-out
    peak_mb: float | None


def make_store(root: Path, n_runs: int, tables: tuple[str, ...]) -> None:
    """``n_runs`` run directories under ``root``, each a copy of the template's ``tables``
    with its own run.json (id, experiment name, seed); spec.yaml with the full tables."""
    from softtrack.store.ids import new_id

    info = json.loads((TEMPLATE / "run.json").read_text())
    spec = (TEMPLATE / "spec.yaml").read_text() if tables == FULL_TABLES else None
    root.mkdir(parents=True)
    for i in range(n_runs):
        run_id = new_id()
        path = root / run_id
        (path / "tables").mkdir(parents=True)
        for name in tables:
            shutil.copyfile(
                TEMPLATE / "tables" / f"{name}.parquet", path / "tables" / f"{name}.parquet"
            )
        if spec is not None:
            (path / "spec.yaml").write_text(spec)
        experiment = f"exp-{i // SEEDS_PER_EXPERIMENT:05d}"
        run = {**info, "run_id": run_id, "name": experiment, "seed": i % SEEDS_PER_EXPERIMENT}
        (path / "run.json").write_text(json.dumps(run, indent=2))
        if (i + 1) % 1000 == 0:
            print(f"  made {i + 1}/{n_runs} runs", file=sys.stderr, flush=True)


def _run(command: list[str], env: dict[str, str], timeout: float) -> Timing:
    """One call of ``command`` in the code's own directory (``python -m`` imports from the
    working directory first); ``/usr/bin/time`` gives the peak memory."""
    start = time.perf_counter()
    try:
        done = subprocess.run(
            ["/usr/bin/time", "-f", "%M", *command],
            env=env,
            cwd=env["PYTHONPATH"],
            capture_output=True,
            text=True,
            timeout=timeout,
            check=False,
        )
    except subprocess.TimeoutExpired:
        return Timing(None, None)
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed: {done.stderr.strip()[-500:]}")
    peak_kb = float(done.stderr.strip().splitlines()[-1])
    return Timing(seconds, peak_kb / 1024)


def _median(timings: list[Timing]) -> Timing:
    if any(t.seconds is None for t in timings):
        return Timing(None, None)
    seconds = statistics.median(t.seconds for t in timings if t.seconds is not None)
    return Timing(seconds, max(t.peak_mb or 0.0 for t in timings))


def _code_env(code: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "SOFTTRACK_RUNS_DIR"}
    env["PYTHONPATH"] = str(code)
    return env


def _commands(root: Path, lean: bool, limit: bool) -> list[tuple[str, list[str]]]:
    cli = [sys.executable, "-m", "softtrack.cli"]
    where = ["--runs-dir", str(root)]
    runs = [*cli, "runs", *where, *(["--limit", "50"] if limit else [])]
    commands = [
        ("softtrack --help", [*cli, "--help"]),
        ("runs" + (" --limit 50" if limit else ""), runs),
        ("query: SELECT count(*) FROM runs", [*cli, "query", "SELECT count(*) FROM runs", *where]),
        (
            "query: avg rmse_3d over every eval_metrics row",
            [
                *cli,
                "query",
                "SELECT trajectory, arm, avg(rmse_3d) AS rmse, count(*) AS n FROM eval_metrics "
                "JOIN runs USING (run_id) GROUP BY ALL ORDER BY ALL",
                *where,
            ],
        ),
    ]
    if not lean:
        commands.append(
            ("compare exp-00000 exp-00001", [*cli, "compare", "exp-00000", "exp-00001", *where])
        )
    return commands


def _write_seconds(code: Path, root: Path) -> float:
    run = next(p for p in sorted(root.iterdir()) if (p / "run.json").is_file())
    out = subprocess.run(
        [sys.executable, "-c", _WRITE_SCRIPT, str(run), str(TEMPLATE)],
        env=_code_env(code),
        cwd=code,
        capture_output=True,
        text=True,
        check=True,
    )
    return float(out.stdout.strip())


def _cell(timing: Timing | None, timeout: float) -> str:
    if timing is None:
        return "–"
    return f">{timeout:.0f}" if timing.seconds is None else f"{timing.seconds:.2f}"


def bench_size(n_runs: int, work: Path, before: Path | None, args: argparse.Namespace) -> list[str]:
    lean = n_runs >= args.lean_from
    root = work / f"store-{n_runs}"
    if not root.is_dir():
        print(f"making {n_runs} runs in {root}", file=sys.stderr, flush=True)
        make_store(root, n_runs, LEAN_TABLES if lean else FULL_TABLES)
    shutil.rmtree(root / ".softtrack-catalog", ignore_errors=True)
    after_env = _code_env(REPO)
    first_use = _run(_commands(root, lean, True)[1][1], after_env, args.build_timeout)
    lines = [
        f"\n{n_runs} runs ({'run.json and eval_metrics' if lean else ', '.join(FULL_TABLES)}); "
        f"first use, catalog built from the directories: {_cell(first_use, args.build_timeout)} s",
        "",
        "| command | before (s) | after (s) | before/after | after: peak MB |",
        "|---|---|---|---|---|",
    ]
    for label, command in _commands(root, lean, lean):
        _run(command, after_env, args.timeout)  # warm the file cache
        after = _median([_run(command, after_env, args.timeout) for _ in range(args.repeats)])
        old = None
        if before is not None and n_runs <= args.before_up_to:
            old_command = [c for c in command if c not in ("--limit", "50")]
            old = _median([_run(old_command, _code_env(before), args.timeout)])
        ratio = (
            f"{old.seconds / after.seconds:.0f}×"
            if old is not None and old.seconds and after.seconds
            else ""
        )
        peak = f"{after.peak_mb:.0f}" if after.peak_mb else ""
        lines.append(
            f"| {label} | {_cell(old, args.timeout)} | {_cell(after, args.timeout)} | {ratio} | {peak} |"
        )
        print(lines[-1], file=sys.stderr, flush=True)
    write_after = _write_seconds(REPO, root)
    write_before = _write_seconds(before, root) if before is not None else None
    lines.append(
        f"| write one run's tables (append + write_tables, ms) | "
        f"{'' if write_before is None else f'{write_before * 1e3:.1f}'} | {write_after * 1e3:.1f} | "
        f"{'' if write_before is None else f'+{(write_after - write_before) * 1e3:.1f} ms'} | |"
    )
    return lines


def _worktree(ref: str, work: Path) -> Path:
    path = work / f"before-{ref}"
    if not path.is_dir():
        subprocess.run(
            ["git", "-C", str(REPO), "worktree", "add", "--detach", str(path), ref],
            check=True,
            capture_output=True,
        )
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 10_000, 100_000])
    parser.add_argument("--before", metavar="REF", help="also time this commit's code")
    parser.add_argument(
        "--before-up-to", type=int, default=10_000, help="largest store for --before"
    )
    parser.add_argument("--lean-from", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--timeout", type=float, default=600.0)
    parser.add_argument("--build-timeout", type=float, default=3600.0)
    parser.add_argument("--work", type=Path, help="keep the stores here (default: a temporary dir)")
    args = parser.parse_args()

    from softtrack.store.provenance import cpu_description

    work = args.work or Path(tempfile.mkdtemp(prefix="bench-store-"))
    work.mkdir(parents=True, exist_ok=True)
    before = _worktree(args.before, work) if args.before else None
    print(f"bench_store: {cpu_description()}; stores in {work}")
    try:
        for n_runs in args.sizes:
            print("\n".join(bench_size(n_runs, work, before, args)), flush=True)
    finally:
        if before is not None:
            subprocess.run(
                ["git", "-C", str(REPO), "worktree", "remove", "--force", str(before)],
                check=False,
                capture_output=True,
            )
        if args.work is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
