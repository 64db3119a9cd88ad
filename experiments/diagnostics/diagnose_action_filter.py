"""Is a bang-bang policy's switching noise or control? Low-pass its actions and re-measure.

    .venv/bin/python experiments/diagnostics/diagnose_action_filter.py models/td3-sbx-4e6-seed1
    .venv/bin/python experiments/diagnostics/diagnose_action_filter.py RUN --alpha 1 0.5 0.25

For each smoothing factor α the trained policy drives the arms on the circle, rectangle and
figure-eight with its clipped actions passed through a first-order filter,
a_applied(k) = α·a_policy(k) + (1 − α)·a_applied(k − 1) (α = 1: the policy as trained), and
the 3-D RMSE of each arm is printed. If filtering made tracking better, the switching would be
noise that costs accuracy; if it makes tracking worse, the policy uses the switching to control
the arms (closed loop, like sliding-mode control). Nothing is written to the run directory.
"""

from __future__ import annotations

import argparse

import numpy as np

from softtrack.evaluation import EVAL_TRAJECTORIES, run_episode
from softtrack.evaluation.metrics import tracking_metrics
from softtrack.rl.policy import load_policy
from softtrack.spec.env_config import env_config
from softtrack.store.selection import select_one_run


def filtered(policy, alpha: float):
    """``policy`` with its clipped actions low-pass filtered by factor ``alpha`` (0 < α ≤ 1)."""
    state: dict[str, np.ndarray | None] = {"last": None}

    def act(observation: np.ndarray) -> np.ndarray:
        action = np.clip(np.asarray(policy(observation), dtype=np.float64).reshape(-1), -1, 1)
        last = state["last"]
        state["last"] = action if last is None else alpha * action + (1 - alpha) * last
        return state["last"]

    return act


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", help="run id, id prefix or run directory (e.g. models/...)")
    parser.add_argument("--alpha", type=float, nargs="+", default=[1.0, 0.5, 0.25])
    args = parser.parse_args()
    record = select_one_run(args.run)
    spec = record.load_spec()
    policy = load_policy(record, spec)
    config = env_config(spec)
    print(f"{record.run_id}: 3-D RMSE arm 1 / arm 2, m, with actions filtered by α")
    for alpha in args.alpha:
        if not 0 < alpha <= 1:
            raise SystemExit(f"--alpha {alpha}: use 0 < α ≤ 1")
        cells = []
        for trajectory in EVAL_TRAJECTORIES:
            episode = run_episode(
                filtered(policy, alpha), config, trajectory, float(spec.training.eval_duration)
            )
            rmse = [
                tracking_metrics(episode.tips[:, arm], episode.target)["rmse_3d"]
                for arm in range(episode.tips.shape[1])
            ]
            cells.append(f"{trajectory} {' / '.join(f'{v:.4f}' for v in rmse)}")
        print(f"α = {alpha:<5g} " + "   ".join(cells), flush=True)


if __name__ == "__main__":
    main()
