"""Training throughput of the study's TD3 setting, per backend, with the time split.

The setting: TD3, actor and critics [64, 64] ReLU, batch 128, one gradient step per
environment step (``n_envs`` environments per vector step and ``gradient_steps = n_envs``),
Gaussian exploration noise 0.1, the default physics, random target. Each backend trains the same
model through softtrack's own factory (what ``softtrack train`` runs) after a warm-up, and the
same number of environment steps is then timed for the environment alone (random actions) and
for the physics alone (the rod engine), so the time splits into physics, environment layer and
learning (policy inference, replay buffer, gradient updates). Run on one core:

    taskset -c 0 .venv/bin/python benchmarks/bench_training.py

Prints environment steps/s per backend, the split, and the projected time of the study's
budget of 1e7 environment steps (the study: 8.5 h on a laptop i7 + RTX 4070).
"""

from __future__ import annotations

import argparse
import importlib.util
import time

import numpy as np

from softtrack.rl.factory import build_model, make_vec_env
from softtrack.sim import RodBatch
from softtrack.spec import ExperimentSpec
from softtrack.spec.env_config import env_config
from softtrack.store.provenance import cpu_description

STUDY_BUDGET = 10_000_000
STUDY_HOURS = 8.5


def study_spec(backend: str, n_envs: int) -> ExperimentSpec:
    """The study's TD3 with one gradient step per environment step."""
    return ExperimentSpec.model_validate({
        "name": f"bench-{backend}",
        "algo": {"name": "td3", "backend": backend, "learning_starts": 2000,
                 "buffer_size": 200_000, "train_freq": 1, "gradient_steps": n_envs,
                 "device": "cpu"},
        "training": {"n_envs": n_envs, "total_timesteps": 10_000_000, "torch_threads": 1},
    })


def time_learning(spec: ExperimentSpec, steps: int) -> float:
    """Seconds for ``steps`` environment steps of training, after the warm-up."""
    env = make_vec_env(spec)
    model = build_model(spec, env, seed=0)
    model.learn(spec.algo.learning_starts + 2 * spec.training.n_envs * 100)  # + JIT compile
    start = time.perf_counter()
    model.learn(steps, reset_num_timesteps=False)
    return time.perf_counter() - start


def time_environment(spec: ExperimentSpec, steps: int) -> tuple[float, float]:
    """(environment, physics-only) seconds for ``steps`` environment steps, random actions."""
    n_envs = spec.training.n_envs
    env = make_vec_env(spec)
    env.reset()
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(64, n_envs, 24)).astype(np.float32)
    start = time.perf_counter()
    for k in range(steps // n_envs):
        env.step(actions[k % 64])
    env_seconds = time.perf_counter() - start
    engine = RodBatch(n_envs, env_config(spec).sim)
    controls = actions.astype(np.float64).reshape(64, n_envs, 2, 2, 6)
    start = time.perf_counter()
    for k in range(steps // n_envs):
        engine.set_actions(controls[k % 64])
        engine.advance()
    return env_seconds, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=16_000, help="timed environment steps")
    parser.add_argument("--n-envs", type=int, default=8, help="environments per vector step")
    args = parser.parse_args()
    backends = ["sb3"] + (["sbx"] if importlib.util.find_spec("sbx") else [])
    print(f"TD3 [64, 64], batch 128, one gradient step per env step, {args.n_envs} envs, "
          f"{args.steps:,} timed env steps after warm-up; CPU: {cpu_description()}")
    for backend in backends:
        spec = study_spec(backend, args.n_envs)
        total = time_learning(spec, args.steps)
        env_s, physics_s = time_environment(spec, args.steps)
        rate = args.steps / total
        hours = STUDY_BUDGET / rate / 3600
        print(f"  {backend}: {rate:7,.0f} env steps/s   physics {physics_s / total:5.1%}  "
              f"environment {(env_s - physics_s) / total:5.1%}  learning "
              f"{(total - env_s) / total:5.1%}   1e7 steps in {hours:4.2f} h "
              f"(study: {STUDY_HOURS} h, {STUDY_HOURS / hours:4.1f}× faster)")


if __name__ == "__main__":
    main()
