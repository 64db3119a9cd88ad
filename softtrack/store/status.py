"""What ``softtrack runs`` shows of a run: its effective status, progress and final-stage return.

A run's status comes from its ``run.json``, except that a ``running`` run whose process is gone
(nobody holds its ``run.lock``, and its heartbeat is stale or its pid is dead on this host)
shows as ``lost``; run.json itself is never changed here. The final-stage return is computed
from the run's ``train_episodes`` table.
"""

from __future__ import annotations

import os
import socket
from collections.abc import Sequence
from datetime import UTC, datetime
from typing import Any

import numpy as np
import pandas as pd

from softtrack.store.runs import (
    RunRecord,
    RunStore,
    lock_held,
    parse_time,
    pid_alive,
    resolve_runs_dir,
)
from softtrack.store.tables import TableError, read_table

__all__ = [
    "DEFAULT_FINAL_STAGE_FRACTION",
    "DEFAULT_HEARTBEAT_INTERVAL_S",
    "RUN_TABLE_COLUMNS",
    "effective_status",
    "final_stage_return",
    "format_failures",
    "format_runs_table",
    "is_lost",
    "list_run_summaries",
    "run_summary",
    "stale_after_s",
]

#: ``training.final_stage_fraction`` of a spec that does not set it.
DEFAULT_FINAL_STAGE_FRACTION = 0.1
#: ``training.heartbeat_interval`` (s) of a spec that does not set it.
DEFAULT_HEARTBEAT_INTERVAL_S = 30.0


def _training_value(raw: dict[str, Any], key: str, default: float) -> float:
    training = raw.get("training")
    value = training.get(key) if isinstance(training, dict) else None
    return (
        float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else default
    )


# ---- final-stage return ---------------------------------------------------------------------
def _final_mean(df: pd.DataFrame, threshold: float) -> tuple[float | None, int]:
    """Mean finite ``return`` of the rows with ``global_step > threshold``, and their count."""
    final = pd.to_numeric(df.loc[df["global_step"] > threshold, "return"], errors="coerce")
    final = final[np.isfinite(final)]
    return (float(final.mean()), int(final.size)) if not final.empty else (None, 0)


def final_stage_return(
    record: RunRecord, fraction: float | None = None
) -> tuple[float | None, int, int]:
    """Mean training-episode return over the last ``fraction`` of the run's budget (SPEC §4).

    Episodes count when their ``global_step`` (at the episode's end) exceeds
    ``(1 - fraction) · total_timesteps``. ``fraction`` defaults to the run's
    ``training.final_stage_fraction`` (0.1).

    An independent run's table has an ``arm`` column (0, 1) and counts ``global_step`` per arm:
    each arm's final stage is the last ``fraction`` of its own budget (``arm_total_timesteps``),
    and the result is the mean over the arms of their final-stage means (single-arm returns,
    not comparable with dual-arm ones). Rows without an arm (column absent, null or negative)
    are a centralized policy's.

    Returns:
        ``(mean return or None if no episode qualifies, number of such episodes,
        env steps the table reaches: its largest global_step, summed over the arms, or 0)``.
    """
    if fraction is None:
        fraction = _training_value(
            record.raw_spec(), "final_stage_fraction", DEFAULT_FINAL_STAGE_FRACTION
        )
    df = read_table(record.table_path("train_episodes"), missing_ok=True)
    if df.empty or not {"global_step", "return"} <= set(df.columns):
        return None, 0, 0
    arms = pd.to_numeric(df["arm"], errors="coerce") if "arm" in df.columns else None
    if arms is None or not (arms >= 0).any():
        threshold = (1.0 - fraction) * record.info.total_timesteps
        mean, count = _final_mean(df, threshold)
        return mean, count, int(df["global_step"].max())
    info = record.info
    budget = info.arm_total_timesteps or info.total_timesteps // max(1, int(arms.max()) + 1)
    means, count, last_step = [], 0, 0
    for _, rows in df[arms >= 0].groupby(arms[arms >= 0]):
        mean, n = _final_mean(rows, (1.0 - fraction) * budget)
        last_step += int(rows["global_step"].max())
        count += n
        if mean is not None:
            means.append(mean)
    return (float(np.mean(means)) if means else None), count, last_step


