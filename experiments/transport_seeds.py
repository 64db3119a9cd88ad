"""Transport recipes seed by seed, against the per-seed target and the workspace floor.

    .venv/bin/python experiments/transport_seeds.py record RECIPE --runs-dir runs/transport-tta \
        [--runs-dir models] --record docs/data/transport-seeds/RECIPE.json
    .venv/bin/python experiments/transport_seeds.py figure docs/data/transport-seeds/*.json \
        --figure docs/figures/transport_seeds.png

``record`` reads the evaluated runs of one experiment (``softtrack evaluate RUN --random 20``:
the circle, rectangle and figure-eight and 20 random held-out targets) from one or more runs
directories (a seed found twice is taken from the first directory that has it), prints per
seed the sphere's 3-D RMSE on each path, the paths it dropped the sphere on, the random
targets carried to the end, the minutes from the command's start to its end and whether the
seed meets issue 62's per-seed target (every path at or below ``--at-most`` without a drop,
at least ``--carried`` of the random targets carried), then how many seeds meet it with a 95 %
Wilson interval; with ``--record`` it also writes that table and the spec's recorded
workspace floors (``softtrack workspace``) to a JSON file.

``figure`` draws the records side by side: per recipe each seed's worst path (a filled marker
when the seed meets the target, open when not), beside the target and the floor. Nothing is
trained or evaluated.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import textwrap
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from datetime import datetime
from pathlib import Path

import pandas as pd

from softtrack.evaluation import EVAL_TRAJECTORIES
from softtrack.evaluation.statistics import wilson_interval
from softtrack.evaluation.workspace_floors import known_floors
from softtrack.spec.env_config import env_config
from softtrack.store.query import connect
from softtrack.store.runs import RunStore

AT_MOST = 0.025  # m: issue 62's per-seed target on every path
CARRIED = 19  # of 20 random held-out targets


@dataclass(frozen=True)
class SeedResult:
    """One seed's kept model: the sphere's 3-D RMSE per path (m), the paths it dropped the sphere
    on, the random held-out targets carried to the end of how many, their mean RMSE (m), and
    the minutes from the training command's start to its end."""

    seed: int
    run_id: str
    paths: dict[str, float]
    dropped_on: list[str]
    carried: int
    episodes: int
    random_mean: float
    minutes: float

    @property
    def worst_path(self) -> float:
        return max(self.paths.values())

    def meets(self, at_most: float, carried: int) -> bool:
        """Issue 62's per-seed target: every path ≤ ``at_most`` m without a drop and at least
        ``carried`` random targets carried."""
        return self.worst_path <= at_most and not self.dropped_on and self.carried >= carried


def _minutes(run_json: dict[str, object]) -> float:
    started, ended = run_json.get("started"), run_json.get("ended")
    if not isinstance(started, str) or not isinstance(ended, str):
        return math.nan
    span = datetime.fromisoformat(ended.replace("Z", "+00:00")) - datetime.fromisoformat(
        started.replace("Z", "+00:00")
    )
    return span.total_seconds() / 60.0


def read_seeds(recipe: str, runs_dirs: Sequence[Path]) -> list[SeedResult]:
    """The evaluated, completed runs of experiment ``recipe`` in ``runs_dirs``, one per seed."""
    found: dict[int, SeedResult] = {}
    for runs_dir in runs_dirs:
        db = connect(runs_dir)
        runs = db.execute(
            "SELECT run_id, seed, dir FROM runs WHERE name = ? AND status = 'completed'", [recipe]
        ).df()
        if runs.empty:
            continue
        ids = list(runs["run_id"])
        paths = db.execute(
            "SELECT run_id, trajectory, max(object_rmse_3d) AS rmse, bool_or(dropped) AS dropped "
            "FROM eval_metrics WHERE list_contains(?, run_id) GROUP BY run_id, trajectory",
            [ids],
        ).df()
        randoms = db.execute(
            "SELECT run_id, episode, bool_or(dropped) AS dropped, max(object_rmse_3d) AS rmse "
            "FROM eval_random WHERE list_contains(?, run_id) GROUP BY run_id, episode",
            [ids],
        ).df()
        for row in runs.itertuples():
            seed = int(row.seed)
            mine = paths[paths["run_id"] == row.run_id].set_index("trajectory")
            episodes = randoms[randoms["run_id"] == row.run_id]
            if seed in found or not set(EVAL_TRAJECTORIES) <= set(mine.index) or episodes.empty:
                continue
            run_json = json.loads((runs_dir / str(row.dir) / "run.json").read_text("utf-8"))
            found[seed] = SeedResult(
                seed=seed,
                run_id=str(row.run_id),
                paths={t: float(mine.loc[t, "rmse"]) for t in EVAL_TRAJECTORIES},
                dropped_on=[t for t in EVAL_TRAJECTORIES if bool(mine.loc[t, "dropped"])],
                carried=int((~episodes["dropped"].astype(bool)).sum()),
                episodes=len(episodes),
                random_mean=float(episodes["rmse"].mean()),
                minutes=_minutes(run_json),
            )
    return [found[seed] for seed in sorted(found)]


def recipe_floors(recipe: str, runs_dirs: Sequence[Path]) -> dict[str, float] | None:
    """The recorded workspace floors (m) of the recipe's physics and paths, from one of its runs."""
    for runs_dir in runs_dirs:
        runs = connect(runs_dir).execute("SELECT run_id FROM runs WHERE name = ?", [recipe]).df()
        if not runs.empty:
            spec = RunStore(runs_dir).get_run(str(runs["run_id"].iloc[0])).load_spec()
            return known_floors(env_config(spec))
    return None


