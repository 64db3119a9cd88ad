"""Reinforcement learning on the tracking environments with Stable-Baselines3.

* :mod:`softtrack.rl.factory`: the algorithm, its environment and exploration noise from a spec.
* :mod:`softtrack.rl.callbacks`: episode table, checkpoints, heartbeat and progress bar.
* :mod:`softtrack.rl.train`: :func:`train_run`, fresh or resumed, with signal handling.

Importing this package does not import torch; the submodules do.
"""
