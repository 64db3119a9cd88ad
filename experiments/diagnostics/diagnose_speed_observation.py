"""Does the target-speed observation hurt a policy trained at one constant target speed?

    .venv/bin/python experiments/diagnostics/diagnose_speed_observation.py models/td3-sbx-4e6-seed0
    .venv/bin/python experiments/diagnostics/diagnose_speed_observation.py RUN --speed 0.3

The study's random training target always moves at 0.3 m/s, so observation 77 (target speed) is
the constant 0.3 in training; the evaluation targets move at 0.13-0.27 m/s. For each run this
drives the arms on the circle, rectangle and figure-eight twice and prints the 3-D RMSE of each
arm: once as evaluated, and once with observation 77 replaced by ``--speed`` (the training
speed) while everything else, including the target's real motion, stays the same. If the
second is better, the policy suffers from the off-distribution input (what
``experiments/variants/td3-sbx-64-4e6-speeds.yaml`` trains away). A diagnosis only: the replaced
input is false information, not a controller. Nothing is written to the run directory.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np

from softtrack.env.observation import observation_labels
from softtrack.evaluation import EVAL_TRAJECTORIES, run_episode
from softtrack.evaluation.metrics import tracking_metrics
from softtrack.rl.policy import load_policy
from softtrack.spec.env_config import env_config
from softtrack.store.selection import select_one_run

Policy = Callable[[np.ndarray], np.ndarray]
TARGET_SPEED_INDEX = observation_labels(n_arms=2).index("target.speed")  # 77


def with_target_speed(policy: Policy, speed: float) -> Policy:
    """``policy`` fed observations whose target-speed entry (index 77) is ``speed``, m/s."""

    def act(observation: np.ndarray) -> np.ndarray:
        replaced = np.array(observation, dtype=np.float32, copy=True)
        replaced[..., TARGET_SPEED_INDEX] = speed
        return policy(replaced)

    return act


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", help="run ids, id prefixes or run directories")
    parser.add_argument(
        "--speed",
        type=float,
        default=0.3,
        help="target speed fed to the policy, m/s (default: the training 0.3)",
    )
    args = parser.parse_args()
    print(
        f"3-D RMSE arm 1 / arm 2, m: as evaluated, and with observation {TARGET_SPEED_INDEX} "
        f"(target speed) fixed at {args.speed:g} m/s"
    )
    for reference in args.runs:
        record = select_one_run(reference)
        spec = record.load_spec()
        if spec.controller != "centralized":
            raise SystemExit(
                f"{reference}: a {spec.controller} run; this needs a centralized one "
                "(81 observations)"
            )
        policy = load_policy(record, spec)
        config = env_config(spec)
        for label, driver in (
            ("as evaluated", policy),
            (f"speed obs {args.speed:g}", with_target_speed(policy, args.speed)),
        ):
            cells = []
            for trajectory in EVAL_TRAJECTORIES:
                episode = run_episode(
                    driver, config, trajectory, float(spec.training.eval_duration)
                )
                rmse = [
                    tracking_metrics(episode.tips[:, arm], episode.target)["rmse_3d"]
                    for arm in range(episode.tips.shape[1])
                ]
                cells.append(f"{trajectory} {rmse[0]:.3f} / {rmse[1]:.3f}")
            print(f"{reference:<40} {label:<15} " + "   ".join(cells), flush=True)


if __name__ == "__main__":
    main()
