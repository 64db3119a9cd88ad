"""Numba kernels of the clamped Cosserat-rod engine (private).

One compiled call, :func:`advance`, integrates every rod of a batch by ``n_steps`` Position
Verlet steps; the batch travels as three named structures (:class:`BatchState`,
:class:`BatchMaterial`, :class:`BatchContact`). A step is a sequence of stages named after the
PyElastica function they mirror (:func:`_compute_internal_stresses`,
:func:`_compute_internal_torques_and_kick`, :func:`_compute_internal_forces`, the contact stages,
the drift).

Inside a kernel a rod's work arrays travel as the tuple built once before the loops
(:func:`_rod_work`, :func:`_material_work`, :func:`_rest_geometry`) into the elastic stages
and the loading; the contact stages (:func:`~softtrack.sim.rod_contact.rod_rod_contact`,
:func:`~softtrack.sim.sphere_contact.sphere_stage`) take their arrays one by one: as tuples,
even built once, or wrapped in one more inlined stage, they cost the contact and sphere steps
12-18 % (numba's reference counting; session 26, ``benchmarks/bench_engine_versions.py``).
Every stage keeps the arithmetic of the code it was split from, operation for operation: the
state after 150 control steps of the free, contact and held-sphere scenes is bit for bit the
one before the split. (Written otherwise, LLVM may fuse multiply-adds differently: 1e-15 m in
a contact step, which the closed loop turns into a 1 % different RMSE of a shipped contact
policy; ``benchmarks/check_exported_policies.py`` checks it.)

Without contact each rod is integrated to the end before the next one starts, so
its whole state (a few kB) stays in L1 cache; with rod–rod contact (:mod:`softtrack.sim.rod_contact`)
the rods of an environment advance together and the contact stage runs inside every step,
between the forces and the kick, as PyElastica's synchronize stage.

The discretisation is PyElastica 1.0.0's (Gazzola et al. 2018, RSOS), written out per element:
shear/stretch strain σ = e·Q·t − d₃, curvature from the rotation log map between neighbouring
frames divided by the rest Voronoi length, Voronoi-averaged bend stiffness, the 1/e and 1/ε³
dilatation factors, the Lagrangian-transport and unsteady-dilatation couples, and the
PyElastica-0.1 explicit damping of docs/physics.md.

Speed: the loops run over elements with unit stride and no branches, so LLVM vectorises them.
Each rod is copied into work arrays padded to ``n_pad`` elements (the next multiple of 8 above
N, a compile-time constant of the kernel built for it), so every loop has a constant trip count
that is a whole number of 8-wide AVX-512 vectors: no scalar remainder iterations, and the tip
node and last element need no special cases. The padding is exactly inert (zero stiffness,
damping and weight, unit masses and rest lengths, zero velocities; padded curvatures are
masked to 0 before the log map so they cannot produce NaN).
Small rotations (all of them, in practice) use Taylor series instead of sin/cos/acos; a rod
with a large rotation in a step falls back to the trigonometric formulas for that step.

Development note: numba caches each kernel keyed on this file's modification time, and the
contact stage (:mod:`softtrack.sim.rod_contact`) is inlined into the contact kernel; after editing
contact.py alone, touch this file (or delete ``__pycache__/*.nbi``) so the kernel recompiles.

Array layout (float64): positions/velocities (env, arm, 3, node), directors
(env, arm, 3, 3, element) with row r = d_{r+1} in lab coordinates, angular velocities
(env, arm, 3, element) in the local frame, torques (env, arm, 2, element) = (d₁, d₂) couples.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit

from softtrack.sim.rod_contact import rod_rod_contact
from softtrack.sim.sphere_contact import sphere_drift, sphere_stage

__all__ = ["BatchContact", "BatchMaterial", "BatchState", "advance"]

# PyElastica regularises zero lengths and angles with this offset; kept for parity.
_EPS = 1e-14
# Series are used below these squared angles; their truncation error is < 1e-13 relative.
_ROTATION_SERIES_MAX = 1e-2  # θ² of a half-step frame rotation
_CURVATURE_SERIES_MIN_COS = 0.0  # the trig-free log map holds up to 90° between neighbours

_FLAGS = {"contract", "arcp", "nsz"}  # no 'nnan'/'ninf': NaN detection must keep working


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _rotation_coefficients_series(theta_sq):
    """(sin θ/θ, (1 − cos θ)/θ²) by Taylor series, for θ² < _ROTATION_SERIES_MAX."""
    a = 1.0 - theta_sq * (
        1.0 / 6.0
        - theta_sq * (1.0 / 120.0 - theta_sq * (1.0 / 5040.0 - theta_sq * (1.0 / 362880.0)))
    )
    b = 0.5 - theta_sq * (
        1.0 / 24.0
        - theta_sq * (1.0 / 720.0 - theta_sq * (1.0 / 40320.0 - theta_sq * (1.0 / 3628800.0)))
    )
    return a, b


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _rotation_coefficients_trig(theta_sq):
    """(sin θ/θ, (1 − cos θ)/θ²) for any squared angle θ², as PyElastica computes them."""
    theta = math.sqrt(theta_sq)
    return math.sin(theta) / (theta + _EPS), (1.0 - math.cos(theta)) / (theta * (theta + _EPS))


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _rotate_frames(directors, omega, scale, n_elem, coefficients):
    """Q_k ← exp(−scale·[ω_k]ₓ)·Q_k for every element k (Rodrigues formula).

    directors: (3, 3, N), updated in place; omega: (3, N) rad/s, local frame; scale: s;
    coefficients: one of the ``_rotation_coefficients_*`` functions.
    """
    for k in range(n_elem):
        w0 = scale * omega[0, k]
        w1 = scale * omega[1, k]
        w2 = scale * omega[2, k]
        a, b = coefficients(w0 * w0 + w1 * w1 + w2 * w2)
        bw0 = b * w0
        bw1 = b * w1
        r00 = 1.0 - b * (w1 * w1 + w2 * w2)
        r11 = 1.0 - b * (w0 * w0 + w2 * w2)
        r22 = 1.0 - bw0 * w0 - bw1 * w1
        r01 = a * w2 + bw0 * w1
        r10 = -a * w2 + bw0 * w1
        r02 = -a * w1 + bw0 * w2
        r20 = a * w1 + bw0 * w2
        r12 = a * w0 + bw1 * w2
        r21 = -a * w0 + bw1 * w2
        for j in range(3):
            q0 = directors[0, j, k]
            q1 = directors[1, j, k]
            q2 = directors[2, j, k]
            directors[0, j, k] = r00 * q0 + r01 * q1 + r02 * q2
            directors[1, j, k] = r10 * q0 + r11 * q1 + r12 * q2
            directors[2, j, k] = r20 * q0 + r21 * q1 + r22 * q2


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _drift(position, velocity, directors, omega, drift_dt, base_position, base_directors, n_pad):
    """Kinematic step x += h·v, Q ← exp(−h[ω]ₓ)Q with h = drift_dt, then re-apply the clamp.

    Runs over the ``n_pad`` padded nodes/elements; padded entries have v = ω = 0 and stay put.
    """
    for i in range(3):
        for k in range(n_pad):
            position[i, k] += drift_dt * velocity[i, k]
    largest = 0.0
    for k in range(n_pad):
        theta_sq = (
            drift_dt
            * drift_dt
            * (omega[0, k] * omega[0, k] + omega[1, k] * omega[1, k] + omega[2, k] * omega[2, k])
        )
        largest = max(largest, theta_sq)
    if largest < _ROTATION_SERIES_MAX:
        _rotate_frames(directors, omega, drift_dt, n_pad, _rotation_coefficients_series)
    else:
        _rotate_frames(directors, omega, drift_dt, n_pad, _rotation_coefficients_trig)
    for i in range(3):
        position[i, 0] = base_position[i]
        for j in range(3):
            directors[i, j, 0] = base_directors[i, j]


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _log_map_factor_halving(sin_sq, cos_theta):
    """θ / sin θ for θ ∈ [0, π/2] (cos θ ≥ 0) without trigonometric calls (vectorisable).

    Three half-angle steps take tan(θ/2) = sin θ/(1 + cos θ) to x = tan(θ/8) ≤ 0.199, where
    atan(x)/x is an alternating series; then θ/sin θ = 8·atan(x)·(1 + tan²(θ/2))/(2 tan(θ/2)).
    Relative error < 1e-15 over the whole range (checked against 40-digit arithmetic).
    """
    t_sq = sin_sq / ((1.0 + cos_theta) * (1.0 + cos_theta))  # tan²(θ/2)
    r1 = 1.0 + math.sqrt(1.0 + t_sq)
    t2_sq = t_sq / (r1 * r1)  # tan²(θ/4)
    r2 = 1.0 + math.sqrt(1.0 + t2_sq)
    x = t2_sq / (r2 * r2)  # tan²(θ/8)
    # atan(√x)/√x = Σ (−x)ⁿ/(2n+1), n ≤ 11
    atan_ratio = 1.0 - x * (
        1.0 / 3.0
        - x
        * (
            1.0 / 5.0
            - x
            * (
                1.0 / 7.0
                - x
                * (
                    1.0 / 9.0
                    - x
                    * (
                        1.0 / 11.0
                        - x
                        * (
                            1.0 / 13.0
                            - x
                            * (
                                1.0 / 15.0
                                - x
                                * (
                                    1.0 / 17.0
                                    - x * (1.0 / 19.0 - x * (1.0 / 21.0 - x * (1.0 / 23.0)))
                                )
                            )
                        )
                    )
                )
            )
        )
    )
    return 4.0 * atan_ratio * (1.0 + t_sq) / (r1 * r2)


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _log_map_factor_trig(sin_sq, cos_theta):
    """θ / sin θ for any angle θ ∈ [0, π], as PyElastica computes it."""
    theta = math.acos(min(max(cos_theta, -1.0), 1.0)) + _EPS
    return theta / math.sin(theta)


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _curvatures(directors, inv_rest_voronoi, voronoi_mask, kappa, cosines, n_pad, log_map_factor):
    """κ_j = log(Q_{j+1} Q_jᵀ)^∨ / D̂_j at the Voronoi points, local frame, 1/m.

    Also stores cos θ_j of the angle between neighbouring frames in ``cosines``, so the caller
    can see whether the series (valid for cos θ ≥ _CURVATURE_SERIES_MIN_COS) held.
    ``log_map_factor`` is one of the ``_log_map_factor_*`` functions. Runs over ``n_pad``
    points; where ``voronoi_mask`` is 0 (padding) the angle is replaced by 0 before the log
    map (so no NaN even for θ = π), giving κ = 0 and cos θ = 1; where it is 1 nothing changes.
    """
    for j in range(n_pad):
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
        mask = voronoi_mask[j]
        v0 = (m21 - m12) * mask
        v1 = (m02 - m20) * mask
        v2 = (m10 - m01) * mask
        sin_sq = 0.25 * (v0 * v0 + v1 * v1 + v2 * v2)
        cos_theta = (0.5 * trace - 0.5) * mask + (1.0 - mask)
        cosines[j] = cos_theta
        mag = -0.5 * log_map_factor(sin_sq, cos_theta) * inv_rest_voronoi[j]
        kappa[0, j] = mag * v0
        kappa[1, j] = mag * v1
        kappa[2, j] = mag * v2


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _compute_internal_stresses(rod, material, rest, n_pad):
    """Geometry, strains and stresses of one rod's elements and Voronoi points (outputs in
    place): PyElastica's ``_compute_geometry_from_state``, ``_compute_shear_stretch_strains``,
    ``_compute_internal_shear_stretch_stresses_from_model``, ``_compute_dilatation_rate``,
    ``_compute_bending_twist_strains``, ``_compute_internal_bending_twist_stresses_from_model``
    and the PyElastica-0.1 damping force.

    Per rod (3, n_pad+1) nodes and (3, n_pad) elements: lengths, 1/lengths (m, 1/m); qt = Q·t;
    n_local (N, local frame); f_elem = Qᵀn/e (N, lab frame); dil_rate (1/s); damp_f, the
    damping force of each element on each of its nodes (N); kappa (1/m), couple and kxc (N·m)
    at the Voronoi points; cosines of the angles between neighbouring frames. ``rod``,
    ``material``, ``rest``: the tuples of :func:`_rod_work`, :func:`_material_work` and
    :func:`_rest_geometry`.
    """
    pos, vel, dirs = rod[:3]
    lengths, inv_lengths, dil_rate, f_elem, n_local, qt, damp_f, couple, kxc = rod[5:14]
    kappa, cosines, damp_coef = material[:3]
    shear_k, bend_k = material[8:]
    rest_len, inv_rest_len, rest_vor, inv_rest_vor, vor_mask = rest
    for k in range(n_pad):
        dx = pos[0, k + 1] - pos[0, k]
        dy = pos[1, k + 1] - pos[1, k]
        dz = pos[2, k + 1] - pos[2, k]
        length = math.sqrt(dx * dx + dy * dy + dz * dz) + _EPS
        lengths[k] = length
        inv_lengths[k] = 1.0 / length
    for k in range(n_pad):
        inv_length = inv_lengths[k]
        tx = (pos[0, k + 1] - pos[0, k]) * inv_length
        ty = (pos[1, k + 1] - pos[1, k]) * inv_length
        tz = (pos[2, k + 1] - pos[2, k]) * inv_length
        e = lengths[k] * inv_rest_len[k]
        q0 = dirs[0, 0, k] * tx + dirs[0, 1, k] * ty + dirs[0, 2, k] * tz
        q1 = dirs[1, 0, k] * tx + dirs[1, 1, k] * ty + dirs[1, 2, k] * tz
        q2 = dirs[2, 0, k] * tx + dirs[2, 1, k] * ty + dirs[2, 2, k] * tz
        qt[0, k] = q0
        qt[1, k] = q1
        qt[2, k] = q2
        n_local[0, k] = shear_k[0, k] * (e * q0)
        n_local[1, k] = shear_k[1, k] * (e * q1)
        n_local[2, k] = shear_k[2, k] * (e * q2 - 1.0)
    for k in range(n_pad):
        inv_e = rest_len[k] * inv_lengths[k]
        n0 = n_local[0, k] * inv_e
        n1 = n_local[1, k] * inv_e
        n2 = n_local[2, k] * inv_e
        f_elem[0, k] = dirs[0, 0, k] * n0 + dirs[1, 0, k] * n1 + dirs[2, 0, k] * n2
        f_elem[1, k] = dirs[0, 1, k] * n0 + dirs[1, 1, k] * n1 + dirs[2, 1, k] * n2
        f_elem[2, k] = dirs[0, 2, k] * n0 + dirs[1, 2, k] * n1 + dirs[2, 2, k] * n2
    for k in range(n_pad):
        dx = pos[0, k + 1] - pos[0, k]
        dy = pos[1, k + 1] - pos[1, k]
        dz = pos[2, k + 1] - pos[2, k]
        dvx = vel[0, k + 1] - vel[0, k]
        dvy = vel[1, k + 1] - vel[1, k]
        dvz = vel[2, k + 1] - vel[2, k]
        dil_rate[k] = (dx * dvx + dy * dvy + dz * dvz) * inv_lengths[k] * inv_rest_len[k]
    for k in range(n_pad):
        c = damp_coef[k] * lengths[k]
        damp_f[0, k] = c * (vel[0, k] + vel[0, k + 1])
        damp_f[1, k] = c * (vel[1, k] + vel[1, k + 1])
        damp_f[2, k] = c * (vel[2, k] + vel[2, k + 1])

    # --- Voronoi points: curvature and bend/twist couple
    _curvatures(dirs, inv_rest_vor, vor_mask, kappa, cosines, n_pad, _log_map_factor_halving)
    smallest_cos = 1.0
    for j in range(n_pad):
        smallest_cos = min(smallest_cos, cosines[j])
    if smallest_cos < _CURVATURE_SERIES_MIN_COS:
        _curvatures(dirs, inv_rest_vor, vor_mask, kappa, cosines, n_pad, _log_map_factor_trig)
    for j in range(n_pad):
        vor_dil = 0.5 * (lengths[j] + lengths[j + 1]) * inv_rest_vor[j]
        inv3 = 1.0 / (vor_dil * vor_dil * vor_dil)
        k0 = kappa[0, j]
        k1 = kappa[1, j]
        k2 = kappa[2, j]
        c0 = bend_k[0, j] * k0
        c1 = bend_k[1, j] * k1
        c2 = bend_k[2, j] * k2
        couple[0, j] = c0 * inv3
        couple[1, j] = c1 * inv3
        couple[2, j] = c2 * inv3
        w = 0.5 * rest_vor[j] * inv3
        kxc[0, j] = (k1 * c2 - k2 * c1) * w
        kxc[1, j] = (k2 * c0 - k0 * c2) * w
        kxc[2, j] = (k0 * c1 - k1 * c0) * w


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _compute_internal_torques_and_kick(rod, material, rest, env_damping, dt, n_pad):
    """PyElastica's ``_compute_internal_torques`` with the damping and actuation couples, then
    the angular kick: ω += dt·J⁻¹·τ·e for every element (element 0 clamped), τ the internal,
    damping and actuation couples (local frame)."""
    om, tq, lengths, inv_lengths, dil_rate = rod[3:8]
    n_local, qt, _damp_f, couple, kxc = rod[9:14]
    inert, inv_inert = material[6:8]
    rest_len, inv_rest_len = rest[:2]
    for k in range(1, n_pad + 1):
        ti0 = couple[0, k] - couple[0, k - 1] + kxc[0, k] + kxc[0, k - 1]
        ti1 = couple[1, k] - couple[1, k - 1] + kxc[1, k] + kxc[1, k - 1]
        ti2 = couple[2, k] - couple[2, k - 1] + kxc[2, k] + kxc[2, k - 1]
        e = lengths[k] * inv_rest_len[k]
        inv_e = rest_len[k] * inv_lengths[k]
        w0 = om[0, k]
        w1 = om[1, k]
        w2 = om[2, k]
        jw0 = inert[0, k] * w0 * inv_e
        jw1 = inert[1, k] * w1 * inv_e
        jw2 = inert[2, k] * w2 * inv_e
        unsteady = dil_rate[k] * inv_e
        q0 = qt[0, k]
        q1 = qt[1, k]
        q2 = qt[2, k]
        n0 = n_local[0, k]
        n1 = n_local[1, k]
        n2 = n_local[2, k]
        dl = rest_len[k]
        damp = env_damping * lengths[k]
        t0 = (
            ti0
            + (q1 * n2 - q2 * n1) * dl
            + (jw1 * w2 - jw2 * w1)
            + jw0 * unsteady
            + tq[0, k]
            - damp * w0
        )
        t1 = (
            ti1
            + (q2 * n0 - q0 * n2) * dl
            + (jw2 * w0 - jw0 * w2)
            + jw1 * unsteady
            + tq[1, k]
            - damp * w1
        )
        t2 = ti2 + (q0 * n1 - q1 * n0) * dl + (jw0 * w1 - jw1 * w0) + jw2 * unsteady - damp * w2
        om[0, k] = w0 + dt * (inv_inert[0, k] * t0 * e)
        om[1, k] = w1 + dt * (inv_inert[1, k] * t1 * e)
        om[2, k] = w2 + dt * (inv_inert[2, k] * t2 * e)
    for i in range(3):
        om[i, 0] = 0.0


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _rod_work(width):
    """One rod's work arrays, ``width`` entries per row: positions, velocities, directors,
    angular velocities, torques, lengths, 1/lengths, dilatation rates, f_elem, n_local, qt,
    damp_f, couple, kxc; for contact the contact node forces, the element radii and reaches,
    and the forces on the nodes before contact (:func:`_compute_internal_forces`); the clamp's
    position (3,) and directors (3, 3)."""
    return (
        np.zeros((3, width)),
        np.zeros((3, width)),
        np.zeros((3, 3, width)),
        np.zeros((3, width)),
        np.zeros((2, width)),
        np.ones(width),
        np.ones(width),
        np.zeros(width),
        np.zeros((3, width)),
        np.zeros((3, width)),
        np.zeros((3, width)),
        np.zeros((3, width)),
        np.zeros((3, width)),
        np.zeros((3, width)),
        np.zeros((3, width)),
        np.zeros((2, width)),
        np.zeros((3, width)),
        np.empty(3),
        np.empty((3, 3)),
    )


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _second_rod_work(width, first):
    """The work arrays of a second rod whose kick runs right after its own forces: the arrays
    only that kick reads (dilatation rates, n_local, qt, couples) are ``first``'s, so the
    two rods' work arrays fit the L1 cache together."""
    own = _rod_work(width)
    shared = (first[7], own[8], first[9], first[10], own[11], first[12], first[13])
    return own[:7] + shared + own[14:]


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _material_work(width):
    """The work arrays shared by the rods of an environment, inert in the padding:
    curvatures and cosines (per step), damping coefficients, 1/masses, masses, volumes,
    inertias, 1/inertias, shear and bend stiffnesses (:func:`_load_material` fills them)."""
    return (
        np.zeros((3, width)),
        np.ones(width),
        np.zeros(width),
        np.ones(width),
        np.zeros(width),
        np.zeros(width),
        np.ones((3, width)),
        np.ones((3, width)),
        np.zeros((3, width)),
        np.zeros((3, width)),
    )


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _rest_geometry(rest_lengths, rest_voronoi, width):
    """Padded rest lengths, their inverses, rest Voronoi lengths, their inverses and the
    Voronoi mask (1 at real points, 0 in the padding)."""
    n_elem = rest_lengths.shape[0]
    rest_len = np.ones(width)
    inv_rest_len = np.ones(width)
    rest_vor = np.ones(width)
    inv_rest_vor = np.ones(width)
    vor_mask = np.zeros(width)
    for k in range(n_elem):
        rest_len[k] = rest_lengths[k]
        inv_rest_len[k] = 1.0 / rest_lengths[k]
    for j in range(n_elem - 1):
        rest_vor[j] = rest_voronoi[j]
        inv_rest_vor[j] = 1.0 / rest_voronoi[j]
        vor_mask[j] = 1.0
    return rest_len, inv_rest_len, rest_vor, inv_rest_vor, vor_mask


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _load_material(env, material_fields, material):
    """Copy environment ``env``'s material (model error, :class:`BatchMaterial` fields) into
    the padded work arrays (``material``: :func:`_material_work`)."""
    damping, inv_mass, mass, inertia, inv_inertia, shear, bend, volume = material_fields[:8]
    damp_coef, inv_m, weight_m, vol, inert, inv_inert, shear_k, bend_k = material[2:]
    n_elem = volume.shape[1]
    for k in range(n_elem):
        damp_coef[k] = -0.25 * damping[env]
        vol[k] = volume[env, k]
        for i in range(3):
            inert[i, k] = inertia[env, i, k]
            inv_inert[i, k] = inv_inertia[env, i, k]
            shear_k[i, k] = shear[env, i, k]
    for j in range(n_elem - 1):
        for i in range(3):
            bend_k[i, j] = bend[env, i, j]
    for k in range(n_elem + 1):
        inv_m[k] = inv_mass[env, k]
        weight_m[k] = mass[env, k]


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _load_rod(state_fields, material_fields, env, arm, rod, n_pad):
    """Copy one rod's state, torques and clamp (:class:`BatchState`, :class:`BatchMaterial`
    fields) into its padded work arrays (``rod``: :func:`_rod_work`); padded nodes continue
    the last element's line beyond the tip, at rest, with its frame."""
    position, velocity, directors, omega, torques = state_fields[:5]
    base_position, base_directors = material_fields[10:]
    pos, vel, dirs, om, tq = rod[:5]
    base_pos, base_dirs = rod[17:]
    n_elem = omega.shape[3]
    for i in range(3):
        for k in range(n_elem + 1):
            pos[i, k] = position[env, arm, i, k]
            vel[i, k] = velocity[env, arm, i, k]
        step_out = pos[i, n_elem] - pos[i, n_elem - 1]
        for k in range(n_elem + 1, n_pad + 1):
            pos[i, k] = pos[i, n_elem] + (k - n_elem) * step_out
            vel[i, k] = 0.0
        for k in range(n_elem):
            om[i, k] = omega[env, arm, i, k]
        for k in range(n_elem, n_pad + 1):
            om[i, k] = 0.0
        for j in range(3):
            for k in range(n_elem):
                dirs[i, j, k] = directors[env, arm, i, j, k]
            for k in range(n_elem, n_pad + 1):
                dirs[i, j, k] = dirs[i, j, n_elem - 1]
        base_pos[i] = base_position[arm, i]
        for j in range(3):
            base_dirs[i, j] = base_directors[arm, i, j]
    for i in range(2):
        for k in range(n_elem):
            tq[i, k] = torques[env, arm, i, k]


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _store_rod(rod, env, arm, state_fields):
    """Copy a rod's real entries (``rod``: :func:`_rod_work`) back into the batch state
    (:class:`BatchState` fields); returns their sum (NaN and inf propagate through it, so one
    reduction checks the whole state)."""
    position, velocity, directors, omega = state_fields[:4]
    pos, vel, dirs, om = rod[:4]
    n_elem = omega.shape[3]
    checksum = 0.0
    for i in range(3):
        for k in range(n_elem + 1):
            position[env, arm, i, k] = pos[i, k]
            velocity[env, arm, i, k] = vel[i, k]
            checksum += pos[i, k] + vel[i, k]
        for k in range(n_elem):
            omega[env, arm, i, k] = om[i, k]
            checksum += om[i, k]
        for j in range(3):
            for k in range(n_elem):
                directors[env, arm, i, j, k] = dirs[i, j, k]
                checksum += dirs[i, j, k]
    return checksum


