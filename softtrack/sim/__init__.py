"""The Cosserat-rod engine: two clamped soft arms, PyElastica's discretisation, numba speed.

Names are imported on first use, so ``softtrack.sim.params`` (used by the spec and the CLI)
loads without numba and SciPy.
"""

from __future__ import annotations

from softtrack.lazy import lazy_exports

__all__ = [
    "InvalidParameterError",
    "RodBatch",
    "SimParams",
    "actions_to_element_torques",
    "rollout",
    "spline_matrix",
]

_HOME = {
    "InvalidParameterError": "softtrack.sim.params",
    "SimParams": "softtrack.sim.params",
    "RodBatch": "softtrack.sim.engine",
    "actions_to_element_torques": "softtrack.sim.actuation",
    "spline_matrix": "softtrack.sim.actuation",
    "rollout": "softtrack.sim.open_loop",
}


__getattr__, __dir__ = lazy_exports(__name__, _HOME, __all__)
