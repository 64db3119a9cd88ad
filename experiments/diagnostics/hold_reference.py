"""The do-nothing reference of a transport spec: hold the sphere where it starts.

    .venv/bin/python experiments/diagnostics/hold_reference.py \
        experiments/variants/td3-sbx-128-3e6-mirror-fast-transport-fine-10ms-reachable.yaml \
        [--episodes 20]

Every control value stays 0, so the arms only squeeze with the task's grip (``env.task.grip``)
and the sphere stays about where it starts. This tracks the spec's circle, rectangle and
figure-eight and ``--episodes`` random held-out targets (the validation's seeds) with that
action, in one batch of the engine, and prints per path the sphere's 3-D RMSE and whether it
was dropped, and the random episodes carried to the end with a 95 % Wilson interval. A
controller that moves the sphere must beat these numbers. Nothing is written.
"""

from __future__ import annotations

import argparse

import numpy as np

from softtrack.evaluation.statistics import wilson_interval
from softtrack.rl.validation import checkpoint_rows
from softtrack.spec import load_spec
from softtrack.spec.env_config import env_config

TRAJECTORIES = ("circle", "rectangle", "figure8")


def do_nothing(observation: np.ndarray) -> np.ndarray:
    """(n, 81) observations → (n, 24) zero actions (the grip alone)."""
    return np.zeros((observation.shape[0], 24))


do_nothing.accepts_batches = True  # type: ignore[attr-defined]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("spec")
    parser.add_argument("--episodes", type=int, default=20)
    args = parser.parse_args()
    spec = load_spec(args.spec)
    if spec.env.task.name != "transport":
        parser.error(f"{args.spec} is not a transport spec (env.task.name: transport)")
    rows = checkpoint_rows(
        "hold",
        do_nothing,
        env_config(spec, None),
        float(spec.training.eval_duration),
        args.episodes,
        TRAJECTORIES,
        None,
    )
    assert rows is not None
    per_episode = rows[rows["arm"] == 0]
    for trajectory in TRAJECTORIES:
        row = per_episode[per_episode["trajectory"] == trajectory].iloc[0]
        print(
            f"{trajectory}: sphere 3-D RMSE {row['object_rmse_3d']:.3f} m, "
            f"{'dropped' if row['dropped'] else 'not dropped'}, both arms touching "
            f"{100 * row['two_arm_contact']:.0f} % of the time"
        )
    random = per_episode[per_episode["trajectory"] == "random"]
    carried = int((~random["dropped"].astype(bool)).sum())
    low, high = wilson_interval(carried, len(random))
    print(
        f"random targets: {carried} of {len(random)} carried to the end "
        f"[95 % Wilson {low:.2f}, {high:.2f}], sphere 3-D RMSE median "
        f"{random['object_rmse_3d'].median():.3f} m"
    )


if __name__ == "__main__":
    main()
