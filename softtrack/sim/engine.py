"""The batched rod engine: state arrays of many environments and one call to advance them."""

from __future__ import annotations

import numpy as np

from softtrack.sim.actuation import spline_matrix
from softtrack.sim.kernels import advance as _advance_kernel
from softtrack.sim.params import RodConstants, SimParams

__all__ = ["RodBatch"]


class RodBatch:
    """State of ``n_envs`` environments, each with ``params.n_arms`` clamped Cosserat rods.

    All arrays are float64, laid out (env, arm, component, node/element):

    * ``position``, ``velocity``: (E, A, 3, N+1), m and m/s, lab frame;
    * ``directors``: (E, A, 3, 3, N), row r = d_{r+1} in lab coordinates;
    * ``omega``: (E, A, 3, N), rad/s, local frame;
    * ``torques``: (E, A, 2, N), N·m, the applied (d₁, d₂) element couples;
    * ``time``: (E,), s since the environment's last reset.

    Every environment starts straight and at rest. :meth:`advance` integrates all of them in
    one compiled call.
    """

    def __init__(self, n_envs: int, params: SimParams | None = None) -> None:
        if not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
            raise ValueError(f"n_envs={n_envs!r} must be an integer ≥ 1")
        self.params = params if params is not None else SimParams()
        self.params.validate()
        self.constants = RodConstants.build(self.params)
        p = self.params
        shape_nodes = (n_envs, p.n_arms, 3, p.n_nodes)
        self.position = np.empty(shape_nodes)
        self.velocity = np.empty(shape_nodes)
        self.directors = np.empty((n_envs, p.n_arms, 3, 3, p.n_elem))
        self.omega = np.empty((n_envs, p.n_arms, 3, p.n_elem))
        self.torques = np.zeros((n_envs, p.n_arms, 2, p.n_elem))
        self.time = np.zeros(n_envs)
        self._finite = np.ones(n_envs, dtype=np.bool_)
        self._spline_scaled = p.torque_scale * spline_matrix(p.n_elem)  # (N, 6)
        self.reset()

    @property
    def n_envs(self) -> int:
        return self.position.shape[0]

    @property
    def tip_position(self) -> np.ndarray:
        """(E, A, 3) tip node positions, m (a view)."""
        return self.position[:, :, :, -1]

    @property
    def tip_velocity(self) -> np.ndarray:
        """(E, A, 3) tip node velocities, m/s (a view)."""
        return self.velocity[:, :, :, -1]

    def reset(self, env_indices: np.ndarray | None = None) -> None:
        """Put the listed environments (default: all) back to straight, at rest, unforced."""
        idx = slice(None) if env_indices is None else np.asarray(env_indices, dtype=np.intp)
        c = self.constants
        self.position[idx] = c.rest_position
        self.velocity[idx] = 0.0
        self.directors[idx] = c.base_directors[:, :, :, None]
        self.omega[idx] = 0.0
        self.torques[idx] = 0.0
        self.time[idx] = 0.0
        self._finite[idx] = True

    def set_actions(self, actions: np.ndarray) -> None:
        """Set the element torques from control values.

        Args:
            actions: (E, A, 2, 6) control values (direction 0 normal, 1 binormal), used as
                given (clip them before if needed).
        """
        e, a = self.torques.shape[:2]
        np.matmul(np.reshape(actions, (e * a * 2, -1)), self._spline_scaled.T,
                  out=self.torques.reshape(e * a * 2, -1))

    def set_element_torques(self, element_torques: np.ndarray) -> None:
        """Set the element torques directly: (E, A, 2, N) N·m."""
        self.torques[...] = element_torques

    def advance(self, n_steps: int | None = None) -> None:
        """Integrate every environment by ``n_steps`` steps (default ``steps_per_action``)."""
        p = self.params
        steps = p.steps_per_action if n_steps is None else int(n_steps)
        if steps < 0:
            raise ValueError(f"n_steps={n_steps!r} must be ≥ 0")
        if steps == 0:
            return
        c = self.constants
        _advance_kernel(
            self.position, self.velocity, self.directors, self.omega, self.torques, steps,
            float(p.dt), float(p.damping), float(p.gravity), c.rest_lengths, c.rest_voronoi_lengths, c.inv_mass,
            c.mass, c.inertia, c.inv_inertia, c.shear_stiffness, c.bend_stiffness,
            c.base_position, c.base_directors, self._finite,
        )
        self.time += steps * p.dt

    def finite(self) -> np.ndarray:
        """(E,) bool: True where every state value of the environment was finite after the
        last :meth:`advance` (or since a reset)."""
        return self._finite.copy()

