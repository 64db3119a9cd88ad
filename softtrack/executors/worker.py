"""``python -m softtrack.executors.worker --runs-dir D RUN_ID``: train one run (see
:func:`softtrack.executors.base.run_job`); the exit code says how it ended."""

from __future__ import annotations

import argparse
import sys

from softtrack.executors.base import run_job


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m softtrack.executors.worker")
    parser.add_argument("--runs-dir", required=True, help="directory holding the runs")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    parser.add_argument("run_id", help="the run to train or resume")
    args = parser.parse_args(argv)
    return run_job(args.runs_dir, args.run_id, threads=args.threads)


if __name__ == "__main__":
    sys.exit(main())
