"""Environment steps per second: the tracking environments against the bare engine.

Measures what the environment layer (action clipping, spline torques, target motion,
observation, reward, termination, info, auto-reset bookkeeping) adds on top of the physics:

  (a) one ``DualArmTrackingEnv`` stepped one control step at a time, against ``RodBatch(1)``
      doing only ``set_actions`` + ``advance()``;
  (b) ``TrackingVecEnv`` with 64 environments (rates per environment), against
      ``RodBatch(64)`` doing only ``set_actions`` + ``advance()``.

Both sides get the same random actions (float32, as a policy emits them) and start from a
reset state in every timed run; env and engine runs alternate so that the noise of a shared
machine hits both alike, and the median of the repeats is reported. Run on one core:

    taskset -c 0 .venv/bin/python benchmarks/bench_env.py

Prints control steps/s (one control step = 10 integration steps of both arms) for each pair
and the environment-layer overhead (env time − engine time) / engine time; the target for
the batched case is < 25 %.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np

from softtrack.env import DualArmTrackingEnv, make_config
from softtrack.env.vec_env import TrackingVecEnv
from softtrack.sim import RodBatch
from softtrack.store.provenance import cpu_description


def _timed(setup: Callable[[], None], run: Callable[[], None]) -> float:
    """Seconds of one call of ``run`` after an untimed ``setup``."""
    setup()
    start = time.perf_counter()
    run()
    return time.perf_counter() - start


def _compare(
    env_pair: tuple[Callable[[], None], Callable[[], None]],
    engine_pair: tuple[Callable[[], None], Callable[[], None]],
    repeats: int,
) -> tuple[float, float]:
    """Median seconds per run of the env and of the engine, measured alternately."""
    _timed(*env_pair)  # warm-up (numba cache load, first-call allocations)
    _timed(*engine_pair)
    env_times, engine_times = [], []
    for _ in range(repeats):
        env_times.append(_timed(*env_pair))
        engine_times.append(_timed(*engine_pair))
    return statistics.median(env_times), statistics.median(engine_times)


def bench_single(actions: np.ndarray, steps: int, repeats: int, target: str) -> tuple[float, float]:
    """(env, engine) control steps/s of one environment stepped one control step per call."""
    env = DualArmTrackingEnv(target=target)
    engine = RodBatch(1, env.config.sim)
    controls = np.clip(actions.astype(np.float64), -1.0, 1.0).reshape(len(actions), 1, 2, 2, 6)
    n = len(actions)

    def env_setup() -> None:
        env.reset(seed=0)

    def env_run() -> None:
        step = env.step
        for k in range(steps):
            step(actions[k % n])

    def engine_run() -> None:
        set_actions, advance = engine.set_actions, engine.advance
        for k in range(steps):
            set_actions(controls[k % n])
            advance()

    env_s, engine_s = _compare((env_setup, env_run), (engine.reset, engine_run), repeats)
    return steps / env_s, steps / engine_s


def bench_batch(
    actions: np.ndarray, n_envs: int, steps: int, repeats: int, target: str
) -> tuple[float, float]:
    """(env, engine) control steps/s per environment of a batch of ``n_envs``."""
    venv = TrackingVecEnv(n_envs, make_config(target=target))
    engine = RodBatch(n_envs, venv.config.sim)
    # one (n_envs, 24) action per control step; environment i gets its own random row
    batched = np.stack([np.roll(actions, i, axis=0) for i in range(n_envs)], axis=1)
    controls = np.clip(batched.astype(np.float64), -1.0, 1.0).reshape(len(actions), n_envs, 2, 2, 6)
    n = len(actions)

    def env_setup() -> None:
        venv.seed(0)
        venv.reset()

    def env_run() -> None:
        step = venv.step
        for k in range(steps):
            step(batched[k % n])

    def engine_run() -> None:
        set_actions, advance = engine.set_actions, engine.advance
        for k in range(steps):
            set_actions(controls[k % n])
            advance()

    env_s, engine_s = _compare((env_setup, env_run), (engine.reset, engine_run), repeats)
    return steps * n_envs / env_s, steps * n_envs / engine_s


def _row(label: str, rate: float) -> str:
    return f"  {label:<34}{rate:12,.0f} steps/s   ({1e6 / rate:7.2f} µs/step)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--single-steps",
        type=int,
        default=2000,
        help="control steps per timed run of the single environment",
    )
    parser.add_argument(
        "--batch-steps", type=int, default=100, help="control steps per timed run of the batch"
    )
    parser.add_argument("--batch", type=int, default=64, help="environments in the batch")
    parser.add_argument("--repeats", type=int, default=7, help="timed runs per measurement (≥ 5)")
    parser.add_argument(
        "--target", default="random", help="target mode (random: the training setting)"
    )
    args = parser.parse_args()
    if args.repeats < 5:
        parser.error("--repeats must be ≥ 5")

    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.3, 0.3, size=(50, 24)).astype(np.float32)

    env1, engine1 = bench_single(actions, args.single_steps, args.repeats, args.target)
    envb, engineb = bench_batch(actions, args.batch, args.batch_steps, args.repeats, args.target)

    print(
        f"control steps/s (10 integration steps of both arms each), target={args.target}, "
        f"median of {args.repeats} runs; CPU: {cpu_description()}"
    )
    for label, env_rate, engine_rate in (
        ("1 env", env1, engine1),
        (f"{args.batch} envs, per env", envb, engineb),
    ):
        overhead = (1.0 / env_rate - 1.0 / engine_rate) / (1.0 / engine_rate)
        print(f"{label}:")
        print(_row("engine alone (set_actions+advance)", engine_rate))
        env_name = "DualArmTrackingEnv.step" if label == "1 env" else "TrackingVecEnv.step"
        print(_row(env_name, env_rate))
        print(
            f"  environment-layer overhead        {100.0 * overhead:11.1f} %"
            f"   (+{1e6 / env_rate - 1e6 / engine_rate:.2f} µs/step)"
        )


if __name__ == "__main__":
    main()
