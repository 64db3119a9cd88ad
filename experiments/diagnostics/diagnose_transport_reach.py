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
import dataclasses

import numpy as np

from softtrack import api
from softtrack.env.core import TrackingCore
from softtrack.env.settings import TrackingConfig
from softtrack.env.targets import trajectory_position
from softtrack.sim.actuation import N_CONTROL_POINTS
from softtrack.spec.env_config import env_config

#: Paths the evaluation tracks (docs/environment.md).
PATHS = ("circle", "rectangle", "figure8")
#: Number of action parameters per sample: (arm, direction, offset/slope) = 2 × 2 × 2.
N_PARAMETERS = 8
#: The transport issue's target error, m.
TARGET_ERROR = 0.065
#: Speed below which a held sphere counts as still, m/s.
STILL_SPEED = 0.05
#: Seconds at the end of a sample over which holding and stillness are judged.
JUDGE_WINDOW = 0.5


def actions_from_parameters(parameters: np.ndarray) -> np.ndarray:
    """(n, 24) control values from (n, 8) parameters, clipped to [−1, 1].

    Columns 0–3 are the common part (normal offset, normal slope, binormal offset, binormal
    slope), 4–7 the differential part of the same; arm 1 gets common + differential, arm 2
    common − differential, along the six control points as offset + slope·(k/5 − 1/2).
    """
    ramp = np.linspace(-0.5, 0.5, N_CONTROL_POINTS)  # (6,)
    common, differential = parameters[:, :4], parameters[:, 4:]
    per_arm = np.stack([common + differential, common - differential], axis=1)  # (n, 2, 4)
    offsets, slopes = per_arm[:, :, 0::2], per_arm[:, :, 1::2]  # (n, 2, 2): arm, direction
    values = offsets[..., None] + slopes[..., None] * ramp  # (n, 2, 2, 6)
    return np.clip(values.reshape(len(parameters), -1), -1.0, 1.0)


def hold_positions(
    config: TrackingConfig, parameters: np.ndarray, ramp: float, hold: float
) -> tuple[np.ndarray, np.ndarray]:
    """Run one environment per parameter row.

    Args:
        config: a transport configuration.
        parameters: (n, 8) action parameters.
        ramp: seconds over which the action is brought in, s.
        hold: seconds the action is kept after the ramp, s.

    Returns:
        (n,) bool, held still; (n, 3) the sphere's mean position over the last
        :data:`JUDGE_WINDOW` seconds, m.
    """
    n = len(parameters)
    config = dataclasses.replace(config, episode_duration=ramp + hold)
    core = TrackingCore(n, config)
    core.reset(np.arange(n), [np.random.default_rng(i) for i in range(n)])
    final_actions = actions_from_parameters(parameters)
    dt = config.sim.control_dt
    n_steps = round((ramp + hold) / dt)
    window = max(1, round(JUDGE_WINDOW / dt))
    alive = np.ones(n, dtype=bool)
    both_touching = np.zeros(n)
    speed = np.zeros(n)
    position = np.zeros((n, 3))
    for step in range(n_steps):
        tau = min(1.0, (step + 1) * dt / ramp) if ramp > 0 else 1.0
        result = core.step(final_actions * (3.0 * tau**2 - 2.0 * tau**3))
        alive &= ~result.terminated
        if step >= n_steps - window:
            assert result.touching is not None
            both_touching += result.touching.all(axis=1)
            speed += np.linalg.norm(core.engine.sphere_velocity, axis=1)
            position += core.engine.sphere_position
    held = alive & (both_touching >= 0.5 * window) & (speed / window < STILL_SPEED)
    return held, position / window


def path_points(config: TrackingConfig, name: str, n_points: int = 1000) -> np.ndarray:
    """(n_points, 3) one lap of a closed-form path with the spec's target settings, m."""
    target = dataclasses.replace(config.target, name=name)
    t = np.linspace(0.0, target.period, n_points, endpoint=False)
    return trajectory_position(target, t)


def nearest_distances(points: np.ndarray, reached: np.ndarray) -> np.ndarray:
    """(p,) distance from each of ``points`` (p, 3) to the nearest of ``reached`` (r, 3), m
    (inf when nothing was reached)."""
    if len(reached) == 0:
        return np.full(len(points), np.inf)
    diff = points[:, None, :] - reached[None, :, :]
    return np.sqrt(np.einsum("prk,prk->pr", diff, diff)).min(axis=1)


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
