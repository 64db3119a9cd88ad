"""Claims from fresh seeds: train a recipe on seeds that no choice saw and count how many reach
the study.

Seeds 0–9 are where recipes are chosen (docs/results/time-to-accuracy.md); a claim about a
recipe ("reaches the study", "minutes to accuracy", "final accuracy") is measured here, on seeds
100 and up. Per seed this runs one ``softtrack train SPEC --seed S`` (one seed at a time per
core of ``--cores``), stamps every validation line the training prints with the seconds since
that command started (start-up, compilation, warm-up, training and the validations before it
all count), then evaluates the run's kept model on the circle, rectangle and figure-eight.
It prints per seed whether the kept model meets the task's target (``--criterion``,
:mod:`fresh_seed_criteria`: by default at or below the study's 3-D RMSE in all six trajectory ×
arm cells; ``contact``: the arms' quadratic mean at or below 0.055 m; ``viewpoints``: the six
cells and the arms' overlap at or below 5 mm), the minutes from the command's start to the first
validated checkpoint that meets it, the whole command's minutes and the kept cells; then the
pass rate with its 95 % Wilson interval and the interquartile mean of the kept models' cells
with its 95 % stratified bootstrap interval (``softtrack compare``'s statistics).

Running it again continues: a seed with a completed run is read, not retrained (its timing from
the first time); an interrupted run resumes (its minutes then cover the resumed session only,
marked ``resumed``). Timings are kept in ``<runs dir>/.fresh-seeds/``; ``--record FILE``
also writes the per-seed results as JSON (``docs/data/fresh-seeds/``: the frontier figure's
input, ``experiments/diagnostics/fresh_seed_frontier.py``).

Usage (one core, the others idle or busy with other work; say which in a claim)::

    .venv/bin/python experiments/fresh_seeds.py experiments/variants/td3-sbx-128-3e6-mirror-tta.yaml \\
        --seeds 100-109 --runs-dir runs/fresh --cores 1
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from fresh_seed_criteria import (
    CELLS,
    CRITERIA,
    TRAJECTORIES,
    at_study,
    quadratic_means,
    study_cells,
)

from softtrack.evaluation.seed_statistics import stratified_bootstrap
from softtrack.evaluation.statistics import wilson_interval
from softtrack.executors.sweep import parse_seeds
from softtrack.spec import ExperimentSpec, SpecError, load_spec, spec_hash
from softtrack.store.provenance import cpu_kind
from softtrack.store.runs import RunRecord, RunStore, resolve_runs_dir
from softtrack.store.tables import read_table

ROOT = Path(__file__).resolve().parent.parent
#: The seeds recipes are chosen on; a fresh seed is none of them.
CHOSEN_SEEDS = range(0, 10)
VALIDATION_LINE = re.compile(r"validation at ([\d,]+) steps")
TIMINGS_DIR = ".fresh-seeds"


@dataclass(frozen=True)
class SeedResult:
    """One fresh seed: its run, the kept model's cells (m, in :data:`CELLS` order), the
    minutes from the command's start to the first checkpoint that meets ``criterion``
    (``None``: never), the whole command's minutes, whether its clock covers a resumed session
    only, and the kept model's deepest overlap of the arms' surfaces (m; ``None``: not
    recorded)."""

    seed: int
    run_id: str
    kept: tuple[float, ...]
    minutes_to_target: float | None
    minutes_total: float
    resumed: bool
    overlap: float | None = None
    criterion: str = "study"

    @property
    def cells(self) -> dict[tuple[str, int], float]:
        return dict(zip(CELLS, self.kept, strict=True))

    @property
    def reached(self) -> bool:
        """Whether the kept model meets the criterion's target."""
        return CRITERIA[self.criterion].passes(self.cells, self.overlap)


def check_request(spec: ExperimentSpec, seeds: Sequence[int]) -> None:
    """Refuse (SpecError, one line) seeds that overlap the chosen ones and a recipe whose
    checkpoints do not track the three trajectories (no time to the study's accuracy)."""
    overlap = sorted(set(seeds) & set(CHOSEN_SEEDS))
    if overlap:
        raise SpecError(
            "--seeds",
            f"seeds {', '.join(map(str, overlap))} are among the seeds recipes are chosen on "
            f"({CHOSEN_SEEDS.start}–{CHOSEN_SEEDS.stop - 1})",
            "give fresh seeds, e.g. --seeds 100-109",
        )
    if spec.controller != "centralized" or not spec.training.validation_trajectories:
        raise SpecError(
            spec.name,
            "the recipe's checkpoints do not track the circle, rectangle and figure-eight",
            "use a centralized spec with training.validation_trajectories: true",
        )


