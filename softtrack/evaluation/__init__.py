"""Evaluation of controllers: episodes, their metrics and tables, and the evaluation of runs.

* :mod:`softtrack.evaluation.episodes`: deterministic episodes of a policy on a closed-form or
  random target (:func:`run_episode`, :class:`Episode`), the dual-arm policy of two single-arm
  ones (:func:`independent_policy`) and the seeds of held-out episodes.
* :mod:`softtrack.evaluation.metrics`: the tracking and actuation metrics of docs/environment.md (pure NumPy).
* :mod:`softtrack.evaluation.tables`: the tables of an episode (trajectory, metrics, moments)
  and the validation score of a checkpoint's metrics rows.
* :mod:`softtrack.evaluation.runs`: evaluate a stored run's policy and write its ``eval_*``
  tables, with the policy loader the caller passes in (``softtrack.rl.policy.load_policy``):
  this package sits below :mod:`softtrack.rl`, which uses it for validation, and never
  imports it.

The names below are those of :mod:`~softtrack.evaluation.episodes` and
:mod:`~softtrack.evaluation.tables`.
"""

from softtrack.evaluation.episodes import (
    CONFIRM_SEED,
    EVAL_TRAJECTORIES,
    RANDOM_TARGET_SEED,
    VALIDATION_SEED,
    Episode,
    Policy,
    accepts_batches,
    independent_policy,
    iter_episodes,
    run_episode,
    run_episodes,
)
from softtrack.evaluation.tables import (
    STEADY_START,
    element_moments_table,
    element_peaks_frame,
    metrics_table,
    moment_peaks_table,
    moments_table,
    trajectory_table,
    validation_score,
)

__all__ = [
    "CONFIRM_SEED",
    "EVAL_TRAJECTORIES",
    "RANDOM_TARGET_SEED",
    "STEADY_START",
    "VALIDATION_SEED",
    "Episode",
    "Policy",
    "accepts_batches",
    "element_moments_table",
    "element_peaks_frame",
    "independent_policy",
    "iter_episodes",
    "metrics_table",
    "moment_peaks_table",
    "moments_table",
    "run_episode",
    "run_episodes",
    "trajectory_table",
    "validation_score",
]
