"""Optional backend: the study's scenario built in the real PyElastica 1.0.0.

This module is the independent reference for the numba engine (``docs/physics.md``). It uses
PyElastica's own public classes (``CosseratRod.straight_rod``, ``OneEndFixedBC``,
``GravityForces``, ``PositionVerlet``) and adds two forcing classes of its own:

* :class:`LegacyExplicitDamping` — the PyElastica-0.1 "dissipation coefficient" damping. It
  is a *forcing* (added to ``external_forces`` / ``external_torques`` during the
  synchronize stage), not a PyElastica ``Damping`` module: 1.0.0's dampers act on the rates
  *after* the kick, whereas this project's damping (docs/physics.md) is an explicit force evaluated inside the step
  with the half-step positions (current element lengths) and the start-of-step velocities.
* :class:`ElementCouples` — the actuation: per-element couples in the local frame, normal
  value on d₁ (component 0), binormal on d₂ (component 1), read every step from an array
  owned by :class:`PyElasticaDualArm` (so changing the torques costs no re-finalisation).

Because both are added to ``external_torques``, PyElastica multiplies them, like the
internal couples, by the element dilatation e in ``update_accelerations``
(ω += dt·J⁻¹·(τ_int + τ_ext)·e), which is step 3 of docs/physics.md.

PyElastica is imported lazily, so ``softtrack`` imports without it; every entry point
raises an :class:`ImportError` naming ``pip install pyelastica==1.0.0`` when it is missing.
"""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit

from softtrack.sim.actuation import actions_to_element_torques
from softtrack.sim.open_loop import validate_open_loop_input
from softtrack.sim.params import InvalidParameterError, SimParams

if TYPE_CHECKING:  # pragma: no cover - typing only
    from types import ModuleType

# ``LegacyExplicitDamping`` and ``ElementCouples`` are reachable as module attributes (built
# lazily by ``__getattr__``) but are left out of ``__all__`` so that ``import *`` works
# without PyElastica.
__all__ = ["PyElasticaDualArm", "require_pyelastica", "rollout_pyelastica"]

PYELASTICA_VERSION = "1.0.0"
_INSTALL_HINT = f"pip install pyelastica=={PYELASTICA_VERSION}"
_ZERO_TIME = np.float64(0.0)  # default `time` argument of PyElastica's forcing interface


def require_pyelastica() -> ModuleType:
    """Import and return the ``elastica`` package.

    Returns:
        The imported ``elastica`` module.

    Raises:
        ImportError: PyElastica is not installed; the message says how to install it.
    """
    try:
        import elastica
    except ImportError as exc:  # pragma: no cover - exercised only without pyelastica
        raise ImportError(
            f"the PyElastica backend needs PyElastica {PYELASTICA_VERSION}: {_INSTALL_HINT}"
        ) from exc
    return elastica


# ---- numba kernels (in-place additions to PyElastica's external load arrays) -----------------


@njit(cache=True)
def _add_legacy_damping_forces(
    nu: float, lengths: np.ndarray, velocity: np.ndarray, external_forces: np.ndarray
) -> None:
    """external_forces[:, e] and [:, e+1] −= ½·ν·l_e·½(v_e + v_{e+1}) for every element e.

    Args:
        nu: dissipation coefficient ν_d, N·s/m².
        lengths: (N,) current element lengths, m.
        velocity: (3, N+1) node velocities, m/s.
        external_forces: (3, N+1) N, modified in place.
    """
    n_elem = lengths.shape[0]
    for k in range(n_elem):
        scale = nu * lengths[k]
        for i in range(3):
            half_force = 0.5 * (scale * 0.5 * (velocity[i, k] + velocity[i, k + 1]))
            external_forces[i, k] -= half_force
            external_forces[i, k + 1] -= half_force


@njit(cache=True)
def _add_legacy_damping_torques(
    nu: float, lengths: np.ndarray, omega: np.ndarray, external_torques: np.ndarray
) -> None:
    """external_torques[:, e] −= ν·l_e·ω_e (local frame) for every element e.

    Args:
        nu: dissipation coefficient ν_d, N·s/m².
        lengths: (N,) current element lengths, m.
        omega: (3, N) element angular velocities, rad/s, local frame.
        external_torques: (3, N) N·m, local frame, modified in place.
    """
    n_elem = lengths.shape[0]
    for k in range(n_elem):
        scale = nu * lengths[k]
        for i in range(3):
            external_torques[i, k] -= scale * omega[i, k]