class BatchState(NamedTuple):
    """The state a kernel integrates in place (module docstring: array layout).

    Attributes:
        position, velocity: (E, A, 3, N+1) m and m/s. directors: (E, A, 3, 3, N).
        omega: (E, A, 3, N) rad/s. torques: (E, A, 2, N) N·m, held over the steps.
        finite: (E,) bool output: False where any state value of the environment is NaN/inf.
    """

    position: np.ndarray
    velocity: np.ndarray
    directors: np.ndarray
    omega: np.ndarray
    torques: np.ndarray
    finite: np.ndarray


class BatchMaterial(NamedTuple):
    """The rods' material, per environment (model error), their rest geometry and clamps.

    Attributes:
        damping: (E,) ν_d, N·s/m². inv_mass, mass: (E, N+1) 1/kg and kg.
        inertia, inv_inertia: (E, 3, N) kg·m² and its inverse. shear: (E, 3, N) N.
        bend: (E, 3, N−1) N·m². volume: (E, N) m³ (sets the contact radius).
        rest_lengths: (N,) m. rest_voronoi: (N−1,) m. base_position: (A, 3) m.
        base_directors: (A, 3, 3).
    """

    damping: np.ndarray
    inv_mass: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    inv_inertia: np.ndarray
    shear: np.ndarray
    bend: np.ndarray
    volume: np.ndarray
    rest_lengths: np.ndarray
    rest_voronoi: np.ndarray
    base_position: np.ndarray
    base_directors: np.ndarray


