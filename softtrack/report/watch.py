"""``softtrack watch``: a live terminal view of the running and recent runs.

Each refresh reads the runs directory's catalog without writing it (``read_catalog(...,
write=False)``) and, for the runs shown, their ``validation`` table (re-read only when the file
changed); nothing in the store is created or changed. The view is plain text redrawn in place
(rich's ``Live``), so it works over SSH and on a SLURM login node.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from softtrack.store.catalog import read_catalog
from softtrack.store.catalog_format import file_stamp
from softtrack.store.location import resolve_runs_dir
from softtrack.store.run_summaries import summary_from_row
from softtrack.store.runs import RunStore, RunStoreError

__all__ = ["WatchRow", "sparkline", "watch_rows", "watch_table"]

_BARS = "▁▂▃▄▅▆▇█"
#: Statuses shown as live (the others are recent history).
LIVE = ("running", "queued")


def sparkline(values: Sequence[float], width: int = 16) -> str:
    """The last ``width`` finite values as bars, low to high (NaN/inf: a space)."""
    tail = list(values)[-width:]
    finite = [v for v in tail if math.isfinite(v)]
    if not finite:
        return " " * len(tail)
    low, high = min(finite), max(finite)
    span = (high - low) or 1.0
    return "".join(
        _BARS[min(7, int((v - low) / span * 7.999))] if math.isfinite(v) else " " for v in tail
    )


@dataclass(frozen=True)
class WatchRow:
    """One run as the view shows it (steps in env steps, speeds in env steps/s, scores in m)."""

    run_id: str
    name: str
    seed: int | None
    status: str
    step: int
    total: int | None
    steps_per_second: float | None
    seconds_left: float | None
    last_score: float | None
    best_score: float | None
    scores: tuple[float, ...]
    cpu: str | None


class _ScoreCache:
    """Validation scores per run, re-read only when the run's validation file changed."""

    def __init__(self) -> None:
        self._seen: dict[str, tuple[str, tuple[float, ...]]] = {}

    def scores(self, root: Path, directory: str) -> tuple[float, ...]:
        path = root / directory / "tables" / "validation.parquet"
        stamp = file_stamp(str(path))
        cached = self._seen.get(directory)
        if cached is not None and cached[0] == stamp:
            return cached[1]
        scores = _read_scores(root / directory) if stamp != "-" else ()
        self._seen[directory] = (stamp, scores)
        return scores


def _read_scores(run_path: Path) -> tuple[float, ...]:
    # pandas: loaded only for runs with a validation table, not by every refresh
    from softtrack.report.data import load_run
    from softtrack.report.group_summaries import validation_scores

    try:
        record = RunStore(run_path.parent).read_record(run_path)
        table = validation_scores(load_run(record, ["validation"]))
    except (RunStoreError, OSError, ValueError, KeyError):
        return ()
    if table.empty:
        return ()
    first_policy = table[table["policy"] == table["policy"].min()]
    return tuple(float(s) for s in first_policy.sort_values("global_step")["score"])


def watch_rows(
    runs_dir: str | os.PathLike[str] | None = None,
    selection: Sequence[str] = (),
    recent: int = 8,
    cache: _ScoreCache | None = None,
) -> list[WatchRow]:
    """The runs to show now: every running or queued run and the ``recent`` that ended last,
    or, with ``selection`` (run ids, id prefixes or experiment names), those runs."""
    root = resolve_runs_dir(runs_dir)
    if not root.is_dir():
        return []
    snapshot = read_catalog(root, write=False)
    rows = [row for row in snapshot.rows() if not row.get("unreadable")]
    if selection:
        keys = [s.upper() for s in selection]
        rows = [
            r
            for r in rows
            if r["name"] in selection
            or any(str(r["run_id"] or "").upper().startswith(k) for k in keys)
        ]
    now = datetime.now(UTC)
    summaries = [(row, summary_from_row(row, root / row["dir"], now)) for row in rows]
    if not selection:
        live = [pair for pair in summaries if pair[1]["status"] in LIVE]
        ended = [pair for pair in summaries if pair[1]["status"] not in LIVE]
        ended.sort(key=lambda pair: str(pair[1]["ended"] or pair[1]["created"] or ""))
        summaries = live + ended[-recent:] if recent > 0 else live
    cache = cache or _ScoreCache()
    return [_watch_row(root, row, summary, cache) for row, summary in summaries]


