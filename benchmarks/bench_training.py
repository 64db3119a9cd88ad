"""Training throughput of the study's TD3 setting, per backend, with the time split, and of
learner variants side by side with today's sbx setting.

The setting: TD3, actor and critics [64, 64] ReLU, batch 128, one gradient step per
environment step (``n_envs`` environments per vector step and ``gradient_steps = n_envs``),
Gaussian exploration noise 0.1, the default physics, random target. Each backend trains the same
model through softtrack's own factory (what ``softtrack train`` runs) after a warm-up, and the
same number of environment steps is then timed for the environment alone (random actions) and
for the physics alone (the rod engine), so the time splits into physics, environment layer and
learning (policy inference, replay buffer, gradient updates).

Learning is compute-bound, so the variants (:data:`VARIANTS`) time what each lever of the sbx
learner buys against today's setting (``study_spec("sbx", 8)``, variant ``today``): gradient
steps per jitted ``train()`` call at the same update-to-data ratio (UTD, gradient steps per
env step), batch size against UTD at equal samples per env step, the second core for XLA's
intra-op thread pool, and the widths of the time-to-accuracy work with mirror replay. Each
measurement runs in its own subprocess (XLA reads its flags and sizes its thread pool when jax
starts), pinned to ``cores`` CPUs (default 1: the first CPU this process may use); the variants
run interleaved in ``--repeats`` rounds (A B C ... A B C ...). Whether float32 holds throughout
(spaces, replay buffer, the batch sbx passes to its jitted update, network parameters) is
checked, not timed. Run on one core:

    taskset -c 0 .venv/bin/python benchmarks/bench_training.py [--steps 8000] [--repeats 3]
        [--variants today,gs32-per-call,2-cores]

Prints environment steps/s per backend, the split, and the projected time of the study's
budget of 1e7 environment steps (the study: 8.5 h on a laptop i7 + RTX 4070); then the float32
check; then each round's env steps/s per variant and a table of the variants: gradient steps
per jit call, UTD, samples per env step, cores, median env steps/s and its ratio to today's
median (``today`` is always run: it is the reference).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from softtrack.rl.factory import build_model, make_vec_env
from softtrack.sim import RodBatch
from softtrack.spec import ExperimentSpec
from softtrack.spec.env_config import env_config
from softtrack.store.provenance import cpu_description

STUDY_BUDGET = 10_000_000
STUDY_HOURS = 8.5


def _study_data(backend: str, n_envs: int) -> dict[str, Any]:
    return {
        "name": f"bench-{backend}",
        "algo": {
            "name": "td3",
            "backend": backend,
            "learning_starts": 2000,
            "buffer_size": 200_000,
            "train_freq": 1,
            "gradient_steps": n_envs,
            "device": "cpu",
        },
        "training": {"n_envs": n_envs, "total_timesteps": 10_000_000, "torch_threads": 1},
    }


def study_spec(backend: str, n_envs: int) -> ExperimentSpec:
    """The study's TD3 with one gradient step per environment step."""
    return ExperimentSpec.model_validate(_study_data(backend, n_envs))


def _learn(spec: ExperimentSpec, steps: int) -> tuple[int, float]:
    """(environment steps done, seconds) of training ``steps`` env steps after the warm-up;
    the steps done exceed ``steps`` by up to one rollout (train_freq vector steps)."""
    env = make_vec_env(spec)
    model = build_model(spec, env, seed=0)
    model.learn(spec.algo.learning_starts + 2 * spec.training.n_envs * 100)  # + JIT compile
    before = model.num_timesteps
    start = time.perf_counter()
    model.learn(steps, reset_num_timesteps=False)
    return model.num_timesteps - before, time.perf_counter() - start


def time_learning(spec: ExperimentSpec, steps: int) -> float:
    """Seconds for ``steps`` environment steps of training, after the warm-up."""
    return _learn(spec, steps)[1]


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


