"""The frontier of recipes on fresh seeds: the fraction of seeds at the study against the
wall-clock minutes from each command's start.

    .venv/bin/python experiments/fresh_seed_frontier.py docs/data/fresh-seeds/*.json \
        --figure docs/figures/fresh_seed_frontier.png

Reads the per-seed records that ``experiments/fresh_seeds.py --record FILE`` writes (one file
per recipe and set of fresh seeds) and, per recipe, draws two step curves over minutes m:

* solid: the share of its seeds whose command had ended by m with a kept model at or below the
  study's 3-D RMSE in all six cells (what a user gets from ``softtrack train`` + ``evaluate``);
* dashed: the share with a validated checkpoint at the study by m (what a perfect choice among
  checkpoints with early stopping would get: the bound of model selection).

It prints each recipe's counts at the 5-minute target and at the end, with 95 % Wilson
intervals. Nothing is trained.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from softtrack.evaluation.statistics import wilson_interval

TARGET_MINUTES = 5.0


@dataclass(frozen=True)
class RecipeRecord:
    """One recipe's fresh seeds: its name, the seeds' range as text, the minutes at which
    each seed's command ended with its kept model at the study (``inf``: it is not), and the
    minutes to each seed's first checkpoint at the study (``inf``: none); ``criterion``: the
    target its record judged (``fresh_seeds.py --criterion``; only ``study`` is drawn)."""

    recipe: str
    seeds: str
    kept_at: np.ndarray
    checkpoint_at: np.ndarray
    criterion: str = "study"


def read_record(path: Path) -> RecipeRecord:
    """A record file of ``fresh_seeds.py --record``.

    Raises:
        ValueError: the file is not such a record (naming what is missing)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        rows = data["seeds"]
        kept = [r["minutes_total"] if _passes(r) else np.inf for r in rows]
        first = [_minutes_to_target(r) for r in rows]
        seeds = [int(r["seed"]) for r in rows]
        recipe = str(data["recipe"])
        criterion = str(data.get("criterion", "study"))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(
            f"{path}: not a record of experiments/fresh_seeds.py --record ({exc})"
        ) from exc
    if not rows:
        raise ValueError(f"{path}: the record has no seeds")
    return RecipeRecord(
        recipe,
        f"{min(seeds)}–{max(seeds)}",
        np.array(kept, float),
        np.array(first, float),
        criterion,
    )


def _passes(row: dict[str, object]) -> bool:
    """A seed's kept model meets its record's target (records before the criteria: the study)."""
    return bool(row.get("kept_passes", row["kept_at_study"]))


def _minutes_to_target(row: dict[str, object]) -> float:
    """Minutes to a seed's first checkpoint at its target (``inf``: never)."""
    value = row["minutes_to_target"] if "minutes_to_target" in row else row["minutes_to_study"]
    return np.inf if value is None else float(value)  # type: ignore[arg-type]


def share_by(minutes: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The share of seeds (``at``: (S,) minutes, ``inf`` for never) done by each of
    ``minutes`` (M,): (M,)."""
    return (at[None, :] <= minutes[:, None]).mean(axis=1)


def summary(records: Sequence[RecipeRecord]) -> str:
    """Per recipe: kept at the study by the 5-minute target and by the end, and a checkpoint at
    the study by the target, each with its Wilson interval."""
    lines = []
    for r in records:
        n = len(r.kept_at)
        counts = (
            ("kept at the study, command ended", int(np.isfinite(r.kept_at).sum())),
            (
                f"kept at the study within {TARGET_MINUTES:g} min",
                int((r.kept_at <= TARGET_MINUTES).sum()),
            ),
            (
                f"a checkpoint at the study within {TARGET_MINUTES:g} min",
                int((r.checkpoint_at <= TARGET_MINUTES).sum()),
            ),
        )
        parts = []
        for label, k in counts:
            low, high = wilson_interval(k, n)
            parts.append(f"{label} {k} of {n} [{low:.2f}, {high:.2f}]")
        lines.append(f"{r.recipe} (seeds {r.seeds}): " + "; ".join(parts))
    return "\n".join(lines)


def draw(records: Sequence[RecipeRecord], out: Path) -> None:
    """The frontier figure (module docstring) as a PNG at ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    finite = [v for r in records for v in (*r.kept_at, *r.checkpoint_at) if np.isfinite(v)]
    end = max(finite, default=TARGET_MINUTES) * 1.05
    minutes = np.linspace(0.0, end, 500)
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    for k, r in enumerate(records):
        colour = f"C{k}"
        label = f"{r.recipe} (seeds {r.seeds})"
        ax.step(minutes, share_by(minutes, r.kept_at), where="post", color=colour, label=label)
        ax.step(
            minutes, share_by(minutes, r.checkpoint_at), where="post", color=colour, ls="--", lw=1
        )
    ax.axvline(TARGET_MINUTES, color="0.5", lw=0.8)
    ax.axhline(0.9, color="0.5", lw=0.8, ls=":")
    ax.text(TARGET_MINUTES, 0.02, " 5-min target", color="0.4", fontsize=8)
    ax.text(0.2, 0.91, "9 of 10", color="0.4", fontsize=8)
    ax.set_xlabel("minutes from the command's start (one core)")
    ax.set_ylabel("share of fresh seeds at the study")
    ax.set_ylim(0, 1.02)
    ax.set_xlim(0, end)
    ax.set_title(
        "Fresh seeds at the study in all six cells\n"
        "solid: kept model, command ended; dashed: a validated checkpoint",
        fontsize=10,
    )
    ax.legend(fontsize=8, loc="center right")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("records", nargs="+", type=Path, help="fresh_seeds.py --record files")
    parser.add_argument("--figure", type=Path, default=None, help="write the figure (PNG) here")
    args = parser.parse_args(argv)
    try:
        records = [read_record(path) for path in args.records]
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for path, record in zip(args.records, records, strict=True):
        if record.criterion != "study":
            print(f"note: leaving out {path}: its target is {record.criterion!r}, not the study's")
    records = [r for r in records if r.criterion == "study"]
    if not records:
        print("error: no record of the study's target to draw", file=sys.stderr)
        return 2
    print(summary(records))
    if args.figure is not None:
        draw(records, args.figure)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
