"""Can constant actions hold the sphere still away from its start? Open loop, against the paths.

    .venv/bin/python experiments/diagnostics/diagnose_transport_reach.py \
        experiments/variants/td3-sbx-128-3e6-mirror-fast-transport-fine-10ms-long.yaml \
        [--amplitude 0.02 0.05 0.1 0.2] [--differential 0] [--samples 64] [--ramp 1] [--hold 3]

Open loop, the spec's transport task (its grip, torque per control unit, gravity and sphere):
every environment ramps one constant action in with a smoothstep over ``--ramp`` seconds and
keeps it for ``--hold`` seconds more. Per direction (normal, binormal) the action on control
point k = 0…5 is offset + slope·(k/5 − 1/2); arm 1 gets the common part plus the differential
part, arm 2 the common part minus it (the task's grip is added by the environment as in
training). With no differential part both arms get the same torques, so without the sphere
their tips would stay 0.2 m apart, the sphere's width with the two arm radii: the motion that
carries the sphere. The common offsets and slopes are uniform in [−A, A] (``--amplitude``), the
differential ones in [−D, D] (``--differential``). A sample *holds the sphere still* when the
episode did not end on a drop, both arms touched the sphere in at least half of the last 0.5 s's
control steps and the sphere's mean speed over them was below 0.05 m/s; its position is then the
mean over those steps.

Printed per amplitude: how many samples held the sphere still and how far from its start (median,
maximum); then, over every held position, the distance from each point of the circle, rectangle
and figure-eight (one lap, 1,000 points, the spec's target settings) to the nearest one: RMSE,
median and the share within 0.065 m (the transport issue's target). Nothing is written.
"""

from __future__ import annotations

import argparse

import numpy as np

from softtrack import api
from softtrack.evaluation.workspace import (
    N_PARAMETERS,
    hold_positions,
    nearest_distances,
    path_points,
)
from softtrack.spec.env_config import env_config

#: Paths the evaluation tracks (docs/environment.md).
PATHS = ("circle", "rectangle", "figure8")
#: The transport issue's target error, m.
TARGET_ERROR = 0.065


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("spec", help="a transport spec file")
    parser.add_argument(
        "--amplitude", type=float, nargs="+", default=[0.02, 0.05, 0.1, 0.2], help="A"
    )
    parser.add_argument("--differential", type=float, default=0.0, help="D")
    parser.add_argument("--samples", type=int, default=64, help="per amplitude")
    parser.add_argument("--ramp", type=float, default=1.0, help="s")
    parser.add_argument("--hold", type=float, default=3.0, help="s")
    parser.add_argument("--batch", type=int, default=64, help="environments stepped together")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    config = env_config(api.validate_spec(args.spec))
    if not config.task.carries_object or config.sim.sphere is None:
        parser.error(f"{args.spec} is not a transport spec (env.task.name: transport)")
    rng = np.random.default_rng(args.seed)
    start = np.asarray(config.sim.sphere.center)
    reached = np.zeros((0, 3))
    for amplitude in args.amplitude:
        parameters = np.concatenate(
            [
                rng.uniform(-amplitude, amplitude, size=(args.samples, N_PARAMETERS // 2)),
                rng.uniform(
                    -args.differential, args.differential, size=(args.samples, N_PARAMETERS // 2)
                ),
            ],
            axis=1,
        )
        held_here = []
        for first in range(0, args.samples, args.batch):
            held, position = hold_positions(
                config, parameters[first : first + args.batch], args.ramp, args.hold
            )
            held_here.append(position[held])
        positions = np.concatenate(held_here)
        reached = np.concatenate([reached, positions])
        moved = np.linalg.norm(positions - start, axis=1)
        print(
            f"amplitude {amplitude:g}: {len(positions)} of {args.samples} held the sphere still"
            + (
                f", {np.median(moved):.3f} m from its start (median; at most {moved.max():.3f})"
                if len(positions)
                else ""
            ),
            flush=True,
        )
    for name in PATHS:
        gap = nearest_distances(path_points(config, name), reached)
        print(
            f"{name}: path point to the nearest held position RMSE {np.sqrt(np.mean(gap**2)):.3f}"
            f" m, median {np.median(gap):.3f}; within {TARGET_ERROR} m: "
            f"{np.mean(gap <= TARGET_ERROR):.0%}",
            flush=True,
        )


if __name__ == "__main__":
    main()
