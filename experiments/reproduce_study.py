"""Reproduce every run behind ``reports/study/`` and the README's results, then rebuild the report.

    .venv/bin/python experiments/reproduce_study.py            # everything, one run at a time
    .venv/bin/python experiments/reproduce_study.py --jobs 2   # two runs at once, one core each
    .venv/bin/python experiments/reproduce_study.py --list     # what it would do, and budgets
    .venv/bin/python experiments/reproduce_study.py --only ddpg-sbx --report-only
    .venv/bin/python experiments/reproduce_study.py --only td3-sbx-128 --no-report
    .venv/bin/python experiments/reproduce_study.py --robustness --jobs 2   # then the report
                  (the robustness experiments' grids, then every contact-free controller
                  with contact on)

``--only`` takes an experiment name (the spec's ``name``, as in ``models/`` and the report) or
a spec file under ``experiments/`` (``variants/td3-sbx-128-4e6.yaml``); experiments/README.md
lists which file each experiment comes from.

Each job is one (spec, seed). A job whose directory under ``models/`` exists is done. Otherwise
the script looks in the runs directory (``runs/`` or ``--runs-dir``) for a run of the same
experiment, seed and spec: a completed one is exported, an interrupted or lost one is resumed
(`softtrack train --resume`), and without one a new run is trained, unless a completed run of
another experiment trained exactly like it (the same seed and training fields, e.g. the
`softtrack tune` trial whose values the spec took): that run is derived under the job's spec
(:func:`derive_run`) instead of trained again. So the script can be stopped at any time and
started again; a training continues from its last checkpoint.
The ``-confirm`` experiments train exactly like a shipped run and only add a confirmation
after training (``training.confirm_episodes``), so their runs are derived from the shipped
ones once every training is done (:func:`derive_run`), then confirmed.
Finished runs are evaluated with `softtrack evaluate --random 20` (the three trajectories and
20 episodes of the random training target) and exported with `softtrack export` (no
checkpoints or replay buffers); a run of an experiment the report does not draw keeps no
per-step positions (:func:`lean`). The report is then rebuilt from ``models/`` with
`softtrack report ... --runs-dir models --out reports/study --figures-for ...`.

Time on one core of the project's machine (2,000-2,300 env steps/s with the JAX backend):
td3-sbx, td3-sbx-speeds and td3-sbx-arm-bonus ~30 min per seed, td3-sbx-128 ~65 min per seed
(~1,060 env steps/s), td3-sbx-1e7 ~75 min, independent-td3-sbx ~60 min (two arms of 4e6),
independent-td3-sbx-2e6 ~30 min per seed (two arms of 2e6), ddpg-sbx ~6 min per seed (1e6 steps),
ppo-sbx ~8 min per seed (4e6 steps, ~9,000 env steps/s). On the slower CPU of later sessions
(~1/3 of these rates): td3-sbx-per-arm 2.3 h per seed (481 env steps/s), td3-sbx-128-per-arm
3.9 h per seed (~290-380 env steps/s with a second training on the other core),
td3-sbx-per-arm-nets ~380-600 env steps/s in its first 700k steps beside another training.
On the later 2-core AVX-512 machine, two td3-sbx-own-arm-actors seeds side by side: 1.6 h
(686 env steps/s) and 83 min (807 env steps/s, pinned to one core); with --jobs 2,
td3-sbx-per-arm-nets seed 2 81 min (819 env steps/s) beside td3-sbx-128-per-arm seed 2 1.79 h
(620 env steps/s; training clocks as in the report). td3-sbx-128-mirror-val: seeds 0-1 1.72 h
(~645 env steps/s, beside another training) on that machine; seed 2 2.26 h (491 env steps/s)
alone on a 2-core Intel Xeon with AVX-512. Deriving and confirming the -confirm runs there:
11 min for td3-sbx-128-mirror-val-confirm's three seeds, 14 min for
independent-td3-sbx-2e6-val-confirm's (side by side, evaluation included).
"""

from __future__ import annotations

import argparse
import functools
import json
import queue
import shutil
import subprocess
import sys
from collections.abc import Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from softtrack import api
from softtrack.evaluation import EVAL_TRAJECTORIES
from softtrack.evaluation.episode_tables import VALIDATION_SCORED_COLUMNS
from softtrack.report.data import Group, load_runs, representative_run
from softtrack.rl.confirmation import confirm_run
from softtrack.spec import ExperimentSpec, chain_comment, spec_chain, spec_hash, spec_to_yaml
from softtrack.store.atomic import atomic_write_text
from softtrack.store.ids import create_unique_dir
from softtrack.store.provenance import portable_path
from softtrack.store.runs import RunRecord, RunStore, resolve_runs_dir
from softtrack.store.selection import select_one_run
from softtrack.store.tables import read_table, write_table

