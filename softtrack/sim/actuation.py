"""B-spline distributed torques: control values → per-element couples (docs/physics.md).

Per arm and direction, six control values a₁…a₆ are placed at s = linspace(0, 1, 8)[1:7]
with zero torque at both ends, interpolated by a cubic not-a-knot spline and evaluated at the
rest-length element centres s_i = (i + ½)/N. The interpolant is linear in the data, so the
whole map is one fixed (N, 6) matrix: torques = scale · B · a.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["N_CONTROL_POINTS", "actions_to_element_torques", "spline_matrix"]

N_CONTROL_POINTS = 6


@lru_cache(maxsize=8)
def _spline_matrix_cached(n_elem: int) -> np.ndarray:
    # SciPy's splines are imported here, once (lru_cache): at the module's top they cost every
    # command that only needs N_CONTROL_POINTS (the spec models) half a second
    from scipy.interpolate import make_interp_spline

    knots_s = np.linspace(0.0, 1.0, N_CONTROL_POINTS + 2)
    centres = (np.arange(n_elem) + 0.5) / n_elem
    matrix = np.empty((n_elem, N_CONTROL_POINTS))
    for j in range(N_CONTROL_POINTS):
        data = np.zeros(N_CONTROL_POINTS + 2)
        data[j + 1] = 1.0
        matrix[:, j] = make_interp_spline(knots_s, data, k=3)(centres)
    matrix.setflags(write=False)
    return matrix


def spline_matrix(n_elem: int = 20) -> np.ndarray:
    """The (n_elem, 6) read-only matrix B mapping control values to unit-scale element torques."""

    return _spline_matrix_cached(int(n_elem))


def actions_to_element_torques(
    actions: np.ndarray, n_elem: int = 20, torque_scale: float = 75.0
) -> np.ndarray:
    """Element torques (N·m) from control values.

    Args:
        actions: (..., 6) control values (not clipped here).
        n_elem: elements per arm.
        torque_scale: torque at a control value of 1, N·m.

    Returns:
        (..., n_elem) torques, N·m, in the element's local frame.
    """
    actions = np.asarray(actions, dtype=np.float64)
    return torque_scale * actions @ spline_matrix(n_elem).T
