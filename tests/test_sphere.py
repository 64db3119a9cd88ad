"""A rigid sphere held by the arms (softtrack.sim.sphere, sphere_contact; docs/physics.md,
"A rigid object").

Checked against closed forms (free fall, steady spin, equal and opposite contact forces),
against the real PyElastica 1.0.0 (``Sphere`` and ``RodSphereContact`` built inside the test)
and against the settings' checks.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from softtrack.sim import RodBatch, SimParams
from softtrack.sim.params import CONTACT_ON, InvalidParameterError
from softtrack.sim.sphere import SphereParams

PARITY_TOL = 1e-10  # m, node and centre positions over 2 s
FAR = (0.0, 3.0, 0.0)  # a centre out of the arms' reach, m


def _squeeze_and_sweep(time_s: float, n_elem: int, squeeze: float, sweep: float) -> np.ndarray:
    """(2, 2, N) N·m: the arms bend towards each other with a couple pulsing between 0.2 and
    2.2 × ``squeeze`` (1 Hz) and sway together along z with ``sweep``·sin(π t)."""
    torques = np.zeros((2, 2, n_elem))
    press = squeeze * (1.2 + np.sin(2.0 * np.pi * time_s))
    torques[0, 0] = -press
    torques[1, 0] = press
    torques[:, 1] = sweep * np.sin(np.pi * time_s)
    return torques


def _params(**changes: object) -> SimParams:
    return SimParams.from_overrides(**CONTACT_ON, **changes)


# ---- settings -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("sphere", "message"),
    [
        ({"radius": -0.05}, "sphere radius=-0.05 must be a finite number > 0 m"),
        ({"density": 0.0}, "sphere density=0.0 must be a finite number > 0"),
        ({"center": (0.03, 0.975, 0.0)}, "by 30 mm; move the centre or use a radius ≤ 0.02 m"),
        ({"center": (0.05, 0.975, 0.0)}, "by 50 mm; move the centre off the arms"),
        ({"contact_k": 0.0}, "sphere contact_nu=100.0 needs contact between the arms and"),
        (
            {"contact_k": 0.0, "contact_nu": 0.0, "velocity_damping": 0.0},
            "sphere friction=0.5 needs contact",
        ),
        ({"contact_k": 1e8}, "exceeds the explicit stability limit of the sphere's contact"),
        ({"velocity_damping": 1e4}, "makes the friction unstable"),
        ({"friction": -0.1}, "sphere friction=-0.1 must be a finite number ≥ 0"),
        ({"mass": 1.0}, "unknown sphere field 'mass'"),
    ],
)
def test_bad_sphere_settings_are_rejected(sphere: dict, message: str) -> None:
    with pytest.raises(InvalidParameterError, match=message):
        SimParams.from_overrides(sphere=sphere)


def test_sphere_needs_two_arms() -> None:
    with pytest.raises(InvalidParameterError, match="needs the two-arm scene"):
        SimParams.from_overrides(
            base_positions=((0.0, 0.0, 0.0),), sphere={"center": (0.3, 0.5, 0.0)}
        )


def test_default_sphere_touches_both_straight_arms() -> None:
    sphere = SphereParams()
    assert sphere.rest_overlap(SimParams()) == pytest.approx(0.0, abs=1e-12)
    assert sphere.stiffness_limit(SimParams()) > 10 * sphere.contact_k
    assert sphere.mass == pytest.approx(500.0 * 4.0 / 3.0 * np.pi * 0.05**3)


# ---- closed forms ---------------------------------------------------------------------------


def test_free_fall_is_exact() -> None:
    """Out of reach, the sphere falls as x(t) = x₀ − ½gt² (Position Verlet is exact for a
    constant force) and the arms are the sphere-free engine's, bit for bit."""
    with_sphere = RodBatch(1, _params(gravity=9.81, sphere={"center": FAR}))
    without = RodBatch(1, _params(gravity=9.81))
    for batch in (with_sphere, without):
        batch.advance(1000)
    t = 1000 * with_sphere.params.dt
    np.testing.assert_allclose(
        with_sphere.sphere_position[0], [0.0, 3.0 - 0.5 * 9.81 * t**2, 0.0], atol=1e-12
    )
    np.testing.assert_allclose(with_sphere.sphere_velocity[0], [0.0, -9.81 * t, 0.0], atol=1e-12)
    assert np.array_equal(with_sphere.position, without.position)
    force, overlap, steps = with_sphere.sphere_contact_state()
    assert not force.any() and not overlap.any() and not steps.any()