class BatchContact(NamedTuple):
    """Contact between the two arms and with the rigid sphere: outputs and kept state.

    Attributes:
        penetration: (E,) output, the deepest overlap of the two arms over the steps, m.
        contact_force: (E,) output, the magnitude of the total contact force between the arms,
            mean over the steps, N.
        sphere: (E, 18) the rigid sphere's state rows (:mod:`softtrack.sim.sphere_contact`),
            integrated in place when ``sphere_params[0]`` > 0.
        sphere_params: (7,) radius R (m; 0: no sphere), mass (kg), inertia 2/5·m·R² (kg·m²),
            contact k (N/m), ν (N·s/m), velocity damping coefficient (N·s/m), friction μ.
        sphere_out: (E, 6) output with a sphere: per arm the magnitude of its contact force on
            the sphere, mean over the steps (N, columns 0–1), its deepest overlap (m, 2–3) and
            its steps with an overlap (4–5).
        contact_pairs: (E, N², 2) int64, contact_listed: (E,) int64 and contact_anchor:
            (E, 2, 4, N+1): each environment's neighbour list of element pairs, its length (−1:
            none, built at the next step) and the nodes and reaches it was built at
            (:mod:`softtrack.sim.rod_contact`); kept between calls.
    """

    penetration: np.ndarray
    contact_force: np.ndarray
    sphere: np.ndarray
    sphere_params: np.ndarray
    sphere_out: np.ndarray
    contact_pairs: np.ndarray
    contact_listed: np.ndarray
    contact_anchor: np.ndarray


