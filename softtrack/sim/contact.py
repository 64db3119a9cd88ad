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

Broad phase (speed only, the result is unchanged): PyElastica's bounding boxes of the two rods
(nodes ± (max r + max l)), then a per-pair test on element midpoints that skips only pairs whose
segments are provably farther apart than r_i + r_j + 1e-5 (a midpoint distance above
r_i + r_j + ½(l_i + l_j) + 1e-5 + 1e-9), so that every pair PyElastica evaluates is evaluated,
in PyElastica's order.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["rod_rod_contact"]

_FLAGS = {"contract", "arcp", "nsz"}
_PARALLEL_TOLERANCE = 1e-6  # 1 − cos² of the angle below which two segments count as parallel
_GAMMA_CUTOFF = -1e-5  # pairs separated by more than this are skipped (m), as PyElastica
_BROAD_PHASE_MARGIN = 1e-9  # m, added to the provable bound so rounding cannot skip a pair


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
def _element_geometry(pos, lengths, volume, radius, edge, n_pad):
    """Radius r = √(V/(π·l)) (m) and edge l·t (m) of every element, t = (x_{k+1} − x_k)/l."""
    for k in range(n_pad):
        radius[k] = math.sqrt(volume[k] / lengths[k] / math.pi)
    for i in range(3):
        for k in range(n_pad):
            edge[i, k] = lengths[k] * ((pos[i, k + 1] - pos[i, k]) / lengths[k])


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _boxes_apart(pos_a, radius_a, lengths_a, pos_b, radius_b, lengths_b, n_elem):
    """True when the rods' bounding boxes (nodes ± (max r + max l)) do not intersect."""
    reach_a = 0.0
    reach_b = 0.0
    max_ra = 0.0
    max_la = 0.0
    max_rb = 0.0
    max_lb = 0.0
    for k in range(n_elem):
        max_ra = max(max_ra, radius_a[k])
        max_la = max(max_la, lengths_a[k])
        max_rb = max(max_rb, radius_b[k])
        max_lb = max(max_lb, lengths_b[k])
    reach_a = max_ra + max_la
    reach_b = max_rb + max_lb
    for i in range(3):
        low_a = pos_a[i, 0]
        high_a = pos_a[i, 0]
        low_b = pos_b[i, 0]
        high_b = pos_b[i, 0]
        for k in range(1, n_elem + 1):
            low_a = min(low_a, pos_a[i, k])
            high_a = max(high_a, pos_a[i, k])
            low_b = min(low_b, pos_b[i, k])
            high_b = max(high_b, pos_b[i, k])
        if high_b + reach_b < low_a - reach_a or low_b - reach_b > high_a + reach_a:
            return True
    return False


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def _candidate_pairs(pos_a, edge_a, radius_a, lengths_a, pos_b, edge_b, radius_b, lengths_b,
                     reach_b, pairs, n_elem, n_pad):
    """Write the element pairs (i, j) that may touch into ``pairs`` in PyElastica's order.

    ``reach_b`` (n_pad,) work array. Returns the number of pairs written.
    """
    for j in range(n_pad):
        reach_b[j] = (radius_b[j] + 0.5 * lengths_b[j] - _GAMMA_CUTOFF + _BROAD_PHASE_MARGIN
                      if j < n_elem else -1.0)
    count = 0
    for i in range(n_elem):
        mx = pos_a[0, i] + 0.5 * edge_a[0, i]
        my = pos_a[1, i] + 0.5 * edge_a[1, i]
        mz = pos_a[2, i] + 0.5 * edge_a[2, i]
        reach_a = radius_a[i] + 0.5 * lengths_a[i]
        for j in range(n_elem):
            dx = pos_b[0, j] + 0.5 * edge_b[0, j] - mx
            dy = pos_b[1, j] + 0.5 * edge_b[1, j] - my
            dz = pos_b[2, j] + 0.5 * edge_b[2, j] - mz
            reach = reach_a + reach_b[j]
            if dx * dx + dy * dy + dz * dz <= reach * reach:
                pairs[count, 0] = i
                pairs[count, 1] = j
                count += 1
    return count