def test_spin_keeps_its_rate_and_turns_the_frame() -> None:
    """A spinning sphere without couples keeps ω (isotropic inertia) and its frame turns by
    exp(−t[ω]ₓ) about the spin axis."""
    batch = RodBatch(1, _params(sphere={"center": FAR}))
    state = batch.get_state()
    assert state.sphere is not None
    state.sphere[0, 6:9] = (0.0, 0.0, 2.0)  # rad/s about d₃ = z
    batch.set_state(state)
    batch.advance(500)
    angle = 2.0 * 500 * batch.params.dt
    turned = batch.sphere[0, 9:].reshape(3, 3)
    cos, sin = np.cos(angle), np.sin(angle)
    np.testing.assert_allclose(turned, [[cos, sin, 0.0], [-sin, cos, 0.0], [0, 0, 1]], atol=1e-12)
    np.testing.assert_allclose(batch.sphere[0, 6:9], (0.0, 0.0, 2.0), atol=1e-15)


def test_held_sphere_forces_balance_and_momentum_is_exchanged() -> None:
    """Squeezed without gravity and without rod–rod contact, the sphere is pushed by both
    arms with mean forces of equal size (mirror symmetry) and stays between them, overlapping
    each by well under a millimetre."""
    params = SimParams.from_overrides(sphere={})
    batch = RodBatch(1, params)
    overlaps = []
    for k in range(300):
        batch.set_element_torques(
            _squeeze_and_sweep(k * params.control_dt, params.n_elem, 1.0, 0.0)[None]
        )
        batch.advance()
        force, overlap, steps = batch.sphere_contact_state()
        assert steps[0, 0] == steps[0, 1]
        if k >= 5:  # it starts just touching: the first squeeze closes the gap
            assert steps[0, 0] == params.steps_per_action
        np.testing.assert_allclose(force[0, 0], force[0, 1], rtol=1e-9)
        overlaps.append(overlap.max())
    assert 0.0 < max(overlaps) < 1e-3
    np.testing.assert_allclose(batch.sphere_position[0, 0], 0.0, atol=1e-9)
    assert abs(batch.sphere_position[0, 1] - params.sphere.center[1]) < 0.02


def test_state_round_trip_includes_the_sphere() -> None:
    params = _params(sphere={})
    batch = RodBatch(2, params)
    batch.set_element_torques(np.stack([_squeeze_and_sweep(0.0, params.n_elem, 1.0, 1.0)] * 2))
    batch.advance(50)
    saved = batch.get_state([0])
    batch.advance(50)
    after = batch.sphere[0].copy()
    batch.set_state(saved, [0])
    batch.advance(50)
    assert np.array_equal(batch.sphere[0], after)
    with pytest.raises(ValueError, match="has no sphere"):
        batch.set_state(dataclasses.replace(saved, sphere=None), [0])


# ---- PyElastica parity ----------------------------------------------------------------------


@pytest.mark.pyelastica
@pytest.mark.parametrize(
    ("overrides", "squeeze", "sweep"),
    [
        ({}, 2.0, 3.0),
        ({"gravity": 9.81}, 1.5, 2.0),
        (
            {
                "youngs_modulus": 5e6,
                "density": 1200.0,
                "sphere": {
                    "density": 1000.0,
                    "contact_k": 3e5,
                    "contact_nu": 150.0,
                    "velocity_damping": 50.0,
                    "friction": 0.3,
                },
            },
            0.7,
            1.0,
        ),
    ],
    ids=["friction", "gravity", "softer-arms-heavier-ball"],
)
def test_matches_pyelastica_sphere_contact(overrides: dict, squeeze: float, sweep: float) -> None:
    """The arms squeeze the sphere (pulsing) and carry it sideways for 2 s, with rod–rod
    contact on: softtrack's node positions and the sphere's centre equal PyElastica 1.0.0's
    (``Sphere``, ``RodSphereContact(k, nu, velocity_damping_coefficient,
    friction_coefficient)``) to ≤ 1e-10 m."""
    pytest.importorskip("elastica")
    from softtrack.sim.pyelastica_backend import PyElasticaDualArm

    params = _params(**{"sphere": {}, **overrides})
    ours = RodBatch(1, params)
    theirs = PyElasticaDualArm(params)
    worst_nodes = worst_centre = 0.0
    held_steps = 0
    n_control = round(2.0 / params.control_dt)
    for k in range(n_control):
        torques = _squeeze_and_sweep(k * params.control_dt, params.n_elem, squeeze, sweep)
        ours.set_element_torques(torques[None])
        theirs.set_element_torques(torques)
        ours.advance()
        theirs.advance(params.steps_per_action)
        worst_nodes = max(worst_nodes, float(np.abs(ours.position[0] - theirs.positions).max()))
        worst_centre = max(
            worst_centre, float(np.abs(ours.sphere[0, :3] - theirs.sphere_state[:3]).max())
        )
        held_steps += int(ours.sphere_contact_state()[2][0].min() > 0)
    assert held_steps >= 0.9 * n_control  # both arms touch the sphere nearly all the time
    assert abs(ours.sphere_position[0, 2]) > 0.05  # and carry it sideways
    print(f"worst difference: nodes {worst_nodes:.1e} m, sphere centre {worst_centre:.1e} m")
    assert worst_nodes <= PARITY_TOL
    assert worst_centre <= PARITY_TOL