@njit(cache=True)
def _add_element_couples(couples: np.ndarray, external_torques: np.ndarray) -> None:
    """external_torques[0:2, e] += couples[0:2, e] (d₁, d₂ components, local frame).

    Args:
        couples: (2, N) N·m, rows (normal on d₁, binormal on d₂).
        external_torques: (3, N) N·m, local frame, modified in place.
    """
    n_elem = couples.shape[1]
    for k in range(n_elem):
        external_torques[0, k] += couples[0, k]
        external_torques[1, k] += couples[1, k]


# ---- PyElastica classes (built on first use so that PyElastica stays optional) ---------------


@lru_cache(maxsize=1)
def _elastica_classes() -> dict[str, Any]:
    """Define the forcing classes and the simulator type against the installed PyElastica.

    Returns:
        ``{"LegacyExplicitDamping": cls, "ElementCouples": cls, "Simulator": cls}``.
    """
    require_pyelastica()  # the ImportError with the install hint
    from elastica import BaseSystemCollection, Constraints, Contact, Forcing
    from elastica.external_forces import NoForces

    class _LegacyExplicitDamping(NoForces):
        """PyElastica-0.1 explicit damping as a PyElastica 1.0.0 forcing (docs/physics.md).

        Evaluated in the synchronize stage of every Position Verlet step, i.e. with the
        half-step positions (``rod.lengths`` is refreshed by
        ``compute_internal_forces_and_torques`` just before) and the start-of-step
        velocities:

        * force: each element e with current length l_e has f_e = ν_d·l_e·½(v_e + v_{e+1});
          each of its end nodes receives −½·f_e (lab frame);
        * couple: each element receives −ν_d·l_e·ω_e in its local frame.

        Args:
            dissipation: ν_d, N·s/m² (30 in the study).
        """

        def __init__(self, dissipation: float) -> None:
            super().__init__()
            self.dissipation = float(dissipation)

        def apply_forces(self, system: Any, time: np.float64 = _ZERO_TIME) -> None:
            _add_legacy_damping_forces(
                self.dissipation,
                system.lengths,
                system.velocity_collection,
                system.external_forces,
            )

        def apply_torques(self, system: Any, time: np.float64 = _ZERO_TIME) -> None:
            _add_legacy_damping_torques(
                self.dissipation,
                system.lengths,
                system.omega_collection,
                system.external_torques,
            )

    class _ElementCouples(NoForces):
        """Per-element actuation couples in the local frame (docs/physics.md).

        Args:
            couples: (2, N) N·m array, rows (normal on d₁, binormal on d₂). The array is
                *read every step*, not copied: writing into it changes the applied torques.
        """

        def __init__(self, couples: np.ndarray) -> None:
            super().__init__()
            self.couples = couples

        def apply_torques(self, system: Any, time: np.float64 = _ZERO_TIME) -> None:
            _add_element_couples(self.couples, system.external_torques)

    _LegacyExplicitDamping.__name__ = _LegacyExplicitDamping.__qualname__ = "LegacyExplicitDamping"
    _ElementCouples.__name__ = _ElementCouples.__qualname__ = "ElementCouples"
    _LegacyExplicitDamping.__module__ = _ElementCouples.__module__ = __name__

    class _Simulator(BaseSystemCollection, Constraints, Forcing, Contact):
        """Rods + clamp + forcing + contact; no callbacks (the state is read after
        ``advance``)."""

    return {
        "LegacyExplicitDamping": _LegacyExplicitDamping,
        "ElementCouples": _ElementCouples,
        "Simulator": _Simulator,
    }


def __getattr__(name: str) -> Any:
    """Lazy access to the PyElastica forcing classes (``LegacyExplicitDamping``, ``ElementCouples``)."""
    if name in ("LegacyExplicitDamping", "ElementCouples"):
        return _elastica_classes()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# ---- the dual-arm scenario -------------------------------------------------------------------


