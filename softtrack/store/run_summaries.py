"""``softtrack runs``: one summary per run, from the catalog, and the runs table as text.

Light on purpose: the listing reads the catalog (:mod:`softtrack.store.catalog`), so it needs
neither pandas nor the spec models, and answers in a fraction of a second at 10,000 runs.
A run's status is its ``run.json`` status, except that a ``running`` run whose process is
gone shows as ``lost`` (:func:`~softtrack.store.liveness.is_lost_process`); nothing is
changed by listing.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from softtrack.file_kinds import printable
from softtrack.store.catalog import read_catalog
from softtrack.store.errors import RunStoreError, unreadable_fix
from softtrack.store.liveness import heartbeat_stale, is_lost_process, parse_time
from softtrack.store.location import resolve_runs_dir

__all__ = [
    "RUN_TABLE_COLUMNS",
    "RunListing",
    "format_failures",
    "format_runs_table",
    "list_run_summaries",
    "run_listing",
    "summary_from_row",
    "unreadable_summary",
]

RUN_TABLE_COLUMNS = (
    "ID",
    "NAME",
    "ALGO",
    "CONTROLLER",
    "SEED",
    "STATUS",
    "STEPS",
    "FINAL RETURN",
    "STARTED (UTC)",
    "ENDED (UTC)",
)


def summary_from_row(row: Mapping[str, Any], run_path: Path, now: datetime) -> dict[str, Any]:
    """One row of ``softtrack runs`` (JSON-serialisable) from a catalog row
    (:data:`~softtrack.store.catalog_format.ROW_COLUMNS`) of the run in ``run_path``."""
    if row.get("unreadable"):
        return unreadable_summary(run_path, str(row["unreadable"]))
    status = str(row["status"])
    stale = heartbeat_stale(
        status,
        row["heartbeat"] or row["started"] or row["created"],
        float(row["heartbeat_interval"] or 30.0),
        now,
    )
    lost = status == "running" and is_lost_process(
        run_path, stale=stale, host=row["host"], pid=row["pid"]
    )
    return {
        "run_id": row["run_id"],
        "name": row["name"],
        "algo": row["algo"],
        "controller": row["controller"],
        "seed": row["seed"],
        "status": "lost" if lost else status,
        "stored_status": status,
        "stale": stale,
        "sweep": row["sweep"],
        "global_step": max(int(row["global_step"] or 0), int(row["last_step"] or 0)),
        "total_timesteps": row["total_timesteps"],
        "final_return": row["final_return"],
        "final_return_episodes": int(row["final_return_episodes"] or 0),
        "steps_per_second": row["steps_per_second"],
        "cpu": row["cpu"],
        "created": row["created"],
        "started": row["started"],
        "ended": row["ended"],
        "spec_hash": row["spec_hash"],
        "git_commit": row["git_commit"],
        "git_dirty": row["git_dirty"],
        "error": row["error"],
        "traceback": row["traceback"],
        "path": str(run_path),
    }


def unreadable_summary(run_path: Path, reason: str) -> dict[str, Any]:
    """The ``softtrack runs`` row of a run whose run.json is missing or unreadable: status
    ``unreadable``, the directory name as its id and the reason, with the fix, as its error."""
    return {
        "run_id": printable(run_path.name),
        "name": "",
        "algo": "",
        "controller": "",
        "seed": None,
        "status": "unreadable",
        "stored_status": None,
        "stale": False,
        "sweep": None,
        "global_step": None,
        "total_timesteps": None,
        "final_return": None,
        "final_return_episodes": 0,
        "steps_per_second": None,
        "cpu": None,
        "created": None,
        "started": None,
        "ended": None,
        "spec_hash": None,
        "git_commit": None,
        "git_dirty": None,
        "error": printable(f"{reason}; {unreadable_fix(run_path)}"),
        "traceback": None,
        "path": printable(str(run_path)),
    }


@dataclass
class RunListing:
    """What ``softtrack runs`` shows.

    Attributes:
        summaries: the listed runs, oldest first (by directory name), then the unreadable ones.
        total: the number of runs before ``limit`` (unreadable ones included).
        notices: one line each about the catalog (built, rebuilt, not writable).
    """

    summaries: list[dict[str, Any]]
    total: int
    notices: list[str] = field(default_factory=list)


def run_listing(
    runs_dir: str | os.PathLike[str] | None = None,
    *,
    failed: bool = False,
    limit: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> RunListing:
    """Summaries of the runs under ``runs_dir`` (resolved with ``resolve_runs_dir``) from its
    catalog; with ``failed=True`` only the failed runs; with ``limit`` only the ``limit``
    created last, in directory order as always.
    ``progress(done, total)`` is called while runs are read from their directories.

    Raises:
        RunStoreError: ``runs_dir`` is a file (a missing directory has no runs).
    """
    root = resolve_runs_dir(runs_dir)
    if root.exists() and not root.is_dir():
        raise RunStoreError(
            f"{root} is not a directory; pass the directory your runs are in with --runs-dir "
            "(the shipped runs: --runs-dir models)"
        )
    if not root.is_dir():
        return RunListing([], 0)
    snapshot = read_catalog(root, progress=progress)
    now = datetime.now(UTC)
    head = snapshot.columns(["status", "unreadable", "created"])
    statuses, unreadable = head["status"], head["unreadable"]
    readable = [i for i, bad in enumerate(unreadable) if bad is None]
    if failed:
        readable = [i for i in readable if statuses[i] == "failed"]
    bad = [] if failed else [i for i, reason in enumerate(unreadable) if reason is not None]
    total = len(readable) + len(bad)
    if limit:
        created = head["created"]
        readable = sorted(sorted(readable, key=lambda i: created[i] or "")[-limit:])
    chosen = readable + bad
    start = min(chosen, default=0)
    columns = snapshot.columns(start=start)  # from the first chosen row on
    rows = [{name: values[i - start] for name, values in columns.items()} for i in chosen]
    summaries = [summary_from_row(row, root / row["dir"], now) for row in rows]
    return RunListing(summaries, total, snapshot.notices)


def list_run_summaries(
    runs_dir: str | os.PathLike[str] | None = None, *, failed: bool = False
) -> list[dict[str, Any]]:
    """Summaries of every run under ``runs_dir``, oldest first, then the unreadable ones; with
    ``failed=True`` only the failed runs (:func:`run_listing`)."""
    return run_listing(runs_dir, failed=failed).summaries


# ---- text output ----------------------------------------------------------------------------
def format_failures(summaries: Sequence[dict[str, Any]]) -> str:
    """Each failed run's id, experiment, seed, error and stored traceback."""
    blocks = []
    for s in summaries:
        head = f"== {s['run_id']}  {s['name']}  seed {s['seed']}: {s.get('error') or '(no error)'}"
        body = (s.get("traceback") or "").rstrip()
        blocks.append(
            head + ("\n" + "\n".join("   " + line for line in body.splitlines()) if body else "")
        )
    return "\n".join(blocks)


