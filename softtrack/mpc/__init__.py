"""Model predictive control: sampling planners (MPPI, CEM) over the batched rod engine.

* :mod:`softtrack.mpc.planner_config`: :class:`PlannerConfig`, the planner settings (no numba).
* :mod:`softtrack.mpc.planner`: :class:`SamplingPlanner`.
* :mod:`softtrack.mpc.controller`: :class:`MpcController`, a planner as an evaluation policy.

Names are imported on first use, so the spec validates ``mpc:`` without loading the engine.
"""

from __future__ import annotations

from softtrack.lazy import lazy_exports

__all__ = ["MpcController", "PlannerConfig", "SamplingPlanner"]

_HOME = {
    "MpcController": "softtrack.mpc.controller",
    "PlannerConfig": "softtrack.mpc.planner_config",
    "SamplingPlanner": "softtrack.mpc.planner",
}


__getattr__, __dir__ = lazy_exports(__name__, _HOME, __all__)