class PyElasticaDualArm:
    """The clamped multi-arm scenario of ``docs/physics.md`` in PyElastica 1.0.0.

    One ``CosseratRod.straight_rod`` per entry of ``params.base_positions``; each is clamped
    at node 0 / element 0 with ``OneEndFixedBC``, damped by :class:`LegacyExplicitDamping`,
    pulled by ``GravityForces`` (−``params.gravity`` along y, only when it is non-zero) and
    actuated by :class:`ElementCouples`; with ``params.contact_k`` > 0 the two arms touch
    through ``RodRodContact(contact_k, contact_nu)``, registered after the forcings; with
    ``params.sphere`` a ``Sphere`` (gravity as the rods) touches each arm through
    ``RodSphereContact``, registered after that. Time
    integration: PyElastica's ``PositionVerlet``.

    Shapes use A = arms, N = ``params.n_elem`` elements (N + 1 nodes).

    Args:
        params: the scenario settings (validated again here).

    Raises:
        ImportError: PyElastica is missing (``pip install pyelastica==1.0.0``).
        InvalidParameterError: invalid ``params``.
    """

    def __init__(self, params: SimParams | None = None) -> None:
        params = SimParams() if params is None else params
        params.validate()
        ea = require_pyelastica()
        classes = _elastica_classes()
        self.params = params
        self._dt = np.float64(params.dt)
        self._torques = np.zeros((params.n_arms, 2, params.n_elem), dtype=np.float64)

        sim = classes["Simulator"]()
        direction = np.asarray(params.direction, dtype=np.float64)
        normal = np.asarray(params.normal, dtype=np.float64)
        self.rods: list[Any] = []
        for arm, base in enumerate(params.base_positions):
            rod = ea.CosseratRod.straight_rod(
                params.n_elem,
                np.asarray(base, dtype=np.float64),
                direction.copy(),
                normal.copy(),
                params.length,
                params.radius,
                params.density,
                youngs_modulus=params.youngs_modulus,
                shear_modulus=params.shear_modulus,
            )
            sim.append(rod)
            sim.constrain(rod).using(
                ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,)
            )
            if params.damping != 0.0:
                sim.add_forcing_to(rod).using(
                    classes["LegacyExplicitDamping"], dissipation=params.damping
                )
            if params.gravity != 0.0:
                sim.add_forcing_to(rod).using(
                    ea.GravityForces,
                    acc_gravity=np.array([0.0, -float(params.gravity), 0.0]),
                )
            sim.add_forcing_to(rod).using(classes["ElementCouples"], couples=self._torques[arm])
            self.rods.append(rod)
        if params.contact_k > 0.0:
            # registered after every forcing, so it runs after them in the synchronize stage
            sim.detect_contact_between(self.rods[0], self.rods[1]).using(
                ea.RodRodContact, k=np.float64(params.contact_k), nu=np.float64(params.contact_nu)
            )
        self.sphere: Any = None
        if params.sphere is not None:
            self.sphere = self._add_sphere(sim, ea, params)
        sim.finalize()
        self.simulator = sim
        self.stepper = ea.PositionVerlet()
        self._time = np.float64(0.0)

    def _add_sphere(self, sim: Any, ea: ModuleType, params: SimParams) -> Any:
        """The ``Sphere`` of ``params.sphere``, pulled by gravity (when on) and touching each
        arm through ``RodSphereContact``, registered after the rod–rod contact, arm 1 first."""
        spec = params.sphere
        assert spec is not None
        sphere = ea.Sphere(np.asarray(spec.center, dtype=np.float64), spec.radius, spec.density)
        sim.append(sphere)
        if params.gravity != 0.0:
            sim.add_forcing_to(sphere).using(
                ea.GravityForces, acc_gravity=np.array([0.0, -float(params.gravity), 0.0])
            )
        if spec.contact_k > 0.0:
            for rod in self.rods:
                sim.detect_contact_between(rod, sphere).using(
                    ea.RodSphereContact,
                    k=np.float64(spec.contact_k),
                    nu=np.float64(spec.contact_nu),
                    velocity_damping_coefficient=np.float64(spec.velocity_damping),
                    friction_coefficient=np.float64(spec.friction),
                )
        return sphere

    # ---- control --------------------------------------------------------------------------
    def set_element_torques(self, torques: np.ndarray) -> None:
        """Set the per-element couples held from now on.

        Args:
            torques: (A, 2, N) N·m, [arm, direction (0 normal on d₁, 1 binormal on d₂),
                element], local frame.

        Raises:
            InvalidParameterError: wrong shape or non-finite values.
        """
        torques = np.asarray(torques, dtype=np.float64)
        if torques.shape != self._torques.shape:
            raise InvalidParameterError(
                f"torques have shape {torques.shape}; expected {self._torques.shape} = "
                "(arm, direction (0 normal, 1 binormal), element)"
            )
        if not np.all(np.isfinite(torques)):
            raise InvalidParameterError("torques contain a non-finite value")
        self._torques[...] = torques  # in place: the forcing objects hold views of this array

    @property
    def element_torques(self) -> np.ndarray:
        """(A, 2, N) N·m, the couples currently applied (a copy)."""
        return self._torques.copy()

    def advance(self, n_steps: int) -> None:
        """Integrate ``n_steps`` Position Verlet steps of ``params.dt``.

        The loop is PyElastica's ``PositionVerlet.step`` and nothing else: the torques are
        read in place by the forcing objects, and no callback records anything.

        Args:
            n_steps: number of integration steps (≥ 0).
        """
        step = self.stepper.step
        sim = self.simulator
        dt = self._dt
        time = self._time
        for _ in range(int(n_steps)):
            time = step(sim, time, dt)
        self._time = time

    # ---- state ------------------------------------------------------------------------------
    @property
    def time(self) -> float:
        """Simulated time since construction, s."""
        return float(self._time)

    @property
    def positions(self) -> np.ndarray:
        """(A, 3, N+1) node positions, m, lab frame (a copy)."""
        return np.stack([rod.position_collection for rod in self.rods])

    @property
    def velocities(self) -> np.ndarray:
        """(A, 3, N+1) node velocities, m/s, lab frame (a copy)."""
        return np.stack([rod.velocity_collection for rod in self.rods])

    @property
    def directors(self) -> np.ndarray:
        """(A, 3, 3, N) director matrices Q (row r = d_{r+1} in lab coordinates) (a copy)."""
        return np.stack([rod.director_collection for rod in self.rods])

    @property
    def omegas(self) -> np.ndarray:
        """(A, 3, N) element angular velocities, rad/s, local frame (a copy)."""
        return np.stack([rod.omega_collection for rod in self.rods])

    @property
    def sphere_state(self) -> np.ndarray:
        """(18,) the sphere's state row as the engine lays it out (centre m, velocity m/s,
        angular velocity rad/s, frame row-major); raises ValueError without a sphere."""
        if self.sphere is None:
            raise ValueError("this scene holds no sphere (params.sphere is None)")
        sphere = self.sphere
        return np.concatenate(
            [
                sphere.position_collection[:, 0],
                sphere.velocity_collection[:, 0],
                sphere.omega_collection[:, 0],
                sphere.director_collection[:, :, 0].ravel(),
            ]
        )


