"""Explicit stability limit of the damped Position Verlet scheme on the discretised rod.

The highest-frequency modes of the rod decouple into three families; for each we know the
angular frequency ω and the explicit damping rate γ (per unit inertia) in closed form:

* axial zig-zag of the nodes: ω² = 4E/(ρ·dl²), undamped (the element-averaged damping force
  of an alternating mode vanishes);
* alternating bending rotation of the elements: ω² = 4E/(ρ·dl²) + α_c·G·A/(ρ·I₁), damped at
  γ = ν_d/(ρ·I₁) by the couple −ν_d·l·ω;
* alternating twist: ω² = 4G/(ρ·dl²), γ = ν_d/(ρ·I₃).

Position Verlet with an explicit damping kick maps (x, v) of the test equation
x'' = −ω²x − γx' by a 2×2 matrix; a mode is stable while that matrix's spectral radius is ≤ 1.
The limit is found by bisection on dt. At the SPEC defaults it is ≈ 2.2e-4 s, which matches
the time step where the full nonlinear engine starts to diverge.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from softtrack.sim.params import SimParams

__all__ = ["stable_time_step_limit", "mode_is_stable"]


def _amplification_matrix(omega: float, gamma: float, dt: float) -> np.ndarray:
    """(2, 2) map of (x, v) over one step: half drift, damped kick, half drift."""
    h = 0.5 * dt
    drift = np.array([[1.0, h], [0.0, 1.0]])
    kick = np.array([[1.0, 0.0], [-dt * omega**2, 1.0 - dt * gamma]])
    return drift @ kick @ drift


def mode_is_stable(omega: float, gamma: float, dt: float) -> bool:
    """True if the damped test mode (ω rad/s, γ 1/s) does not grow at time step dt (s)."""
    radius = max(abs(np.linalg.eigvals(_amplification_matrix(omega, gamma, dt))))
    return bool(radius <= 1.0 + 1e-12)


def _critical_dt(omega: float, gamma: float) -> float:
    """Largest stable dt (s) for one mode, by bisection on [0, 2/ω]."""
    lo, hi = 0.0, 2.0 / omega if omega > 0 else 2.0 / max(gamma, 1e-300)
    while not mode_is_stable(omega, gamma, hi) and hi - lo > 1e-15:
        mid = 0.5 * (lo + hi)
        if mode_is_stable(omega, gamma, mid):
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-6 * hi:
            break
    return lo if not mode_is_stable(omega, gamma, hi) else hi


def stable_time_step_limit(params: "SimParams") -> float:
    """The largest stable time step (s) for ``params``' material, discretisation and damping."""
    dl = params.length / params.n_elem
    rho, e_mod, g_mod = params.density, params.youngs_modulus, params.shear_modulus
    area = params.area
    i1 = params.second_moment
    i3 = 2.0 * i1
    modes = [
        (math.sqrt(4.0 * e_mod / (rho * dl**2)), 0.0),
        (
            math.sqrt(4.0 * e_mod / (rho * dl**2) + params.shear_correction * g_mod * area / (rho * i1)),
            params.damping / (rho * i1),
        ),
        (math.sqrt(4.0 * g_mod / (rho * dl**2)), params.damping / (rho * i3)),
    ]
    return min(_critical_dt(omega, gamma) for omega, gamma in modes)