# Padding (elements n_elem.., nodes n_elem+1.., Voronoi points n_elem−1..) is inert in both
# kernels: zero stiffness, damping, gravity and volume, unit rest lengths, masses and inertias,
# zero velocities, so it exerts no force or couple on the real rod, never moves and never
# touches anything. Every work array is allocated in the kernel and copied from the batch
# once per environment and advance; the step loops touch nothing else.


def _build_advance(n_pad):
    """The contact-free integrator for rods padded to ``n_pad`` elements (a multiple of 8,
    > n_elem): each rod is integrated to the end before the next starts.

    ``n_pad`` is a closure constant, so every element/node loop has a compile-time trip count
    that is a multiple of the vector width: no scalar remainder iterations.
    """
    width = n_pad + 8  # room for the node/element just past the padded range (index n_pad)

    @njit(cache=True, fastmath=_FLAGS, error_model="numpy")
    def advance_padded(state_fields, material_fields, n_steps, dt, gravity):
        position, finite = state_fields[0], state_fields[5]
        damping = material_fields[0]
        rest = _rest_geometry(material_fields[8], material_fields[9], width)
        rod = _rod_work(width)
        pos, vel, dirs, om = rod[:4]
        f_elem, damp_f = rod[8], rod[11]
        material = _material_work(width)
        inv_m, weight_m = material[3:5]
        base_pos, base_dirs = rod[17:]
        half_dt = 0.5 * dt
        for env in range(position.shape[0]):
            _load_material(env, material_fields, material)
            checksum = 0.0
            for arm in range(position.shape[1]):
                _load_rod(state_fields, material_fields, env, arm, rod, n_pad)
                # The closing half drift of one step and the opening half drift of the next
                # are one drift of dt (same velocities, same rotation axis), so they are fused.
                _drift(pos, vel, dirs, om, half_dt, base_pos, base_dirs, n_pad)
                for step in range(n_steps):
                    _compute_internal_stresses(rod, material, rest, n_pad)
                    # v += dt·F/m, F = internal + damping + gravity in one pass (written out
                    # here: as an inlined helper this loop ran 25 % slower)
                    for i in range(3):
                        g = -gravity if i == 1 else 0.0
                        for k in range(1, n_pad + 1):
                            f = (
                                f_elem[i, k]
                                - f_elem[i, k - 1]
                                + damp_f[i, k]
                                + damp_f[i, k - 1]
                                + g * weight_m[k]
                            )
                            vel[i, k] += dt * (f * inv_m[k])
                        vel[i, 0] = 0.0
                    _compute_internal_torques_and_kick(rod, material, rest, damping[env], dt, n_pad)
                    drift_dt = half_dt if step == n_steps - 1 else dt
                    _drift(pos, vel, dirs, om, drift_dt, base_pos, base_dirs, n_pad)
                checksum += _store_rod(rod, env, arm, state_fields)
            finite[env] = math.isfinite(checksum)

    return advance_padded


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _compute_internal_forces(f_elem, damp_f, weight, gravity, node_force, n_pad):
    """node_force (3, ·) ← each node's internal Δ(Qᵀn/e) + damping + gravity force, N (the
    forces before contact; the sum in the contact-free kernel's order)."""
    for i in range(3):
        g = -gravity if i == 1 else 0.0
        node_force[i, 0] = f_elem[i, 0] + damp_f[i, 0] + g * weight[0]
        for k in range(1, n_pad + 1):
            node_force[i, k] = (
                f_elem[i, k] - f_elem[i, k - 1] + damp_f[i, k] + damp_f[i, k - 1] + g * weight[k]
            )


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _norm3(vector):
    """The length of a (3,) vector."""
    return math.sqrt(vector[0] * vector[0] + vector[1] * vector[1] + vector[2] * vector[2])


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _store_contact_env(env, rod_a, rod_b, state_fields, contact_fields, totals, n_steps):
    """Copy an environment's two rods back and write its contact outputs
    (:class:`BatchContact` fields): ``totals`` (deepest overlap, m; summed force on rod B, N;
    the neighbour list's length), the sphere's mean forces; sets ``finite``."""
    penetration, contact_force, sphere, sphere_params, sphere_out = contact_fields[:5]
    penetration[env] = totals[0]
    contact_force[env] = totals[1] / max(n_steps, 1)
    contact_fields[6][env] = totals[2]
    checksum = _store_rod(rod_a, env, 0, state_fields)
    checksum += _store_rod(rod_b, env, 1, state_fields)
    if sphere_params[0] > 0.0:
        sphere_out[env, 0:2] /= max(n_steps, 1)
        checksum += np.sum(sphere[env])
    state_fields[5][env] = math.isfinite(checksum)


