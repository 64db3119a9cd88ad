"""Does TD3's target actor (a Polyak average of the actor's weights) track better than the actor?

    .venv/bin/python experiments/diagnostics/target_actor.py \
        models/td3-sbx-128-mirror-tta-3e6-seed?/ [--models kept last]

Validated checkpoints pass or miss the study one by one (seed 0 of the headline recipe passes
at 2.3, 2.8 and 3.0 million steps and misses between: ``selection_levers.py``), as if the
actor oscillated around a good policy. The target actor, which TD3 keeps as a running average of
the actor (``tau`` per update), is saved in every sbx model file and costs nothing to use. For
each run and model file (``kept``: the policy ``softtrack evaluate`` reads; ``last``: its newest
checkpoint) this
tracks the circle, rectangle and figure-eight with the actor and with the target actor (the
validation's batched episodes: equal to ``softtrack evaluate`` on this CPU) and prints each one's
six 3-D RMSE cells, whether all six are at or below the study's, and their mean.

Nothing is written. Chosen seeds (0–9) decide; fresh seeds only measure.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from softtrack.report.reference import STUDY_RMSE_3D
from softtrack.rl.factory import model_class
from softtrack.rl.policy import deterministic_policy
from softtrack.rl.validation import checkpoint_rows
from softtrack.spec import load_spec
from softtrack.spec.env_config import env_config

TRAJECTORIES = ("circle", "rectangle", "figure8")
STUDY = STUDY_RMSE_3D["centralized"]


def model_files(run_dir: Path, which: list[str]) -> dict[str, Path]:
    """The run's model files by name: ``kept`` (the policy ``softtrack evaluate`` reads: the
    newest ``best/`` model of a ``final_policy: best_validated`` run, else ``model.zip``),
    ``last`` (the newest checkpoint)."""
    files: dict[str, Path] = {}
    best = sorted((run_dir / "best").glob("step-*/model.zip"))
    if "kept" in which:
        files["kept"] = best[-1] if best else run_dir / "model.zip"
    checkpoints = sorted((run_dir / "checkpoints").glob("step-*/model.zip"))
    if "last" in which and checkpoints:
        files["last"] = checkpoints[-1]
    return files


def tracking_cells(run_dir: Path, model: Any) -> pd.Series:
    """3-D RMSE (m) per (trajectory, arm) of ``model`` (the run's spec sets the scene)."""
    spec = load_spec(run_dir / "spec.yaml")
    act = deterministic_policy(model, None, batches=True)
    rows = checkpoint_rows(
        "diagnostic",
        act,
        env_config(spec, None),
        float(spec.training.eval_duration),
        0,
        TRAJECTORIES,
        None,
    )
    assert rows is not None
    return rows.set_index(["trajectory", "arm"])["rmse_3d"]


def with_target_actor(model: Any) -> Any:
    """``model`` acting with its target actor's weights."""
    state = model.policy.actor_state
    model.policy.actor_state = state.replace(params=state.target_params)
    return model


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--models", nargs="+", default=["kept", "last"], choices=["kept", "last"])
    args = parser.parse_args()
    limits = pd.Series({(t, arm): STUDY[t][arm] for t in TRAJECTORIES for arm in (0, 1)})
    lines = []
    for run_dir in args.runs:
        spec = load_spec(run_dir / "spec.yaml")
        seed = json.loads((run_dir / "run.json").read_text())["seed"]
        for name, path in model_files(run_dir, args.models).items():
            for actor in ("actor", "target"):
                model = model_class(spec).load(str(path), device="cpu")
                if actor == "target":
                    model = with_target_actor(model)
                cells = tracking_cells(run_dir, model)[limits.index]
                passed = bool((cells <= limits).all())
                lines.append(
                    {"seed": seed, "model": name, "actor": actor, "pass": int(passed)}
                    | {f"{t[:4]}{arm + 1}": round(v, 4) for (t, arm), v in cells.items()}
                    | {"mean": round(float(cells.mean()), 4)}
                )
                print(" ".join(f"{k}={v}" for k, v in lines[-1].items()), flush=True)
    table = pd.DataFrame(lines)
    print(table.to_string(index=False))
    summary = table.groupby(["model", "actor"]).agg(
        passing=("pass", "sum"), runs=("pass", "size"), mean_cell=("mean", "mean")
    )
    paired = table.pivot_table(index=["seed", "model"], columns="actor", values="mean")
    summary["target/actor mean cell (paired)"] = np.nan
    for model_name, group in paired.groupby(level="model"):
        ratio = float((group["target"] / group["actor"]).mean())
        summary.loc[(model_name, "target"), "target/actor mean cell (paired)"] = round(ratio, 3)
    print(summary.to_string())


if __name__ == "__main__":
    main()
