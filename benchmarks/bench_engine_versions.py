"""The engine of this checkout against the engine of another commit, side by side.

Each measurement runs in a child process that imports ``softtrack`` from one of the two trees
(the other commit's ``softtrack/`` is extracted with ``git archive`` into a temporary folder);
the children of the two versions alternate (A B, B A, ...), ``--rounds`` times, so the
machine's load affects both alike. Each child warms up (numba compilation or cache load), then times
``--repeats`` runs of the scenes of ``bench_engine.py``: one environment stepped a control step
(10 integration steps) per call, a batch of 64 with random actions, the same batch pressed
together with rod–rod contact, and the sphere held with contact and gravity. Run on one core:

    taskset -c 0 .venv/bin/python benchmarks/bench_engine_versions.py 1758733

Prints, per scene, the median integration steps/s (both arms) of each version and the median
over the rounds of their ratio (this checkout / the other), with the lowest and highest round.
The same code in two folders gives ratios of 0.95-1.04 on this shared machine (6 rounds): the
noise a comparison has to beat.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCENES = ("single", "batch", "contact", "sphere")


def _measure(scene: str, repeats: int, control_steps: int, batch: int) -> list[float]:
    """Steps/s of ``repeats`` timed runs of ``scene`` in this process's softtrack."""
    import numpy as np
    from bench_engine import _timed, holding_torques, make_softtrack_runner, scene_torques

    from softtrack.sim import SimParams
    from softtrack.sim.params import CONTACT_ON
    from softtrack.sim.sphere import SphereParams

    rng = np.random.default_rng(0)
    steps_per_action = SimParams().steps_per_action
    n_envs = 1 if scene == "single" else batch
    calls = control_steps if scene == "single" else max(control_steps // batch, 5)
    if scene in ("single", "batch"):
        params, torques = SimParams(), scene_torques("random", SimParams(), rng)
    elif scene == "contact":
        params, torques = SimParams(**CONTACT_ON), scene_torques("pressed", SimParams(), rng)
    else:
        params = SimParams(**CONTACT_ON, gravity=9.81, sphere=SphereParams())
        torques = holding_torques(SimParams())
    run = make_softtrack_runner(params, torques, n_envs, calls)
    run()  # warm-up
    n_steps = calls * steps_per_action * n_envs
    return [n_steps / _timed(run) for _ in range(repeats)]


def _extract(ref: str, into: Path) -> Path:
    """``softtrack/`` of commit ``ref`` under ``into`` (or ``ref`` itself: a folder that holds
    a ``softtrack/`` package, e.g. a variant under test)."""
    if (Path(ref) / "softtrack").is_dir():
        return Path(ref)
    archive = subprocess.run(
        ["git", "-C", str(REPO), "archive", "--format=tar", ref, "softtrack"],
        check=True,
        capture_output=True,
    ).stdout
    with tarfile.open(fileobj=BytesIO(archive)) as tar:
        tar.extractall(into, filter="data")
    return into


def _child(tree: Path, args: argparse.Namespace) -> dict[str, list[float]]:
    env = {**os.environ, "PYTHONPATH": str(tree), "PYTHONDONTWRITEBYTECODE": "1"}
    command = [
        sys.executable,
        str(Path(__file__).resolve()),
        "--child",
        "--repeats",
        str(args.repeats),
        "--control-steps",
        str(args.control_steps),
        "--batch",
        str(args.batch),
    ]
    done = subprocess.run(command, env=env, check=True, capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "base", nargs="?", default="HEAD", help="the other commit, or a folder with softtrack/"
    )
    parser.add_argument("--rounds", type=int, default=5, help="child processes per version")
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per scene and child")
    parser.add_argument("--control-steps", type=int, default=200)
    parser.add_argument("--batch", type=int, default=64)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        rates = {s: _measure(s, args.repeats, args.control_steps, args.batch) for s in SCENES}
        print(json.dumps(rates))
        return

    from softtrack.store.provenance import cpu_description

    with tempfile.TemporaryDirectory(prefix="softtrack-base-") as folder:
        base_tree = _extract(args.base, Path(folder))
        trees = {"this checkout": REPO, args.base: base_tree}
        medians: dict[str, dict[str, list[float]]] = {
            name: {s: [] for s in SCENES} for name in trees
        }
        for round_ in range(args.rounds):
            order = list(trees.items())  # A B, B A, A B, ...: a drifting load favours neither
            for name, tree in order if round_ % 2 == 0 else order[::-1]:
                rates = _child(tree, args)
                for scene in SCENES:
                    medians[name][scene].append(statistics.median(rates[scene]))
            print(f"round {round_ + 1}/{args.rounds} done", file=sys.stderr)
    here, there = medians["this checkout"], medians[args.base]
    print(
        f"integration steps/s (both arms), median over {args.rounds} alternating child "
        f"processes of the median of {args.repeats} runs; CPU: {cpu_description()}"
    )
    print(
        f"  {'scene':10} {'this checkout':>14} {args.base[:12]:>14}   ratio [lowest, highest round]"
    )
    for scene in SCENES:
        ratios = [a / b for a, b in zip(here[scene], there[scene], strict=True)]
        print(
            f"  {scene:10} {statistics.median(here[scene]):14,.0f} "
            f"{statistics.median(there[scene]):14,.0f}   {statistics.median(ratios):.3f} "
            f"[{min(ratios):.3f}, {max(ratios):.3f}]"
        )


if __name__ == "__main__":
    main()
