"""Reinforcement learning on the tracking environments with Stable-Baselines3: the core.

* :mod:`softtrack.rl.factory`: the algorithm, its environment and exploration noise from a spec
  (asking :mod:`softtrack.rl.variants` what an enabled research variant changes).
* :mod:`softtrack.rl.callbacks`: episode table, checkpoints, heartbeat and progress bar.
* :mod:`softtrack.rl.policy_training`: train one policy (centralized, or one arm's) to its budget.
* :mod:`softtrack.rl.train`: :func:`train_run`, fresh or resumed, with signal handling; an
  independent run trains one single-arm policy per arm, one after the other.
* :mod:`softtrack.rl.policy`: a run's deterministic policy loaded from its model file(s).
* Model selection: :mod:`softtrack.rl.validation` (held-out episodes after each checkpoint,
  best-validated model) and :mod:`softtrack.rl.confirmation` (best vs last on more episodes).
* :mod:`softtrack.rl.policy_export`: exported runs with inference-only model copies.
* :mod:`softtrack.rl.variants`: research variants (per-arm critics, mirror replay) and their
  registry.
* :mod:`softtrack.rl.moved`: old module paths of moved modules, for model files pickled
  before the move (installed here, when this package is imported).

Evaluation episodes and metrics live below this package, in :mod:`softtrack.evaluation`.
Importing this package does not import torch; the submodules do.
"""

from softtrack.rl import moved

moved.install()