ROOT = Path(__file__).resolve().parent.parent
SOFTTRACK = [sys.executable, "-m", "softtrack.cli"]
REPORT_DIR = "reports/study"
#: The experiments whose trajectories, errors over time and moments the report draws
#: (`softtrack report --figures-for`): the study protocol, the best centralized variant and the
#: independent baseline selected alike. Only their runs keep ``eval_trajectories`` in models/.
FEATURED = ("td3-sbx-1e7", "td3-sbx-128-mirror-val-confirm", "independent-td3-sbx-2e6-val-confirm")
#: Experiments whose shipped runs keep their per-step tables: the featured ones, and those the
#: report's contact figures draw (clearance and contact force per step); the others drop their
#: ``eval_trajectories`` and ``eval_moments`` (:func:`lean`).
KEEP_STEPS = (
    *FEATURED,
    "td3-sbx-128-mirror-fast-contact",
    "td3-sbx-128-mirror-tta-solid",
    "td3-sbx-128-mirror-fast-viewpoints",
    "mpc-mppi-64x50-contact",
    "mpc-mppi-64x50-viewpoints",
    "td3-sbx-128-mirror-fast-transport",
    "td3-sbx-128-mirror-fast-transport-calm",
    "td3-sbx-128-mirror-fast-transport-grip",
    "mpc-mppi-64x50-transport",
    "mpc-mppi-64x50-transport-grip",
    "td3-sbx-128-mirror-fast-transport-fine-10ms-long",
    "td3-sbx-128-mirror-fast-transport-fine-10ms-long-gravity",
)
RANDOM_EPISODES = 20  # held-out random-target episodes per run (`softtrack evaluate --random`)
#: Experiments no longer shipped in models/ (superseded variants, to keep models/ under 60 MB),
#: with the commit whose tree last holds their runs: `git checkout COMMIT -- models/<dest>`
#: restores one; their numbers stay in docs/results/ and docs/models.md ("Retired runs").
#: Their jobs run only when named with --only, and the report leaves them out.
RETIRED: dict[str, str] = {
    name: "9dcb49c"
    for name in (
        "td3-sbx-128-mirror-fast-contact",
        "independent-td3-sbx-128-fast-contact",
        "td3-sbx-128-mirror-tta-viewpoints",
        "td3-sbx-128-mirror-tta-viewpoints-apart",
        "td3-sbx-128-mirror-fast-transport-fine-10ms-long",
        "td3-sbx-128-mirror-dr-warmup",
        "td3-sbx-128-val",
        "mpc-mppi-64x50-transport-grip",
        "td3-sbx-128-per-arm",
        "td3-sbx-128-mirror-fast-nstep3",
        "td3-sbx-128-mirror-fast-transport-fine-10ms-track",
    )
}


@functools.cache
def load_experiment(spec: str) -> ExperimentSpec:
    """The resolved spec of ``experiments/<spec>`` (its ``base:`` chain merged)."""
    return api.validate_spec(ROOT / "experiments" / spec)


@dataclass(frozen=True)
class Job:
    """One training: the spec file ``experiments/<spec>`` with ``seed``, kept as
    ``models/<dest>``.

    With ``derive_from``, the spec differs from that shipped run's only in what its training
    does not see (:func:`_training_fields`), so its training is that run's: the run is derived from
    ``models/<derive_from>`` (:func:`derive_run`) instead of trained. With ``policy_only``
    the export leaves out the run's other model (``softtrack export --policy-only``).
    """

    spec: str
    seed: int
    dest: str
    derive_from: str | None = None
    policy_only: bool = False

    @property
    def name(self) -> str:
        """The experiment's name (the spec's ``name``: run.json, ``models/``, the report)."""
        return load_experiment(self.spec).name


def seeded_jobs(spec: str, dest: str, seeds: Iterable[int], policy_only: bool = False) -> list[Job]:
    """The jobs of spec file ``experiments/<spec>`` for ``seeds``, kept as
    ``models/<dest>-seed<s>`` (``dest``: the experiment's name and budget, e.g.
    ``td3-sbx-128-mirror-tta-3e6``)."""
    return [Job(spec, s, f"{dest}-seed{s}", policy_only=policy_only) for s in seeds]