def float32_report(spec: ExperimentSpec) -> str:
    """One line: whether every array of the sbx learner is float32, by inspection.

    Checked: the observation and action spaces, the replay buffer's arrays, a sampled batch as
    sbx passes it to its jitted update (``.numpy()`` of the buffer's tensors), the actor's and
    critics' parameters, and ``jax_enable_x64`` (off: jax computes float64 input in float32).
    """
    import jax

    env = make_vec_env(spec)
    model = build_model(spec, env, seed=0)
    model.learn(4 * spec.training.n_envs)  # random warm-up actions only: fills the buffer
    buffer = model.replay_buffer
    batch = buffer.sample(spec.algo.batch_size)
    params = jax.tree_util.tree_leaves(
        (model.policy.actor_state.params, model.policy.qf_state.params)
    )
    dtypes = {
        "observation space": env.observation_space.dtype,
        "action space": env.action_space.dtype,
        "buffer observations": buffer.observations.dtype,
        "buffer next_observations": buffer.next_observations.dtype,
        "buffer actions": buffer.actions.dtype,
        "buffer rewards": buffer.rewards.dtype,
        "batch observations": batch.observations.numpy().dtype,
        "batch actions": batch.actions.numpy().dtype,
        "batch rewards": batch.rewards.numpy().dtype,
        **{f"parameter {i}": leaf.dtype for i, leaf in enumerate(params)},
    }
    wide = sorted(name for name, dtype in dtypes.items() if np.dtype(dtype) != np.float32)
    x64 = bool(jax.config.read("jax_enable_x64"))
    if not wide and not x64:
        return (
            "float32 throughout, not timed: observation/action spaces, replay buffer "
            "(observations, next_observations, actions, rewards), the batch sbx passes "
            f"to its jitted update and all {len(params)} network parameter arrays are "
            "float32; jax_enable_x64 is off"
        )
    return (
        f"not float32: {', '.join(wide) or '-'}; jax_enable_x64 {x64}; softtrack exposes "
        "no dtype setting, so no float32 variant is timed"
    )


@dataclass(frozen=True)
class Variant:
    """A learner setting: spec overrides on top of today's ``study_spec("sbx", 8)``.

    ``algo`` and ``training`` are merged into the spec's sections (``policy_kwargs`` too);
    ``cores`` is the number of CPUs its subprocess may use; ``env`` adds environment
    variables (appended to an inherited value of the same name, e.g. ``XLA_FLAGS``).
    """

    name: str
    about: str
    algo: dict[str, Any] = field(default_factory=dict)
    training: dict[str, Any] = field(default_factory=dict)
    cores: int = 1
    env: dict[str, str] = field(default_factory=dict)

    def spec(self) -> ExperimentSpec:
        """The validated spec (pydantic) of this variant."""
        data = _study_data("sbx", 8)
        data["name"] = f"bench-{self.name}"
        policy = {**data["algo"].get("policy_kwargs", {}), **self.algo.get("policy_kwargs", {})}
        data["algo"] = {**data["algo"], **self.algo, "policy_kwargs": policy}
        data["training"] = {**data["training"], **self.training}
        return ExperimentSpec.model_validate(data)


