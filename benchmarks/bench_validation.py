"""What validation costs against training, before and after running it as one batch.

A run with ``training.validation_episodes: K`` and ``validation_trajectories`` validates every
``checkpoint_interval`` env steps: K random-target episodes and one episode per evaluation
trajectory of its model. Before (sessions up to 21), the K episodes ran as one batch with one
policy call per episode and control step, and the trajectories one after the other; now
(:func:`softtrack.rl.validation.checkpoint_rows`) all of them run as one batch of the engine
with one policy call per control step. This benchmark times, interleaved in ``--repeats``
rounds on the model of a shipped run:

* ``before``: the random episodes (``run_episodes``, one observation per policy call) and then
  each trajectory alone (``run_episode``);
* ``after``: ``checkpoint_rows`` with the batched policy;
* ``training``: ``--train-steps`` env steps of the run's spec trained from scratch after a
  warm-up (``bench_training.time_learning``), scaled to one checkpoint interval;

and prints the medians, each validation's share of the training time of one interval (issue
63's target: ≤ 10 %), and how far the batched policy's numbers are from one observation per
call (the rounding of a batch's matrix products, amplified by the closed loop). Run on one core:

    taskset -c 0 .venv/bin/python benchmarks/bench_validation.py \\
        models/td3-sbx-128-mirror-tta-3e6-seed0 [--repeats 3] [--train-steps 20000] [--paths 16]

``--paths 16`` also times the episodes with 16 held-out paths (``training.validation_paths``)
in one batch of ``VALIDATION_BATCH`` policy rows: through the model's own ``predict`` (sbx, as
until 2026-12-07), through the NumPy actor (:mod:`softtrack.rl.numpy_actor`, validation's
policy since), and the paths alone through the NumPy actor (``validation_episodes: 0``, what a
recipe scoring the paths alone needs).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from softtrack.evaluation import VALIDATION_SEED, metrics_table, run_episode
from softtrack.rl.factory import model_class
from softtrack.rl.numpy_actor import numpy_actor
from softtrack.rl.policy import deterministic_policy, model_paths
from softtrack.rl.validation import VALIDATION_BATCH, checkpoint_rows, held_out_rows
from softtrack.spec import ExperimentSpec
from softtrack.spec.env_config import env_config
from softtrack.store.provenance import cpu_description
from softtrack.store.runs import RunStore

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_time_to_accuracy import throughput_spec
from bench_training import time_learning


def before(model: Any, spec: ExperimentSpec) -> pd.DataFrame:
    """The validation of sessions up to 21: random episodes one observation per call, then
    each trajectory alone."""
    act = deterministic_policy(model)
    config = env_config(spec, None)
    duration = float(spec.training.eval_duration)
    rows = held_out_rows(
        "x", act, config, duration, VALIDATION_SEED, spec.training.validation_episodes, None
    )

    tracked = [
        metrics_table("x", run_episode(act, config, t, duration)).assign(episode=0, seed=0)
        for t in spec.training.eval_trajectories
    ]
    assert rows is not None
    return pd.concat([rows, *tracked], ignore_index=True)


def batched(
    model: Any,
    spec: ExperimentSpec,
    paths: int,
    batch: int,
    random: bool = True,
    numpy: bool = False,
) -> pd.DataFrame:
    """Batched validation: every episode (with ``paths`` held-out paths; without the random
    targets unless ``random``) in batches of ``batch``, one policy call per batch and control
    step, through the NumPy actor if ``numpy`` else the model's ``predict``."""
    act = numpy_actor(model) if numpy else deterministic_policy(model, batches=True)
    assert act is not None, "the NumPy actor runs sbx TD3 actors only"
    rows = checkpoint_rows(
        "x",
        act,
        env_config(spec, None),
        float(spec.training.eval_duration),
        spec.training.validation_episodes if random else 0,
        list(spec.training.eval_trajectories),
        None,
        paths=paths,
        batch=batch,
    )
    assert rows is not None
    return rows


