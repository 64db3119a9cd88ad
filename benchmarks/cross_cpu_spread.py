"""How much a deterministic 10-s evaluation moves between CPU kinds.

A policy's evaluation is deterministic on one machine, but its closed loop (a bang-bang
policy fed back through the rod engine) amplifies the last-bit differences of floating-point
rounding between CPUs (different vector extensions compile different kernels), so a stored
metric measured on one CPU kind is not reproduced to the bit on another. This script
evaluates run directories live on this machine, compares each trajectory/arm cell's 3-D RMSE
with the stored one, and prints the relative differences grouped by whether the stored rows
were computed on this CPU kind (``eval_metrics.cpu``; rows stored before that column existed
count as another CPU):

    .venv/bin/python benchmarks/cross_cpu_spread.py models/*/ --csv spread.csv

``--store`` also replaces the runs' evaluation tables by the live ones (what
``softtrack evaluate DIR`` does), after reading the stored rows for the comparison: one pass
re-evaluates the shipped runs on this CPU kind and measures the spread it introduces.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from softtrack import api
from softtrack.store.provenance import cpu_kind
from softtrack.store.tables import read_table

TRAJECTORIES = ["circle", "rectangle", "figure8"]


def compare_run(run_dir: Path, store: bool) -> pd.DataFrame:
    """One row per trajectory and arm: stored and live 3-D RMSE (m), the stored CPU kind."""
    stored = read_table(run_dir / "tables" / "eval_metrics.parquet")
    stored = stored[stored["trajectory"].isin(TRAJECTORIES)]
    live = api.evaluate([str(run_dir)], TRAJECTORIES, write=store, in_place=store)
    rows = stored.merge(live, on=["trajectory", "arm"], suffixes=("_stored", "_live"))
    stored_cpu = rows["cpu_stored"] if "cpu_stored" in rows else pd.Series([None] * len(rows))
    return pd.DataFrame(
        {
            "run": run_dir.name,
            "trajectory": rows["trajectory"],
            "arm": rows["arm"],
            "stored_cpu": stored_cpu.fillna("not recorded").to_numpy(),
            "rmse_3d_stored": rows["rmse_3d_stored"],
            "rmse_3d_live": rows["rmse_3d_live"],
        }
    )


SAME_EPISODE = 1e-9
"""Relative difference below which two evaluations ran the same episode (the metrics then
differ only by the last bits of their summation)."""


def summarize(table: pd.DataFrame, here: str) -> str:
    """Per stored-CPU group: how many cells ran the same episode (|Δ|/stored < 1e-9), and
    the median, 90th percentile and largest |live − stored| / stored of the others."""
    table = table.assign(
        rel=(table["rmse_3d_live"] - table["rmse_3d_stored"]).abs() / table["rmse_3d_stored"]
    )
    lines = [
        f"live CPU kind: {here}; cells: {len(table)} (runs × trajectories × arms), "
        f"runs: {table['run'].nunique()}"
    ]
    same = table["stored_cpu"] == here
    for label, part in (
        ("stored on this CPU kind", table[same]),
        ("stored on another CPU kind or not recorded", table[~same]),
    ):
        if not len(part):
            continue
        moved = part[part["rel"] >= SAME_EPISODE]
        line = (
            f"{label}: {len(part)} cells; same episode in {len(part) - len(moved)}; "
            f"moved in {len(moved)} (of {moved['run'].nunique()} runs)"
        )
        if len(moved):
            rel = moved["rel"].to_numpy()
            line += (
                f": |Δ|/stored median {np.median(rel):.2%}, p90 "
                f"{np.quantile(rel, 0.9):.2%}, max {rel.max():.2%}"
            )
        lines.append(line)
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run directories (e.g. models/*/)")
    parser.add_argument(
        "--store", action="store_true", help="replace the stored evaluation tables by the live ones"
    )
    parser.add_argument("--csv", type=Path, help="also write every cell to this CSV file")
    args = parser.parse_args()
    here = cpu_kind()
    parts = []
    for k, run_dir in enumerate(args.runs, 1):
        start = time.perf_counter()
        part = compare_run(run_dir, args.store)
        parts.append(part)
        worst = (
            (part["rmse_3d_live"] - part["rmse_3d_stored"]).abs() / part["rmse_3d_stored"]
        ).max()
        print(
            f"[{k}/{len(args.runs)}] {run_dir.name}: max |Δ|/stored {worst:.2%} "
            f"({time.perf_counter() - start:.0f} s)",
            file=sys.stderr,
            flush=True,
        )
    table = pd.concat(parts, ignore_index=True)
    if args.csv:
        table.to_csv(args.csv, index=False)
    print(summarize(table, here))


if __name__ == "__main__":
    main()