def _build_advance_contact(n_pad):
    """The integrator of two rods in contact (:mod:`softtrack.sim.rod_contact`), padded as
    :func:`_build_advance`: the two rods advance together, with the contact stages between
    the forces and the kick of every step (PyElastica's synchronize stage)."""
    width = n_pad + 8

    @njit(cache=True, fastmath=_FLAGS, error_model="numpy")
    def advance_contact(
        state_fields, material_fields, contact_fields, n_steps, dt, gravity, contact_k, contact_nu
    ):
        damping = material_fields[0]
        sphere, sphere_params, sphere_out = contact_fields[2:5]
        contact_pairs, contact_listed, contact_anchor = contact_fields[5:]
        n_elem = material_fields[8].shape[0]
        rest = _rest_geometry(material_fields[8], material_fields[9], width)
        rod_a = _rod_work(width)
        rod_b = _second_rod_work(width, rod_a)
        pos_a, vel_a, dirs_a, om_a = rod_a[:4]
        pos_b, vel_b, dirs_b, om_b = rod_b[:4]
        lengths_a, inv_lengths_a, lengths_b, inv_lengths_b = rod_a[5:7] + rod_b[5:7]
        f_elem_a, damp_f_a, f_elem_b, damp_f_b = rod_a[8], rod_a[11], rod_b[8], rod_b[11]
        f_contact_a, geometry_a, node_force_a, base_pos_a, base_dirs_a = rod_a[14:]
        f_contact_b, geometry_b, node_force_b, base_pos_b, base_dirs_b = rod_b[14:]
        material = _material_work(width)
        inv_m, weight_m, vol = material[3:6]
        force_on_b = np.zeros(3)
        half_dt = 0.5 * dt
        has_sphere = sphere_params[0] > 0.0
        sphere_work = np.zeros((2, 3))
        for env in range(material_fields[0].shape[0]):
            _load_material(env, material_fields, material)
            _load_rod(state_fields, material_fields, env, 0, rod_a, n_pad)
            _load_rod(state_fields, material_fields, env, 1, rod_b, n_pad)
            deepest = force_total = 0.0
            env_damping = damping[env]
            n_pairs, pairs = contact_listed[env], contact_pairs[env]
            anchor_a, anchor_b = contact_anchor[env, 0], contact_anchor[env, 1]
            body = sphere[env]
            sphere_out[env, :] = 0.0
            _drift(pos_a, vel_a, dirs_a, om_a, half_dt, base_pos_a, base_dirs_a, n_pad)
            _drift(pos_b, vel_b, dirs_b, om_b, half_dt, base_pos_b, base_dirs_b, n_pad)
            if has_sphere:
                sphere_drift(body, half_dt)
            for step in range(n_steps):
                _compute_internal_stresses(rod_a, material, rest, n_pad)
                _compute_internal_torques_and_kick(rod_a, material, rest, env_damping, dt, n_pad)
                _compute_internal_stresses(rod_b, material, rest, n_pad)
                _compute_internal_torques_and_kick(rod_b, material, rest, env_damping, dt, n_pad)
                _compute_internal_forces(f_elem_a, damp_f_a, weight_m, gravity, node_force_a, n_pad)
                _compute_internal_forces(f_elem_b, damp_f_b, weight_m, gravity, node_force_b, n_pad)
                if contact_k > 0.0:
                    depth, n_pairs = rod_rod_contact(
                        pos_a,
                        vel_a,
                        lengths_a,
                        inv_lengths_a,
                        node_force_a,
                        f_contact_a,
                        geometry_a,
                        anchor_a,
                        pos_b,
                        vel_b,
                        lengths_b,
                        inv_lengths_b,
                        node_force_b,
                        f_contact_b,
                        geometry_b,
                        anchor_b,
                        vol,
                        contact_k,
                        contact_nu,
                        pairs,
                        n_pairs,
                        n_elem,
                        n_pad,
                        force_on_b,
                    )
                    deepest = max(deepest, depth)
                    force_total += _norm3(force_on_b)
                else:
                    f_contact_a[:, : n_pad + 1] = 0.0
                    f_contact_b[:, : n_pad + 1] = 0.0
                if has_sphere:
                    sphere_stage(
                        pos_a,
                        vel_a,
                        lengths_a,
                        inv_lengths_a,
                        f_contact_a,
                        pos_b,
                        vel_b,
                        lengths_b,
                        inv_lengths_b,
                        f_contact_b,
                        vol,
                        n_elem,
                        body,
                        sphere_params,
                        gravity,
                        dt,
                        sphere_work,
                        sphere_out[env],
                    )
                drift_dt = half_dt if step == n_steps - 1 else dt
                # v += dt·F/m, F = (internal + damping + gravity) + contact; with no contact
                # force the sum is bit for bit the contact-free kernel's
                for i in range(3):
                    for k in range(1, n_pad + 1):
                        vel_a[i, k] += dt * ((node_force_a[i, k] + f_contact_a[i, k]) * inv_m[k])
                        vel_b[i, k] += dt * ((node_force_b[i, k] + f_contact_b[i, k]) * inv_m[k])
                    vel_a[i, 0] = 0.0
                    vel_b[i, 0] = 0.0
                _drift(pos_a, vel_a, dirs_a, om_a, drift_dt, base_pos_a, base_dirs_a, n_pad)
                _drift(pos_b, vel_b, dirs_b, om_b, drift_dt, base_pos_b, base_dirs_b, n_pad)
                if has_sphere:
                    sphere_drift(body, drift_dt)
            totals = (deepest, force_total, n_pairs)
            _store_contact_env(env, rod_a, rod_b, state_fields, contact_fields, totals, n_steps)

    return advance_contact