def _time_cell(text: str | None) -> str:
    moment = parse_time(text)
    return moment.strftime("%Y-%m-%d %H:%M:%S") if moment else ""


def format_runs_table(summaries: Sequence[dict[str, Any]]) -> str:
    """A plain, aligned text table of run summaries (one line per run, with a header)."""
    rows = [list(RUN_TABLE_COLUMNS)]
    for s in summaries:
        status = s["status"] + (" (stale)" if s.get("stale") and s["status"] != "lost" else "")
        final = s.get("final_return")
        rows.append(
            [
                s["run_id"],
                s["name"],
                s["algo"],
                s["controller"],
                "" if s["seed"] is None else str(s["seed"]),
                status,
                "" if s["global_step"] is None else f"{s['global_step']}/{s['total_timesteps']}",
                "" if final is None else f"{final:.2f}",
                _time_cell(s.get("started")),
                _time_cell(s.get("ended")),
            ]
        )
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    right = {4, 6, 7}  # numeric columns
    lines = []
    for row in rows:
        cells = [
            cell.rjust(widths[i]) if i in right else cell.ljust(widths[i])
            for i, cell in enumerate(row)
        ]
        lines.append("  ".join(cells).rstrip())
    lines += [
        f"{s['run_id']}: unreadable: {s['error']}" for s in summaries if s["status"] == "unreadable"
    ]
    return "\n".join(lines)
