"""A pool of worker processes on this machine (``softtrack sweep --executor local``).

Each job runs in its own process (:class:`~softtrack.executors.base.Job`'s worker command, in
a new session, output appended to the run's ``train.log``), at most ``workers`` at a time, so a
crash or ``kill -9`` of one never touches the others. SIGINT/SIGTERM to the pool stop it
(:mod:`softtrack.signals`): no new job starts, every running worker gets SIGTERM (it saves a
checkpoint and marks its run ``interrupted``), and :meth:`LocalPool.run` returns once they
have exited.
"""

from __future__ import annotations

import signal
import subprocess
import time
from collections.abc import Callable, Sequence

from softtrack.executors.base import Job, PoolJob, worker_env
from softtrack.signals import StopFlag, stop_on_signals
from softtrack.store.provenance import usable_cores

__all__ = ["LocalPool", "default_workers"]

POLL_S = 0.2


def default_workers() -> int:
    """The number of cores this process may use."""
    return usable_cores()


class LocalPool:
    """Run jobs as worker processes, ``workers`` at a time.

    Args:
        workers: most workers at once (default: the number of cores).
        threads: torch/BLAS/numba threads per worker.
    """

    def __init__(self, workers: int | None = None, threads: int = 1) -> None:
        self.workers = max(1, int(workers or default_workers()))
        self.threads = int(threads)
        self.stop_signal: int | None = None

    def _start(self, job: PoolJob) -> subprocess.Popen[bytes]:
        log = open(job.log_path(), "ab")
        try:
            return subprocess.Popen(
                job.command,
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                env=worker_env(self.threads),
                start_new_session=True,  # a Ctrl-C of the terminal reaches the pool only
            )
        finally:
            log.close()

    def run(
        self,
        jobs: Sequence[PoolJob],
        on_tick: Callable[[], None] | None = None,
        tick_s: float = 2.0,
    ) -> dict[str, int]:
        """Run ``jobs``; returns each started job's worker exit code by its ``key`` (a
        :class:`Job`'s: its run id); each job's ``after_exit`` runs once its worker ended.

        ``on_tick`` is called about every ``tick_s`` seconds (progress display). After a stop
        signal (``stop_signal`` is set) the jobs not yet started are left as they are.
        """
        pending = list(jobs)
        running: dict[str, tuple[PoolJob, subprocess.Popen[bytes]]] = {}
        codes: dict[str, int] = {}
        stop = StopFlag()
        last_tick = 0.0
        with stop_on_signals(stop):
            while pending or running:
                if stop() and self.stop_signal is None:
                    self.stop_signal = stop.signum
                    pending.clear()
                    for _job, proc in running.values():
                        if proc.poll() is None:
                            proc.send_signal(signal.SIGTERM)
                while pending and len(running) < self.workers:
                    job = pending.pop(0)
                    running[job.key] = (job, self._start(job))
                for key, (job, proc) in list(running.items()):
                    code = proc.poll()
                    if code is not None:
                        del running[key]
                        codes[key] = code
                        job.after_exit(code)
                now = time.monotonic()
                if on_tick is not None and now - last_tick >= tick_s:
                    last_tick = now
                    on_tick()
                time.sleep(POLL_S)
        if on_tick is not None:
            on_tick()
        return codes


def main(argv: list[str] | None = None) -> int:
    """``python -m softtrack.executors.local --runs-dir D --workers N RUN_ID...``: a detached
    pool (``softtrack sweep --detach``)."""
    import argparse

    parser = argparse.ArgumentParser(prog="python -m softtrack.executors.local")
    parser.add_argument("--runs-dir", required=True)
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("run_ids", nargs="+")
    args = parser.parse_args(argv)
    pool = LocalPool(args.workers)
    codes = pool.run([Job(args.runs_dir, r) for r in args.run_ids])
    if pool.stop_signal is not None:
        return 128 + pool.stop_signal
    return 0 if all(c == 0 for c in codes.values()) else 1


if __name__ == "__main__":
    import sys

    sys.exit(main())