S, V = "study/", "variants/"
JOBS: tuple[Job, ...] = (
    *(Job(S + "td3-sbx-64-4e6.yaml", s, f"td3-sbx-4e6-seed{s}") for s in (0, 1, 2)),
    *(Job(S + "td3-sbx-64-1e7.yaml", s, f"td3-sbx-1e7-seed{s}") for s in (0, 1, 2)),
    *(Job(V + "td3-sbx-64-4e6-speeds.yaml", s, f"td3-sbx-speeds-4e6-seed{s}") for s in (0, 1, 2)),
    *(
        Job(V + "td3-sbx-64-4e6-arm-bonus.yaml", s, f"td3-sbx-arm-bonus-4e6-seed{s}")
        for s in (0, 1, 2)
    ),
    *(Job(V + "td3-sbx-128-4e6.yaml", s, f"td3-sbx-128-4e6-seed{s}") for s in (0, 1, 2)),
    Job(V + "td3-sbx-64-4e6-per-arm.yaml", 0, "td3-sbx-per-arm-4e6-seed0"),
    *(
        Job(V + "td3-sbx-128-4e6-per-arm.yaml", s, f"td3-sbx-128-per-arm-4e6-seed{s}")
        for s in (0, 1, 2)
    ),
    *(
        Job(V + "td3-sbx-64-4e6-per-arm-nets.yaml", s, f"td3-sbx-per-arm-nets-4e6-seed{s}")
        for s in (0, 1)
    ),
    Job(V + "td3-sbx-64-4e6-own-arm-actors.yaml", 0, "td3-sbx-own-arm-actors-4e6-seed0"),
    *(
        job
        for s in (0, 1, 2)
        for job in (
            Job(V + "td3-sbx-128-4e6-val.yaml", s, f"td3-sbx-128-val-4e6-seed{s}"),
            Job(
                V + "independent-td3-sbx-64-2e6-val.yaml", s, f"independent-td3-sbx-2e6-val-seed{s}"
            ),
        )
    ),
    Job(S + "independent-td3-sbx-64-4e6.yaml", 0, "independent-td3-sbx-4e6-seed0"),
    *(
        Job(S + "independent-td3-sbx-64-2e6.yaml", s, f"independent-td3-sbx-2e6-seed{s}")
        for s in (0, 1, 2)
    ),
    *(Job(S + "ddpg-sbx-64-1e6.yaml", s, f"ddpg-sbx-1e6-seed{s}") for s in (0, 1, 2)),
    *(Job(S + "ppo-sbx-64-4e6.yaml", s, f"ppo-sbx-4e6-seed{s}") for s in (0, 1, 2)),
    # after the -val runs:
    *(
        Job(V + "td3-sbx-64-4e6-own-arm-actors.yaml", s, f"td3-sbx-own-arm-actors-4e6-seed{s}")
        for s in (1, 2)
    ),
    Job(V + "td3-sbx-64-4e6-per-arm-nets.yaml", 2, "td3-sbx-per-arm-nets-4e6-seed2"),
    *(
        Job(V + "td3-sbx-128-4e6-mirror-val.yaml", s, f"td3-sbx-128-mirror-val-4e6-seed{s}")
        for s in (0, 1, 2)
    ),
    # time to accuracy (1e6 steps, checkpoints tracking the trajectories):
    Job(V + "td3-sbx-64-1e6-mirror-fast.yaml", 0, "td3-sbx-64-mirror-fast-1e6-seed0"),
    Job(
        V + "td3-sbx-128-1e6-mirror-fast-nstep3.yaml", 0, "td3-sbx-128-mirror-fast-nstep3-1e6-seed0"
    ),
    # the time-to-accuracy search's recipe (issue 40): 64 envs, UTD 1/32, 3e6 steps
    *(
        Job(
            V + "td3-sbx-128-3e6-mirror-tta.yaml",
            s,
            f"td3-sbx-128-mirror-tta-3e6-seed{s}",
            policy_only=True,
        )
        for s in (1, 2, 3, 4, 0)
    ),
    # centralized against independent with ten seeds each (issue 40), the tta recipe's budget
    *(
        job
        for s in range(10)
        for job in (
            Job(
                V + "independent-td3-sbx-128-15e5-tta.yaml",
                s,
                f"independent-td3-sbx-128-tta-3e6-seed{s}",
                policy_only=True,
            ),
            *(
                [
                    Job(
                        V + "td3-sbx-128-3e6-mirror-tta.yaml",
                        s,
                        f"td3-sbx-128-mirror-tta-3e6-seed{s}",
                        policy_only=True,
                    )
                ]
                if s >= 5
                else []
            ),
        )
    ),
    *(
        Job(V + "td3-sbx-128-1e6-mirror-fast.yaml", s, f"td3-sbx-128-mirror-fast-1e6-seed{s}")
        for s in (0, 1, 2)
    ),
    *(
        Job(V + "sac-sbx-128-1e6-mirror-fast.yaml", s, f"sac-sbx-128-mirror-fast-1e6-seed{s}")
        for s in (0, 1, 2)
    ),
    *(
        Job(V + "td3-sbx-64-1e6-mirror-tuned.yaml", s, f"td3-sbx-64-mirror-tuned-1e6-seed{s}")
        for s in (0, 1, 2)
    ),
    # smooth actuation and domain randomisation (issue 29):
    *(
        job
        for s in (0, 1, 2)
        for job in (
            Job(
                V + "td3-sbx-128-1e6-mirror-smooth.yaml",
                s,
                f"td3-sbx-128-mirror-smooth-1e6-seed{s}",
            ),
            Job(V + "td3-sbx-128-1e6-mirror-dr.yaml", s, f"td3-sbx-128-mirror-dr-1e6-seed{s}"),
        )
    ),
    Job(
        V + "td3-sbx-128-1e6-mirror-smooth-act2.yaml", 0, "td3-sbx-128-mirror-smooth-act2-1e6-seed0"
    ),
    *(
        Job(V + "td3-sbx-128-1e6-mirror-bounded.yaml", s, f"td3-sbx-128-mirror-bounded-1e6-seed{s}")
        for s in (0, 1, 2)
    ),
    *(
        Job(
            V + "td3-sbx-128-1e6-mirror-dr-warmup.yaml",
            s,
            f"td3-sbx-128-mirror-dr-warmup-1e6-seed{s}",
        )
        for s in (0, 1, 2)
    ),
    # sampling MPC (issue 30; evaluated on the three trajectories only: no --random episodes):
    Job(V + "mpc-mppi-64x50.yaml", 0, "mpc-mppi-64x50-seed0"),
    # arms that touch (issue 37): contact on, the shared target and the viewpoints task
    *(
        job
        for s in (0, 1, 2, 3, 4)
        for job in (
            Job(
                V + "td3-sbx-128-1e6-mirror-fast-contact.yaml",
                s,
                f"td3-sbx-128-mirror-fast-contact-1e6-seed{s}",
            ),
            Job(
                V + "td3-sbx-128-1e6-mirror-fast-viewpoints.yaml",
                s,
                f"td3-sbx-128-mirror-fast-viewpoints-1e6-seed{s}",
            ),
            Job(
                V + "independent-td3-sbx-128-5e5-fast-contact.yaml",
                s,
                f"independent-td3-sbx-128-fast-contact-1e6-seed{s}",
            ),
            Job(
                V + "independent-td3-sbx-128-5e5-fast-viewpoints.yaml",
                s,
                f"independent-td3-sbx-128-fast-viewpoints-1e6-seed{s}",
                policy_only=s >= 2,  # shipped after models/ neared its 100 MB
            ),
        )
    ),
    Job(V + "mpc-mppi-64x50-contact.yaml", 0, "mpc-mppi-64x50-contact-seed0"),
    Job(V + "mpc-mppi-64x50-viewpoints.yaml", 0, "mpc-mppi-64x50-viewpoints-seed0"),
    # two arms carry a sphere (issue 41): the fast recipe on the transport task
    *(
        Job(
            V + "td3-sbx-128-1e6-mirror-fast-transport.yaml",
            s,
            f"td3-sbx-128-mirror-fast-transport-1e6-seed{s}",
        )
        for s in (0, 1, 2)
    ),
    *(
        job
        for s in (0, 1, 2)
        for job in (
            Job(
                V + "td3-sbx-128-1e6-fast-transport-own-arm-actors.yaml",
                s,
                f"td3-sbx-128-fast-transport-own-arm-actors-1e6-seed{s}",
            ),
            Job(
                V + "td3-sbx-128-1e6-mirror-fast-transport-calm.yaml",
                s,
                f"td3-sbx-128-mirror-fast-transport-calm-1e6-seed{s}",
            ),
            Job(
                V + "td3-sbx-128-1e6-mirror-fast-transport-grip.yaml",
                s,
                f"td3-sbx-128-mirror-fast-transport-grip-1e6-seed{s}",
            ),
            Job(
                V + "td3-sbx-128-1e6-mirror-fast-transport-gravity.yaml",
                s,
                f"td3-sbx-128-mirror-fast-transport-gravity-1e6-seed{s}",
            ),
        )
    ),
    # the 10-ms recipe, the first learned controller that carries the sphere, and its
    # independent baseline (own-arm actors)
    *seeded_jobs(
        V + "td3-sbx-128-3e6-mirror-fast-transport-fine-10ms-long.yaml",
        "td3-sbx-128-mirror-fast-transport-fine-10ms-long-3e6",
        (0, 1, 2),
        policy_only=True,
    ),
    *seeded_jobs(
        V + "td3-sbx-128-3e6-mirror-fast-transport-fine-10ms-track.yaml",
        "td3-sbx-128-mirror-fast-transport-fine-10ms-track-3e6",
        (0,),  # one seed: it held the sphere a median 4.8 s (docs/results.md)
        policy_only=True,
    ),
    *seeded_jobs(
        V + "td3-sbx-128-3e6-fast-transport-fine-10ms-long-own-arm-actors.yaml",
        "td3-sbx-128-fast-transport-fine-10ms-long-own-arm-actors-3e6",
        (0, 1, 2),
        policy_only=True,
    ),
    *seeded_jobs(
        V + "td3-sbx-128-3e6-mirror-fast-transport-fine-10ms-long-gravity.yaml",
        "td3-sbx-128-mirror-fast-transport-fine-10ms-long-gravity-3e6",
        (0, 1, 2),
        policy_only=True,
    ),
    *seeded_jobs(
        V + "td3-sbx-128-15e5-mirror-fast-transport-fine-10ms-tuned.yaml",
        "td3-sbx-128-mirror-fast-transport-fine-10ms-tuned-15e5",
        (0, 1, 2),
        policy_only=True,
    ),
    *seeded_jobs(
        V + "td3-sbx-128-3e6-mirror-fast-transport-fine-10ms-reachable.yaml",
        "td3-sbx-128-mirror-fast-transport-fine-10ms-reachable-3e6",
        (0,),
        policy_only=True,
    ),
    *seeded_jobs(
        V + "td3-sbx-128-6e6-mirror-tta-stop-transport-reachable-gs8-lr3e-4.yaml",
        "td3-sbx-128-mirror-tta-stop-transport-reachable-gs8-lr3e-4-6e6",
        (0, 1, 2),
        policy_only=True,
    ),
    # the same with a learning rate falling to 3e-5 over the second half: seed 3 (where the
    # constant rate missed, the lever's screen) and the fresh seeds 8-12 of its claim
    *seeded_jobs(
        V + "td3-sbx-128-6e6-mirror-tta-stop-transport-reachable-gs8-lr3e-4-decay.yaml",
        "td3-sbx-128-mirror-tta-stop-transport-reachable-gs8-lr3e-4-decay-6e6",
        (3, 8, 9, 10, 11, 12),
        policy_only=True,
    ),
    # its independent baseline set up alike (own-arm actors, per-arm critics), seeds 0-4
    *seeded_jobs(
        V + "td3-sbx-128-6e6-tta-stop-transport-reachable-gs8-decay-own-arm.yaml",
        "td3-sbx-128-tta-stop-transport-reachable-gs8-decay-own-arm-6e6",
        range(5),
        policy_only=True,
    ),
    # the same centralized recipe with gravity on, the second row
    *seeded_jobs(
        V + "td3-sbx-128-6e6-mirror-tta-stop-transport-reachable-decay-gravity.yaml",
        "td3-sbx-128-mirror-tta-stop-transport-reachable-decay-gravity-6e6",
        (0, 1),
        policy_only=True,
    ),
    Job(V + "mpc-mppi-64x50-transport.yaml", 0, "mpc-mppi-64x50-transport-seed0"),
    Job(V + "mpc-mppi-64x50-transport-grip.yaml", 0, "mpc-mppi-64x50-transport-grip-seed0"),
    Job(
        V + "mpc-mppi-64x50-transport-fine-10ms.yaml",
        0,
        "mpc-mppi-64x50-transport-fine-10ms-seed0",
    ),
    # the ten-seed comparison with solid arms (contact on, issue 40)
    *seeded_jobs(
        V + "td3-sbx-128-3e6-mirror-tta-solid.yaml",
        "td3-sbx-128-mirror-tta-solid-3e6",
        range(10),
        policy_only=True,
    ),
    # the tta recipe with solid arms on the viewpoints task (issue 37)
    *seeded_jobs(
        V + "td3-sbx-128-3e6-mirror-tta-viewpoints.yaml",
        "td3-sbx-128-mirror-tta-viewpoints-3e6",
        range(5),
        policy_only=True,
    ),
    *seeded_jobs(
        V + "td3-sbx-128-3e6-mirror-tta-viewpoints-apart.yaml",
        "td3-sbx-128-mirror-tta-viewpoints-apart-3e6",
        range(5),
        policy_only=True,
    ),
    *seeded_jobs(
        V + "td3-sbx-128-3e6-mirror-tta-viewpoints-margin.yaml",
        "td3-sbx-128-mirror-tta-viewpoints-margin-3e6",
        range(5),
        policy_only=True,
    ),
    # derived from shipped runs (after all trainings):
    *(
        Job(
            V + "independent-td3-sbx-128-15e5-tta-solid.yaml",
            s,
            f"independent-td3-sbx-128-tta-solid-3e6-seed{s}",
            f"independent-td3-sbx-128-tta-3e6-seed{s}",
            policy_only=True,
        )
        for s in range(10)
    ),
    *(
        Job(
            V + "td3-sbx-128-4e6-mirror-val-confirm.yaml",
            s,
            f"td3-sbx-128-mirror-val-confirm-4e6-seed{s}",
            f"td3-sbx-128-mirror-val-4e6-seed{s}",
        )
        for s in (0, 1, 2)
    ),
    *(
        Job(
            V + "independent-td3-sbx-64-2e6-val-confirm.yaml",
            s,
            f"independent-td3-sbx-2e6-val-confirm-seed{s}",
            f"independent-td3-sbx-2e6-val-seed{s}",
        )
        for s in (0, 1, 2)
    ),
)
REPORTED = (
    "td3-sbx",
    "td3-sbx-1e7",
    "td3-sbx-speeds",
    "td3-sbx-arm-bonus",
    "td3-sbx-128",
    "td3-sbx-per-arm",
    "td3-sbx-128-per-arm",
    "td3-sbx-per-arm-nets",
    "td3-sbx-own-arm-actors",
    "td3-sbx-128-val",
    "td3-sbx-128-mirror-val",
    "td3-sbx-128-mirror-val-confirm",
    "independent-td3-sbx",
    "independent-td3-sbx-2e6",
    "independent-td3-sbx-2e6-val",
    "independent-td3-sbx-2e6-val-confirm",
    "ddpg-sbx",
    "ppo-sbx",
    "td3-sbx-128-mirror-fast",
    "td3-sbx-128-mirror-tta",
    "independent-td3-sbx-128-tta",
    "td3-sbx-64-mirror-fast",
    "sac-sbx-128-mirror-fast",
    "td3-sbx-64-mirror-tuned",
    "td3-sbx-128-mirror-smooth",
    "td3-sbx-128-mirror-smooth-act2",
    "td3-sbx-128-mirror-dr",
    "td3-sbx-128-mirror-bounded",
    "td3-sbx-128-mirror-dr-warmup",
    "mpc-mppi-64x50",
    "td3-sbx-128-mirror-fast-contact",
    "td3-sbx-128-mirror-fast-viewpoints",
    "independent-td3-sbx-128-fast-contact",
    "independent-td3-sbx-128-fast-viewpoints",
    "td3-sbx-128-mirror-tta-solid",
    "independent-td3-sbx-128-tta-solid",
    "mpc-mppi-64x50-contact",
    "mpc-mppi-64x50-viewpoints",
    "mpc-mppi-64x50-transport",
    "mpc-mppi-64x50-transport-grip",
    "mpc-mppi-64x50-transport-fine-10ms",
    "td3-sbx-128-mirror-tta-viewpoints",
    "td3-sbx-128-mirror-tta-viewpoints-apart",
    "td3-sbx-128-mirror-tta-viewpoints-margin",
    "td3-sbx-128-mirror-fast-transport-fine-10ms-long",
    "td3-sbx-128-mirror-fast-transport-fine-10ms-track",
    "td3-sbx-128-fast-transport-fine-10ms-long-own-arm-actors",
    "td3-sbx-128-mirror-fast-transport-fine-10ms-long-gravity",
    "td3-sbx-128-mirror-fast-transport-fine-10ms-tuned",
)

