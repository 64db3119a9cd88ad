"""Would another model-selection rule, or a population of K learners, reach the study more often?

    .venv/bin/python experiments/diagnostics/selection_levers.py \
        models/td3-sbx-128-mirror-tta-3e6-seed?/ [--population 1 2 3 4]

Reads each run's ``validation`` table (recorded with ``training.validation_trajectories: true``:
every validated checkpoint has its random-target rows and its circle, rectangle and figure-eight
rows) and answers two questions without training anything:

1. **Selection rules.** Each rule is a score computed from a checkpoint's held-out rows only:
   the random targets, and where the run has them (``training.validation_paths``) the
   held-out paths, and both together (the project's score for such a run); the checkpoint a
   rule keeps is its lowest score. A run *passes* under a rule when that
   checkpoint's trajectory rows are at or below the study's 3-D RMSE in all six cells. The
   ``trajectories`` column is the bound no rule can beat: some checkpoint of the run passes.
   (A checkpoint's trajectory rows equal ``softtrack evaluate`` of its model on the same CPU:
   ``tests/test_validation.py``.)
2. **Populations.** A population of K independent learners keeps the member whose kept model has
   the lowest validation score (the project's rule). Over every K-subset of the runs given, it
   prints the share that passes, beside ``1 - (1 - p)^K`` (what independent members with a
   score that ranks members by pass/fail would give) and the share of subsets where any member
   passes.

Nothing is written. Rules are chosen on the chosen seeds (0–9); fresh seeds only measure.
"""

from __future__ import annotations

import argparse
import itertools
import json
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from softtrack.report.reference import STUDY_RMSE_3D
from softtrack.store.tables import read_table

STUDY = STUDY_RMSE_3D["centralized"]
TRAJECTORIES = tuple(STUDY)
#: The held-out target sets a score may average (rows' ``trajectory``).
TARGET_SETS = (("random",), ("paths",), ("random", "paths"))

#: A rule maps the held-out rows' 3-D RMSE (index (global_step, trajectory, episode), one
#: column per arm, m) to one score per checkpoint (m); the lowest is kept.
Rule = Callable[[pd.DataFrame], pd.Series]

RULES: dict[str, Rule] = {
    "mean (the project's)": lambda arms: arms.mean(axis=1).groupby(level=0).mean(),
    "worst arm per episode": lambda arms: arms.max(axis=1).groupby(level=0).mean(),
    "worst arm's mean": lambda arms: arms.groupby(level=0).mean().max(axis=1),
    "quadratic mean": lambda arms: np.sqrt((arms**2).mean(axis=1).groupby(level=0).mean()),
    "mean of 3 neighbouring checkpoints": lambda arms: (
        arms.mean(axis=1).groupby(level=0).mean().rolling(3, center=True, min_periods=2).mean()
    ),
    "the last checkpoint": lambda arms: (
        -pd.Series(arms.index.get_level_values(0).unique(), dtype=float).set_axis(
            arms.index.get_level_values(0).unique()
        )
    ),
}


def checkpoint_passes(validation: pd.DataFrame) -> pd.Series:
    """Whether each validated checkpoint is at or below the study in all six cells.

    Args:
        validation: a run's ``validation`` table.

    Returns:
        bool per ``global_step`` with trajectory rows.
    """
    tracked = validation[validation["trajectory"].isin(TRAJECTORIES)]
    cells = tracked.pivot_table(
        index="global_step", columns=["trajectory", "arm"], values="rmse_3d"
    )
    limits = pd.Series({(t, arm): STUDY[t][arm] for (t, arm) in cells.columns})
    return (cells <= limits).all(axis=1)


def held_out_rows(validation: pd.DataFrame, targets: Sequence[str] = ("random",)) -> pd.DataFrame:
    """Held-out 3-D RMSE (m) of the ``targets`` rows per (global_step, trajectory, episode),
    one column per arm (empty when the run has none of them)."""
    rows = validation[validation["trajectory"].isin(targets)]
    keys = ["global_step", "trajectory", "episode", "arm"]
    return rows.groupby(keys)["rmse_3d"].mean().unstack("arm")


def rule_outcomes(run_dirs: Sequence[Path]) -> pd.DataFrame:
    """Pass (1) or miss (0) per run (rows: seeds) and rule on each held-out target set the
    runs have (columns "rule [targets]"), plus the bound."""
    outcomes: dict[int, dict[str, int]] = {}
    for run_dir in run_dirs:
        seed = int(json.loads((run_dir / "run.json").read_text())["seed"])
        validation = read_table(run_dir / "tables" / "validation.parquet")
        passes = checkpoint_passes(validation)
        row = {}
        for targets in TARGET_SETS:
            arms = held_out_rows(validation, targets)
            if arms.empty or set(targets) - set(arms.index.get_level_values("trajectory")):
                continue
            for name, rule in RULES.items():
                scores = rule(arms).reindex(passes.index).dropna()
                row[f"{name} [{' + '.join(targets)}]"] = int(passes[scores.idxmin()])
        row["trajectories (bound)"] = int(passes.any())
        outcomes[seed] = row
    return pd.DataFrame(outcomes).T.sort_index()


def population_outcomes(run_dirs: Sequence[Path], sizes: Sequence[int]) -> pd.DataFrame:
    """Share of K-subsets whose best-validated member passes, per population size K."""
    members = []
    for run_dir in run_dirs:
        validation = read_table(run_dir / "tables" / "validation.parquet")
        passes = checkpoint_passes(validation)
        scores = RULES["mean (the project's)"](held_out_rows(validation)).reindex(passes.index)
        kept = scores.idxmin()
        members.append((float(scores[kept]), bool(passes[kept])))
    single = np.mean([passed for _, passed in members])
    rows = []
    for size in sizes:
        subsets = list(itertools.combinations(members, size))
        kept = [min(subset)[1] for subset in subsets]
        rows.append(
            {
                "K": size,
                "subsets": len(subsets),
                "best-validated member passes": np.mean(kept),
                "independent, score ranks pass": 1 - (1 - single) ** size,
                "any member passes": np.mean([any(p for _, p in s) for s in subsets]),
            }
        )
    return pd.DataFrame(rows).set_index("K")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run directories of one recipe")
    parser.add_argument("--population", nargs="+", type=int, default=[1, 2, 3, 4])
    args = parser.parse_args()
    outcomes = rule_outcomes(args.runs)
    print("selection rules: 1 = the kept checkpoint is at the study in all six cells")
    table = outcomes.T
    table["runs passing"] = table.sum(axis=1)
    print(table.to_string())
    print()
    print("populations of K independent runs, the best-validated member kept")
    print(population_outcomes(args.runs, args.population).round(3).to_string())


if __name__ == "__main__":
    main()
