"""``softtrack tune``: hyperparameter search with Optuna over a spec's ``tune:`` section.

A *study* (Optuna, in an RDB storage: by default the SQLite file ``<runs dir>/optuna.db``, or
any ``postgresql://`` / ``mysql://`` URL) holds the tuned spec and its trials; every trial is
one run of the run store, trained like ``softtrack train`` with the sampled values set
(TPE, seeded) and stopped early when the pruner says so after a validated checkpoint.

* :mod:`softtrack.tune.study`: the storage and the study, the trial slots (how the trial count
  stays exact across workers), dead workers, status and the best trial.
* :mod:`softtrack.tune.worker`: a worker: take a trial, train its run, report its score; also
  ``python -m softtrack.tune.worker``, the process the executors start.
* :mod:`softtrack.tune.command`: the ``softtrack tune`` command: create or continue a study, run
  its workers in-process, in a local pool or on SLURM, write the best trial as a spec.

Importing this package does not import Optuna (it is imported when a study is opened).
See ``docs/tuning.md``.
"""

from __future__ import annotations

__all__ = ["TuneError"]


class TuneError(Exception):
    """A user-facing problem with a study (missing, another spec's, no complete trial, an
    unusable storage URL); the message is one line with the fix."""