#: The controllers `--robustness` evaluates under perturbations (`softtrack robustness` on their
#: shipped runs): the study protocol, the best variant, the independent baseline, the fast
#: variant (the nominal twin of the smooth, bounded and domain-randomized ones) and those.
ROBUSTNESS = (
    "td3-sbx-1e7",
    "td3-sbx-128-mirror-val-confirm",
    "independent-td3-sbx-2e6-val-confirm",
    "td3-sbx-128-mirror-fast",
    "td3-sbx-128-mirror-smooth",
    "td3-sbx-128-mirror-smooth-act2",
    "td3-sbx-128-mirror-dr",
    "td3-sbx-128-mirror-bounded",
    "td3-sbx-128-mirror-dr-warmup",
)
#: One factor at a time, then the combination a user expects on hardware (one setting).
ROBUSTNESS_GRIDS = (
    (
        "--grid",
        "obs_noise=0.002,0.005,0.01",
        "--grid",
        "action_delay=1,2,4",
        "--grid",
        "youngs_modulus_scale=0.7,1.3",
        "--grid",
        "gravity=on",
        "--grid",
        "torque_scale_factor=0.85",
    ),
    (
        "--full-grid",
        "--grid",
        "youngs_modulus_scale=0.7",
        "--grid",
        "obs_noise=0.005",
        "--grid",
        "action_delay=2",
        "--grid",
        "gravity=on",
    ),
)


