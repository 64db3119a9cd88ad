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

Then the same with rod-rod contact between the arms on (``CONTACT_ON``: PyElastica's
``RodRodContact`` against softtrack's contact stage) in two scenes: the random actions above,
with which the arms touch now and then, and the arms pressed together (every normal control
value pushing toward the other arm, ±0.15 with noise), where they touch along their length
at every step. Each contact row gives its cost against the contact-free step of the same
batch size, measured in the same interleaved repeats.

Last, the scene with an object (``--no-object`` leaves it out): the arms squeeze the default
rigid sphere (``SphereParams()``, PyElastica's ``Sphere`` with ``RodSphereContact`` to each
arm) with a pulsing couple and carry it sideways, gravity and rod–rod contact on; its cost is
against the contact-free step as above.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

import numpy as np

from softtrack.sim import RodBatch, SimParams, actions_to_element_torques
from softtrack.sim.params import CONTACT_ON
from softtrack.sim.sphere import SphereParams
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
    """A function integrating a batch of ``n_envs`` for ``control_steps`` control steps.

    Every run starts from the state reached after 30 control steps of the same torques, so
    repeats time the same motion (the arms' contacts included).
    """
    batch = RodBatch(n_envs, params)
    tiled = np.broadcast_to(torques[:, None], (len(torques), n_envs, *torques.shape[1:])).copy()
    for k in range(30):
        batch.set_element_torques(tiled[k % len(tiled)])
        batch.advance()
    start = batch.get_state()

    def run() -> None:
        batch.set_state(start)
        for k in range(control_steps):
            batch.set_element_torques(tiled[k % len(tiled)])
            batch.advance()

    return run


def holding_torques(params: SimParams) -> np.ndarray:
    """(50, 2, 2, N) element torques, N·m, over 1 s: the arms bend toward each other with a
    couple pulsing between 0.3 and 3.3 N·m (1 Hz) and sway together along z (±2 N·m)."""
    times = np.arange(50) * 0.02
    torques = np.zeros((50, 2, 2, params.n_elem))
    press = 1.5 * (1.2 + np.sin(2.0 * np.pi * times))
    torques[:, 0, 0] = -press[:, None]
    torques[:, 1, 0] = press[:, None]
    torques[:, :, 1] = 2.0 * np.sin(np.pi * times)[:, None, None]
    return torques


def scene_torques(scene: str, params: SimParams, rng: np.random.Generator) -> np.ndarray:
    """(50, A, 2, N) element torques, N·m: ``random`` actions in ±0.3, or ``pressed``: every
    normal control value curling each arm toward the other (±0.15, noise ±0.05)."""
    if scene == "random":
        actions = rng.uniform(-0.3, 0.3, size=(50, params.n_arms, 2, 6))
    else:
        actions = rng.uniform(-0.05, 0.05, size=(50, params.n_arms, 2, 6))
        actions[:, 0, 0] += -0.15  # arm 1 (x < 0) curls toward +x
        actions[:, 1, 0] += 0.15
    return actions_to_element_torques(actions, params.n_elem, params.torque_scale)


def interleaved_rates(runners: dict, repeats: int) -> dict[str, list[float]]:
    """Steps/s of every runner in each of ``repeats`` interleaved rounds (each round times all
    runners back to back, so the machine's load affects them alike)."""
    for run, _ in runners.values():
        run()  # warm-up: compilation and caches
    rates: dict[str, list[float]] = {name: [] for name in runners}
    for _ in range(repeats):
        for name, (run, n_steps) in runners.items():
            rates[name].append(n_steps / _timed(run))
    return rates


def median_ratio(a: list[float], b: list[float]) -> float:
    """Median over the rounds of a/b."""
    return statistics.median(x / y for x, y in zip(a, b, strict=True))


def warm_start_seconds() -> float:
    """Seconds a fresh process spends importing softtrack and taking its first step."""
    code = (
        "import time; t=time.perf_counter();"
        "from softtrack.sim import RodBatch; b=RodBatch(1); b.advance(1);"
        "print(time.perf_counter()-t)"
    )
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)  # fills cache
    runs = [
        float(
            subprocess.run(
                [sys.executable, "-c", code], check=True, capture_output=True, text=True
            ).stdout
        )
        for _ in range(3)
    ]
    return statistics.median(runs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--control-steps",
        type=int,
        default=200,
        help="control steps (of 10 integration steps) per timed run",
    )
    parser.add_argument("--repeats", type=int, default=11, help="timed runs per measurement")
    parser.add_argument("--batch", type=int, default=64, help="environments in the batch")
    parser.add_argument(
        "--no-object", action="store_true", help="leave out the scene with the sphere"
    )
    parser.add_argument(
        "--no-contact", action="store_true", help="leave out the contact-on measurements"
    )
    args = parser.parse_args()

    params = SimParams()
    rng = np.random.default_rng(0)
    torques = scene_torques("random", params, rng)

    steps = params.steps_per_action
    batch_control_steps = max(args.control_steps // args.batch, 5)
    runners = {
        "pyelastica": (
            make_pyelastica_runner(params, torques, args.control_steps),
            args.control_steps * steps,
        ),
        "single": (
            make_softtrack_runner(params, torques, 1, args.control_steps),
            args.control_steps * steps,
        ),
        "batch": (
            make_softtrack_runner(params, torques, args.batch, batch_control_steps),
            batch_control_steps * steps * args.batch,
        ),
    }
    # ratios are taken within a round, then the median over rounds
    rates = interleaved_rates(runners, args.repeats)
    pyelastica = statistics.median(rates["pyelastica"])
    single = statistics.median(rates["single"])
    batch = statistics.median(rates["batch"])
    single_ratio = median_ratio(rates["single"], rates["pyelastica"])
    batch_ratio = median_ratio(rates["batch"], rates["pyelastica"])
    warm = warm_start_seconds()

    print(
        "integration steps/s (both arms, dt = 2e-4 s), median of",
        args.repeats,
        "interleaved runs; ratios are medians of per-run ratios; CPU:",
        cpu_description(),
    )
    print(f"  PyElastica 1.0.0          {pyelastica:12,.0f}   ({1e6 / pyelastica:6.2f} µs/step)")
    print(
        f"  softtrack, 1 env          {single:12,.0f}   ({1e6 / single:6.2f} µs/step)"
        f"   {single_ratio:5.1f}× PyElastica"
    )
    print(
        f"  softtrack, {args.batch} envs, per env {batch:9,.0f}   ({1e6 / batch:6.2f} µs/step)"
        f"   {batch_ratio:5.1f}× PyElastica"
    )
    print(f"warm start (import + first step, cached compilation): {warm:.2f} s")
    if not args.no_contact:
        contact_rows(args, steps, batch_control_steps)
    if not args.no_object:
        object_rows(args, steps, batch_control_steps)


def side_by_side(
    args: argparse.Namespace,
    steps: int,
    batch_control_steps: int,
    scene: SimParams,
    torques: np.ndarray,
) -> dict[str, list[float]]:
    """Steps/s of PyElastica and of softtrack (1 env, ``args.batch`` envs) in ``scene``, and of
    softtrack in the contact-free scene with the same torques, interleaved."""
    free = SimParams()
    runners = {
        "pyelastica": (
            make_pyelastica_runner(scene, torques, args.control_steps),
            args.control_steps * steps,
        ),
        "single-free": (
            make_softtrack_runner(free, torques, 1, args.control_steps),
            args.control_steps * steps,
        ),
        "single": (
            make_softtrack_runner(scene, torques, 1, args.control_steps),
            args.control_steps * steps,
        ),
        "batch-free": (
            make_softtrack_runner(free, torques, args.batch, batch_control_steps),
            batch_control_steps * steps * args.batch,
        ),
        "batch": (
            make_softtrack_runner(scene, torques, args.batch, batch_control_steps),
            batch_control_steps * steps * args.batch,
        ),
    }
    return interleaved_rates(runners, args.repeats)


def print_rows(rates: dict[str, list[float]], pyelastica_label: str, batch: int) -> None:
    """PyElastica's line, then softtrack's for 1 and ``batch`` envs with their speed-up and
    their cost against the contact-free step."""
    pyelastica = statistics.median(rates["pyelastica"])
    print(f"  {pyelastica_label:30s} {pyelastica:8,.0f}   ({1e6 / pyelastica:6.2f} µs/step)")
    for name, label in (("single", "1 env"), ("batch", f"{batch} envs, per env")):
        rate = statistics.median(rates[name])
        cost = median_ratio(rates[f"{name}-free"], rates[name])
        speedup = median_ratio(rates[name], rates["pyelastica"])
        print(
            f"  softtrack, {label:17s}{rate:10,.0f}   ({1e6 / rate:6.2f} µs/step)"
            f"   {speedup:5.1f}× PyElastica   cost {cost:4.2f}× contact-free"
        )


def contact_rows(args: argparse.Namespace, steps: int, batch_control_steps: int) -> None:
    """The contact-on measurements (module docstring), one block per scene."""
    free = SimParams()
    touching = SimParams(**CONTACT_ON)
    print(
        f"with contact (contact_k = {touching.contact_k:g} N/m, contact_nu = "
        f"{touching.contact_nu:g} N·s/m); cost = contact step time / contact-free step time"
    )
    for scene in ("random", "pressed"):
        torques = scene_torques(scene, free, np.random.default_rng(0))
        rates = side_by_side(args, steps, batch_control_steps, touching, torques)
        probe = RodBatch(args.batch, touching)
        tiled = np.broadcast_to(torques[:, None], (50, args.batch, *torques.shape[1:]))
        touched = []
        for k in range(30 + batch_control_steps):
            probe.set_element_torques(tiled[k % 50])
            probe.advance()
            touched.append(probe.contact_state()[1] > 0)
        share = float(np.mean(touched[30:]))
        print(f" scene '{scene}' (arms touching in {100 * share:.0f} % of control steps):")
        print_rows(rates, "PyElastica + RodRodContact", args.batch)


def object_rows(args: argparse.Namespace, steps: int, batch_control_steps: int) -> None:
    """The scene with the sphere (module docstring)."""
    held = SimParams(**CONTACT_ON, gravity=9.81, sphere=SphereParams())
    rates = side_by_side(args, steps, batch_control_steps, held, holding_torques(SimParams()))
    sphere = held.sphere
    assert sphere is not None
    print(
        f"with a sphere held between the arms (R = {sphere.radius:g} m, {sphere.mass:.2f} kg, "
        f"contact_k = {sphere.contact_k:g} N/m, friction {sphere.friction:g}; gravity and "
        "rod–rod contact on):"
    )
    print_rows(rates, "PyElastica + Sphere + contacts", args.batch)


if __name__ == "__main__":
    main()
