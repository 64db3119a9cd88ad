"""A rigid sphere and its contact with the arms (private numba stages of the engine's step).

The semantics are PyElastica 1.0.0's ``Sphere`` (``elastica/rigidbody/``) integrated by its
``PositionVerlet``, and ``RodSphereContact(k, nu, velocity_damping_coefficient,
friction_coefficient)`` (``elastica/contact_forces.py``, ``_calculate_contact_forces_rod_sphere``
in ``elastica/_contact_functions.py``), applied in the synchronize stage after the forcings
and after the rod–rod contact (registered in that order), with the half-step positions and the
start-of-step velocities.

**The sphere** (centre x, velocity v, frame Q, angular velocity ω in its own frame; mass
m = ρ·4/3·πR³, inertia J = 2/5·m·R² about every axis) moves like a rod node and frame:
the drift x += h·v, Q ← exp(−h[ω]ₓ)·Q; the kick v += dt·F/m, ω += dt·J⁻¹(Jω × ω + τ). F is
m·g (gravity along −y) plus the contact forces. PyElastica 1.0.0's rod–sphere contact acts
through the centre and applies no couple (τ = 0), so a sphere that starts without spin keeps
its orientation.

**Rod–sphere contact**, for one arm and the sphere:

1. skip the arm when the bounding box of its nodes (grown by its largest element radius) and
   the sphere's box do not intersect;
2. for every element i, with c_i the element midpoint and e_i = x_{i+1} − x_i its edge: skip
   it when |c_i − x| ≥ r_i + R + l_i + 2R; the point of the segment c_i + t·e_i (t ∈ [0, 1])
   closest to x gives the unit normal n (from the rod to the sphere) and the overlap
   γ = r_i + R − distance; skip when γ < −1e-5 m. (The segment starts at the midpoint, as
   PyElastica's does: it reaches half an element beyond the tip.)
3. f = ½·[γ > 0]·(k·γ·n − ν·((v − v̄_i)·n)·n), v̄_i the element-mean node velocity;
4. friction in the slip direction s (the tangential part of v − v̄_i):
   f += −min(c_v·|s|, μ·|f|)·s/(|s| + 1e-14), c_v the velocity damping coefficient;
5. the element's nodes receive −f each (the end elements ⅔·f on the end node and 4/3·f on the
   inner one); the sphere receives +2·f.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = [
    "SPHERE_STATE_SIZE",
    "rod_sphere_contact",
    "sphere_drift",
    "sphere_kick",
    "sphere_stage",
]

_FLAGS = {"contract", "arcp", "nsz"}
_GAMMA_CUTOFF = -1e-5  # elements separated by more than this are skipped (m), as PyElastica
_SLIP_EPS = 1e-14  # regularises the slip direction at zero slip, as PyElastica

#: Columns of the sphere state row: centre (0–2, m), velocity (3–5, m/s), angular velocity in
#: the sphere's frame (6–8, rad/s), frame Q row-major (9–17, row r = d_{r+1}).
SPHERE_STATE_SIZE = 18


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def sphere_drift(state, h):
    """Kinematic step of the sphere: x += h·v, Q ← exp(−h[ω]ₓ)·Q (PyElastica's Rodrigues
    rotation). ``state``: (18,) row (:data:`SPHERE_STATE_SIZE`), updated in place; h: s."""
    for c in range(3):
        state[c] += h * state[3 + c]
    w0 = state[6]
    w1 = state[7]
    w2 = state[8]
    theta = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if theta == 0.0:
        return
    w0 /= theta + 1e-14
    w1 /= theta + 1e-14
    w2 /= theta + 1e-14
    theta *= h
    a = math.sin(theta)
    b = 1.0 - math.cos(theta)
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
        q0 = state[9 + j]
        q1 = state[12 + j]
        q2 = state[15 + j]
        state[9 + j] = r00 * q0 + r01 * q1 + r02 * q2
        state[12 + j] = r10 * q0 + r11 * q1 + r12 * q2
        state[15 + j] = r20 * q0 + r21 * q1 + r22 * q2


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def sphere_kick(state, force, mass, inertia, dt):
    """Dynamic step of the sphere: v += dt·F/m, ω += dt·J⁻¹(Jω × ω) (no couple acts on it).

    state: (18,) row, updated in place; force: (3,) N, the total force on the sphere;
    mass: kg; inertia: J, kg·m² (the same about every axis); dt: s.
    """
    for c in range(3):
        state[3 + c] += dt * (force[c] / mass)
    jw0 = inertia * state[6]
    jw1 = inertia * state[7]
    jw2 = inertia * state[8]
    t0 = jw1 * state[8] - jw2 * state[7]
    t1 = jw2 * state[6] - jw0 * state[8]
    t2 = jw0 * state[7] - jw1 * state[6]
    state[6] += dt * (t0 / inertia)
    state[7] += dt * (t1 / inertia)
    state[8] += dt * (t2 / inertia)


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def rod_sphere_contact(
    pos,
    vel,
    lengths,
    inv_lengths,
    volume,
    f_contact,
    n_elem,
    state,
    radius,
    stiffness,
    damping,
    slip_damping,
    friction,
    force_on_sphere,
):
    """Add one arm's contact with the sphere to ``f_contact`` and ``force_on_sphere``.

    Args:
        pos, vel: (3, ≥ n_elem+1) the arm's node positions (m) and velocities (m/s).
        lengths, inv_lengths: (≥ n_elem,) current element lengths (m) and their inverses.
        volume: (≥ n_elem,) element volumes, m³ (the radius r = √(V/(π·l)) as PyElastica).
        f_contact: (3, ≥ n_elem+1) the arm's contact node forces, N; added to.
        n_elem: the arm's elements.
        state: (18,) the sphere's state row; radius: R, m.
        stiffness: k, N/m; damping: ν, N·s/m; slip_damping: c_v, N·s/m; friction: μ.
        force_on_sphere: (3,) N, the force this arm exerts on the sphere is added to it.

    Returns:
        The deepest overlap of this arm with the sphere (0 without contact), m.
    """
    cx = state[0]
    cy = state[1]
    cz = state[2]
    widest = 0.0
    for k in range(n_elem):
        widest = max(widest, math.sqrt(volume[k] * inv_lengths[k] * (1.0 / math.pi)))
    for c in range(3):
        low = pos[c, 0]
        high = pos[c, 0]
        for k in range(1, n_elem + 1):
            low = min(low, pos[c, k])
            high = max(high, pos[c, k])
        if state[c] + radius < low - widest or state[c] - radius > high + widest:
            return 0.0
    deepest = 0.0
    last = n_elem - 1
    for i in range(n_elem):
        mx = 0.5 * (pos[0, i + 1] + pos[0, i])
        my = 0.5 * (pos[1, i + 1] + pos[1, i])
        mz = 0.5 * (pos[2, i + 1] + pos[2, i])
        rod_radius = math.sqrt(volume[i] * inv_lengths[i] * (1.0 / math.pi))
        radii = rod_radius + radius
        dx = mx - cx
        dy = my - cy
        dz = mz - cz
        if math.sqrt(dx * dx + dy * dy + dz * dz) >= radii + (lengths[i] + 2.0 * radius):
            continue
        ex = pos[0, i + 1] - pos[0, i]
        ey = pos[1, i + 1] - pos[1, i]
        ez = pos[2, i + 1] - pos[2, i]
        ee = ex * ex + ey * ey + ez * ez
        t = ((ex * cx + ey * cy + ez * cz) - (mx * ex + my * ey + mz * ez)) / ee
        t = max(0.0, min(t, 1.0))
        nx = cx - mx - t * ex
        ny = cy - my - t * ey
        nz = cz - mz - t * ez
        distance = math.sqrt(nx * nx + ny * ny + nz * nz)
        nx /= distance
        ny /= distance
        nz /= distance
        overlap = radii - distance
        if overlap < _GAMMA_CUTOFF:
            continue
        in_contact = 1.0 if overlap > 0.0 else 0.0
        rx = state[3] - 0.5 * (vel[0, i] + vel[0, i + 1])
        ry = state[4] - 0.5 * (vel[1, i] + vel[1, i + 1])
        rz = state[5] - 0.5 * (vel[2, i] + vel[2, i + 1])
        approach = rx * nx + ry * ny + rz * nz
        fx = 0.5 * in_contact * (-damping * (approach * nx) + stiffness * overlap * nx)
        fy = 0.5 * in_contact * (-damping * (approach * ny) + stiffness * overlap * ny)
        fz = 0.5 * in_contact * (-damping * (approach * nz) + stiffness * overlap * nz)
        sx = rx - approach * nx
        sy = ry - approach * ny
        sz = rz - approach * nz
        slip = math.sqrt(sx * sx + sy * sy + sz * sz)
        coulomb = friction * math.sqrt(fx * fx + fy * fy + fz * fz)
        resist = -min(slip_damping * slip, coulomb) / (slip + _SLIP_EPS)
        fx += resist * sx
        fy += resist * sy
        fz += resist * sz
        share_0 = 2.0 / 3.0 if i == 0 else (4.0 / 3.0 if i == last else 1.0)
        share_1 = 4.0 / 3.0 if i == 0 else (2.0 / 3.0 if i == last else 1.0)
        f_contact[0, i] -= share_0 * fx
        f_contact[1, i] -= share_0 * fy
        f_contact[2, i] -= share_0 * fz
        f_contact[0, i + 1] -= share_1 * fx
        f_contact[1, i + 1] -= share_1 * fy
        f_contact[2, i + 1] -= share_1 * fz
        force_on_sphere[0] += 2.0 * fx
        force_on_sphere[1] += 2.0 * fy
        force_on_sphere[2] += 2.0 * fz
        if in_contact > 0.0:
            deepest = max(deepest, overlap)
    return deepest


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def sphere_stage(
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
    volume,
    n_elem,
    state,
    params,
    gravity,
    dt,
    work,
    out,
):
    """One step's sphere stage after the rod–rod contact: gravity, arm A's then arm B's
    contact with the sphere (into ``f_contact_a/b``), then the sphere's kick.

    Args:
        pos_a … f_contact_b: the two arms' work arrays (:func:`rod_sphere_contact`).
        volume: (≥ n_elem,) element volumes, m³; n_elem: elements per arm.
        state: (18,) the sphere's state row, kicked in place.
        params: (7,) R (m), m (kg), J (kg·m²), k (N/m), ν (N·s/m), c_v (N·s/m), μ.
        gravity: m/s² along −y; dt: s.
        work: (2, 3) scratch: the total force on the sphere and one arm's share, N.
        out: (6,) accumulates per arm the force magnitude (N, 0–1), the deepest overlap (m,
            2–3, a maximum) and the steps with an overlap (4–5).
    """
    total = work[0]
    by_arm = work[1]
    total[0] = 0.0
    total[1] = -gravity * params[1]
    total[2] = 0.0
    for arm in range(2):
        by_arm[:] = 0.0
        depth = rod_sphere_contact(
            pos_a if arm == 0 else pos_b,
            vel_a if arm == 0 else vel_b,
            lengths_a if arm == 0 else lengths_b,
            inv_lengths_a if arm == 0 else inv_lengths_b,
            volume,
            f_contact_a if arm == 0 else f_contact_b,
            n_elem,
            state,
            params[0],
            params[3],
            params[4],
            params[5],
            params[6],
            by_arm,
        )
        out[arm] += math.sqrt(by_arm[0] * by_arm[0] + by_arm[1] * by_arm[1] + by_arm[2] * by_arm[2])
        out[2 + arm] = max(out[2 + arm], depth)
        if depth > 0.0:
            out[4 + arm] += 1.0
        for c in range(3):
            total[c] += by_arm[c]
    sphere_kick(state, total, params[1], params[2], dt)