def _runs_of(store: RunStore, spec: ExperimentSpec) -> dict[int, RunRecord]:
    digest = spec_hash(spec)
    found: dict[int, RunRecord] = {}
    for record in store.list_runs():
        if record.info.spec_hash == digest and record.info.name == spec.name:
            found.setdefault(record.info.seed, record)
    return found


def _train(args: list[str], core: int | None, echo: str) -> tuple[str, float, list[float], int]:
    """Run ``softtrack ARGS`` (taskset to ``core``); returns (its stdout's first line, seconds
    it took, seconds since its start at each validation line, exit code)."""
    command = [sys.executable, "-m", "softtrack.cli", *args]
    if core is not None:
        command = ["taskset", "-c", str(core), *command]
    start = time.monotonic()
    process = subprocess.Popen(
        command,
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "CI": "1"},  # whole progress lines, no bar
    )
    stamps: list[float] = []

    def read_stderr() -> None:
        assert process.stderr is not None
        for line in process.stderr:
            if VALIDATION_LINE.search(line):
                stamps.append(time.monotonic() - start)
            print(f"{echo} {line.rstrip()}", file=sys.stderr, flush=True)

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    assert process.stdout is not None
    out = process.stdout.read()
    code = process.wait()
    reader.join()
    return (out.strip().splitlines() or [""])[0], time.monotonic() - start, stamps, code


def train_seed(spec_path: Path, seed: int, store: RunStore, core: int | None) -> None:
    """Train (or resume, or leave) ``seed`` and keep its timing in ``.fresh-seeds/``."""
    spec = load_spec(spec_path)
    existing = _runs_of(store, spec).get(seed)
    if existing is not None and existing.info.status == "completed":
        return
    timing_dir = store.root / TIMINGS_DIR
    timing_dir.mkdir(parents=True, exist_ok=True)
    if existing is not None:
        args = ["train", "--resume", existing.run_id, "--runs-dir", str(store.root)]
    else:
        args = ["train", str(spec_path), "--seed", str(seed), "--runs-dir", str(store.root)]
    run_id, seconds, stamps, code = _train(args, core, f"[seed {seed}]")
    run_id = existing.run_id if existing is not None else run_id
    if code != 0 or not run_id:
        raise RuntimeError(f"seed {seed}: softtrack train ended with exit code {code}")
    timing = {
        "run_id": run_id,
        "seed": seed,
        "seconds": seconds,
        "validation_seconds": stamps,
        "resumed": existing is not None,
        "cpu": cpu_kind(),
        "core": core,
    }
    (timing_dir / f"{spec.name}-seed{seed}.json").write_text(json.dumps(timing, indent=1))


def _deepest_overlap(rows: pd.DataFrame) -> float | None:
    """The deepest ``max_penetration`` of ``rows`` (m; ``None`` without the column)."""
    if "max_penetration" not in rows:
        return None
    depth = pd.to_numeric(rows["max_penetration"], errors="coerce")
    return float(depth.max()) if depth.notna().any() else None


def _kept_model(record: RunRecord, store: RunStore) -> tuple[tuple[float, ...], float | None]:
    """The kept model's six cells (m, :data:`CELLS` order) and deepest overlap (m or ``None``),
    evaluating it first where it has no evaluation."""
    path = record.table_path("eval_metrics")
    if not path.is_file():
        subprocess.run(
            [
                *(sys.executable, "-m", "softtrack.cli", "evaluate", record.run_id),
                *("-t", "all", "--runs-dir", str(store.root)),
            ],
            cwd=ROOT,
            check=True,
            stdout=subprocess.DEVNULL,
            env={**os.environ, "CI": "1"},
        )
    metrics = read_table(path)
    value = _cells_of(metrics)
    return tuple(value[cell] for cell in CELLS), _deepest_overlap(metrics)


def _cells_of(rows: pd.DataFrame) -> dict[tuple[str, int], float]:
    return {
        (str(t), int(a)): float(v)
        for t, a, v in rows[["trajectory", "arm", "rmse_3d"]].itertuples(index=False)
    }