def _watch_row(
    root: Path, row: dict[str, Any], summary: dict[str, Any], cache: _ScoreCache
) -> WatchRow:
    step, total = int(summary["global_step"]), summary["total_timesteps"]
    speed = summary["steps_per_second"]
    left = None
    if summary["status"] == "running" and speed and total:
        left = max(0.0, (int(total) - step) / float(speed))
    scores = cache.scores(root, row["dir"])
    finite = [s for s in scores if math.isfinite(s)]
    return WatchRow(
        run_id=str(summary["run_id"]),
        name=str(summary["name"]),
        seed=summary["seed"],
        status=str(summary["status"]),
        step=step,
        total=None if total is None else int(total),
        steps_per_second=None if speed is None else float(speed),
        seconds_left=left,
        last_score=scores[-1] if scores else None,
        best_score=min(finite) if finite else None,
        scores=scores,
        cpu=summary["cpu"],
    )


WATCH_COLUMNS = (
    "RUN",
    "NAME",
    "SEED",
    "STATUS",
    "STEPS",
    "STEPS/S",
    "LEFT",
    "VALIDATION (m)",
    "LAST",
    "BEST",
    "CPU",
)


def _duration(seconds: float | None) -> str:
    if seconds is None:
        return ""
    minutes, secs = divmod(int(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}h{minutes:02d}m" if hours else f"{minutes}m{secs:02d}s"


def watch_table(rows: Sequence[WatchRow], title: str) -> Any:
    """A ``rich.table.Table`` of ``rows``."""
    from rich.table import Table

    table = Table(title=title, title_justify="left", header_style="bold", expand=False)
    for column in WATCH_COLUMNS:
        numeric = column in ("SEED", "STEPS", "STEPS/S", "LEFT", "LAST", "BEST")
        table.add_column(
            column,
            justify="right" if numeric else "left",
            no_wrap=True,
            min_width=len(column) if column != "VALIDATION (m)" else 10,
            max_width={"NAME": 34, "CPU": 16}.get(column),
            overflow="ellipsis",
        )
    styles = {
        "running": "green",
        "queued": "cyan",
        "failed": "red",
        "lost": "red",
        "interrupted": "yellow",
    }
    for row in rows:
        progress = f"{row.step:,}"
        if row.total:
            progress += f" ({100.0 * row.step / row.total:.0f} %)"
        table.add_row(
            row.run_id[:10],
            row.name,
            "" if row.seed is None else str(row.seed),
            f"[{styles.get(row.status, 'default')}]{row.status}[/]",
            progress,
            "" if row.steps_per_second is None else f"{row.steps_per_second:,.0f}",
            _duration(row.seconds_left),
            sparkline(row.scores),
            "" if row.last_score is None else f"{row.last_score:.4f}",
            "" if row.best_score is None else f"{row.best_score:.4f}",
            row.cpu or "",
        )
    if not rows:
        table.add_row(*["" for _ in WATCH_COLUMNS[:-1]], "no runs to show")
    return table


def watch(
    runs_dir: str | os.PathLike[str] | None = None,
    selection: Sequence[str] = (),
    *,
    interval: float = 2.0,
    recent: int = 8,
    once: bool = False,
) -> None:
    """Show :func:`watch_rows` and redraw it every ``interval`` s until Ctrl-C (``once``: print
    it once and return)."""
    import time

    from rich.console import Console
    from rich.live import Live

    root = resolve_runs_dir(runs_dir)
    console = Console(width=None if os.isatty(1) else 160)  # a pipe or file: the whole table
    cache = _ScoreCache()

    def view() -> Any:
        rows = watch_rows(root, selection, recent, cache)
        stamp = datetime.now(UTC).strftime("%H:%M:%S UTC")
        return watch_table(rows, f"softtrack watch: {root} at {stamp} (Ctrl-C to stop)")

    if once:
        console.print(view())
        return
    with Live(view(), console=console, auto_refresh=False, screen=False) as live:
        while True:
            time.sleep(interval)
            live.update(view(), refresh=True)
