"""The names of the evaluation trajectories (their shapes: :mod:`softtrack.env.targets`).

A module of its own so the command line offers the names without loading the environments.
"""

from __future__ import annotations

from typing import Literal, get_args

__all__ = ["EVAL_TRAJECTORIES", "TrajectoryName"]

TrajectoryName = Literal["circle", "rectangle", "figure8"]
EVAL_TRAJECTORIES: tuple[TrajectoryName, ...] = get_args(TrajectoryName)
