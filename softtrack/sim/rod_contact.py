"""Rod–rod contact between the two arms (private numba stage of the engine's step).

The semantics are PyElastica 1.0.0's ``RodRodContact(k, nu)`` (``elastica/contact_forces.py``,
``_calculate_contact_forces_rod_rod`` in ``elastica/_contact_functions.py``), applied where its
``Contact`` mixin applies it: in the synchronize stage, after the forcings (damping, gravity,
actuation), with the half-step positions and the start-of-step velocities. For every pair of
elements (i of arm A, j of arm B), in the order i outer, j inner:

1. skip the pair unless the element start nodes are closer than r_i + r_j + l_i + l_j;
2. the closest points of the two centreline segments give the unit normal n (from A to B) and
   the overlap γ = r_i + r_j − distance; skip the pair when γ < −1e-5;
3. the normal-force term: with F_A, F_B the mean of the element's two node forces (internal plus
   external so far, contact forces of earlier pairs included), f_n = |min((F_B − F_A)·n, 0)|;
4. the spring on the overlap k·γ and the damping ν·(v̄_A − v̄_B)·n (v̄: element-mean velocity),
   halved and applied only while γ > 0: f = (f_n + ½·[γ > 0]·(k·γ + ν·(v̄_A − v̄_B)·n))·n;
5. each element node receives f (A: −f, B: +f); the two end elements of a rod give ⅔·f to the
   end node and 4/3·f to the inner one. So the pair pushes each rod with 2·f in all.

The element radius follows volume conservation, r = √(V/(π·l)), as PyElastica's rods do.

Broad phase (speed only, the result is unchanged): a neighbour list of the element pairs whose
midpoints are within r_i + r_j + ½(l_i + l_j) + 1e-5 m + a margin, kept with each environment
between advances and rebuilt when it is missing (after a reset) or when the nodes have moved
(or the radii and lengths grown) by more than the margin since it was built: whatever moved
the nodes (steps, a new state, new materials), the list then holds every pair within reach.
Each step, a listed pair is evaluated only when its midpoints are within
r_i + r_j + ½(l_i + l_j) + 1e-5 m (+1e-9 m for rounding): farther segments are provably
more than r_i + r_j + 1e-5 m apart, so PyElastica skips them too. Listed pairs are kept in
PyElastica's order, so every pair PyElastica evaluates is evaluated in its order.
(PyElastica's rod bounding boxes never separate here: the bases are exactly 2(r + l) apart.)

The contact forces are kept in their own node array ``f_contact`` that the kick adds to the
internal, damping and gravity forces; a step without contact is therefore bit-identical to the
contact-free engine.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["rod_rod_contact"]

_FLAGS = {"contract", "arcp", "nsz"}
_PARALLEL_TOLERANCE = 1e-6  # 1 − cos² of the angle below which two segments count as parallel
_GAMMA_CUTOFF = -1e-5  # pairs separated by more than this are skipped (m), as PyElastica
_BROAD_PHASE_MARGIN = 1e-9  # m, added to the provable bound so rounding cannot skip a pair
_LIST_MARGIN = 0.01  # m, how far the nodes may move before the neighbour list is rebuilt


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _clamp_unit(x):
    return max(0.0, min(x, 1.0))


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _gap(ax, ay, az, ex, ey, ez, t, bx, by, bz, fx, fy, fz, s):
    """|(b + s·f) − (a + t·e)|, m."""
    dx = bx + s * fx - ax - t * ex
    dy = by + s * fy - ay - t * ey
    dz = bz + s * fz - az - t * ez
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _closest_parameters(ax, ay, az, ex, ey, ez, bx, by, bz, fx, fy, fz):
    """Parameters (t, s) ∈ [0, 1]² of the closest points a + t·e and b + s·f of two segments.

    Non-parallel segments: the stationary point of the squared distance; if it falls outside
    the unit square, the best of the four edges of the square (s = 0, s = 1, t = 0, t = 1,
    each with the other parameter projected and clamped; earlier edges win ties), as
    PyElastica's ``_find_min_dist``. Parallel segments: t from projecting b on the first
    segment, then s from projecting that point on the second.
    """
    ee = ex * ex + ey * ey + ez * ez
    ef = ex * fx + ey * fy + ez * fz
    ff = fx * fx + fy * fy + fz * fz
    ae = ax * ex + ay * ey + az * ez
    af = ax * fx + ay * fy + az * fz
    be = ex * bx + ey * by + ez * bz
    bf = bx * fx + by * fy + bz * fz
    if abs(1.0 - ef * ef / (ee * ff)) < _PARALLEL_TOLERANCE:
        t = _clamp_unit((be - ae) / ee)
        s = _clamp_unit((af + t * ef - bf) / ff)
        return t, s
    s = (ee * (af - bf) + ef * (be - ae)) / (ee * ff - ef * ef)
    t = (ef * s + be - ae) / ee
    if 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0:
        return t, s
    # s = 0: the start of the second segment projected on the first
    t = _clamp_unit((be - ae) / ee)
    s = 0.0
    best = _gap(ax, ay, az, ex, ey, ez, t, bx, by, bz, fx, fy, fz, s)
    # s = 1: its end
    t_end = _clamp_unit((be + ef - ae) / ee)
    gap = _gap(ax, ay, az, ex, ey, ez, t_end, bx, by, bz, fx, fy, fz, 1.0)
    if gap < best:
        t, s, best = t_end, 1.0, gap
    # t = 0: the start of the first segment projected on the second
    s_start = _clamp_unit((af - bf) / ff)
    gap = _gap(ax, ay, az, ex, ey, ez, 0.0, bx, by, bz, fx, fy, fz, s_start)
    if gap < best:
        t, s, best = 0.0, s_start, gap
    # t = 1: its end
    s_end = _clamp_unit((af + ef - bf) / ff)
    gap = _gap(ax, ay, az, ex, ey, ez, 1.0, bx, by, bz, fx, fy, fz, s_end)
    if gap < best:
        t, s = 1.0, s_end
    return t, s


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _reach(volume, inv_lengths, lengths, radius, reach, n_elem, n_pad):
    """radius_k = √(V·(1/l)/π) (m, within an ulp or two of PyElastica's √(V/l/π)) and
    reach_k = r_k + ½l_k + 1e-5 m (m) for real elements, −1 in the padding."""
    for k in range(n_pad):
        r = math.sqrt(volume[k] * inv_lengths[k] * (1.0 / math.pi))
        radius[k] = r
        reach[k] = r + 0.5 * lengths[k] - _GAMMA_CUTOFF if k < n_elem else -1.0


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _drift_since(pos, anchor, reach, n_elem):
    """Largest displacement of the real nodes since ``anchor`` (rows 0–2) plus the largest
    growth of the real elements' reach since then (row 3), m."""
    moved = 0.0
    grown = 0.0
    for k in range(n_elem + 1):
        dx = pos[0, k] - anchor[0, k]
        dy = pos[1, k] - anchor[1, k]
        dz = pos[2, k] - anchor[2, k]
        moved = max(moved, dx * dx + dy * dy + dz * dz)
    for k in range(n_elem):
        grown = max(grown, reach[k] - anchor[3, k])
    return math.sqrt(moved) + grown


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _build_neighbours(pos_a, reach_a, pos_b, reach_b, margin, pairs, n_elem):
    """Write the element pairs (i, j) whose midpoints lie within reach_i + reach_j + margin
    into ``pairs``, i outer and j inner; returns their number."""
    count = 0
    for i in range(n_elem):
        mx = 0.5 * (pos_a[0, i] + pos_a[0, i + 1])
        my = 0.5 * (pos_a[1, i] + pos_a[1, i + 1])
        mz = 0.5 * (pos_a[2, i] + pos_a[2, i + 1])
        for j in range(n_elem):
            dx = 0.5 * (pos_b[0, j] + pos_b[0, j + 1]) - mx
            dy = 0.5 * (pos_b[1, j] + pos_b[1, j + 1]) - my
            dz = 0.5 * (pos_b[2, j] + pos_b[2, j + 1]) - mz
            limit = reach_a[i] + reach_b[j] + margin
            if dx * dx + dy * dy + dz * dz <= limit * limit:
                pairs[count, 0] = i
                pairs[count, 1] = j
                count += 1
    return count


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _unit_normal(pos_a, pos_b, i, j):
    """The unit vector from element i of rod A to element j of rod B between their closest
    centreline points, and their distance (m)."""
    ax = pos_a[0, i]
    ay = pos_a[1, i]
    az = pos_a[2, i]
    bx = pos_b[0, j]
    by = pos_b[1, j]
    bz = pos_b[2, j]
    # edges: PyElastica's l·((x_{k+1} − x_k)/l) is x_{k+1} − x_k to an ulp
    ex = pos_a[0, i + 1] - ax
    ey = pos_a[1, i + 1] - ay
    ez = pos_a[2, i + 1] - az
    fx = pos_b[0, j + 1] - bx
    fy = pos_b[1, j + 1] - by
    fz = pos_b[2, j + 1] - bz
    t, s = _closest_parameters(ax, ay, az, ex, ey, ez, bx, by, bz, fx, fy, fz)
    nx = bx + s * fx - ax - t * ex
    ny = by + s * fy - ay - t * ey
    nz = bz + s * fz - az - t * ez
    distance = math.sqrt(nx * nx + ny * ny + nz * nz)
    return nx / distance, ny / distance, nz / distance, distance


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _refresh_neighbours(pos_a, reach_a, anchor_a, pos_b, reach_b, anchor_b, pairs, n_pairs, n_elem):
    """The neighbour list's length, after rebuilding it (and its anchors) when there is none
    (``n_pairs`` < 0) or the nodes have moved more than the margin since it was built."""
    stale = n_pairs < 0
    if not stale:
        moved = _drift_since(pos_a, anchor_a, reach_a, n_elem) + _drift_since(
            pos_b, anchor_b, reach_b, n_elem
        )
        stale = moved > _LIST_MARGIN - _BROAD_PHASE_MARGIN
    if not stale:
        return n_pairs
    listed = _build_neighbours(pos_a, reach_a, pos_b, reach_b, _LIST_MARGIN, pairs, n_elem)
    for c in range(3):
        for k in range(n_elem + 1):
            anchor_a[c, k] = pos_a[c, k]
            anchor_b[c, k] = pos_b[c, k]
    for k in range(n_elem):
        anchor_a[3, k] = reach_a[k]
        anchor_b[3, k] = reach_b[k]
    return listed


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def rod_rod_contact(
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
    volume,
    stiffness,
    damping,
    pairs,
    n_pairs,
    n_elem,
    n_pad,
    force_on_b,
):
    """The contact forces between rods A and B at this step, into ``f_contact_a/b``.

    Args (per rod, A shown; arrays padded to ≥ n_pad elements / n_pad+1 nodes): pos_a, vel_a
    (3, ·) node positions (m) and velocities (m/s); lengths_a, inv_lengths_a (·,) element
    lengths (m) and their inverses; node_force_a (3, ·) each node's internal, damping and
    gravity force, N (before contact); f_contact_a (3, ·) output, the contact force on each
    node, N; geometry_a (2, ·) work: element radii r and reaches r + ½l + 1e-5 m; anchor_a
    (4, ≥ n_elem+1) the real node positions and element reaches when the neighbour list was
    built. volume (·,) element volumes, m³ (0 in the padding); stiffness k, N/m; damping ν,
    N·s/m. pairs (n_elem², 2) int, the neighbour list, n_pairs its length (< 0: none yet,
    it is built). n_elem real elements per rod; n_pad padded count (loop trip count).
    force_on_b (3,) output, the total contact force on rod B (N); A receives −force_on_b.

    Returns:
        (deepest overlap max(γ) of the pairs in contact or 0, m; the neighbour list's length).
    """
    for c in range(3):
        force_on_b[c] = 0.0
        for k in range(n_pad + 1):
            f_contact_a[c, k] = 0.0
            f_contact_b[c, k] = 0.0
    radius_a, reach_a = geometry_a[0], geometry_a[1]
    radius_b, reach_b = geometry_b[0], geometry_b[1]
    _reach(volume, inv_lengths_a, lengths_a, radius_a, reach_a, n_elem, n_pad)
    _reach(volume, inv_lengths_b, lengths_b, radius_b, reach_b, n_elem, n_pad)
    listed = _refresh_neighbours(
        pos_a, reach_a, anchor_a, pos_b, reach_b, anchor_b, pairs, n_pairs, n_elem
    )
    deepest = 0.0
    last = n_elem - 1
    for p in range(listed):
        i = pairs[p, 0]
        j = pairs[p, 1]
        mx = 0.5 * (pos_b[0, j] + pos_b[0, j + 1] - pos_a[0, i] - pos_a[0, i + 1])
        my = 0.5 * (pos_b[1, j] + pos_b[1, j + 1] - pos_a[1, i] - pos_a[1, i + 1])
        mz = 0.5 * (pos_b[2, j] + pos_b[2, j + 1] - pos_a[2, i] - pos_a[2, i + 1])
        limit = reach_a[i] + reach_b[j] + _BROAD_PHASE_MARGIN
        if mx * mx + my * my + mz * mz > limit * limit:
            continue
        # from here on, PyElastica's narrow phase for this pair
        radii = radius_a[i] + radius_b[j]
        dx = pos_a[0, i] - pos_b[0, j]
        dy = pos_a[1, i] - pos_b[1, j]
        dz = pos_a[2, i] - pos_b[2, j]
        if math.sqrt(dx * dx + dy * dy + dz * dz) >= radii + (lengths_a[i] + lengths_b[j]):
            continue
        nx, ny, nz, distance = _unit_normal(pos_a, pos_b, i, j)
        overlap = radii - distance
        if overlap < _GAMMA_CUTOFF:
            continue
        # normal-force term from the element-mean node forces of both rods
        push = 0.0
        for c in range(3):
            mean_a = 0.5 * (
                (node_force_a[c, i] + f_contact_a[c, i])
                + (node_force_a[c, i + 1] + f_contact_a[c, i + 1])
            )
            mean_b = 0.5 * (
                (node_force_b[c, j] + f_contact_b[c, j])
                + (node_force_b[c, j + 1] + f_contact_b[c, j + 1])
            )
            push += (mean_b - mean_a) * (nx if c == 0 else (ny if c == 1 else nz))
        magnitude = abs(min(push, 0.0))
        if overlap > 0.0:
            approach = (
                0.5 * ((vel_a[0, i] + vel_a[0, i + 1]) - (vel_b[0, j] + vel_b[0, j + 1])) * nx
                + 0.5 * ((vel_a[1, i] + vel_a[1, i + 1]) - (vel_b[1, j] + vel_b[1, j + 1])) * ny
                + 0.5 * ((vel_a[2, i] + vel_a[2, i + 1]) - (vel_b[2, j] + vel_b[2, j + 1])) * nz
            )
            magnitude += 0.5 * (damping * approach + stiffness * overlap)
            deepest = max(deepest, overlap)
        share_a0 = 2.0 / 3.0 if i == 0 else (4.0 / 3.0 if i == last else 1.0)
        share_a1 = 4.0 / 3.0 if i == 0 else (2.0 / 3.0 if i == last else 1.0)
        share_b0 = 2.0 / 3.0 if j == 0 else (4.0 / 3.0 if j == last else 1.0)
        share_b1 = 4.0 / 3.0 if j == 0 else (2.0 / 3.0 if j == last else 1.0)
        for c in range(3):
            f = magnitude * (nx if c == 0 else (ny if c == 1 else nz))
            f_contact_a[c, i] -= f * share_a0
            f_contact_a[c, i + 1] -= f * share_a1
            f_contact_b[c, j] += f * share_b0
            f_contact_b[c, j + 1] += f * share_b1
            force_on_b[c] += 2.0 * f
    return deepest, listed
