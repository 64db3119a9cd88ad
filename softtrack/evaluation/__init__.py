"""Evaluation of controllers: episodes, their metrics and tables, and the evaluation of runs.

* :mod:`softtrack.evaluation.episodes`: deterministic episodes of a policy on a closed-form or
  random target (:func:`run_episode`, :class:`Episode`), the dual-arm policy of two single-arm
  ones (:func:`independent_policy`) and the seeds of held-out episodes.
* :mod:`softtrack.evaluation.metrics`: the tracking and actuation metrics of docs/environment.md (pure NumPy).
* :mod:`softtrack.evaluation.episode_tables`: the tables of an episode (trajectory, metrics, moments).
* :mod:`softtrack.evaluation.scores`: the validation score of a checkpoint's metrics rows and
  the transport task's carry score (pandas only: the report and ``compare`` use it).
* :mod:`softtrack.evaluation.run_evaluation`: evaluate a stored run's policy and write its ``eval_*``
  tables, with the policy loader the caller passes in (``softtrack.rl.policy.load_policy``):
  this package sits below :mod:`softtrack.rl`, which uses it for validation, and never
  imports it.

The names below are those of :mod:`~softtrack.evaluation.episodes` and
:mod:`~softtrack.evaluation.episode_tables`.
"""

from __future__ import annotations

from softtrack.lazy import lazy_exports

__all__ = [
    "CONFIRM_SEED",
    "EVAL_TRAJECTORIES",
    "RANDOM_TARGET_SEED",
    "STEADY_START",
    "VALIDATION_PATH_SEED",
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

_HOME = {
    "CONFIRM_SEED": "softtrack.evaluation.episodes",
    "EVAL_TRAJECTORIES": "softtrack.evaluation.episodes",
    "RANDOM_TARGET_SEED": "softtrack.evaluation.episodes",
    "STEADY_START": "softtrack.evaluation.episode_tables",
    "VALIDATION_PATH_SEED": "softtrack.evaluation.episodes",
    "VALIDATION_SEED": "softtrack.evaluation.episodes",
    "Episode": "softtrack.evaluation.episodes",
    "Policy": "softtrack.evaluation.episodes",
    "accepts_batches": "softtrack.evaluation.episodes",
    "element_moments_table": "softtrack.evaluation.episode_tables",
    "element_peaks_frame": "softtrack.evaluation.episode_tables",
    "independent_policy": "softtrack.evaluation.episodes",
    "iter_episodes": "softtrack.evaluation.episodes",
    "metrics_table": "softtrack.evaluation.episode_tables",
    "moment_peaks_table": "softtrack.evaluation.episode_tables",
    "moments_table": "softtrack.evaluation.episode_tables",
    "run_episode": "softtrack.evaluation.episodes",
    "run_episodes": "softtrack.evaluation.episodes",
    "trajectory_table": "softtrack.evaluation.episode_tables",
    "validation_score": "softtrack.evaluation.scores",
}

__getattr__, __dir__ = lazy_exports(__name__, _HOME, __all__)
