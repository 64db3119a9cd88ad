"""Closed-form checks of the numba Cosserat-rod engine (docs/physics.md).

Each test compares the engine with an answer derived independently of its code:

* a couple M = EI·π/(2L) on the last element gives a uniform internal moment, so the settled
  arm is a discrete circular arc of curvature M/EI (a quarter circle in the continuum);
* with no damping and no forcing, the discrete energy is conserved up to the Position-Verlet
  O(dt²) oscillation, without secular drift;
* rotating the whole scenario rotates the solution (frame indifference);
* gravity: initial free fall, the axial shortening of an upright arm and the sag of a
  horizontal cantilever, each against the closed-form static solution of the discrete rod;
* batching: environments of a batch evolve exactly as separate runs, and resetting one of them
  leaves the others alone.

Measured values are quoted next to each tolerance.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from softtrack.sim import RodBatch, SimParams, rollout

STATE = ("position", "velocity", "directors", "omega")


# ---- helpers -------------------------------------------------------------------------------
def advance_to(batch: RodBatch, t_end: float) -> None:
    """Advance every environment of ``batch`` (all at the same time) to ``t_end`` seconds."""
    n = round((t_end - batch.time[0]) / batch.params.dt)
    if n > 0:
        batch.advance(n)


def chord_tangents(position: np.ndarray) -> np.ndarray:
    """Unit tangents of the elements (..., 3, N) from node positions (..., 3, N+1)."""
    t = np.diff(position, axis=-1)
    return t / np.linalg.norm(t, axis=-2, keepdims=True)


def turning_angles(position: np.ndarray) -> np.ndarray:
    """Angles (..., N−1) between neighbouring element chords, rad."""
    t = chord_tangents(position)
    cos = np.einsum("...ik,...ik->...k", t[..., :-1], t[..., 1:])
    return np.arccos(np.clip(cos, -1.0, 1.0))


def director_curvature(directors: np.ndarray, voronoi: np.ndarray) -> np.ndarray:
    """κ (..., 3, N−1) in the local frame from the rotation between neighbouring frames.

    Frames evolve as Q ← exp(−h[ω]ₓ)Q (ω local), so with the same convention along the arm
    Q_{j+1} = exp(−D̂_j [κ_j]ₓ) Q_j, i.e. κ_j = −log(Q_{j+1} Q_jᵀ)^∨ / D̂_j.
    """
    rel = np.einsum("...icj,...lcj->...jil", directors[..., 1:], directors[..., :-1])
    lead = rel.shape[:-3]
    rotvec = Rotation.from_matrix(rel.reshape(-1, 3, 3)).as_rotvec().reshape(*lead, -1, 3)
    return -np.moveaxis(rotvec, -1, -2) / voronoi


def energies(batch: RodBatch) -> dict[str, np.ndarray]:
    """The natural discrete energies (J) of every arm, each (E, A).

    Translational ½Σ m v²; rotational ½Σ ωᵀJω/e (PyElastica's convention with the dilatation
    e = l/l̂); shear/stretch ½Σ σᵀSσ·l̂ with σ = e·Q·t − d₃ (local); bend/twist ½Σ κᵀBκ·D̂.
    """
    c = batch.constants
    x, v, q, w = batch.position, batch.velocity, batch.directors, batch.omega
    dx = np.diff(x, axis=-1)
    e = np.linalg.norm(dx, axis=2) / c.rest_lengths
    translational = 0.5 * np.einsum("k,eaik,eaik->ea", c.mass, v, v)
    rotational = 0.5 * np.einsum("ik,eaik,eaik->ea", c.inertia, w, w / e[:, :, None, :])
    sigma = np.einsum("eaijk,eajk->eaik", q, dx) / c.rest_lengths
    sigma[:, :, 2] -= 1.0
    shear = 0.5 * np.einsum("ik,eaik,eaik,k->ea", c.shear_stiffness, sigma, sigma, c.rest_lengths)
    kappa = director_curvature(q, c.rest_voronoi_lengths)
    bend = 0.5 * np.einsum(
        "ij,eaij,eaij,j->ea", c.bend_stiffness, kappa, kappa, c.rest_voronoi_lengths
    )
    return {"translational": translational, "rotational": rotational, "shear": shear, "bend": bend}


def total_energy(batch: RodBatch) -> np.ndarray:
    return sum(energies(batch).values())


def copy_state(src: RodBatch, dst: RodBatch) -> None:
    for name in STATE:
        getattr(dst, name)[...] = getattr(src, name)


# ---- quarter circle -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def quarter_circle() -> tuple[SimParams, RodBatch, float]:
    """Arm 0: couple M on d₁ of the last element; arm 1: M on d₂. Settled for 6 s (damping 30).

    The slowest mode (ω₁ ≈ 8.8 rad/s) decays at ν_d/(2ρA) ≈ 1.9 s⁻¹, so after 6 s the
    transient is ~1e-5 of the deflection (measured curvature error: 3e-6 at 4 s, 1e-6 at 6 s).
    """
    p = SimParams()
    n = p.n_elem
    moment = p.bending_stiffness * math.pi / (2.0 * p.length)  # 77.106 N·m
    batch = RodBatch(1, p)
    torques = np.zeros((1, p.n_arms, 2, n))
    torques[0, 0, 0, n - 1] = moment
    torques[0, 1, 1, n - 1] = moment
    batch.set_element_torques(torques)
    advance_to(batch, 6.0)
    assert batch.finite().all()
    return p, batch, moment


def test_quarter_circle_moment_value(quarter_circle) -> None:
    p, _, moment = quarter_circle
    assert p.bending_stiffness == pytest.approx(49.087, abs=1e-3)
    assert moment == pytest.approx(77.106, abs=1e-3)


def test_quarter_circle_curvature_is_uniform_from_node_positions(quarter_circle) -> None:
    """Turning angle between neighbouring chords / rest Voronoi length = M/EI at every point.

    In equilibrium the internal force vanishes (free end, no load), so σ = 0, every element
    keeps its rest length and lies along its d₃, and the uniform internal moment M gives the
    same rotation M·D̂/EI between every pair of neighbours.
    """
    p, batch, moment = quarter_circle
    kappa_expected = moment / p.bending_stiffness  # π/(2L)
    assert kappa_expected == pytest.approx(math.pi / (2 * p.length), rel=1e-15)
    angles = turning_angles(batch.position[0])  # (A, N−1)
    kappa = angles / batch.constants.rest_voronoi_lengths
    rel = np.abs(kappa / kappa_expected - 1.0)
    assert rel.max() <= 1e-4, f"curvature relative error {rel.max():.2e} (measured ~1e-6)"
    # Elements keep their rest length (no stretch): measured 2e-7 relative.
    lengths = np.linalg.norm(np.diff(batch.position[0], axis=-1), axis=1)
    assert np.abs(lengths / batch.constants.rest_lengths - 1.0).max() <= 1e-5


def test_quarter_circle_total_turning_angle(quarter_circle) -> None:
    """Element 0 is clamped straight, so the tangent turns by κ·(L − dl) from element 0 to N−1."""
    p, batch, moment = quarter_circle
    kappa = moment / p.bending_stiffness
    dl = p.length / p.n_elem
    t = chord_tangents(batch.position[0])  # (A, 3, N)
    total = np.arccos(np.clip(np.einsum("ai,ai->a", t[:, :, 0], t[:, :, -1]), -1.0, 1.0))
    np.testing.assert_allclose(total, kappa * (p.length - dl), rtol=1e-4)  # 85.5°
    # Element 0 stays along the rest direction.
    np.testing.assert_allclose(t[:, :, 0], np.tile(np.array(p.direction), (p.n_arms, 1)), atol=1e-6)


def test_quarter_circle_director_curvature(quarter_circle) -> None:
    """κ from the frames: (M/EI, 0, 0) for the normal couple, (0, M/EI, 0) for the binormal."""
    p, batch, moment = quarter_circle
    kappa_expected = moment / p.bending_stiffness
    kappa = director_curvature(batch.directors[0], batch.constants.rest_voronoi_lengths)
    expected = np.zeros_like(kappa)
    expected[0, 0] = kappa_expected
    expected[1, 1] = kappa_expected
    err = np.abs(kappa - expected).max() / kappa_expected
    assert err <= 1e-4, f"director curvature relative error {err:.2e}"


def test_quarter_circle_shape_and_sign_convention(quarter_circle) -> None:
    """Nodes lie on the discrete arc: equal chords dl turning by θ = κ·dl from node 1 on.

    docs/physics.md signs: the positive normal (d₁ = +z) couple curls arm 0 toward −x in the x–y
    plane; the positive binormal (d₂ = +x) couple curls arm 1 toward +z in the y–z plane.
    """
    p, batch, moment = quarter_circle
    n, dl = p.n_elem, p.length / p.n_elem
    theta = moment / p.bending_stiffness * dl
    k = np.arange(n)
    along = dl * np.concatenate([[0.0], np.cumsum(np.cos(k * theta))])  # along +y
    across = dl * np.concatenate([[0.0], np.cumsum(np.sin(k * theta))])  # curl direction
    base0, base1 = (np.array(b) for b in p.base_positions)
    expected0 = base0[:, None] + np.stack([-across, along, np.zeros(n + 1)])
    expected1 = base1[:, None] + np.stack([np.zeros(n + 1), along, across])
    x = batch.position[0]
    assert np.abs(x[0] - expected0).max() <= 1e-6  # measured 6e-8 m
    assert np.abs(x[1] - expected1).max() <= 1e-6
    # Signs, stated plainly.
    assert x[0, 0, -1] < base0[0] - 0.5 and abs(x[0, 2, -1]) < 1e-9
    assert x[1, 2, -1] > 0.5 and abs(x[1, 0, -1] - base1[0]) < 1e-9


@pytest.mark.parametrize("direction", [0, 1])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_action_sign_convention(direction: int, sign: float) -> None:
    """Control values through the spline: +normal curls toward −x, +binormal toward +z."""
    actions = np.zeros((250, 2, 2, 6))
    actions[:, :, direction, :] = sign * 0.05
    out = rollout(actions=actions)
    disp = out["tip"][-1] - out["tip"][0]  # (A, 3)
    curl_axis, other_axis, curl_sign = (0, 2, -1.0) if direction == 0 else (2, 0, 1.0)
    assert np.all(sign * curl_sign * disp[:, curl_axis] > 0.1)  # the tips move ~0.4 m
    assert np.abs(disp[:, other_axis]).max() < 1e-9
    np.testing.assert_allclose(disp[0], disp[1], atol=1e-12)  # identical arms


# ---- energy ---------------------------------------------------------------------------------
def _released_batch(amplitude: float, dt: float) -> RodBatch:
    """Arms pre-bent by constant actions (arm 0 normal, arm 1 binormal) with damping, then
    copied into an undamped, unforced batch with time step ``dt``."""
    p = SimParams()
    bent = RodBatch(1, p)
    actions = np.zeros((1, p.n_arms, 2, 6))
    actions[0, 0, 0] = amplitude
    actions[0, 1, 1] = amplitude
    bent.set_actions(actions)
    advance_to(bent, 5.0)
    free = RodBatch(1, dataclasses.replace(p, damping=0.0, dt=dt))
    copy_state(bent, free)
    return free


def _relative_energy_error(batch: RodBatch, t_end: float, every: float = 0.002) -> tuple:
    """(times, |E(t)/E(0) − 1| per arm) sampled every ``every`` seconds up to ``t_end``."""
    e0 = total_energy(batch)[0]
    n = round(every / batch.params.dt)
    times, errors = [], []
    for _ in range(round(t_end / every)):
        batch.advance(n)
        times.append(batch.time[0])
        errors.append(np.abs(total_energy(batch)[0] / e0 - 1.0))
    assert batch.finite().all()
    return np.array(times), np.array(errors)


def test_energy_conserved_without_damping_small_amplitude() -> None:
    """Near-linear regime: a bounded O(dt²) oscillation, no drift.

    Release from a small pre-bend (actions 0.005, 0.15 J per arm): the relative energy error
    is 3.4e-4 at dt = 2e-4 in both [0, 0.5] s and [0.5, 1] s and 8.5e-5 at dt = 1e-4 (ratio
    3.9 ≈ 4 = (dt ratio)², Position Verlet's shadow-energy bound). Almost all of it is the
    high-frequency content excited by switching the torques off at once.
    """
    times, err = _relative_energy_error(_released_batch(0.005, 2e-4), 1.0)
    first, second = err[times <= 0.5].max(), err[times > 0.5].max()
    assert first <= 1e-3 and second <= 1e-3, (first, second)
    assert second <= 1.25 * first, f"energy error grows: {first:.2e} → {second:.2e}"
    _, err_half = _relative_energy_error(_released_batch(0.005, 1e-4), 1.0)
    ratio = err.max() / err_half.max()
    assert 3.0 <= ratio <= 5.0, f"energy error does not scale as dt² (ratio {ratio:.2f})"


def test_energy_bounded_without_damping_large_amplitude() -> None:
    """Study-size deflection (actions 0.1, 61 J per arm): bounded, no secular drift.

    The error is 2.6e-3 and does not shrink with dt (2.6e-3 at dt = 2.9e-5 as well): it is not
    a time-step error but PyElastica's discretisation itself, whose forces are the gradient of
    the natural energy only up to the dilatation factors 1/e and 1/ε³ (O(strain)); it falls
    as ~(r/L)⁴ (2.7e-4 at r = 0.025, 1.7e-5 at r = 0.0125). Over 10 s it stays ≤ 2.6e-3
    (non-planar bending of similar size: ≤ 5.2e-3 over 2 s, slowly rising to 6.8e-3 at 10 s).
    """
    times, err = _relative_energy_error(_released_batch(0.1, 2e-4), 2.0)
    first, second = err[times <= 1.0].max(), err[times > 1.0].max()
    assert first <= 4e-3, f"energy error {first:.2e} in [0, 1] s (measured 2.6e-3)"
    assert second <= 1.1 * first, f"energy error grows: {first:.2e} → {second:.2e}"


# ---- frame indifference -----------------------------------------------------------------------
def test_rigid_rotation_of_the_scenario_rotates_the_solution() -> None:
    """Bases, tangent and normal rotated by R; same local-frame torques → nodes R·x, frames QRᵀ.

    Measured after 0.5 s: nodes 3e-15 m, directors 1e-14, velocities 6e-12 m/s, ω 5e-12 rad/s.
    """
    rot = Rotation.random(random_state=20240601).as_matrix()
    p = SimParams()
    p_rot = SimParams.from_overrides(
        base_positions=[rot @ np.array(b) for b in p.base_positions],
        direction=rot @ np.array(p.direction),
        normal=rot @ np.array(p.normal),
    )
    rng = np.random.default_rng(7)
    actions = rng.uniform(-0.3, 0.3, size=(1, p.n_arms, 2, 6))
    ref, turned = RodBatch(1, p), RodBatch(1, p_rot)
    for k in range(250):  # 0.5 s; the actions change every 50 ms
        if k % 25 == 0:
            actions = rng.uniform(-0.3, 0.3, size=(1, p.n_arms, 2, 6))
        ref.set_actions(actions)
        turned.set_actions(actions)
        ref.advance()
        turned.advance()
    assert np.abs(ref.position - ref.constants.rest_position).max() > 0.1  # not trivial
    node_err = np.abs(np.einsum("ij,eajk->eaik", rot, ref.position) - turned.position).max()
    assert node_err <= 1e-9, f"node error {node_err:.2e} m"
    dir_err = np.abs(np.einsum("eaijk,lj->eailk", ref.directors, rot) - turned.directors).max()
    assert dir_err <= 1e-9
    vel_err = np.abs(np.einsum("ij,eajk->eaik", rot, ref.velocity) - turned.velocity).max()
    assert vel_err <= 1e-7
    assert np.abs(ref.omega - turned.omega).max() <= 1e-6


# ---- gravity ----------------------------------------------------------------------------------
def _node_masses(p: SimParams) -> np.ndarray:
    dl = p.length / p.n_elem
    m = np.full(p.n_nodes, p.density * p.area * dl)
    m[0] *= 0.5
    m[-1] *= 0.5
    return m


def test_gravity_initial_free_fall() -> None:
    """Without damping the free nodes fall freely at first: v = −g·t, y = −½g·t² along −y.

    A disturbance from the clamp travels about one node per step (nearest-neighbour stencil),
    so for the first 10 steps the tip (node 20) is exactly in free fall.
    """
    p = SimParams.from_overrides(gravity=True, damping=0.0)
    assert p.gravity == 9.81
    batch = RodBatch(1, p)
    batch.advance(1)
    v = batch.velocity[0]
    np.testing.assert_allclose(v[:, 1, 1:], -9.81 * p.dt, rtol=1e-9)  # round-off of the
    # internal forces of the straight rest state: measured 2e-11 relative
    assert np.abs(v[:, [0, 2], :]).max() == 0.0 and np.abs(v[:, :, 0]).max() == 0.0
    batch.advance(9)
    t = 10 * p.dt
    tip = batch.position[0, :, :, -1] - batch.constants.rest_position[:, :, -1]
    np.testing.assert_allclose(batch.velocity[0, :, 1, -1], -9.81 * t, rtol=1e-9)
    np.testing.assert_allclose(tip[:, 1], -0.5 * 9.81 * t**2, rtol=1e-9)


def test_gravity_upright_arm_shortens_by_its_weight() -> None:
    """Arms along +y under gravity along −y (below the self-weight buckling length, 1.7 m).

    Element k carries the weight w_k·EA of the nodes beyond it; PyElastica's axial law
    F = EA(1 − 1/e) gives the strain w/(1 + w), so the tip drops by Σ dl·w_k/(1 + w_k)
    (continuum: ρgL²/(2E) = 4.905e-4 m; the 1/e factor removes 0.07 %). Measured: 2e-5 relative.
    """
    p = SimParams.from_overrides(gravity=True)
    batch = RodBatch(1, p)
    advance_to(batch, 6.0)
    dl = p.length / p.n_elem
    masses = _node_masses(p)
    w = np.array([p.gravity * masses[k + 1 :].sum() for k in range(p.n_elem)])
    w /= p.youngs_modulus * p.area
    expected = np.sum(dl * w / (1.0 + w))
    drop = batch.constants.rest_position[:, 1, -1] - batch.position[0, :, 1, -1]
    np.testing.assert_allclose(drop, expected, rtol=1e-4)
    continuum = p.density * 9.81 * p.length**2 / (2 * p.youngs_modulus)
    assert expected == pytest.approx(continuum, rel=1e-3)
    lateral = batch.position[0] - batch.constants.rest_position
    assert np.abs(lateral[:, 0::2, :]).max() <= 1e-12  # x and z unchanged: stays straight


def _discrete_cantilever_sag(p: SimParams) -> float:
    """Tip deflection of the discrete clamped rod under its own weight, small-deflection.

    Static balance of the discrete Cosserat rod: element k carries the shear force W_k (weight
    of the nodes beyond it); the moment at Voronoi point j is dl·Σ_{k>j} W_k; element k turns
    by φ_k = Σ_{j<k} moment_j·dl/EI (element 0 is clamped); the tip drops by Σ dl·φ_k plus the
    shear deflection Σ dl·W_k/(α_c·G·A).
    """
    n, dl = p.n_elem, p.length / p.n_elem
    masses = _node_masses(p)
    shear_force = np.array([p.gravity * masses[k + 1 :].sum() for k in range(n)])
    moment = np.array([dl * shear_force[j + 1 :].sum() for j in range(n - 1)])
    phi = np.concatenate([[0.0], np.cumsum(moment * dl / p.bending_stiffness)])
    shear_stiffness = p.shear_correction * p.shear_modulus * p.area
    return float(np.sum(dl * phi) + np.sum(dl * shear_force / shear_stiffness))


def _settled_horizontal_sag(n_elem: int, gravity: float) -> tuple[SimParams, np.ndarray]:
    dt = min(2e-4, 0.9 * SimParams(n_elem=n_elem).dt_limit)
    p = SimParams.from_overrides(
        n_elem=n_elem, dt=dt, gravity=gravity, direction=(1.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0)
    )
    batch = RodBatch(1, p)
    advance_to(batch, 6.0)
    return p, batch.position[0]


def test_gravity_horizontal_cantilever_sags_as_the_discrete_closed_form() -> None:
    """Arms along +x, gravity 0.0981 m/s² (tip sag 1.8 mm, so linear theory holds).

    Measured: 2.6e-6 relative to the discrete closed form (the geometric nonlinearity, which
    scales with the load: 2.6e-4 at 0.981 m/s²).
    """
    p, x = _settled_horizontal_sag(20, 0.0981)
    sag = -x[:, 1, -1]
    assert np.all(sag > 0)  # the tips hang below the x axis
    np.testing.assert_allclose(sag, _discrete_cantilever_sag(p), rtol=2e-5)
    assert np.abs(x[:, 2, :]).max() <= 1e-12  # stays in its plane


def test_gravity_cantilever_converges_to_timoshenko() -> None:
    """The sag tends to qL⁴/(8EI) + qL²/(2α_cGA) at first order in dl: the clamp holds all of
    element 0 straight, so the arm bends as if clamped at ~dl/2. Measured sag/continuum:
    0.811, 0.903, 0.951 for 10, 20, 40 elements."""
    deficits = []
    for n in (10, 20, 40):
        p, x = _settled_horizontal_sag(n, 0.0981)
        q = p.density * p.area * p.gravity
        continuum = q * p.length**4 / (8 * p.bending_stiffness) + q * p.length**2 / (
            2 * p.shear_correction * p.shear_modulus * p.area
        )
        deficits.append(1.0 + x[0, 1, -1] / continuum)
    assert 0.0 < deficits[2] < deficits[1] < deficits[0] < 0.25
    np.testing.assert_allclose(deficits[0] / deficits[1], 2.0, rtol=0.1)
    np.testing.assert_allclose(deficits[1] / deficits[2], 2.0, rtol=0.1)


# ---- batching -----------------------------------------------------------------------------
def test_batch_equals_separate_single_env_runs_bit_for_bit() -> None:
    rng = np.random.default_rng(11)
    p = SimParams()
    n_envs = 5
    actions = rng.uniform(-0.6, 0.6, size=(100, n_envs, p.n_arms, 2, 6))
    batch = RodBatch(n_envs, p)
    singles = [RodBatch(1, p) for _ in range(n_envs)]
    for a in actions:
        batch.set_actions(a)
        batch.advance()
        for i, single in enumerate(singles):
            single.set_actions(a[i : i + 1])
            single.advance()
    for i, single in enumerate(singles):
        for name in (*STATE, "torques", "time"):
            assert np.array_equal(getattr(batch, name)[i], getattr(single, name)[0]), (i, name)
    # The environments really differ.
    assert np.abs(batch.position[0] - batch.position[1]).max() > 1e-2
    assert batch.finite().all()


def test_reset_one_env_restores_rest_state_and_leaves_others_alone() -> None:
    rng = np.random.default_rng(12)
    p = SimParams()
    batch = RodBatch(4, p)
    fresh = RodBatch(1, p)
    for _ in range(50):
        batch.set_actions(rng.uniform(-0.5, 0.5, size=(4, p.n_arms, 2, 6)))
        batch.advance()
    before = {name: getattr(batch, name).copy() for name in (*STATE, "torques", "time")}
    batch.reset(np.array([2]))
    for name in (*STATE, "torques", "time"):
        value = getattr(batch, name)
        assert np.array_equal(value[2], getattr(fresh, name)[0]), name
        others = [0, 1, 3]
        assert np.array_equal(value[others], before[name][others]), name
    c = batch.constants
    assert np.array_equal(batch.position[2], c.rest_position)
    assert np.all(batch.velocity[2] == 0) and np.all(batch.omega[2] == 0)
    assert np.all(batch.directors[2] == c.base_directors[:, :, :, None])
    # After the reset, env 2 evolves exactly as a fresh environment.
    a = rng.uniform(-0.5, 0.5, size=(4, p.n_arms, 2, 6))
    batch.set_actions(a)
    fresh.set_actions(a[2:3])
    batch.advance(30)
    fresh.advance(30)
    for name in STATE:
        assert np.array_equal(getattr(batch, name)[2], getattr(fresh, name)[0]), name


def test_advance_in_chunks_equals_one_call() -> None:
    """advance(20) fuses inner half drifts; two advance(10) calls agree to round-off."""
    p = SimParams()
    actions = np.full((1, p.n_arms, 2, 6), 0.3)
    one, two = RodBatch(1, p), RodBatch(1, p)
    one.set_actions(actions)
    two.set_actions(actions)
    for _ in range(20):
        one.advance(20)
        two.advance(10)
        two.advance(10)
    assert np.abs(one.position - two.position).max() <= 1e-12
    assert np.abs(one.velocity - two.velocity).max() <= 1e-9
    np.testing.assert_allclose(one.time, two.time, rtol=1e-14)
    before = one.position.copy()
    one.advance(0)
    assert np.array_equal(one.position, before)