def rollout_pyelastica(
    actions: np.ndarray | None = None,
    element_torques: np.ndarray | None = None,
    **params: Any,
) -> dict[str, np.ndarray]:
    """Open-loop rollout in PyElastica 1.0.0, recording the state after every control step.

    Exactly one of ``actions`` and ``element_torques`` is given. Each control step's torques
    are held for ``steps_per_action`` integration steps. Actions are mapped through the
    spline actuation matrix (``actions_to_element_torques``) without clipping.

    Args:
        actions: (T, A, 2, 6) control values [control step, arm, direction (0 normal,
            1 binormal), point].
        element_torques: (T, A, 2, N) N·m, per-element couples bypassing the spline.
        **params: overrides of any :class:`~softtrack.sim.params.SimParams` field.

    Returns:
        ``t`` (T+1,) s; ``tip`` (T+1, A, 3) m; ``nodes`` (T+1, A, 3, N+1) m; ``velocities``
        (T+1, A, 3, N+1) m/s; ``directors`` (T+1, A, 3, 3, N); ``omegas`` (T+1, A, 3, N)
        rad/s, local frame; ``element_torques`` (T, A, 2, N) N·m as applied. Index 0 is the
        initial (straight, resting) state.

    Raises:
        ImportError: PyElastica is missing.
        InvalidParameterError: invalid parameters, wrong input shapes, non-finite inputs.
    """
    p = SimParams.from_overrides(**params)
    kind, data = validate_open_loop_input(actions, element_torques, p)
    if kind == "actions":
        torques = actions_to_element_torques(data, p.n_elem, p.torque_scale)
    else:
        torques = data
    arm = PyElasticaDualArm(p)
    n_steps = data.shape[0]
    t = np.empty(n_steps + 1)
    nodes = np.empty((n_steps + 1, p.n_arms, 3, p.n_nodes))
    velocities = np.empty_like(nodes)
    directors = np.empty((n_steps + 1, p.n_arms, 3, 3, p.n_elem))
    omegas = np.empty((n_steps + 1, p.n_arms, 3, p.n_elem))

    def record(k: int) -> None:
        t[k] = arm.time
        nodes[k] = arm.positions
        velocities[k] = arm.velocities
        directors[k] = arm.directors
        omegas[k] = arm.omegas

    record(0)
    for k in range(n_steps):
        arm.set_element_torques(torques[k])
        arm.advance(p.steps_per_action)
        record(k + 1)
    return {
        "t": t,
        "tip": nodes[:, :, :, -1].copy(),
        "nodes": nodes,
        "velocities": velocities,
        "directors": directors,
        "omegas": omegas,
        "element_torques": np.array(torques, dtype=np.float64, copy=True),
    }