def run_robustness(names: list[str], workers: int) -> None:
    """`softtrack robustness` on the shipped runs of ``names`` (experiments of
    :data:`ROBUSTNESS`) with :data:`ROBUSTNESS_GRIDS`; settings already stored are skipped."""
    runs = [
        f"models/{job.dest}"
        for job in JOBS
        if job.name in names and (ROOT / "models" / job.dest).is_dir()
    ]
    if not runs:
        print("robustness: no shipped run of " + ", ".join(names), flush=True)
        return
    for grid in ROBUSTNESS_GRIDS:
        _softtrack("robustness", *runs, *grid, "--workers", str(workers), "--in-place")


def run_contact_robustness(workers: int) -> None:
    """Every shipped trained controller of a contact-free experiment with contact on
    (`softtrack robustness --grid contact=on`: what ghost-trained policies lose when the arms
    are solid); settings already stored are skipped."""
    runs = []
    for job in JOBS:
        path = ROOT / "models" / job.dest
        if (
            path.is_dir()
            and not job.name.startswith("mpc-")
            and load_experiment(job.spec).env.physics.contact_k == 0.0
        ):
            runs.append(f"models/{job.dest}")
    if runs:
        _softtrack(
            "robustness", *runs, "--grid", "contact=on", "--workers", str(workers), "--in-place"
        )


