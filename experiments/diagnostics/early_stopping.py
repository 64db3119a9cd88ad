"""What would early stopping (``training.stop_score``) have given on runs trained without it?

    .venv/bin/python experiments/diagnostics/early_stopping.py runs/fresh-paths \
        [--grid 0.040 0.060 0.002]

Reads every completed run of a ``fresh_seeds.py`` runs directory (its ``validation`` tables,
recorded with ``training.validation_trajectories: true``, and the seconds since each command's
start at each validation line, ``<runs dir>/.fresh-seeds/``) and, for each threshold T of the
grid, replays the rule: training ends at the first validation whose score (the mean 3-D RMSE
over the random-target and held-out path episodes) is at or below T, and that checkpoint is the
kept model (every earlier score was above T, so it is also the best so far); a run that never
gets there keeps its best-validated model at the end of its budget. Per T it prints how many
runs keep a model at or below the study in all six cells and the median minutes from the
command's start to the stop. Training does not depend on validation, so each run's checkpoints
are the ones an early-stopped run would have had.

Nothing is written. The threshold is chosen on these runs' seeds and claimed on others.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from selection_levers import checkpoint_passes

from softtrack.evaluation.scores import HELD_OUT_TARGETS
from softtrack.store.tables import read_table


@dataclass(frozen=True)
class RunTrace:
    """One run's validated checkpoints in order: their scores (m), whether each is at the study
    in all six cells, and the minutes from the command's start at each validation."""

    seed: int
    scores: np.ndarray
    passes: np.ndarray
    minutes: np.ndarray
    total_minutes: float


def read_traces(runs_dir: Path, targets: Sequence[str] = HELD_OUT_TARGETS) -> list[RunTrace]:
    """The traces of the completed runs that have a timing in ``runs_dir/.fresh-seeds/``, each
    checkpoint scored on its ``targets`` rows."""
    traces = []
    for timing_file in sorted((runs_dir / ".fresh-seeds").glob("*.json")):
        timing = json.loads(timing_file.read_text(encoding="utf-8"))
        run_dir = runs_dir / timing["run_id"]
        validation = read_table(run_dir / "tables" / "validation.parquet")
        held = validation[validation["trajectory"].isin(targets)]
        scores = held.groupby("global_step")["rmse_3d"].mean()
        passes = checkpoint_passes(validation).reindex(scores.index).fillna(False)
        stamps = np.asarray(timing["validation_seconds"], dtype=float)[: len(scores)] / 60.0
        traces.append(
            RunTrace(
                int(timing["seed"]),
                scores.to_numpy(),
                passes.to_numpy(dtype=bool),
                stamps,
                float(timing["seconds"]) / 60.0,
            )
        )
    return traces


def replay(trace: RunTrace, threshold: float) -> tuple[bool, float, bool]:
    """(the kept model is at the study, minutes to the end of training, stopped early)."""
    below = np.flatnonzero(trace.scores <= threshold)
    if below.size:
        k = int(below[0])
        return bool(trace.passes[k]), float(trace.minutes[k]), True
    return bool(trace.passes[int(np.argmin(trace.scores))]), trace.total_minutes, False


def table(traces: Sequence[RunTrace], grid: Sequence[float]) -> pd.DataFrame:
    """Per threshold: runs at the study, runs stopped early, median and largest minutes."""
    rows = []
    for threshold in grid:
        outcomes = [replay(trace, threshold) for trace in traces]
        minutes = [m for _, m, _ in outcomes]
        rows.append(
            {
                "stop_score (m)": round(float(threshold), 4),
                "kept at the study": sum(p for p, _, _ in outcomes),
                "stopped early": sum(s for _, _, s in outcomes),
                "median min": float(np.median(minutes)),
                "max min": float(np.max(minutes)),
            }
        )
    full = [bool(t.passes[int(np.argmin(t.scores))]) for t in traces]
    rows.append(
        {
            "stop_score (m)": None,
            "kept at the study": sum(full),
            "stopped early": 0,
            "median min": float(np.median([t.total_minutes for t in traces])),
            "max min": float(np.max([t.total_minutes for t in traces])),
        }
    )
    return pd.DataFrame(rows)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs_dir", type=Path, help="a fresh_seeds.py runs directory")
    parser.add_argument(
        "--grid",
        nargs=3,
        type=float,
        default=[0.040, 0.060, 0.002],
        metavar=("LOW", "HIGH", "STEP"),
    )
    parser.add_argument(
        "--score",
        choices=["random+paths", "paths", "random"],
        default="random+paths",
        help="the episodes a checkpoint's score averages [random+paths]",
    )
    args = parser.parse_args(argv)
    traces = read_traces(args.runs_dir, args.score.split("+"))
    if not traces:
        print(f"error: {args.runs_dir} has no completed fresh-seed run", file=sys.stderr)
        return 2
    low, high, step = args.grid
    grid = np.arange(low, high + step / 2, step)
    print(f"{len(traces)} runs (seeds {', '.join(str(t.seed) for t in traces)})")
    print(table(traces, grid).to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
