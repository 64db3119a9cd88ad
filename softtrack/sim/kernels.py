"""Numba kernels of the clamped Cosserat-rod engine (private).

One compiled call, :func:`advance`, integrates every rod of a batch by ``n_steps`` Position
Verlet steps. Each rod is integrated to the end before the next one starts, so its whole state
(a few kB) stays in L1 cache; rods are independent (the arms never touch).

The discretisation is PyElastica 1.0.0's (Gazzola et al. 2018, RSOS), written out per element:
shear/stretch strain σ = e·Q·t − d₃, curvature from the rotation log map between neighbouring
frames divided by the rest Voronoi length, Voronoi-averaged bend stiffness, the 1/e and 1/ε³
dilatation factors, the Lagrangian-transport and unsteady-dilatation couples, and the
PyElastica-0.1 explicit damping of SPEC §1.

Array layout (float64): positions/velocities (env, arm, 3, node), directors
(env, arm, 3, 3, element) with row r = d_{r+1} in lab coordinates, angular velocities
(env, arm, 3, element) in the local frame, torques (env, arm, 2, element) = (d₁, d₂) couples.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["advance"]

# PyElastica regularises zero lengths and angles with this offset; kept for exact parity.
_EPS = 1e-14
# Below this squared rotation angle the Rodrigues coefficients use their Taylor series.
_SERIES_THETA_SQ = 1e-2


@njit(cache=True, fastmath=False, inline="always")
def _rotate_frames(directors, omega, scale, n_elem):
    """Q_k ← exp(−scale·[ω_k]ₓ)·Q_k for every element k (Rodrigues formula).

    directors: (3, 3, N) frames, updated in place; omega: (3, N) rad/s local frame;
    scale: time, s.
    """
    for k in range(n_elem):
        w0 = scale * omega[0, k]
        w1 = scale * omega[1, k]
        w2 = scale * omega[2, k]
        theta_sq = w0 * w0 + w1 * w1 + w2 * w2
        if theta_sq < _SERIES_THETA_SQ:
            # sin θ / θ and (1 − cos θ) / θ²
            a = 1.0 - theta_sq / 6.0 * (1.0 - theta_sq / 20.0 * (1.0 - theta_sq / 42.0 * (1.0 - theta_sq / 72.0)))
            b = 0.5 - theta_sq / 24.0 * (1.0 - theta_sq / 30.0 * (1.0 - theta_sq / 56.0 * (1.0 - theta_sq / 90.0)))
        else:
            theta = math.sqrt(theta_sq)
            a = math.sin(theta) / (theta + _EPS)
            b = (1.0 - math.cos(theta)) / (theta * (theta + _EPS))
        r00 = 1.0 - b * (w1 * w1 + w2 * w2)
        r11 = 1.0 - b * (w0 * w0 + w2 * w2)
        r22 = 1.0 - b * (w0 * w0 + w1 * w1)
        r01 = a * w2 + b * w0 * w1
        r10 = -a * w2 + b * w0 * w1
        r02 = -a * w1 + b * w0 * w2
        r20 = a * w1 + b * w0 * w2
        r12 = a * w0 + b * w1 * w2
        r21 = -a * w0 + b * w1 * w2
        for j in range(3):
            q0 = directors[0, j, k]
            q1 = directors[1, j, k]
            q2 = directors[2, j, k]
            directors[0, j, k] = r00 * q0 + r01 * q1 + r02 * q2
            directors[1, j, k] = r10 * q0 + r11 * q1 + r12 * q2
            directors[2, j, k] = r20 * q0 + r21 * q1 + r22 * q2


@njit(cache=True, inline="always")
def _drift(position, velocity, directors, omega, half_dt, base_position, base_directors,
           n_elem):
    """Half kinematic step x += ½dt·v, Q ← exp(−½dt[ω]ₓ)Q, then re-apply the clamp."""
    for i in range(3):
        for k in range(n_elem + 1):
            position[i, k] += half_dt * velocity[i, k]
    _rotate_frames(directors, omega, half_dt, n_elem)
    for i in range(3):
        position[i, 0] = base_position[i]
        for j in range(3):
            directors[i, j, 0] = base_directors[i, j]


@njit(cache=True)
def _step_rod(position, velocity, directors, omega, torque, dt, damping, gravity,
              rest_lengths, rest_voronoi, inv_mass, mass, inertia, inv_inertia,
              shear, bend, base_position, base_directors, scratch):
    """One Position Verlet step of one clamped rod (see module docstring for shapes)."""
    n_elem = rest_lengths.shape[0]
    half_dt = 0.5 * dt
    _drift(position, velocity, directors, omega, half_dt, base_position, base_directors, n_elem)

    lengths = scratch[0]
    dil = scratch[1]
    dil_rate = scratch[2]
    vor_dil_inv3 = scratch[3]
    f_elem = scratch[4:7]        # (3, N) Qᵀn/e, lab frame
    n_local = scratch[7:10]      # (3, N) internal stress, local frame
    qt = scratch[10:13]          # (3, N) Q·t, local frame
    couple = scratch[13:16]      # (3, N−1) bend/twist couple τ, local frame
    kxc = scratch[16:19]         # (3, N−1) (κ×τ)·D̂/ε³
    damp_f = scratch[19:22]      # (3, N) element damping force, lab frame

    # --- elements: geometry, strains, stresses
    for k in range(n_elem):
        dx = position[0, k + 1] - position[0, k]
        dy = position[1, k + 1] - position[1, k]
        dz = position[2, k + 1] - position[2, k]
        length = math.sqrt(dx * dx + dy * dy + dz * dz) + _EPS
        lengths[k] = length
        tx = dx / length
        ty = dy / length
        tz = dz / length
        e = length / rest_lengths[k]
        dil[k] = e
        dvx = velocity[0, k + 1] - velocity[0, k]
        dvy = velocity[1, k + 1] - velocity[1, k]
        dvz = velocity[2, k + 1] - velocity[2, k]
        dil_rate[k] = (dx * dvx + dy * dvy + dz * dvz) / length / rest_lengths[k]
        q0 = directors[0, 0, k] * tx + directors[0, 1, k] * ty + directors[0, 2, k] * tz
        q1 = directors[1, 0, k] * tx + directors[1, 1, k] * ty + directors[1, 2, k] * tz
        q2 = directors[2, 0, k] * tx + directors[2, 1, k] * ty + directors[2, 2, k] * tz
        qt[0, k] = q0
        qt[1, k] = q1
        qt[2, k] = q2
        n0 = shear[0, k] * (e * q0)
        n1 = shear[1, k] * (e * q1)
        n2 = shear[2, k] * (e * q2 - 1.0)
        n_local[0, k] = n0
        n_local[1, k] = n1
        n_local[2, k] = n2
        for j in range(3):
            f_elem[j, k] = (directors[0, j, k] * n0 + directors[1, j, k] * n1
                            + directors[2, j, k] * n2) / e
        c = damping * length * 0.5
        damp_f[0, k] = c * (velocity[0, k] + velocity[0, k + 1])
        damp_f[1, k] = c * (velocity[1, k] + velocity[1, k + 1])
        damp_f[2, k] = c * (velocity[2, k] + velocity[2, k + 1])

    # --- Voronoi points: curvature (rotation log map) and bend/twist couple
    for j in range(n_elem - 1):
        m01 = 0.0
        m10 = 0.0
        m02 = 0.0
        m20 = 0.0
        m12 = 0.0
        m21 = 0.0
        trace = 0.0
        for c in range(3):
            a0 = directors[0, c, j + 1]
            a1 = directors[1, c, j + 1]
            a2 = directors[2, c, j + 1]
            b0 = directors[0, c, j]
            b1 = directors[1, c, j]
            b2 = directors[2, c, j]
            m01 += a0 * b1
            m10 += a1 * b0
            m02 += a0 * b2
            m20 += a2 * b0
            m12 += a1 * b2
            m21 += a2 * b1
            trace += a0 * b0 + a1 * b1 + a2 * b2
        trace = min(max(trace, -1.0), 3.0)
        theta = math.acos(0.5 * trace - 0.5) + _EPS
        mag = -0.5 * theta / math.sin(theta) / rest_voronoi[j]
        k0 = mag * (m21 - m12)
        k1 = mag * (m02 - m20)
        k2 = mag * (m10 - m01)
        c0 = bend[0, j] * k0
        c1 = bend[1, j] * k1
        c2 = bend[2, j] * k2
        vor_dil = 0.5 * (lengths[j] + lengths[j + 1]) / rest_voronoi[j]
        inv3 = 1.0 / (vor_dil * vor_dil * vor_dil)
        vor_dil_inv3[j] = inv3
        couple[0, j] = c0 * inv3
        couple[1, j] = c1 * inv3
        couple[2, j] = c2 * inv3
        w = rest_voronoi[j] * inv3
        kxc[0, j] = (k1 * c2 - k2 * c1) * w
        kxc[1, j] = (k2 * c0 - k0 * c2) * w
        kxc[2, j] = (k0 * c1 - k1 * c0) * w

    # --- nodes: forces → velocities
    for i in range(3):
        g = -gravity if i == 1 else 0.0
        for k in range(n_elem + 1):
            f = 0.0
            fd = 0.0
            if k < n_elem:
                f += f_elem[i, k]
                fd += damp_f[i, k]
            if k > 0:
                f -= f_elem[i, k - 1]
                fd += damp_f[i, k - 1]
            f_ext = -0.5 * fd + g * mass[k]
            velocity[i, k] += dt * ((f + f_ext) * inv_mass[k])
    for i in range(3):
        velocity[i, 0] = 0.0

    # --- elements: couples → angular velocities
    for k in range(n_elem):
        e = dil[k]
        w0 = omega[0, k]
        w1 = omega[1, k]
        w2 = omega[2, k]
        jw0 = inertia[0, k] * w0 / e
        jw1 = inertia[1, k] * w1 / e
        jw2 = inertia[2, k] * w2 / e
        unsteady = dil_rate[k] / e
        q0 = qt[0, k]
        q1 = qt[1, k]
        q2 = qt[2, k]
        n0 = n_local[0, k]
        n1 = n_local[1, k]
        n2 = n_local[2, k]
        dl = rest_lengths[k]
        t0 = (q1 * n2 - q2 * n1) * dl + (jw1 * w2 - jw2 * w1) + jw0 * unsteady
        t1 = (q2 * n0 - q0 * n2) * dl + (jw2 * w0 - jw0 * w2) + jw1 * unsteady
        t2 = (q0 * n1 - q1 * n0) * dl + (jw0 * w1 - jw1 * w0) + jw2 * unsteady
        if k < n_elem - 1:
            t0 += couple[0, k] + 0.5 * kxc[0, k]
            t1 += couple[1, k] + 0.5 * kxc[1, k]
            t2 += couple[2, k] + 0.5 * kxc[2, k]
        if k > 0:
            t0 += -couple[0, k - 1] + 0.5 * kxc[0, k - 1]
            t1 += -couple[1, k - 1] + 0.5 * kxc[1, k - 1]
            t2 += -couple[2, k - 1] + 0.5 * kxc[2, k - 1]
        damp = damping * lengths[k]
        ext0 = torque[0, k] - damp * w0
        ext1 = torque[1, k] - damp * w1
        ext2 = -damp * w2
        omega[0, k] = w0 + dt * (inv_inertia[0, k] * (t0 + ext0) * e)
        omega[1, k] = w1 + dt * (inv_inertia[1, k] * (t1 + ext1) * e)
        omega[2, k] = w2 + dt * (inv_inertia[2, k] * (t2 + ext2) * e)
    for i in range(3):
        omega[i, 0] = 0.0

    _drift(position, velocity, directors, omega, half_dt, base_position, base_directors, n_elem)


@njit(cache=True)
def advance(position, velocity, directors, omega, torques, n_steps, dt, damping, gravity,
            rest_lengths, rest_voronoi, inv_mass, mass, inertia, inv_inertia, shear, bend,
            base_position, base_directors):
    """Integrate every rod of the batch by ``n_steps`` steps of ``dt`` seconds, in place.

    Args:
        position, velocity: (E, A, 3, N+1) m and m/s, lab frame.
        directors: (E, A, 3, 3, N), row r = d_{r+1}.
        omega: (E, A, 3, N) rad/s, local frame.
        torques: (E, A, 2, N) N·m, external couples on d₁ and d₂ held over the steps.
        n_steps: number of integration steps.
        dt: time step, s. damping: ν_d, N·s/m². gravity: m/s² along −y.
        rest_lengths (N,), rest_voronoi (N−1,) m; inv_mass, mass (N+1,); inertia,
        inv_inertia (3, N) kg·m²; shear (3, N) N; bend (3, N−1) N·m²;
        base_position (A, 3) m; base_directors (A, 3, 3).
    """
    n_env = position.shape[0]
    n_arm = position.shape[1]
    n_elem = rest_lengths.shape[0]
    scratch = np.zeros((22, n_elem))
    for env in range(n_env):
        for arm in range(n_arm):
            pos = position[env, arm]
            vel = velocity[env, arm]
            dirs = directors[env, arm]
            om = omega[env, arm]
            tq = torques[env, arm]
            for _ in range(n_steps):
                _step_rod(pos, vel, dirs, om, tq, dt, damping, gravity, rest_lengths,
                          rest_voronoi, inv_mass, mass, inertia, inv_inertia, shear, bend,
                          base_position[arm], base_directors[arm], scratch)