def _minutes_to_target(record: RunRecord, stamps: Sequence[float], criterion: str) -> float | None:
    """Minutes from the command's start to the first checkpoint whose trajectory rows meet
    ``criterion`` (the k-th validated checkpoint is the k-th validation line)."""
    table = read_table(record.table_path("validation"))
    steps = sorted(set(int(s) for s in table["global_step"]))
    for k, step in enumerate(steps[: len(stamps)]):
        rows = table[(table["global_step"] == step) & table["trajectory"].isin(TRAJECTORIES)]
        cells = _cells_of(rows)
        if len(cells) == len(CELLS) and CRITERIA[criterion].passes(cells, _deepest_overlap(rows)):
            return stamps[k] / 60.0
    return None


def collect(
    spec_path: Path, seeds: Sequence[int], store: RunStore, criterion: str = "study"
) -> list[SeedResult]:
    """The results of the seeds that have a completed run and a timing, judged by
    ``criterion`` (a key of :data:`CRITERIA`)."""
    spec = load_spec(spec_path)
    runs = _runs_of(store, spec)
    results = []
    for seed in seeds:
        record = runs.get(seed)
        timing_path = store.root / TIMINGS_DIR / f"{spec.name}-seed{seed}.json"
        if record is None or record.info.status != "completed" or not timing_path.is_file():
            continue
        timing = json.loads(timing_path.read_text())
        kept, overlap = _kept_model(record, store)
        results.append(
            SeedResult(
                seed=seed,
                run_id=record.run_id,
                kept=kept,
                minutes_to_target=_minutes_to_target(
                    record, timing["validation_seconds"], criterion
                ),
                minutes_total=float(timing["seconds"]) / 60.0,
                resumed=bool(timing["resumed"]),
                overlap=overlap,
                criterion=criterion,
            )
        )
    return results


def summary(results: Sequence[SeedResult], budget_minutes: float) -> str:
    """The per-seed table, the pass rate with its Wilson interval, the IQM with its interval
    (and, for the ``contact`` criterion, of the arms' quadratic means per trajectory)."""
    criterion = CRITERIA[results[0].criterion if results else "study"]
    extra = {
        "contact": "  quadratic mean (m)",
        "viewpoints": "  overlap (mm)",
    }.get(criterion.name, "")
    lines = [
        f"target ({criterion.name}): {criterion.target}",
        "seed  run                         kept passes  min to target  min in all"
        f"{extra}  kept 3-D RMSE (m): circle 1/2, rectangle 1/2, figure-eight 1/2",
    ]
    for r in results:
        to_target = "never" if r.minutes_to_target is None else f"{r.minutes_to_target:.1f}"
        note = " (resumed)" if r.resumed else ""
        lines.append(
            f"{r.seed:4d}  {r.run_id:26s}  {'yes' if r.reached else 'no':11s}  {to_target:>13s}  "
            f"{r.minutes_total:10.1f}{_extra_column(r)}  {' '.join(f'{v:.4f}' for v in r.kept)}"
            f"{note}"
        )
    n = len(results)
    if not n:
        return "no fresh seed has a completed run yet"
    passed = [
        r
        for r in results
        if r.reached and r.minutes_to_target is not None and r.minutes_to_target <= budget_minutes
    ]
    reached = [r for r in results if r.reached]
    for label, group in (
        ("kept model passes", reached),
        (f"kept model passes and a checkpoint passed within {budget_minutes:g} min", passed),
    ):
        low, high = wilson_interval(len(group), n)
        lines.append(f"{label}: {len(group)} of {n} [95 % Wilson {low:.2f}, {high:.2f}]")
    iqm = stratified_bootstrap(np.array([r.kept for r in results]))
    mean_study = float(np.mean(study_cells()))
    lines.append(
        f"kept models, IQM over runs and cells: {iqm.value:.4f} m [{iqm.low:.4f}, {iqm.high:.4f}] "
        f"= {iqm.value / mean_study:.2f}x the study's mean cell ({mean_study:.4f} m); CPU here: "
        f"{cpu_kind()}"
    )
    if criterion.name == "contact":
        means = stratified_bootstrap(np.array([quadratic_means(r.cells) for r in results]))
        lines.append(
            f"kept models' quadratic mean of the arms, IQM over runs and trajectories: "
            f"{means.value:.4f} m [{means.low:.4f}, {means.high:.4f}] (floor 0.05 m)"
        )
    return "\n".join(lines)


def _extra_column(result: SeedResult) -> str:
    """The criterion's own column of :func:`summary`'s per-seed line."""
    if result.criterion == "contact":
        return f"  {float(np.mean(quadratic_means(result.cells))):18.4f}"
    if result.criterion == "viewpoints":
        depth = "n/a" if result.overlap is None else f"{1000 * result.overlap:.1f}"
        return f"  {depth:>12s}"
    return ""


