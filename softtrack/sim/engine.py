"""The batched rod engine: state arrays of many environments and one call to advance them."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from softtrack.sim.actuation import spline_matrix
from softtrack.sim.kernels import BatchContact, BatchMaterial, BatchState
from softtrack.sim.kernels import advance as advance_batch
from softtrack.sim.params import (
    MODEL_PARAMETERS,
    InvalidParameterError,
    RodConstants,
    SimParams,
    scaled_params,
)
from softtrack.sim.sphere_contact import SPHERE_STATE_SIZE

__all__ = ["RodBatch", "RodState"]

_TORQUE_COLUMN = list(MODEL_PARAMETERS).index("torque_scale_factor")


@dataclass(frozen=True)
class RodState:
    """The dynamic state of k environments of a :class:`RodBatch` (copies, float64).

    Attributes:
        position, velocity: (k, A, 3, N+1) m, m/s.
        directors: (k, A, 3, 3, N).
        omega: (k, A, 3, N) rad/s, local frame.
        torques: (k, A, 2, N) N·m, the applied element couples.
        time: (k,) s since the last reset.
        finite: (k,) bool, the state was finite after the last advance.
        sphere: (k, 18) the rigid sphere's state rows (centre m, velocity m/s, angular
            velocity rad/s, frame; :data:`~softtrack.sim.sphere_contact.SPHERE_STATE_SIZE`),
            or None in a scene without one.
    """

    position: np.ndarray
    velocity: np.ndarray
    directors: np.ndarray
    omega: np.ndarray
    torques: np.ndarray
    time: np.ndarray
    finite: np.ndarray
    sphere: np.ndarray | None = None

    @property
    def n_envs(self) -> int:
        return int(self.position.shape[0])


class RodBatch:
    """State of ``n_envs`` environments, each with ``params.n_arms`` clamped Cosserat rods.

    All arrays are float64, laid out (env, arm, component, node/element):

    * ``position``, ``velocity``: (E, A, 3, N+1), m and m/s, lab frame;
    * ``directors``: (E, A, 3, 3, N), row r = d_{r+1} in lab coordinates;
    * ``omega``: (E, A, 3, N), rad/s, local frame;
    * ``torques``: (E, A, 2, N), N·m, the applied (d₁, d₂) element couples;
    * ``time``: (E,), s since the environment's last reset.

    Every environment starts straight and at rest. :meth:`advance` integrates all of them in
    one compiled call. With ``params.sphere`` each environment also holds a rigid sphere
    (``sphere``: (E, 18) rows of centre, velocity, angular velocity and frame), at rest at
    its centre after a reset.

    Model error: each environment has its own material constants (masses, inertias,
    stiffnesses), damping and torque factor, the nominal ones of ``params`` until
    :meth:`set_parameters` scales them; ``factors`` (E, 5) holds the factors of
    :data:`~softtrack.sim.params.MODEL_PARAMETERS`, in that order.
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
        # per-environment constants (model error), the nominal ones to start with
        c = self.constants
        self.factors = np.ones((n_envs, len(MODEL_PARAMETERS)))
        self._mass = np.tile(c.mass, (n_envs, 1))  # (E, N+1) kg
        self._inv_mass = np.tile(c.inv_mass, (n_envs, 1))
        self._inertia = np.tile(c.inertia, (n_envs, 1, 1))  # (E, 3, N) kg·m²
        self._inv_inertia = np.tile(c.inv_inertia, (n_envs, 1, 1))
        self._shear = np.tile(c.shear_stiffness, (n_envs, 1, 1))  # (E, 3, N) N
        self._bend = np.tile(c.bend_stiffness, (n_envs, 1, 1))  # (E, 3, N−1) N·m²
        self._volume = np.tile(c.volume, (n_envs, 1))  # (E, N) m³, sets the contact radius
        self._damping = np.full(n_envs, float(p.damping))  # (E,) N·s/m²
        self._penetration = np.zeros(n_envs)  # (E,) m, contact outputs of the last advance
        self._contact_force = np.zeros(n_envs)  # (E,) N
        self._torque_factor = np.ones(n_envs)  # (E,)
        self._scaled_torques = False  # any torque factor ≠ 1
        self.sphere = np.zeros((n_envs, SPHERE_STATE_SIZE))
        self._sphere_params = (
            p.sphere.kernel_params() if p.sphere is not None else np.zeros(7)
        )  # (7,) R, m, J, k, ν, c_v, μ; R = 0: no sphere
        self._sphere_out = np.zeros((n_envs, 6))  # per-arm force, overlap, contact steps
        # each environment's neighbour list of element pairs for rod–rod contact (kept between
        # advances; −1: none yet), softtrack.sim.rod_contact
        self._contact_pairs = np.zeros((n_envs, p.n_elem * p.n_elem, 2), dtype=np.int64)
        self._contact_listed = np.full(n_envs, -1, dtype=np.int64)
        self._contact_anchor = np.zeros((n_envs, 2, 4, p.n_nodes))
        # the arrays above as the engine's structures, built once: the arrays are only ever
        # changed in place
        self._structures = (
            BatchState(
                self.position, self.velocity, self.directors, self.omega, self.torques, self._finite
            ),
            BatchMaterial(
                self._damping,
                self._inv_mass,
                self._mass,
                self._inertia,
                self._inv_inertia,
                self._shear,
                self._bend,
                self._volume,
                c.rest_lengths,
                c.rest_voronoi_lengths,
                c.base_position,
                c.base_directors,
            ),
            BatchContact(
                self._penetration,
                self._contact_force,
                self.sphere,
                self._sphere_params,
                self._sphere_out,
                self._contact_pairs,
                self._contact_listed,
                self._contact_anchor,
            ),
        )
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
        self._penetration[idx] = 0.0
        self._contact_force[idx] = 0.0
        self._sphere_out[idx] = 0.0
        self._contact_listed[idx] = -1
        if self.params.sphere is not None:
            rest = np.zeros(SPHERE_STATE_SIZE)
            rest[:3] = self.params.sphere.center
            rest[9:] = np.eye(3).ravel()
            self.sphere[idx] = rest

    @property
    def has_sphere(self) -> bool:
        """True when the scene holds a rigid sphere (``params.sphere``)."""
        return self.params.sphere is not None

    @property
    def sphere_position(self) -> np.ndarray:
        """(E, 3) the sphere's centre, m (a view; zeros without a sphere)."""
        return self.sphere[:, 0:3]

    @property
    def sphere_velocity(self) -> np.ndarray:
        """(E, 3) the sphere's velocity, m/s (a view)."""
        return self.sphere[:, 3:6]

    def sphere_contact_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The arms' contact with the sphere during the last :meth:`advance` (zeros without
        a sphere).

        Returns:
            force: (E, 2) N, the magnitude of each arm's contact force on the sphere, mean
            over the steps.
            overlap: (E, 2) m, each arm's deepest overlap with the sphere.
            steps: (E, 2) the steps on which each arm overlapped the sphere.
        """
        out = self._sphere_out
        return out[:, 0:2].copy(), out[:, 2:4].copy(), out[:, 4:6].copy()

    def get_state(self, env_indices: Sequence[int] | np.ndarray | None = None) -> RodState:
        """A copy of the listed environments' state (default: all)."""
        idx = slice(None) if env_indices is None else np.asarray(env_indices, dtype=np.intp)
        return RodState(
            self.position[idx].copy(),
            self.velocity[idx].copy(),
            self.directors[idx].copy(),
            self.omega[idx].copy(),
            self.torques[idx].copy(),
            self.time[idx].copy(),
            self._finite[idx].copy(),
            self.sphere[idx].copy() if self.has_sphere else None,
        )

    def set_state(
        self, state: RodState, env_indices: Sequence[int] | np.ndarray | None = None
    ) -> None:
        """Put ``state`` into the listed environments (default: all), bit for bit; a state of
        one environment is copied into every listed one (branching a plan from one state).

        Raises:
            ValueError: the state's arrays do not fit these environments.
        """
        idx = slice(None) if env_indices is None else np.asarray(env_indices, dtype=np.intp)
        k = len(self.time[idx])
        if state.n_envs not in (1, k) or state.position.shape[1:] != self.position.shape[1:]:
            raise ValueError(
                f"a state of {state.n_envs} environments with nodes {state.position.shape[1:]} "
                f"does not fit {k} environments with nodes {self.position.shape[1:]}"
            )
        self.position[idx] = state.position
        self.velocity[idx] = state.velocity
        self.directors[idx] = state.directors
        self.omega[idx] = state.omega
        self.torques[idx] = state.torques
        self.time[idx] = state.time
        self._finite[idx] = state.finite
        if self.has_sphere:
            if state.sphere is None:
                raise ValueError("the state has no sphere, but this scene holds one")
            self.sphere[idx] = state.sphere

    def set_parameters(
        self,
        env_indices: Sequence[int] | np.ndarray | None,
        factors: Mapping[str, ArrayLike],
        *,
        validate: bool = True,
    ) -> None:
        """Scale the listed environments' physical parameters (model error).

        The factors multiply the nominal ``params`` (not the current values), and stay until
        the next call (a :meth:`reset` keeps them). The constants are those of
        :class:`~softtrack.sim.params.RodConstants` built from the scaled ``SimParams``, so
        the radius changes area, second moments, masses, inertias and stiffnesses together, as
        for a rod built with that radius; a factor of exactly 1 gives the nominal constants
        bit for bit. ``torque_scale_factor`` multiplies the torques of :meth:`set_actions`
        (not those given to :meth:`set_element_torques`).

        Args:
            env_indices: (k,) environments (``None``: all).
            factors: some of ``youngs_modulus_scale``, ``density_scale``, ``radius_scale``,
                ``damping_scale``, ``torque_scale_factor`` → a factor (> 0) for all k or a
                (k,) array of them; a missing name means 1 (nominal).
            validate: check each environment's scaled parameters with
                ``SimParams.validate()`` (which includes the stability limit of ``dt``,
                ~10 ms each); callers that checked the worst case of a range may skip it.

        Raises:
            InvalidParameterError: an unknown name, a factor that is not a finite number > 0,
                or (``validate``) scaled parameters that are invalid or unstable at ``dt``.
        """
        idx = (
            np.arange(self.n_envs)
            if env_indices is None
            else np.atleast_1d(np.asarray(env_indices, dtype=np.intp))
        )
        unknown = sorted(set(factors) - set(MODEL_PARAMETERS))
        if unknown:
            raise InvalidParameterError(
                f"unknown model-error factor {unknown[0]!r}; valid names: "
                + ", ".join(MODEL_PARAMETERS)
            )
        table = np.ones((idx.size, len(MODEL_PARAMETERS)))
        for column, name in enumerate(MODEL_PARAMETERS):
            if name in factors:
                table[:, column] = np.broadcast_to(
                    np.asarray(factors[name], dtype=np.float64), (idx.size,)
                )
        if not (np.all(np.isfinite(table)) and np.all(table > 0)):
            raise InvalidParameterError(
                f"model-error factors must be finite numbers > 0, got {table.tolist()}"
            )
        built = []  # everything is checked before anything changes
        for row, env in zip(table, idx.tolist(), strict=True):
            if np.all(row == 1.0):
                built.append((env, row, self.params, self.constants))
                continue
            named = dict(zip(MODEL_PARAMETERS, row.tolist(), strict=True))
            params = scaled_params(self.params, named)
            if validate:
                try:
                    params.validate()
                except InvalidParameterError as err:
                    raise InvalidParameterError(
                        f"environment {env} with factors {named}: {err}"
                    ) from None
            built.append((env, row, params, RodConstants.build(params)))
        for env, row, params, c in built:
            self._mass[env] = c.mass
            self._inv_mass[env] = c.inv_mass
            self._inertia[env] = c.inertia
            self._inv_inertia[env] = c.inv_inertia
            self._shear[env] = c.shear_stiffness
            self._bend[env] = c.bend_stiffness
            self._volume[env] = c.volume
            self._damping[env] = float(params.damping)
            self._torque_factor[env] = row[_TORQUE_COLUMN]
            self.factors[env] = row
        self._scaled_torques = bool(np.any(self._torque_factor != 1.0))

    def set_actions(self, actions: np.ndarray) -> None:
        """Set the element torques from control values.

        Args:
            actions: (E, A, 2, 6) control values (direction 0 normal, 1 binormal), used as
                given (clip them before if needed).
        """
        e, a = self.torques.shape[:2]
        np.matmul(
            np.reshape(actions, (e * a * 2, -1)),
            self._spline_scaled.T,
            out=self.torques.reshape(e * a * 2, -1),
        )
        if self._scaled_torques:
            self.torques *= self._torque_factor[:, None, None, None]

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
        advance_batch(
            *self._structures,
            steps,
            float(p.dt),
            float(p.gravity),
            float(p.contact_k),
            float(p.contact_nu),
        )
        self.time += steps * p.dt

    @property
    def contact_on(self) -> bool:
        """True when the arms touch each other (``params.contact_k`` > 0)."""
        return self.params.contact_k > 0.0 and self.params.n_arms > 1

    def contact_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Contact between the arms during the last :meth:`advance` (zeros without contact).

        Returns:
            penetration: (E,) m, the deepest overlap of the two arms' surfaces over its steps.
            force: (E,) N, the magnitude of the total contact force one arm exerts on the
            other, mean over its steps.
        """
        return self._penetration.copy(), self._contact_force.copy()

    def finite(self) -> np.ndarray:
        """(E,) bool: True where every state value of the environment was finite after the
        last :meth:`advance` (or since a reset)."""
        return self._finite.copy()