# train_freq counts vector steps (softtrack/spec/algo_models.py, SB3's TrainFreq "step"): one
# train() call per train_freq × n_envs env steps, so UTD = gradient_steps / (train_freq·n_envs).
VARIANTS: tuple[Variant, ...] = (
    Variant("today", "the study's sbx setting (reference)"),
    Variant(
        "gs1-per-call",
        "n_envs 1, 1 gradient step per train() call",
        algo={"gradient_steps": 1},
        training={"n_envs": 1},
    ),
    Variant(
        "gs32-per-call",
        "train_freq 4 vector steps, 32 gradient steps per call",
        algo={"train_freq": 4, "gradient_steps": 32},
    ),
    Variant(
        "b256-utd0.5",
        "batch 256, 4 gradient steps per 8 env steps",
        algo={"batch_size": 256, "gradient_steps": 4},
    ),
    Variant(
        "b512-utd0.25",
        "batch 512, 2 gradient steps per 8 env steps",
        algo={"batch_size": 512, "gradient_steps": 2},
    ),
    # XLA sizes its intra-op pool from the CPU affinity; the flag is its default, made explicit
    # ("intra_op_parallelism_threads" is TensorFlow's, which XLA_FLAGS silently ignores).
    Variant(
        "2-cores",
        "XLA intra-op threads on 2 cores",
        cores=2,
        env={"XLA_FLAGS": "--xla_cpu_multi_thread_eigen=true"},
    ),
    Variant("64-mirror", "[64, 64] with mirror replay", algo={"mirror_replay": True}),
    Variant(
        "128-mirror",
        "[128, 128] with mirror replay (td3-sbx-128-mirror-val)",
        algo={"mirror_replay": True, "policy_kwargs": {"net_arch": [128, 128]}},
    ),
    Variant(
        "128-mirror-2-cores",
        "[128, 128] with mirror replay, XLA intra-op threads on 2 cores",
        algo={"mirror_replay": True, "policy_kwargs": {"net_arch": [128, 128]}},
        cores=2,
        env={"XLA_FLAGS": "--xla_cpu_multi_thread_eigen=true"},
    ),
)
VARIANT_NAMES = {variant.name: variant for variant in VARIANTS}


def _cpus(count: int) -> set[int]:
    """``count`` CPUs: this process's allowed ones first, then the machine's others."""
    allowed = sorted(os.sched_getaffinity(0))
    others = [cpu for cpu in range(os.cpu_count() or 1) if cpu not in allowed]
    return set((allowed + others)[:count])