def _softtrack(*args: str, taskset: int | None = None) -> str:
    """Run the CLI, echoing its output; return stdout. Exits with its code on failure."""
    command = [*SOFTTRACK, *args]
    if taskset is not None:
        command = ["taskset", "-c", str(taskset), *command]
    print("$", " ".join(["softtrack", *args]), flush=True)
    done = subprocess.run(command, check=False, cwd=ROOT, stdout=subprocess.PIPE, text=True)
    sys.stdout.write(done.stdout)
    if done.returncode:
        raise SystemExit(f"failed ({done.returncode}): softtrack {' '.join(args)}")
    return done.stdout


def _existing_run(job: Job, runs_dir: Path) -> tuple[str, str] | None:
    """(run id, status) of the newest run of ``job``'s experiment, seed and spec, if any."""
    spec = load_experiment(job.spec)
    if not runs_dir.is_dir():
        return None
    candidates = [
        r
        for r in RunStore(runs_dir).list_runs()
        if r.info.name == spec.name
        and r.info.seed == job.seed
        and r.info.spec_hash == spec_hash(spec)
    ]
    if not candidates:
        return None
    newest = candidates[-1]
    return newest.run_id, api.effective_status(newest)


#: run.json notes a derived run does not take from its source: the export's mark and a
#: ``softtrack tune`` trial's study (its storage, trial numbers and pruning).
NOT_DERIVED_NOTES = ("read_only", "tune", "pruned")


def derive_run(job: Job, runs_dir: Path, base: RunRecord | None = None) -> str:
    """Create ``job``'s run in ``runs_dir`` from ``base`` (default ``models/<job.derive_from>``):
    its files but the evaluation tables and training checkpoints, under a new run id, with
    ``job``'s spec, and ``notes.derived_from`` in run.json. The two specs must train alike
    (:func:`_training_fields`). Returns the run id."""
    if base is None:
        assert job.derive_from is not None
        base = select_one_run(str(ROOT / "models" / job.derive_from))
    spec = load_experiment(job.spec).with_seed(job.seed)
    base_spec = base.load_spec()
    if not _trains_like(spec, base_spec) or base.info.seed != job.seed:
        raise SystemExit(
            f"experiments/{job.spec} (seed {job.seed}) does not train like "
            f"{portable_path(base.path, ROOT)}; train it instead of deriving it"
        )
    run_id, path = create_unique_dir(runs_dir)
    shutil.copytree(
        base.path,
        path,
        dirs_exist_ok=True,
        ignore=lambda _dir, names: [
            n
            for n in names
            if n in ("run.json", "run.lock", "spec.yaml", "checkpoints") or n.startswith("eval_")
        ],
    )
    header = (
        f"# fully resolved spec of run {run_id} (seed {job.seed}), derived from run "
        f"{base.info.run_id} ({base.info.name})\n"
    )
    header += chain_comment(
        [portable_path(f, ROOT) for f in spec_chain(ROOT / "experiments" / job.spec)]
    )
    atomic_write_text(path / "spec.yaml", header + spec_to_yaml(spec))
    info = base.info.model_copy(
        update={
            "run_id": run_id,
            "name": spec.name,
            "spec_hash": spec_hash(spec),
            "notes": {
                **{k: v for k, v in base.info.notes.items() if k not in NOT_DERIVED_NOTES},
                "derived_from": {
                    "run_id": base.info.run_id,
                    "name": base.info.name,
                    "spec_hash": base.info.spec_hash,
                    "why": _derivation_reason(spec, base_spec),
                },
            },
        }
    )
    atomic_write_text(path / "run.json", info.model_dump_json(indent=2) + "\n")  # last
    print(
        f"derived run {run_id} ({job.name} seed {job.seed}) from run {base.info.run_id} "
        f"({base.info.name})",
        flush=True,
    )
    return run_id


def _derivation_reason(spec: ExperimentSpec, base: ExperimentSpec) -> str:
    """run.json ``notes.derived_from.why`` of a run of ``spec`` derived from one of ``base``."""
    changes = _evaluation_only_changes(spec, base)
    if not changes:
        return "the same training under another name"
    return "the same training; the spec changes " + ", ".join(changes)


def _trained_twin(job: Job, runs_dir: Path) -> RunRecord | None:
    """A completed run in ``runs_dir`` of another experiment that trained exactly like ``job``
    (:func:`_training_fields`, the same seed), e.g. the ``softtrack tune`` trial whose values
    ``job``'s spec took: the newest, or None."""
    if not runs_dir.is_dir():
        return None
    spec = load_experiment(job.spec).with_seed(job.seed)
    twins = []
    for record in RunStore(runs_dir).list_runs():
        if record.info.seed != job.seed or record.info.name == spec.name:
            continue
        if record.info.total_timesteps != spec.training.total_timesteps:
            continue  # cheap filter before reading the spec
        if api.effective_status(record) == "completed" and _trains_like(spec, record.load_spec()):
            twins.append(record)
    return twins[-1] if twins else None