def summary(results: Sequence[SeedResult], at_most: float, carried: int) -> str:
    """The per-seed table and the count of seeds meeting the target with its interval."""
    lines = [
        "seed  circle  rectangle  figure8  dropped on  carried  random mean  minutes  target",
    ]
    for r in results:
        lines.append(
            f"{r.seed:4d}  {r.paths['circle']:6.4f}  {r.paths['rectangle']:9.4f}  "
            f"{r.paths['figure8']:7.4f}  {','.join(r.dropped_on) or '-':>10}  "
            f"{r.carried:3d}/{r.episodes:<3d}  {r.random_mean:11.4f}  {r.minutes:7.1f}  "
            f"{'meets' if r.meets(at_most, carried) else 'misses'}"
        )
    passed = sum(r.meets(at_most, carried) for r in results)
    low, high = wilson_interval(passed, len(results))
    lines.append(
        f"{passed} of {len(results)} seeds meet the target (every path <= {at_most:g} m without "
        f"a drop, >= {carried} of 20 carried): 95 % [{low:.2f}, {high:.2f}]"
    )
    return "\n".join(lines)


def write_record(
    path: Path, recipe: str, results: Sequence[SeedResult], floors: dict[str, float] | None
) -> None:
    data = {
        "recipe": recipe,
        "floors": floors,
        "seeds": [{**asdict(r), "worst_path": r.worst_path} for r in results],
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")


def draw(records: Sequence[Path], out: Path, at_most: float, carried: int) -> None:
    """Each record's seeds (worst path, m) in a column, the target and the lowest floor as lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = [json.loads(p.read_text(encoding="utf-8")) for p in records]
    fig, ax = plt.subplots(figsize=(1.8 + 1.6 * len(data), 4.2))
    floors = []
    for column, record in enumerate(data):
        seeds = pd.DataFrame(record["seeds"])
        meets = (
            (seeds["worst_path"] <= at_most)
            & (seeds["dropped_on"].map(len) == 0)
            & (seeds["carried"] >= carried)
        )
        # seeds side by side within the column, so that equal errors stay apart
        x = column + 0.08 * (seeds.index.to_numpy() - (len(seeds) - 1) / 2)
        for hit, face in ((True, "C0"), (False, "none")):
            ax.scatter(
                x[(meets == hit).to_numpy()],
                seeds["worst_path"][meets == hit],
                facecolors=face,
                edgecolors="C0",
                s=36,
                zorder=3,
            )
        for at, row in zip(x, seeds.itertuples(), strict=True):
            ax.annotate(
                str(row.seed),
                (at, row.worst_path),
                xytext=(0, 6),
                textcoords="offset points",
                fontsize=7,
                ha="center",
            )
        if record.get("floors"):
            floors.append(max(record["floors"][t] for t in EVAL_TRAJECTORIES))
    ax.axhline(at_most, color="C3", linestyle="--", linewidth=1, label=f"target {at_most:g} m")
    if floors:
        ax.axhline(max(floors), color="0.4", linestyle=":", linewidth=1, label="workspace floor")
    ax.set_xticks(range(len(data)))
    ax.set_xticklabels([textwrap.fill(r["recipe"], 24) for r in data], fontsize=6.5)
    ax.set_xlim(-0.6, len(data) - 0.4)
    ax.set_ylim(0, 1.15 * max(max(s["worst_path"] for s in r["seeds"]) for r in data))
    ax.set_ylabel("sphere 3-D RMSE, worst of the three paths (m)")
    ax.set_title(
        f"per seed: filled = every path ≤ {at_most:g} m, no drop, ≥ {carried}/20 carried",
        fontsize=8,
    )
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=130)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("record", help="read one recipe's seeds (and write a record)")
    rec.add_argument("recipe", help="the experiment name (its runs share it)")
    rec.add_argument("--runs-dir", type=Path, action="append", required=True)
    rec.add_argument("--record", type=Path, help="also write the seeds to this JSON file")
    fig = sub.add_parser("figure", help="draw records side by side")
    fig.add_argument("records", type=Path, nargs="+")
    fig.add_argument("--figure", type=Path, required=True)
    for p in (rec, fig):
        p.add_argument("--at-most", type=float, default=AT_MOST, help="m on every path [0.025]")
        p.add_argument("--carried", type=int, default=CARRIED, help="of 20 random targets [19]")
    args = parser.parse_args(argv)
    if args.command == "figure":
        missing = [str(p) for p in args.records if not p.is_file()]
        if missing:
            print(f"error: no record {', '.join(missing)}", file=sys.stderr)
            return 2
        draw(args.records, args.figure, args.at_most, args.carried)
        print(f"wrote {args.figure}")
        return 0
    results = read_seeds(args.recipe, args.runs_dir)
    if not results:
        dirs = ", ".join(str(d) for d in args.runs_dir)
        print(
            f"error: no evaluated, completed run of {args.recipe} in {dirs}; "
            "evaluate its runs with `softtrack evaluate RUN --random 20`",
            file=sys.stderr,
        )
        return 2
    print(summary(results, args.at_most, args.carried))
    if args.record is not None:
        write_record(args.record, args.recipe, results, recipe_floors(args.recipe, args.runs_dir))
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
