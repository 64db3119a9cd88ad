"""Where runs execute: a local process pool, or a SLURM cluster through submitit.

A *job* is one run of the store (:class:`~softtrack.executors.base.Job`: runs directory + run
id). Every executor runs the same worker entry point,
``python -m softtrack.workers train --runs-dir D RUN_ID``, in its own process: it trains
the run (resuming it from its last checkpoint if it has started before) and records the
outcome in ``run.json``, so the run store stays the single source of truth and a crash of
one job never affects the others.

* :mod:`~softtrack.executors.local`: up to ``--workers`` worker processes on this machine.
* :mod:`~softtrack.executors.slurm`: a SLURM job array (or submitit's local executor in tests)
  whose jobs requeue on preemption/time-out and resume their run.
* :mod:`~softtrack.executors.sweep`: grid expansion and the progress of a set of runs.
"""
