"""Model predictive control: sampling planners (MPPI, CEM) over the batched rod engine.

* :mod:`softtrack.mpc.config`: :class:`PlannerConfig`, the planner settings (no numba).
* :mod:`softtrack.mpc.planner`: :class:`SamplingPlanner`.
* :mod:`softtrack.mpc.controller`: :class:`MpcController`, a planner as an evaluation policy.

Names are imported on first use, so the spec validates ``mpc:`` without loading the engine.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["MpcController", "PlannerConfig", "SamplingPlanner"]

_HOME = {
    "MpcController": "softtrack.mpc.controller",
    "PlannerConfig": "softtrack.mpc.config",
    "SamplingPlanner": "softtrack.mpc.planner",
}


def __getattr__(name: str) -> Any:
    if name in _HOME:
        return getattr(importlib.import_module(_HOME[name]), name)
    raise AttributeError(f"module 'softtrack.mpc' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
