"""Reinforcement learning on the tracking environments with Stable-Baselines3.

* :mod:`softtrack.rl.factory`: the algorithm, its environment and exploration noise from a spec.
* :mod:`softtrack.rl.callbacks`: episode table, checkpoints, heartbeat and progress bar.
* :mod:`softtrack.rl.policy_training`: train one policy (centralized, or one arm's) to its budget.
* :mod:`softtrack.rl.train`: :func:`train_run`, fresh or resumed, with signal handling; an
  independent run trains one single-arm policy per arm, one after the other.

Importing this package does not import torch; the submodules do.
"""
