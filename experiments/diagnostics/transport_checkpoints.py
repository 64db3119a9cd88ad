"""Every validated checkpoint of transport runs: held-out paths score, drops, the three paths.

    .venv/bin/python experiments/diagnostics/transport_checkpoints.py runs/transport-tta/RUN_ID/ \
        [--at-most 0.025] [--quiet]

Reads each run's ``tables/validation.parquet`` (recorded with
``training.validation_trajectories: true``) and prints, per checkpoint: env steps, minutes of
training (``wall_time``), the mean sphere 3-D RMSE over its held-out episodes (random targets
and paths; a drop counts 1 m from then on, as the validation score) and how many of them
dropped the sphere, then the sphere's 3-D RMSE on the circle, rectangle and figure-eight with a
``D`` where it was dropped. A summary line per run counts the checkpoints that carry the sphere
along all three evaluation paths without a drop at or below ``--at-most`` m (the issue's
per-seed target: 0.025 m) and names the best of them. Nothing is written.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

from softtrack.evaluation import EVAL_TRAJECTORIES
from softtrack.evaluation.scores import validation_score
from softtrack.spec.spec_io import load_spec
from softtrack.store.tables import read_table

PATHS = EVAL_TRAJECTORIES


@dataclass(frozen=True)
class Checkpoint:
    """One validated checkpoint: env steps, training minutes, held-out score (m), held-out
    drops of how many episodes, and per evaluation path its sphere 3-D RMSE (m) and drop."""

    step: int
    minutes: float
    held_out_score: float
    held_out_drops: int
    held_out_episodes: int
    paths: dict[str, tuple[float, bool]]

    def carries_all(self, at_most: float) -> bool:
        """All three evaluation paths carried without a drop at or below ``at_most`` m."""
        return len(self.paths) == len(PATHS) and all(
            not dropped and rmse <= at_most for rmse, dropped in self.paths.values()
        )

    @property
    def worst_path(self) -> float:
        """The largest of the three paths' sphere 3-D RMSE (m)."""
        return max(rmse for rmse, _ in self.paths.values())


def read_checkpoints(run_dir: Path) -> list[Checkpoint]:
    """The checkpoints of one transport run, in order of env steps (``ValueError``: not a
    transport run)."""
    table = read_table(run_dir / "tables" / "validation.parquet")
    if "object_rmse_3d" not in table:
        raise ValueError(f"{run_dir}: not a transport run (no sphere columns in its validation)")
    duration = load_spec(run_dir / "spec.yaml").training.eval_duration
    checkpoints = []
    for step, all_rows in table.groupby("global_step", sort=True):
        rows = all_rows.drop_duplicates(["trajectory", "episode"])
        held = rows[~rows["trajectory"].isin(PATHS)]
        tracked = rows[rows["trajectory"].isin(PATHS)]
        checkpoints.append(
            Checkpoint(
                step=int(step),
                minutes=float(rows["wall_time"].iloc[0]) / 60.0,
                held_out_score=validation_score(all_rows, duration),
                held_out_drops=int(held["dropped"].astype(bool).sum()),
                held_out_episodes=len(held),
                paths={
                    str(t): (float(r), bool(d))
                    for t, r, d in tracked[["trajectory", "object_rmse_3d", "dropped"]].itertuples(
                        index=False
                    )
                },
            )
        )
    return checkpoints


def _cell(value: tuple[float, bool] | None) -> str:
    if value is None:
        return "      -"
    rmse, dropped = value
    return f"{rmse:6.3f}{'D' if dropped else ' '}"


def report(run_dir: Path, at_most: float, quiet: bool) -> None:
    """Print one run's checkpoints (unless ``quiet``) and its summary line."""
    checkpoints = read_checkpoints(run_dir)
    if not quiet:
        print(
            f"{run_dir.name}\n   env steps  minutes  held-out (m)  drops   circle  rectangle  fig-8"
        )
        for c in checkpoints:
            cells = "  ".join(_cell(c.paths.get(p)) for p in PATHS)
            print(
                f"{c.step:12,}  {c.minutes:7.1f}  {c.held_out_score:12.4f}  "
                f"{c.held_out_drops:2d}/{c.held_out_episodes:<2d}  {cells}"
            )
    passing = [c for c in checkpoints if c.carries_all(at_most)]
    carried = [c for c in checkpoints if c.carries_all(float("inf"))]
    best = min(carried, key=lambda c: c.worst_path, default=None)
    best_text = (
        "none carries all three"
        if best is None
        else f"best worst path {best.worst_path:.3f} m at {best.step:,}"
    )
    print(
        f"{run_dir.name}: {len(passing)} of {len(checkpoints)} checkpoints carry all three paths "
        f"at <= {at_most:g} m without a drop; {len(carried)} carry all three; {best_text}"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run directories")
    parser.add_argument("--at-most", type=float, default=0.025, help="m (default 0.025)")
    parser.add_argument("--quiet", action="store_true", help="the summary lines only")
    args = parser.parse_args(argv)
    for run_dir in args.runs:
        if not (run_dir / "tables" / "validation.parquet").is_file():
            print(f"{run_dir}: no tables/validation.parquet; pass a run directory", file=sys.stderr)
            return 2
        try:
            report(run_dir, args.at_most, args.quiet)
        except ValueError as error:
            print(error, file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