def after(model: Any, spec: ExperimentSpec) -> pd.DataFrame:
    """Today's validation of the run's episodes: one batch, one policy call per control step."""
    return batched(model, spec, 0, VALIDATION_BATCH)


def timed(work: Callable[[], Any]) -> tuple[float, Any]:
    start = time.perf_counter()
    result = work()
    return time.perf_counter() - start, result


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path, help="a centralized run directory with a policy")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--train-steps", type=int, default=20_000)
    parser.add_argument(
        "--paths",
        type=int,
        default=0,
        help="also time the run's episodes with this many held-out paths in one batch of "
        f"{VALIDATION_BATCH} rows: through sbx, through the NumPy actor, and the paths alone",
    )
    args = parser.parse_args(argv)
    record = RunStore(args.run.parent).get_run(args.run.name)
    spec = record.load_spec()
    if spec.controller != "centralized" or spec.training.validation_episodes < 1:
        parser.error(f"{args.run}: needs a centralized run trained with validation")
    model = model_class(spec).load(str(model_paths(record, spec)[0]), device="cpu")
    interval = int(spec.training.checkpoint_interval)
    train_spec = throughput_spec(spec)
    after(model, spec)  # compile and warm up both paths once
    variants: dict[str, Callable[[Any, ExperimentSpec], pd.DataFrame]] = {
        "before": before,
        "after": after,
    }
    if args.paths:
        p, rows = args.paths, VALIDATION_BATCH
        variants[f"with {p} paths, sbx predict"] = lambda m, s: batched(m, s, p, rows)
        variants[f"with {p} paths, NumPy actor"] = lambda m, s: batched(m, s, p, rows, numpy=True)
        variants[f"{p} paths alone, NumPy actor"] = lambda m, s: batched(
            m, s, p, rows, random=False, numpy=True
        )
    times: dict[str, list[float]] = {name: [] for name in (*variants, "training")}
    results: dict[str, pd.DataFrame] = {}
    for round_ in range(args.repeats):
        for name, work in variants.items():
            seconds, results[name] = timed(lambda w=work: w(model, spec))
            times[name].append(seconds)
        seconds = time_learning(train_spec, args.train_steps) * interval / args.train_steps
        times["training"].append(seconds)
        timings = ", ".join(f"{name} {times[name][-1]:.2f} s" for name in variants)
        print(
            f"round {round_ + 1}/{args.repeats}: {timings}, training of {interval:,} env steps "
            f"{times['training'][-1]:.1f} s",
            flush=True,
        )
    median = {name: statistics.median(values) for name, values in times.items()}
    episodes = spec.training.validation_episodes + len(spec.training.eval_trajectories)
    print(
        f"\n{record.info.name} ({record.run_id}), {episodes} episodes of "
        f"{spec.training.eval_duration:g} s per checkpoint, every {interval:,} env steps; "
        f"{cpu_description()}; medians of {args.repeats}:"
    )
    print("| validation | seconds per checkpoint | share of training time |")
    print("|---|---|---|")
    for name in variants:
        print(f"| {name} | {median[name]:.2f} | {median[name] / median['training']:.1%} |")
    print(
        f"training of {interval:,} env steps: {median['training']:.1f} s; after/before = "
        f"{median['after'] / median['before']:.3f} ({median['before'] / median['after']:.1f}x "
        "faster)"
    )
    old, new = (
        results[k].set_index(["trajectory", "episode", "arm"])["rmse_3d"]
        for k in ("before", "after")
    )
    gap = ((new - old).abs() / old).to_numpy()
    print(
        f"3-D RMSE of the batched policy against one observation per call: largest relative "
        f"difference {np.nanmax(gap):.2e}, median {np.nanmedian(gap):.2e}; "
        f"{int((new == old).sum())} of {len(gap)} episode-arm cells bit for bit equal"
    )


if __name__ == "__main__":
    main()
