"""How long do the arms hold the sphere under exploration-like noise, per torque per control unit?

    .venv/bin/python experiments/diagnostics/diagnose_transport_hold.py \
        experiments/variants/td3-sbx-128-1e6-mirror-fast-transport-grip.yaml \
        --torque-scale 75 7.5 --noise 0.1 0.3 --offset 0 0.1 [--steps-per-action 10 50]

Open loop, transport task of SPEC (its grip squeeze included), ``--envs`` environments on the
random target: each control step every one of the 24 control values gets a fixed random offset
of ±``offset`` (an actor that has drifted) plus Gaussian noise of std ``noise`` (TD3's
exploration), in control units. With ``--torque-scale`` the torque per control unit is changed
and the grip rescaled so that it squeezes with the same torque (N·m); with ``--steps-per-action``
the control step (integration steps of ``dt`` per action, the noise drawn once per control
step). Printed: the time each
environment held the sphere (until the episode ended on a drop, or its end), median and range;
then how far a constant control value on one arm's normal direction moves its tip in 2 s (the
reach a smaller torque per unit leaves). Nothing is written.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from softtrack import api
from softtrack.env.core import TrackingCore
from softtrack.env.settings import TrackingConfig, make_config
from softtrack.sim.actuation import N_CONTROL_POINTS
from softtrack.spec.env_config import env_config


def hold_times(
    config: TrackingConfig, n_envs: int, noise: float, offset: float, seed: int = 0
) -> np.ndarray:
    """(n_envs,) seconds until each environment dropped the sphere (or its episode ended)."""
    core = TrackingCore(n_envs, config)
    rng = np.random.default_rng(seed)
    core.reset(np.arange(n_envs), [np.random.default_rng(seed + i) for i in range(n_envs)])
    bias = offset * rng.choice([-1.0, 1.0], size=(n_envs, core.action_dim))
    held = np.zeros(n_envs)
    alive = np.ones(n_envs, dtype=bool)
    dt = config.sim.control_dt
    for _ in range(config.max_episode_steps):
        actions = np.clip(bias + noise * rng.normal(size=bias.shape), -1.0, 1.0)
        alive &= ~core.step(actions).terminated
        held += alive * dt
        if not alive.any():
            break
    return held


def reach(torque_scale: float, values: list[float], seconds: float = 2.0) -> np.ndarray:
    """Tip displacement (m) of arm 1 after ``seconds`` of a constant control value on its six
    normal control points, one environment per value (shared task, no sphere)."""
    config = make_config(target="circle", episode_duration=seconds + 1.0, torque_scale=torque_scale)
    core = TrackingCore(len(values), config)
    core.reset(np.arange(len(values)), [np.random.default_rng(i) for i in range(len(values))])
    start = core.engine.tip_position[:, 0].copy()
    actions = np.zeros((len(values), core.action_dim))
    actions[:, :N_CONTROL_POINTS] = np.asarray(values)[:, None]
    for _ in range(round(seconds / config.sim.control_dt)):
        core.step(actions)
    return np.linalg.norm(core.engine.tip_position[:, 0] - start, axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("spec", help="a transport spec file")
    parser.add_argument("--torque-scale", type=float, nargs="+", default=[75.0, 7.5])
    parser.add_argument("--noise", type=float, nargs="+", default=[0.1])
    parser.add_argument("--offset", type=float, nargs="+", default=[0.0, 0.1])
    parser.add_argument(
        "--steps-per-action", type=int, nargs="+", default=None, help="default: the spec's"
    )
    parser.add_argument("--envs", type=int, default=8)
    parser.add_argument("--duration", type=float, default=8.0, help="episode length, s")
    args = parser.parse_args()
    base = env_config(api.validate_spec(args.spec))
    if not base.task.carries_object:
        parser.error(f"{args.spec} is not a transport spec (env.task.name: transport)")
    for scale in args.torque_scale:
        grip = base.task.grip * base.sim.torque_scale / scale
        for steps in args.steps_per_action or [base.sim.steps_per_action]:
            sim = dataclasses.replace(base.sim, torque_scale=scale, steps_per_action=steps)
            config = dataclasses.replace(
                base,
                sim=sim,
                task=dataclasses.replace(base.task, grip=grip),
                episode_duration=args.duration,
            )
            for noise in args.noise:
                for offset in args.offset:
                    held = hold_times(config, args.envs, noise, offset)
                    print(
                        f"{scale:g} N·m per unit (grip {grip:.3g}), control step "
                        f"{sim.control_dt * 1e3:g} ms, noise {noise:g}, offset ±{offset:g}: "
                        f"held median {np.median(held):.2f} s "
                        f"({held.min():.2f}–{held.max():.2f} s)",
                        flush=True,
                    )
        values = [0.01, 0.03, 0.1, 0.3, 1.0]
        moved = reach(scale, values)
        print(
            f"{scale:g} N·m per unit: tip moved in 2 s by "
            + ", ".join(f"{d:.2f} m at {v:g}" for v, d in zip(values, moved, strict=True))
        )


if __name__ == "__main__":
    main()