def run_variant(variant: Variant, steps: int) -> float:
    """Env steps/s of one timed training of ``variant`` in a fresh subprocess on its cores.

    Raises:
        RuntimeError: the subprocess failed; the message holds the end of its stderr.
    """
    env = dict(os.environ)
    for key, value in variant.env.items():
        env[key] = f"{env[key]} {value}" if env.get(key) else value
    # The child inherits the affinity of the thread that starts it, from its first
    # instruction on (a preexec_fn would fork this multithreaded, jax-running process).
    own = os.sched_getaffinity(0)
    os.sched_setaffinity(0, _cpus(variant.cores))
    try:
        child = subprocess.Popen(
            [
                sys.executable,
                os.path.abspath(__file__),
                "--variant",
                variant.name,
                "--steps",
                str(steps),
            ],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
    finally:
        os.sched_setaffinity(0, own)
    stdout, stderr = child.communicate()
    lines = [line for line in stdout.splitlines() if line.startswith("{")]
    if child.returncode != 0 or not lines:
        raise RuntimeError(f"{variant.name} failed ({child.returncode}): {stderr.strip()[-2000:]}")
    record = json.loads(lines[-1])
    if len(record["cpus"]) != variant.cores:
        print(
            f"\n  {variant.name} ran on CPUs {record['cpus']}, not {variant.cores}", file=sys.stderr
        )
    return float(record["steps"] / record["seconds"])


def compare_variants(variants: list[Variant], steps: int, repeats: int) -> None:
    """Time ``variants`` interleaved in ``repeats`` rounds and print the table (env steps/s)."""
    rates: dict[str, list[float]] = {variant.name: [] for variant in variants}
    print(
        f"\nLearner variants: {steps:,} timed env steps each, one subprocess per measurement, "
        f"{repeats} round(s) A B C ..."
    )
    for round_ in range(repeats):
        print(f"  round {round_ + 1}:", end="", flush=True)
        for k, variant in enumerate(variants):
            comma = "," if k else ""
            try:
                rates[variant.name].append(run_variant(variant, steps))
                print(f"{comma} {variant.name} {rates[variant.name][-1]:,.0f}", end="", flush=True)
            except RuntimeError as error:
                print(f"{comma} {variant.name} failed", end="", flush=True)
                print(f"\n  {error}", file=sys.stderr)
        print()
    medians = {
        name: statistics.median(values) if values else float("nan")
        for name, values in rates.items()
    }
    reference = medians.get("today", float("nan"))
    print(
        f"\n  {'variant':<18} {'grad/call':>9} {'UTD':>5} {'samples/step':>12} {'cores':>5} "
        f"{'env steps/s':>11} {'× today':>8}  setting"
    )
    for variant in variants:
        spec = variant.spec()
        utd = spec.algo.gradient_steps / (spec.algo.train_freq * spec.training.n_envs)
        print(
            f"  {variant.name:<18} {spec.algo.gradient_steps:>9} {utd:>5.2f} "
            f"{utd * spec.algo.batch_size:>12.0f} {variant.cores:>5} "
            f"{medians[variant.name]:>11,.0f} {medians[variant.name] / reference:>8.2f}  "
            f"{variant.about}"
        )
    print(
        "  (medians over the rounds; samples/step = batch × UTD; 2-cores is only meaningful "
        "when the second core is idle)"
    )


def _child(name: str, steps: int) -> None:
    """Subprocess side of :func:`run_variant`: print one JSON line of the timing."""
    done, seconds = _learn(VARIANT_NAMES[name].spec(), steps)
    print(
        json.dumps(
            {
                "variant": name,
                "steps": done,
                "seconds": seconds,
                "cpus": sorted(os.sched_getaffinity(0)),
            }
        )
    )


def _variant_list(text: str) -> list[Variant]:
    names = [name.strip() for name in text.split(",") if name.strip()]
    unknown = [name for name in names if name not in VARIANT_NAMES]
    if unknown:
        raise argparse.ArgumentTypeError(
            f"unknown variant(s) {', '.join(unknown)}; choose from {', '.join(VARIANT_NAMES)}"
        )
    return [VARIANT_NAMES["today"]] * ("today" not in names) + [VARIANT_NAMES[n] for n in names]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--steps", type=int, default=8_000, help="timed environment steps per measurement"
    )
    parser.add_argument(
        "--n-envs",
        type=int,
        default=8,
        help="environments per vector step of the per-backend split",
    )
    parser.add_argument("--repeats", type=int, default=3, help="rounds of the variants")
    parser.add_argument(
        "--variants",
        type=_variant_list,
        default=list(VARIANTS),
        help=f"comma-separated subset of: {', '.join(VARIANT_NAMES)}",
    )
    parser.add_argument("--variant", choices=list(VARIANT_NAMES), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.variant:
        _child(args.variant, args.steps)
        return
    backends = ["sb3"] + (["sbx"] if importlib.util.find_spec("sbx") else [])
    print(
        f"TD3 [64, 64], batch 128, one gradient step per env step, {args.n_envs} envs, "
        f"{args.steps:,} timed env steps after warm-up; CPU: {cpu_description()}"
    )
    for backend in backends:
        spec = study_spec(backend, args.n_envs)
        total = time_learning(spec, args.steps)
        env_s, physics_s = time_environment(spec, args.steps)
        rate = args.steps / total
        hours = STUDY_BUDGET / rate / 3600
        print(
            f"  {backend}: {rate:7,.0f} env steps/s   physics {physics_s / total:5.1%}  "
            f"environment {(env_s - physics_s) / total:5.1%}  learning "
            f"{(total - env_s) / total:5.1%}   1e7 steps in {hours:4.2f} h "
            f"(study: {STUDY_HOURS} h, {STUDY_HOURS / hours:4.1f}× faster)"
        )
    if "sbx" not in backends:
        print("\nsbx is not installed: no float32 check and no learner variants")
        return
    print("\n" + float32_report(study_spec("sbx", 8)))
    compare_variants(args.variants, args.steps, args.repeats)


if __name__ == "__main__":
    main()