def _trains_like(spec: ExperimentSpec, other: ExperimentSpec) -> bool:
    """Whether runs of the two specs train alike: equal :func:`_training_fields`."""
    return _training_fields(spec) == _training_fields(other)


#: What a derived run's spec may change: fields its training does not see. An independent
#: run's arm policies learn and are validated in single-arm scenes, where there is no other arm
#: to touch, so the contact between the arms acts in its dual-arm evaluation only.
EVALUATION_ONLY = ("training.confirm_episodes",)
INDEPENDENT_EVALUATION_ONLY = ("env.physics.contact_k", "env.physics.contact_nu")


def _evaluation_only(spec: ExperimentSpec) -> tuple[str, ...]:
    """The dotted fields of ``spec`` that its training does not see."""
    extra = INDEPENDENT_EVALUATION_ONLY if spec.controller == "independent" else ()
    return (*EVALUATION_ONLY, *extra)


def _training_fields(spec: ExperimentSpec) -> dict[str, Any]:
    """The spec without what a derived run may change: its name, its list of seeds (the seed
    is checked on its own), :func:`_evaluation_only`."""
    data = spec.model_dump(mode="json", exclude={"name", "cluster", "seeds"})
    for field in _evaluation_only(spec):
        *parents, leaf = field.split(".")
        node = data
        for key in parents:
            node = node[key]
        node.pop(leaf)
    return data


def _evaluation_only_changes(spec: ExperimentSpec, base: ExperimentSpec) -> list[str]:
    """The fields of :func:`_evaluation_only` in which ``spec`` differs from ``base``."""
    new, old = spec.model_dump(mode="json"), base.model_dump(mode="json")
    changed = []
    for field in _evaluation_only(spec):
        a, b = new, old
        for key in field.split("."):
            a, b = a[key], b[key]
        if a != b:
            changed.append(field)
    return changed


def run_job(job: Job, runs_dir: Path, core: int | None) -> None:
    """Train (or resume, or derive) ``job`` if needed, then export and evaluate it into
    ``models/``."""
    dest = ROOT / "models" / job.dest
    if dest.is_dir():
        print(f"done: models/{job.dest}", flush=True)
        return
    found = _existing_run(job, runs_dir)
    runs = ["--runs-dir", str(runs_dir)]
    if job.derive_from is not None:
        run_id = derive_run(job, runs_dir) if found is None else found[0]
        record = RunStore(runs_dir).get_run(run_id)
        confirm_run(record, record.load_spec())  # each policy once, also after a kill
    elif load_experiment(job.spec).controller == "mpc":  # a planner: nothing to train
        if found is None:
            out = _softtrack("evaluate", f"experiments/{job.spec}", *runs, taskset=core)
            run_id = out.split()[0]
        else:
            run_id = found[0]
            _softtrack("evaluate", run_id, *runs, taskset=core)
        _softtrack("export", run_id, f"models/{job.dest}", *runs)
        lean(dest, job.name)
        return
    elif found is None:
        twin = _trained_twin(job, runs_dir)
        if twin is not None:
            run_id = derive_run(job, runs_dir, twin)
        else:
            out = _softtrack(
                "train", f"experiments/{job.spec}", "--seed", str(job.seed), *runs, taskset=core
            )
            run_id = out.split()[0]
    else:
        run_id, status = found
        if status == "running":
            print(
                f"busy: run {run_id} ({job.name} seed {job.seed}) is training in another "
                "process; run this script again when it has finished",
                flush=True,
            )
            return
        if status != "completed":
            _softtrack("train", "--resume", run_id, *runs, taskset=core)
    _softtrack("evaluate", run_id, "--random", str(RANDOM_EPISODES), *runs, taskset=core)
    lean_model = ["--policy-only"] if job.policy_only else []
    _softtrack("export", run_id, f"models/{job.dest}", *lean_model, *runs)
    lean(dest, job.name)


def lean(run_dir: Path, name: str) -> None:
    """Drop from a run under ``models/`` what its experiment's report and derived runs do not
    read. Unless it is in :data:`KEEP_STEPS`: the per-step tables, the tip and target positions
    (``eval_trajectories``) and the moment histories (``eval_moments``; the peaks stay in
    ``eval_moment_peaks``): the report draws them for the featured and contact experiments only,
    and `softtrack evaluate models/<run>` writes them again in seconds. Unless a derived run
    confirms its models (:func:`keeps_other_models`): the other model beside the policy
    (``other_models/``, what ``softtrack evaluate --model last`` runs), as ``softtrack export
    --policy-only`` leaves it out. And the validation table's columns that nothing reads
    (:func:`lean_validation`)."""
    if name not in KEEP_STEPS:
        for table in ("eval_trajectories", "eval_moments"):
            (run_dir / "tables" / f"{table}.parquet").unlink(missing_ok=True)
    if not keeps_other_models(name):
        drop_other_models(run_dir)
    lean_validation(run_dir)


def lean_validation(run_dir: Path) -> None:
    """Keep of ``tables/validation.parquet`` the columns that scores and the report read
    (:data:`~softtrack.evaluation.episode_tables.VALIDATION_SCORED_COLUMNS`, with ``run_id``,
    ``seed`` and ``wall_time``): the per-axis and action metrics of every checkpoint are four
    fifths of a shipped transport run's bytes, and the run directory under ``runs/`` keeps
    them."""
    path = run_dir / "tables" / "validation.parquet"
    if not path.is_file():
        return
    rows = read_table(path)
    keep = {"run_id", "seed", "wall_time", *VALIDATION_SCORED_COLUMNS}
    write_table(path, rows[[c for c in rows.columns if c in keep]])