def write_record(path: Path, recipe: str, spec_path: Path, results: Sequence[SeedResult]) -> None:
    """Write ``results`` as JSON: the recipe's name and spec file, the criterion, the CPU, and
    per seed its run, whether the kept model passes (and, whatever the criterion, whether it is
    at the study in all six cells), the minutes to the first checkpoint that passes (null:
    never) and of the whole command, the kept cells (m), the arms' quadratic mean per
    trajectory (m) and the deepest overlap (mm; null: not recorded)."""
    try:
        spec_file = str(spec_path.resolve().relative_to(ROOT))
    except ValueError:
        spec_file = spec_path.name
    record = {
        "recipe": recipe,
        "spec": spec_file,
        "criterion": results[0].criterion if results else "study",
        "cpu": cpu_kind(),
        "seeds": [
            {
                "seed": r.seed,
                "run_id": r.run_id,
                "kept_passes": r.reached,
                "kept_at_study": at_study(r.cells),
                "minutes_to_target": r.minutes_to_target,
                "minutes_total": r.minutes_total,
                "resumed": r.resumed,
                "kept_cells_m": list(r.kept),
                "quadratic_means_m": list(quadratic_means(r.cells)),
                "deepest_overlap_mm": None if r.overlap is None else 1000 * r.overlap,
            }
            for r in results
        ],
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")


def parse_cores(text: str | None) -> list[int | None]:
    """The cores of ``--cores`` ("1", "0,1"), each one this process may run on; ``[None]``
    (no pinning) without it.

    Raises:
        ValueError: an entry is not a core number this process may use (naming those)."""
    if not text:
        return [None]
    usable = sorted(os.sched_getaffinity(0))
    cores: list[int | None] = []
    for entry in text.split(","):
        if not entry.strip().isdigit() or int(entry) not in usable:
            raise ValueError(
                f"--cores {text}: {entry.strip()!r} is not a core this machine lets it use; "
                f"give a comma-separated list of core numbers among {', '.join(map(str, usable))}"
            )
        cores.append(int(entry))
    return cores


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("spec", type=Path, help="the recipe's spec file")
    parser.add_argument("--seeds", default="100-109", help="fresh seeds, e.g. 100-109 [100-109]")
    parser.add_argument("--runs-dir", default=None, help="where the runs go [runs/]")
    parser.add_argument(
        "--cores",
        default=None,
        help="train one seed at a time on each of these cores, e.g. 1 or 0,1",
    )
    parser.add_argument("--no-train", action="store_true", help="only summarise what is there")
    parser.add_argument(
        "--record",
        type=Path,
        default=None,
        help="also write the per-seed results to this JSON file (for "
        "experiments/diagnostics/fresh_seed_frontier.py)",
    )
    parser.add_argument(
        "--criterion",
        choices=sorted(CRITERIA),
        default="study",
        help="what a seed must reach: study (the six cells), contact (the arms' quadratic "
        "mean <= 0.055 m), viewpoints (the six cells, overlap <= 5 mm) [study]",
    )
    parser.add_argument(
        "--budget-minutes", type=float, default=5.0, help="the time target per seed, min [5]"
    )
    args = parser.parse_args(argv)
    try:
        spec = load_spec(args.spec)
        seeds = parse_seeds(args.seeds) or []
        check_request(spec, seeds)
        cores = parse_cores(args.cores)
    except (SpecError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    store = RunStore(resolve_runs_dir(args.runs_dir))
    failed: list[int] = []  # seeds whose training ended with an error
    if not args.no_train:
        pending = list(seeds)
        lock = threading.Lock()

        def worker(core: int | None) -> None:
            while True:
                with lock:
                    if not pending:
                        return
                    seed = pending.pop(0)
                try:
                    train_seed(args.spec, seed, store, core)
                except RuntimeError as exc:  # e.g. another process trains that seed
                    failed.append(seed)
                    print(
                        f"error: {exc}; its result is left out (run the command again to "
                        "resume it)",
                        file=sys.stderr,
                        flush=True,
                    )

        threads = [threading.Thread(target=worker, args=(core,)) for core in cores]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    results = collect(args.spec, seeds, store, args.criterion)
    print(summary(results, args.budget_minutes))
    if args.record is not None:
        write_record(args.record, load_spec(args.spec).name, args.spec, results)
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
