"""Explicit stability limit of the damped Position Verlet scheme on the discretised rod.

The highest-frequency modes of the rod are zig-zag modes that alternate from one node (or
element) to the next. Each family is a small linear system M·q'' = −K·q − C·q' with closed-form
stiffness and damping per unit inertia, A = M⁻¹K and D = M⁻¹C:

* axial zig-zag of the nodes: A = 4E/(ρ·dl²), undamped (the element-averaged damping force of an
  alternating mode vanishes);
* bending: the sideways zig-zag of the nodes u and the alternating rotation of the elements φ
  are coupled through the shear stiffness s = α_c·G·A. With m = ρ·A·dl and J = ρ·I₁·dl,
  A = [[4s/(m·dl), 2s/m], [2s/J, (s·dl + 4EI/dl)/J]] and D = diag(0, ν_d/(ρ·I₁)) (the couple
  −ν_d·l·ω damps rotation only);
* twist: A = 4G/(ρ·dl²), D = ν_d/(ρ·I₃).

* contact (only with ``contact_k`` > 0): the element-mean approach of the two arms, a mode the
  rod's zig-zag stiffness does not touch. A pair in contact pushes each node of its two
  elements with ½(k·γ + ν·γ'); the node next to the tip takes 4/3 of its end element's share
  plus all of its inner element's, and both arms move, so A = (7/3)·k/m, D = (7/3)·ν/m with m
  the interior node mass ρ·A·dl. (The engine stays stable up to about 3–5 times this k in the
  hardest press test, tests/test_contact.py: several pairs rarely peak on one node.)

Position Verlet with an explicit damping kick maps (q, q') by the matrix
drift(½dt)·kick(dt)·drift(½dt); a mode is stable while its spectral radius is ≤ 1. The limit
is found by bisection on dt. At the default settings it is 2.32e-4 s; the full nonlinear engine
diverges within 0.3 % of this limit at damping 0–60 (tests/test_engine_validation.py).
"""

from __future__ import annotations

import numpy as np

from softtrack.sim.rod_properties import RodProperties

__all__ = [
    "contact_mode",
    "contact_stiffness_limit",
    "mode_is_stable",
    "rod_modes",
    "stable_time_step_limit",
]


def _step_matrix(stiffness: np.ndarray, damping: np.ndarray, dt: float) -> np.ndarray:
    """(2n, 2n) map of (q, q') over one step: half drift, damped kick, half drift."""
    n = stiffness.shape[0]
    eye = np.eye(n)
    zero = np.zeros((n, n))
    drift = np.block([[eye, 0.5 * dt * eye], [zero, eye]])
    kick = np.block([[eye, zero], [-dt * stiffness, eye - dt * damping]])
    return drift @ kick @ drift


def mode_is_stable(stiffness: np.ndarray, damping: np.ndarray, dt: float) -> bool:
    """True if the mode q'' = −A·q − D·q' (A, D: (n, n), 1/s² and 1/s) does not grow at dt (s)."""
    radius = np.max(np.abs(np.linalg.eigvals(_step_matrix(stiffness, damping, dt))))
    return bool(radius <= 1.0 + 1e-12)


def _critical_dt(stiffness: np.ndarray, damping: np.ndarray) -> float:
    """Largest stable dt (s) of one mode, by bisection to 1e-6 relative."""
    omega_max = float(np.sqrt(np.max(np.abs(np.linalg.eigvals(stiffness)))))
    hi = 2.0 / omega_max  # the undamped limit; damping only lowers it here
    lo = 0.0
    while hi - lo > 1e-6 * hi:
        mid = 0.5 * (lo + hi)
        if mode_is_stable(stiffness, damping, mid):
            lo = mid
        else:
            hi = mid
    return lo


def rod_modes(params: RodProperties) -> list[tuple[np.ndarray, np.ndarray]]:
    """(A, D) pairs of the axial, coupled bending and twist zig-zag modes (module docstring)."""
    dl = params.length / params.n_elem
    rho, e_mod, g_mod = params.density, params.youngs_modulus, params.shear_modulus
    i1 = params.second_moment
    i3 = 2.0 * i1
    s = params.shear_correction * g_mod * params.area
    m = rho * params.area * dl
    j = rho * i1 * dl
    bending = np.array(
        [[4.0 * s / (m * dl), 2.0 * s / m], [2.0 * s / j, (s * dl + 4.0 * e_mod * i1 / dl) / j]]
    )
    return [
        (np.array([[4.0 * e_mod / (rho * dl**2)]]), np.zeros((1, 1))),
        (bending, np.diag([0.0, params.damping / (rho * i1)])),
        (np.array([[4.0 * g_mod / (rho * dl**2)]]), np.array([[params.damping / (rho * i3)]])),
    ]


_CONTACT_NODE_SHARE = 7.0 / 3.0  # 2 arms × (4/3 + 1) × ½, module docstring


def contact_mode(
    params: RodProperties, stiffness: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(A, D) of the contact mode (module docstring), 1/s² and 1/s.

    Args:
        params: the settings (their ``contact_nu``, and ``contact_k`` unless ``stiffness``).
        stiffness: a contact stiffness to use instead of ``params.contact_k``, N/m.
    """
    k = params.contact_k if stiffness is None else stiffness
    node_mass = params.density * params.area * params.length / params.n_elem
    share = _CONTACT_NODE_SHARE / node_mass
    return np.array([[share * k]]), np.array([[share * params.contact_nu]])


def stable_time_step_limit(params: RodProperties) -> float:
    """The largest stable time step (s) for ``params``' material, discretisation, damping and
    (when ``contact_k`` > 0) contact."""
    modes = rod_modes(params)
    if params.contact_k > 0.0:
        modes.append(contact_mode(params))
    return min(_critical_dt(a, d) for a, d in modes)


def contact_stiffness_limit(params: RodProperties) -> float:
    """The largest contact stiffness (N/m) stable at ``params.dt`` with ``params.contact_nu``,
    to 1e-4 relative; 0 when the contact damping alone is unstable there."""
    if not mode_is_stable(*contact_mode(params, 0.0), params.dt):
        return 0.0
    node_mass = params.density * params.area * params.length / params.n_elem
    hi = 4.0 * node_mass / (_CONTACT_NODE_SHARE * params.dt**2)  # the undamped limit, ×1
    lo = 0.0
    while hi - lo > 1e-4 * hi:
        mid = 0.5 * (lo + hi)
        if mode_is_stable(*contact_mode(params, mid), params.dt):
            lo = mid
        else:
            hi = mid
    return lo