# ---- status ---------------------------------------------------------------------------------
def stale_after_s(heartbeat_interval: float) -> float:
    """A running run's heartbeat older than this is stale: max(120 s, 10 heartbeat intervals)."""
    return max(120.0, 10.0 * heartbeat_interval)


def _is_stale(record: RunRecord, heartbeat_interval: float, now: datetime) -> bool:
    if record.info.status != "running":
        return False
    beat = parse_time(record.info.heartbeat or record.info.started or record.info.created)
    if beat is None:
        return False
    return (now - beat).total_seconds() > stale_after_s(heartbeat_interval)


def _heartbeat_interval(record: RunRecord) -> float:
    return _training_value(record.raw_spec(), "heartbeat_interval", DEFAULT_HEARTBEAT_INTERVAL_S)


def is_lost(record: RunRecord, *, now: datetime | None = None, stale: bool | None = None) -> bool:
    """A ``running`` run whose process is gone: nobody holds its ``run.lock``, and its
    heartbeat is stale or (on this host) its pid is not alive."""
    info = record.info
    if info.status != "running" or lock_held(record) is True:
        return False
    if stale is None:
        stale = _is_stale(record, _heartbeat_interval(record), now or datetime.now(UTC))
    if stale:
        return True
    return info.host == socket.gethostname() and not pid_alive(info.pid)


def effective_status(record: RunRecord, *, now: datetime | None = None) -> str:
    """run.json's status, or ``lost`` for a running run whose process is gone (:func:`is_lost`);
    run.json itself is never changed by this."""
    return "lost" if is_lost(record, now=now) else record.info.status


# ---- summaries ------------------------------------------------------------------------------
def run_summary(record: RunRecord, *, now: datetime | None = None) -> dict[str, Any]:
    """One row of ``softtrack runs`` (JSON-serialisable)."""
    raw = record.raw_spec()
    info = record.info
    try:
        final, n_final, last_step = final_stage_return(
            record, _training_value(raw, "final_stage_fraction", DEFAULT_FINAL_STAGE_FRACTION)
        )
    except TableError:
        final, n_final, last_step = None, 0, 0
    now = now or datetime.now(UTC)
    stale = _is_stale(
        record, _training_value(raw, "heartbeat_interval", DEFAULT_HEARTBEAT_INTERVAL_S), now
    )
    return {
        "run_id": info.run_id,
        "name": info.name,
        "algo": info.algo,
        "controller": info.controller,
        "seed": info.seed,
        "status": "lost" if is_lost(record, now=now, stale=stale) else info.status,
        "stored_status": info.status,
        "stale": stale,
        "sweep": (info.notes or {}).get("sweep"),
        "global_step": max(info.global_step, last_step),
        "total_timesteps": info.total_timesteps,
        "final_return": final,
        "final_return_episodes": n_final,
        "steps_per_second": info.steps_per_second,
        "cpu": info.cpu,
        "created": info.created,
        "started": info.started,
        "ended": info.ended,
        "spec_hash": info.spec_hash,
        "git_commit": info.git_commit,
        "git_dirty": info.git_dirty,
        "error": info.error,
        "traceback": info.traceback,
        "path": str(record.path),
    }


def list_run_summaries(
    runs_dir: str | os.PathLike[str] | None = None, *, failed: bool = False
) -> list[dict[str, Any]]:
    """Summaries of every run under ``runs_dir`` (resolved with ``resolve_runs_dir``), oldest
    first; with ``failed=True`` only the failed runs."""
    store = RunStore(resolve_runs_dir(runs_dir))
    now = datetime.now(UTC)
    rows = [run_summary(record, now=now) for record in store.list_runs()]
    return [r for r in rows if r["status"] == "failed"] if failed else rows


# ---- text output ----------------------------------------------------------------------------
def format_failures(summaries: Sequence[dict[str, Any]]) -> str:
    """Each failed run's id, experiment, seed, error and stored traceback."""
    blocks = []
    for s in summaries:
        head = f"== {s['run_id']}  {s['name']}  seed {s['seed']}: {s.get('error') or '(no error)'}"
        body = (s.get("traceback") or "").rstrip()
        blocks.append(head + ("\n" + "\n".join("   " + line for line in body.splitlines())
                              if body else ""))
    return "\n".join(blocks)


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
                str(s["seed"]),
                status,
                f"{s['global_step']}/{s['total_timesteps']}",
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
    return "\n".join(lines)
