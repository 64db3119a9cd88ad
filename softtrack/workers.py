"""The worker processes the pools and SLURM start, at the top of the package so that the
layers below them (executors, evaluation) never import training or policy loading:

``python -m softtrack.workers train --runs-dir D RUN_ID``
    train (or resume) one run (:func:`run_job`); its exit code says how it ended.
``python -m softtrack.workers robustness RUN_DIR --level f=v ... [--trajectories ...]``
    evaluate one robustness setting of one run and write its rows to the run's part file
    (:mod:`softtrack.evaluation.robustness_runs` merges them).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import traceback

from softtrack.evaluation.perturbations import Setting
from softtrack.evaluation.robustness_runs import evaluate_setting, part_path
from softtrack.executors.base import EXIT_LOCKED
from softtrack.rl.policy import load_policy
from softtrack.rl.train import train_run
from softtrack.store.runs import RunLockedError, RunStore, RunStoreError, lock_held
from softtrack.store.selection import select_one_run
from softtrack.store.tables import write_table

__all__ = ["main", "robustness_main", "run_job", "train_main"]


def run_job(runs_dir: str | os.PathLike[str], run_id: str, *, threads: int = 1) -> int:
    """Train run ``run_id`` in this process (resuming it if it started before); its exit code.

    0 completed (or already completed), 128 + signal interrupted, 1 failed (the traceback is
    in run.json), :data:`~softtrack.executors.base.EXIT_LOCKED` another process is training
    the run, 2 no such run or no readable spec (the run keeps its status). An error before
    training starts (an invalid stored spec, say) is recorded as failed.
    """
    import torch

    torch.set_num_threads(threads)
    store = RunStore(runs_dir)
    try:
        record = store.get_run(run_id)
    except RunStoreError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if record.info.status == "completed":
        print(f"{record.run_id}: already completed", file=sys.stderr)
        return 0
    problem = record.spec_problem()
    if problem is not None:  # nothing to train from: the run keeps its status
        print(f"error: {problem}", file=sys.stderr)
        return 2
    started = record.info.status != "queued" or bool(record.info.global_step)
    try:
        outcome = train_run(store, record, resume=started, show_progress=False)
    except RunLockedError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_LOCKED
    except Exception as exc:
        text = "".join(traceback.format_exception(exc))
        print(text, file=sys.stderr)
        line = " ".join(f"{type(exc).__name__}: {exc}".split())
        if lock_held(record) is not True:
            store.mark_finished(record.run_id, "failed", error=line, traceback=text)
        return 1
    print(f"{outcome.run_id}: {outcome.status} at step {outcome.global_step}", file=sys.stderr)
    return outcome.exit_code


def train_main(argv: list[str] | None = None) -> int:
    """``python -m softtrack.workers train --runs-dir D [--threads N] RUN_ID``."""
    parser = argparse.ArgumentParser(prog="python -m softtrack.workers train")
    parser.add_argument("--runs-dir", required=True, help="directory holding the runs")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    parser.add_argument("run_id", help="the run to train or resume")
    args = parser.parse_args(argv)
    return run_job(args.runs_dir, args.run_id, threads=args.threads)


def robustness_main(argv: list[str] | None = None) -> int:
    """``python -m softtrack.workers robustness RUN_DIR --level f=v ...``: evaluate one setting
    of one run and write its rows to the run's part file."""
    parser = argparse.ArgumentParser(prog="python -m softtrack.workers robustness")
    parser.add_argument("run", help="run directory")
    parser.add_argument("--level", action="append", default=[], metavar="FACTOR=LEVEL")
    parser.add_argument("--trajectories", default="circle,rectangle,figure8")
    parser.add_argument("--episodes", type=int, default=1)
    parser.add_argument("--keep-realism", action="store_true")
    args = parser.parse_args(argv)
    record = select_one_run(args.run)
    spec = record.load_spec()
    setting = Setting(tuple((f, v) for f, _, v in (item.partition("=") for item in args.level)))
    trajectories = args.trajectories.split(",")
    started = time.monotonic()
    rows = evaluate_setting(
        record.run_id,
        load_policy(record, spec),
        spec,
        setting,
        trajectories,
        args.episodes,
        keep_realism=args.keep_realism,
    )
    path = part_path(record, setting, trajectories, args.episodes, args.keep_realism)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_table(path, rows)
    print(f"{record.run_id} {setting.key}: {len(rows)} rows in {time.monotonic() - started:.0f} s")
    return 0


_COMMANDS = {"train": train_main, "robustness": robustness_main}


def main(argv: list[str] | None = None) -> int:
    """``python -m softtrack.workers {train,robustness} ...``."""
    args = sys.argv[1:] if argv is None else list(argv)
    if not args or args[0] not in _COMMANDS:
        print(f"usage: python -m softtrack.workers {{{','.join(_COMMANDS)}}} ...", file=sys.stderr)
        return 2
    return _COMMANDS[args[0]](args[1:])


if __name__ == "__main__":
    sys.exit(main())