@njit(cache=True, fastmath=_FLAGS, error_model="numpy", inline="always")
def rod_rod_contact(pos_a, vel_a, lengths_a, force_int_a, force_ext_a, radius_a, edge_a,
                    pos_b, vel_b, lengths_b, force_int_b, force_ext_b, radius_b, edge_b,
                    volume, stiffness, damping, pairs, reach_b, n_elem, n_pad, force_on_b):
    """Add the contact forces between rods A and B to their external node forces.

    Args:
        pos_a, vel_a: (3, ≥ n_pad+1) node positions (m) and velocities (m/s) of rod A.
        lengths_a: (≥ n_pad,) current element lengths, m.
        force_int_a: (3, ≥ n_pad+1) internal node forces, N (read).
        force_ext_a: (3, ≥ n_pad+1) external node forces so far, N (contact added in place).
        radius_a, edge_a: (≥ n_pad,) and (3, ≥ n_pad) work arrays (element radius, m; edge, m).
        pos_b … edge_b: the same for rod B.
        volume: (≥ n_pad,) element volumes, m³ (0 in the padding).
        stiffness: k, N/m; damping: ν, N·s/m.
        pairs: (n_elem², 2) int work array; reach_b: (≥ n_pad,) work array.
        n_elem: real elements per rod; n_pad: padded element count (loop trip count).
        force_on_b: (3,) output, the total contact force on rod B (N); A receives its negative.

    Returns:
        The deepest overlap max(γ) over the pairs in contact, m (0 when none overlaps).
    """
    force_on_b[0] = 0.0
    force_on_b[1] = 0.0
    force_on_b[2] = 0.0
    _element_geometry(pos_a, lengths_a, volume, radius_a, edge_a, n_pad)
    _element_geometry(pos_b, lengths_b, volume, radius_b, edge_b, n_pad)
    if _boxes_apart(pos_a, radius_a, lengths_a, pos_b, radius_b, lengths_b, n_elem):
        return 0.0
    n_pairs = _candidate_pairs(pos_a, edge_a, radius_a, lengths_a, pos_b, edge_b, radius_b,
                               lengths_b, reach_b, pairs, n_elem, n_pad)
    deepest = 0.0
    last = n_elem - 1
    for p in range(n_pairs):
        i = pairs[p, 0]
        j = pairs[p, 1]
        ax = pos_a[0, i]
        ay = pos_a[1, i]
        az = pos_a[2, i]
        bx = pos_b[0, j]
        by = pos_b[1, j]
        bz = pos_b[2, j]
        radii = radius_a[i] + radius_b[j]
        dx = ax - bx
        dy = ay - by
        dz = az - bz
        if math.sqrt(dx * dx + dy * dy + dz * dz) >= radii + (lengths_a[i] + lengths_b[j]):
            continue
        ex = edge_a[0, i]
        ey = edge_a[1, i]
        ez = edge_a[2, i]
        fx = edge_b[0, j]
        fy = edge_b[1, j]
        fz = edge_b[2, j]
        t, s = _closest_parameters(ax, ay, az, ex, ey, ez, bx, by, bz, fx, fy, fz)
        nx = bx + s * fx - ax - t * ex
        ny = by + s * fy - ay - t * ey
        nz = bz + s * fz - az - t * ez
        distance = math.sqrt(nx * nx + ny * ny + nz * nz)
        nx /= distance
        ny /= distance
        nz /= distance
        overlap = radii - distance
        if overlap < _GAMMA_CUTOFF:
            continue
        # normal-force term from the element-mean node forces of both rods
        push = 0.0
        for c, n_c in ((0, nx), (1, ny), (2, nz)):
            mean_a = 0.5 * (force_ext_a[c, i] + force_ext_a[c, i + 1] + force_int_a[c, i]
                            + force_int_a[c, i + 1])
            mean_b = 0.5 * (force_ext_b[c, j] + force_ext_b[c, j + 1] + force_int_b[c, j]
                            + force_int_b[c, j + 1])
            push += (mean_b - mean_a) * n_c
        magnitude = abs(min(push, 0.0))
        if overlap > 0.0:
            approach = 0.0
            for c, n_c in ((0, nx), (1, ny), (2, nz)):
                approach += 0.5 * ((vel_a[c, i] + vel_a[c, i + 1])
                                   - (vel_b[c, j] + vel_b[c, j + 1])) * n_c
            magnitude += 0.5 * (damping * approach + stiffness * overlap)
            deepest = max(deepest, overlap)
        share_a0 = 2.0 / 3.0 if i == 0 else (4.0 / 3.0 if i == last else 1.0)
        share_a1 = 4.0 / 3.0 if i == 0 else (2.0 / 3.0 if i == last else 1.0)
        share_b0 = 2.0 / 3.0 if j == 0 else (4.0 / 3.0 if j == last else 1.0)
        share_b1 = 4.0 / 3.0 if j == 0 else (2.0 / 3.0 if j == last else 1.0)
        for c, n_c in ((0, nx), (1, ny), (2, nz)):
            f = magnitude * n_c
            force_ext_a[c, i] -= f * share_a0
            force_ext_a[c, i + 1] -= f * share_a1
            force_ext_b[c, j] += f * share_b0
            force_ext_b[c, j + 1] += f * share_b1
            force_on_b[c] += 2.0 * f
    return deepest

