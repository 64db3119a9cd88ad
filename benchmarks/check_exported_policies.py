"""Load every exported policy with the plain library and drive it with plain Gymnasium.

For each exported run directory (``policy.json`` beside ``model.zip``, see
``softtrack export``), this loads each policy file with the bare sbx / Stable-Baselines3
algorithm class (``sbx.TD3.load(path)``; no softtrack loader), builds the run's environment
with ``gymnasium.make("softtrack/DualArmTracking-v0", **env_kwargs(spec))`` on the circle, runs
the deterministic policy for the run's evaluation length, and compares each arm's 3-D RMSE
with the run's stored ``eval_metrics``. Rows stored on this CPU kind must be reproduced to
1e-9 (a deterministic episode); the others are shown with their difference (the closed loop
amplifies rounding differences between CPU kinds, see ``benchmarks/cross_cpu_spread.py``). Planner
runs (``controller: mpc``) have no policy and are skipped:

    .venv/bin/python benchmarks/check_exported_policies.py models/*/

Exit status 1 if a policy stored on this CPU kind does not reproduce its metrics, or a run
is not exported in the current layout (``softtrack upgrade`` converts older ones).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import softtrack.env  # noqa: F401  (registers the environments)
from softtrack.env.observation import arm_view_columns
from softtrack.spec import load_spec
from softtrack.spec.env_config import env_kwargs
from softtrack.store.provenance import cpu_kind
from softtrack.store.tables import read_table

SAME_EPISODE = 1e-9


def plain_model(spec_algo: str, backend: str, path: Path):  # type: ignore[no-untyped-def]
    """The model at ``path`` loaded with the library's own class, e.g. ``sbx.TD3``,
    ``sbx.CrossQ`` or, for tqc with backend sb3, ``sb3_contrib.TQC``."""
    library = importlib.import_module(
        "sbx" if backend == "sbx" else "sb3_contrib" if spec_algo == "tqc" else "stable_baselines3"
    )
    name = "CrossQ" if spec_algo == "crossq" else spec_algo.upper()
    return getattr(library, name).load(str(path), device="cpu")


def circle_rmse(run_dir: Path) -> np.ndarray:
    """Each arm's 3-D RMSE (m) on the circle: sqrt(mean over control steps of distance²)."""
    spec = load_spec(run_dir / "spec.yaml")
    independent = spec.controller == "independent"
    policy_files = (
        [run_dir / "models" / f"arm{k}" / "model.zip" for k in (0, 1)]
        if independent
        else [run_dir / "model.zip"]
    )
    models = [plain_model(spec.algo.name, spec.algo.backend, f) for f in policy_files]
    kwargs = {
        **env_kwargs(spec),
        "target": "circle",
        "episode_duration": spec.training.eval_duration,
    }
    env = gym.make("softtrack/DualArmTracking-v0", **kwargs)
    observation, _ = env.reset(seed=0)
    squared, steps = np.zeros(2), 0
    while True:
        if independent:
            views = [observation[arm_view_columns(k, 2, len(observation))] for k in (0, 1)]
            action = np.concatenate(
                [m.predict(v, deterministic=True)[0] for m, v in zip(models, views, strict=True)]
            )
        else:
            action = models[0].predict(observation, deterministic=True)[0]
        observation, _, terminated, truncated, info = env.step(action)
        squared += np.asarray(info["distances"]) ** 2
        steps += 1
        if terminated or truncated:
            return np.sqrt(squared / steps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="exported run directories")
    args = parser.parse_args()
    here, failures = cpu_kind(), 0
    print(f"CPU kind here: {here}")
    for run_dir in args.runs:
        if load_spec(run_dir / "spec.yaml").controller == "mpc":
            print(f"{run_dir.name}: a planner (controller: mpc), no policy to load; skipped")
            continue
        if (
            not (run_dir / "policy.json").is_file()
            and not (run_dir / "models" / "arm0" / "policy.json").is_file()
        ):
            print(f"{run_dir.name}: not in the exported layout; run `softtrack upgrade {run_dir}`")
            failures += 1
            continue
        live = circle_rmse(run_dir)
        stored = read_table(run_dir / "tables" / "eval_metrics.parquet")
        stored = stored[stored["trajectory"] == "circle"].sort_values("arm")
        stored_cpu = str(stored["cpu"].iloc[0]) if "cpu" in stored else "not recorded"
        rel = np.abs(live - stored["rmse_3d"].to_numpy()) / stored["rmse_3d"].to_numpy()
        same = bool((rel < SAME_EPISODE).all())
        verdict = "equal" if same else f"differs by up to {rel.max():.2%}"
        if stored_cpu == here and not same:
            failures += 1
            verdict += "  <-- stored on this CPU kind"
        print(
            f"{run_dir.name}: live {live[0]:.6f} / {live[1]:.6f} m, stored on "
            f"{stored_cpu}: {verdict}"
        )
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
