"""Integration steps per second: softtrack's numba engine against PyElastica 1.0.0.

Both simulate the identical SPEC scenario (two clamped 20-element rods, dt = 2e-4 s, the
PyElastica-0.1 damping, random actions held for 10 steps), side by side in one process.
Each measurement is repeated and the median is reported, so the ratio is robust to the noise
of a shared machine. Run on one core:

    taskset -c 0 .venv/bin/python benchmarks/bench_engine.py

Prints steps/s (one step = both arms advanced by dt) for PyElastica, for softtrack with one
environment (stepped one control step = 10 integration steps per call, as an environment
does), and for softtrack with a batch of 64 environments (per environment), plus the ratios,
and the time a warm process spends before its first step (numba cache load).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

import numpy as np

from softtrack.sim import RodBatch, SimParams, actions_to_element_torques


def _median_rate(run_once, n_steps_per_run: int, repeats: int) -> float:
    """Median steps/s over ``repeats`` timed calls of ``run_once``."""
    rates = []
    for _ in range(repeats):
        start = time.perf_counter()
        run_once()
        rates.append(n_steps_per_run / (time.perf_counter() - start))
    return statistics.median(rates)


def bench_pyelastica(params: SimParams, torques: np.ndarray, control_steps: int, repeats: int) -> float:
    from softtrack.sim.pyelastica_backend import PyElasticaDualArm

    sim = PyElasticaDualArm(params)

    def run() -> None:
        for k in range(control_steps):
            sim.set_element_torques(torques[k % len(torques)])
            sim.advance(params.steps_per_action)

    run()  # warm-up (numba compilation of PyElastica's kernels)
    return _median_rate(run, control_steps * params.steps_per_action, repeats)


def bench_softtrack(params: SimParams, torques: np.ndarray, n_envs: int, control_steps: int,
                    repeats: int) -> float:
    """Per-environment integration steps/s of a batch of ``n_envs``."""
    batch = RodBatch(n_envs, params)
    tiled = np.broadcast_to(torques[:, None], (len(torques), n_envs) + torques.shape[1:]).copy()

    def run() -> None:
        for k in range(control_steps):
            batch.set_element_torques(tiled[k % len(tiled)])
            batch.advance()

    run()
    return _median_rate(run, control_steps * params.steps_per_action * n_envs, repeats)


def warm_start_seconds() -> float:
    """Seconds a fresh process spends importing softtrack and taking its first step."""
    code = (
        "import time; t=time.perf_counter();"
        "from softtrack.sim import RodBatch; b=RodBatch(1); b.advance(1);"
        "print(time.perf_counter()-t)"
    )
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)  # fills cache
    runs = [float(subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                                 text=True).stdout) for _ in range(3)]
    return statistics.median(runs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--control-steps", type=int, default=200,
                        help="control steps (of 10 integration steps) per timed run")
    parser.add_argument("--repeats", type=int, default=7, help="timed runs per measurement")
    parser.add_argument("--batch", type=int, default=64, help="environments in the batch")
    args = parser.parse_args()

    params = SimParams()
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.3, 0.3, size=(50, params.n_arms, 2, 6))
    torques = actions_to_element_torques(actions, params.n_elem, params.torque_scale)

    pyelastica = bench_pyelastica(params, torques, args.control_steps, args.repeats)
    single = bench_softtrack(params, torques, 1, args.control_steps, args.repeats)
    batch = bench_softtrack(params, torques, args.batch, max(args.control_steps // args.batch, 5),
                            args.repeats)
    warm = warm_start_seconds()

    print("integration steps/s (both arms, dt = 2e-4 s), median of", args.repeats, "runs")
    print(f"  PyElastica 1.0.0          {pyelastica:12,.0f}   ({1e6 / pyelastica:6.2f} µs/step)")
    print(f"  softtrack, 1 env          {single:12,.0f}   ({1e6 / single:6.2f} µs/step)"
          f"   {single / pyelastica:5.1f}× PyElastica")
    print(f"  softtrack, {args.batch} envs, per env {batch:9,.0f}   ({1e6 / batch:6.2f} µs/step)"
          f"   {batch / pyelastica:5.1f}× PyElastica")
    print(f"warm start (import + first step, cached compilation): {warm:.2f} s")


if __name__ == "__main__":
    main()