def lean_undrawn_steps(name: str) -> None:
    """For an experiment in :data:`KEEP_STEPS` but not :data:`FEATURED`, once every one of its
    jobs is shipped: drop the per-step tables of the runs the report does not draw, i.e. all
    but each evaluation trajectory's representative run (the median seed over all runs,
    :func:`softtrack.report.data.representative_run`) and, in the transport task, the lowest
    seed (the transport figure's)."""
    dests = [ROOT / "models" / job.dest for job in JOBS if job.name == name]
    if name not in KEEP_STEPS or name in FEATURED or not all(d.is_dir() for d in dests):
        return
    runs = load_runs(select_one_run(str(d)) for d in dests)
    group = Group("", "", name, "", name, name, tuple(runs))
    drawn = {id(representative_run(group, t)) for t in EVAL_TRAJECTORIES}
    if any(r.metrics is not None and "object_rmse_3d" in r.metrics for r in runs):
        drawn.add(id(min(runs, key=lambda r: r.seed)))
    for run in runs:
        if id(run) not in drawn:
            for table in ("eval_trajectories", "eval_moments"):
                (run.record.path / "tables" / f"{table}.parquet").unlink(missing_ok=True)


def keeps_other_models(name: str) -> bool:
    """Whether experiment ``name``'s shipped runs keep their other models: those a derived run
    confirms against its policy (``training.confirm_episodes``), and the derived runs that did."""
    experiment_of = {job.dest: job.name for job in JOBS}
    keep: set[str] = set()
    for job in JOBS:
        if job.derive_from is not None and load_experiment(job.spec).training.confirm_episodes:
            keep |= {job.name, experiment_of[job.derive_from]}
    return name in keep


def drop_other_models(run_dir: Path) -> None:
    """Remove every policy's ``other_models/`` under ``run_dir`` and empty the list of them in
    its ``policy.json``."""
    for manifest in sorted(run_dir.rglob("policy.json")):
        shutil.rmtree(manifest.parent / "other_models", ignore_errors=True)
        data = json.loads(manifest.read_text(encoding="utf-8"))
        if data.get("other_models"):
            data["other_models"] = {}
            atomic_write_text(manifest, json.dumps(data, indent=2) + "\n")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=1, help="runs at once (one core each)")
    parser.add_argument(
        "--only",
        action="append",
        metavar="NAME",
        help="only the jobs of this experiment: its name or its spec file under "
        "experiments/ (repeatable)",
    )
    parser.add_argument("--runs-dir", default=None, help="where runs are trained [runs/]")
    parser.add_argument("--list", action="store_true", help="print the jobs and stop")
    parser.add_argument("--report-only", action="store_true", help="only rebuild the report")
    parser.add_argument(
        "--robustness",
        action="store_true",
        help="evaluate the shipped runs of the robustness experiments under "
        "perturbations (softtrack robustness; with --only, those named) instead "
        "of training",
    )
    parser.add_argument(
        "--no-report",
        action="store_true",
        help="do not rebuild the report (e.g. for two --only processes at once)",
    )
    args = parser.parse_args(argv)
    jobs = [
        j
        for j in JOBS
        if ({j.name, j.spec} & set(args.only) if args.only else j.name not in RETIRED)
    ]
    unknown = sorted(set(args.only or ()) - {j.name for j in JOBS} - {j.spec for j in JOBS})
    if unknown and not args.robustness:
        parser.exit(
            2,
            f"error: --only {', '.join(unknown)}: no job of this script has that experiment "
            "name or spec file; `--list` prints them\n",
        )
    if args.list:
        for job in jobs:
            spec = load_experiment(job.spec)
            state = "done" if (ROOT / "models" / job.dest).is_dir() else "to do"
            if job.name in RETIRED:
                state = f"retired: last shipped at commit {RETIRED[job.name]}"
            per_arm = " per arm" if spec.controller == "independent" else ""
            how = f"derived from models/{job.derive_from}, " if job.derive_from else ""
            budget = (
                "no training (planner)"
                if spec.controller == "mpc"
                else f"{spec.training.total_timesteps:>10,d} env steps{per_arm}"
            )
            print(
                f"{job.name:35s} seed {job.seed}  {budget}  models/{job.dest}  "
                f"(experiments/{job.spec}; {how}{state})"
            )
        return
    if args.robustness:
        run_robustness(
            [n for n in ROBUSTNESS if not args.only or n in args.only], max(1, args.jobs)
        )
        if not args.only:
            run_contact_robustness(max(1, args.jobs))
    elif not args.report_only:
        runs_dir = resolve_runs_dir(args.runs_dir)
        n = max(1, args.jobs)
        cores: queue.Queue[int | None] = queue.Queue()
        pin = n > 1 and shutil.which("taskset") is not None
        for core in range(n):
            cores.put(core if pin else None)

        def on_free_core(job: Job) -> None:
            core = cores.get()
            try:
                run_job(job, runs_dir, core)
            finally:
                cores.put(core)

        for phase in (
            [job for job in jobs if job.derive_from is None],
            [job for job in jobs if job.derive_from is not None],  # from the trained runs
        ):
            with ThreadPoolExecutor(n) as pool:
                for future in [pool.submit(on_free_core, job) for job in phase]:
                    future.result()
        for name in {job.name for job in jobs}:
            lean_undrawn_steps(name)
    if args.no_report:
        return
    shipped = {job.name for job in JOBS if (ROOT / "models" / job.dest).is_dir()}
    waiting = [name for name in REPORTED if name not in shipped and name not in RETIRED]
    if waiting:
        print(f"not in the report yet (no finished run in models/): {', '.join(waiting)}")
    reported = [name for name in REPORTED if name in shipped and name not in RETIRED]
    figures = [arg for name in FEATURED if name in reported for arg in ("--figures-for", name)]
    _softtrack("report", *reported, "--runs-dir", "models", "--out", REPORT_DIR, *figures)


if __name__ == "__main__":
    main()
