"""The Cosserat-rod engine: two clamped soft arms, PyElastica's discretisation, numba speed."""

from softtrack.sim.actuation import actions_to_element_torques, spline_matrix
from softtrack.sim.engine import RodBatch
from softtrack.sim.params import InvalidParameterError, SimParams
from softtrack.sim.rollout import rollout

__all__ = [
    "InvalidParameterError",
    "RodBatch",
    "SimParams",
    "actions_to_element_torques",
    "rollout",
    "spline_matrix",
]
