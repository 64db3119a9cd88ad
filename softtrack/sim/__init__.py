"""The Cosserat-rod engine: two clamped soft arms, PyElastica's discretisation, numba speed.

Names are imported on first use, so ``softtrack.sim.params`` (used by the spec and the CLI)
loads without numba and SciPy.
"""

from __future__ import annotations

import importlib
from typing import Any

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


def __getattr__(name: str) -> Any:
    if name in _HOME:
        return getattr(importlib.import_module(_HOME[name]), name)
    raise AttributeError(f"module 'softtrack.sim' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