_KERNELS: dict[tuple[int, bool], Callable[..., None]] = {}  # (n_pad, contact) → compiled kernel


def advance(
    state: BatchState,
    material: BatchMaterial,
    contact: BatchContact,
    n_steps: int,
    dt: float,
    gravity: float,
    contact_k: float,
    contact_nu: float,
) -> None:
    """Integrate every rod of the batch by ``n_steps`` steps of ``dt`` seconds, in place.

    Args:
        state: positions, velocities, directors, angular velocities, torques, and the
            ``finite`` output (:class:`BatchState`).
        material: per-environment material, rest geometry and clamps (:class:`BatchMaterial`).
        contact: contact outputs, the sphere and the neighbour lists (:class:`BatchContact`);
            used only with contact on (two arms, ``contact_k`` > 0 or a sphere).
        n_steps: number of integration steps. dt: time step, s. gravity: m/s² along −y.
        contact_k: rod–rod contact stiffness, N/m (0: no contact, the arms pass through each
            other). contact_nu: contact damping, N·s/m.
    """
    n_pad = (material.rest_lengths.shape[0] // 8 + 1) * 8  # multiple of 8, > N: room for the tip
    contact_on = (contact_k > 0.0 or contact.sphere_params[0] > 0.0) and state.position.shape[
        1
    ] == 2
    key = (n_pad, contact_on)
    kernel = _KERNELS.get(key)
    if kernel is None:
        builder = _build_advance_contact if contact_on else _build_advance
        kernel = _KERNELS[key] = builder(n_pad)
    # plain tuples: numba types a named tuple argument in Python, ~3 µs each call (a third of
    # a one-environment control step); the kernel names the fields again
    if contact_on:
        kernel(
            tuple(state),
            tuple(material),
            tuple(contact),
            n_steps,
            dt,
            gravity,
            contact_k,
            contact_nu,
        )
    else:
        kernel(tuple(state), tuple(material), n_steps, dt, gravity)
