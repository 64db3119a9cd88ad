"""Integration steps per second: softtrack's numba engine against PyElastica 1.0.0.

Both simulate the identical study scenario (two clamped 20-element rods, dt = 2e-4 s, the
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
from softtrack.store.provenance import cpu_description


def _timed(run_once) -> float:
    start = time.perf_counter()
    run_once()
    return time.perf_counter() - start


def make_pyelastica_runner(params: SimParams, torques: np.ndarray, control_steps: int):
    """A function integrating PyElastica for ``control_steps`` control steps."""
    from softtrack.sim.pyelastica_backend import PyElasticaDualArm

    sim = PyElasticaDualArm(params)

    def run() -> None:
        for k in range(control_steps):
            sim.set_element_torques(torques[k % len(torques)])
            sim.advance(params.steps_per_action)

    return run


def make_softtrack_runner(params: SimParams, torques: np.ndarray, n_envs: int, control_steps: int):
    """A function integrating a batch of ``n_envs`` for ``control_steps`` control steps."""
    batch = RodBatch(n_envs, params)
    tiled = np.broadcast_to(torques[:, None], (len(torques), n_envs) + torques.shape[1:]).copy()

    def run() -> None:
        for k in range(control_steps):
            batch.set_element_torques(tiled[k % len(tiled)])
            batch.advance()

    return run


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
    parser.add_argument("--repeats", type=int, default=11, help="timed runs per measurement")
    parser.add_argument("--batch", type=int, default=64, help="environments in the batch")
    args = parser.parse_args()

    params = SimParams()
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.3, 0.3, size=(50, params.n_arms, 2, 6))
    torques = actions_to_element_torques(actions, params.n_elem, params.torque_scale)

    steps = params.steps_per_action
    batch_control_steps = max(args.control_steps // args.batch, 5)
    runners = {
        "pyelastica": (make_pyelastica_runner(params, torques, args.control_steps),
                       args.control_steps * steps),
        "single": (make_softtrack_runner(params, torques, 1, args.control_steps),
                   args.control_steps * steps),
        "batch": (make_softtrack_runner(params, torques, args.batch, batch_control_steps),
                  batch_control_steps * steps * args.batch),
    }
    for run, _ in runners.values():
        run()  # warm-up: compilation and caches
    # Interleaved repeats: each repeat times all three back to back, so the machine's load
    # affects them alike; ratios are taken within a repeat, then the median over repeats.
    rates: dict[str, list[float]] = {name: [] for name in runners}
    for _ in range(args.repeats):
        for name, (run, n_steps) in runners.items():
            rates[name].append(n_steps / _timed(run))
    pyelastica = statistics.median(rates["pyelastica"])
    single = statistics.median(rates["single"])
    batch = statistics.median(rates["batch"])
    single_ratio = statistics.median(s / p for s, p in zip(rates["single"], rates["pyelastica"]))
    batch_ratio = statistics.median(b / p for b, p in zip(rates["batch"], rates["pyelastica"]))
    warm = warm_start_seconds()

    print("integration steps/s (both arms, dt = 2e-4 s), median of", args.repeats,
          "interleaved runs; ratios are medians of per-run ratios; CPU:", cpu_description())
    print(f"  PyElastica 1.0.0          {pyelastica:12,.0f}   ({1e6 / pyelastica:6.2f} µs/step)")
    print(f"  softtrack, 1 env          {single:12,.0f}   ({1e6 / single:6.2f} µs/step)"
          f"   {single_ratio:5.1f}× PyElastica")
    print(f"  softtrack, {args.batch} envs, per env {batch:9,.0f}   ({1e6 / batch:6.2f} µs/step)"
          f"   {batch_ratio:5.1f}× PyElastica")
    print(f"warm start (import + first step, cached compilation): {warm:.2f} s")


if __name__ == "__main__":
    main()
