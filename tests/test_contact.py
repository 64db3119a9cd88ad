"""Rod–rod contact between the arms (softtrack.sim.rod_contact, docs/physics.md "Contact").

Checked against the real PyElastica 1.0.0 (``RodRodContact`` built inside the test), against
geometry (pressed arms stop at their surfaces instead of passing through) and against the
stability limit that ``SimParams.validate`` enforces.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from softtrack.sim import RodBatch, SimParams, rollout
from softtrack.sim.params import CONTACT_ON, InvalidParameterError
from softtrack.sim.stability import contact_stiffness_limit

PARITY_TOL = 1e-10  # m, node positions over 2 s


def _press_actions(n_steps: int, amplitude: float, period_s: float = 0.8) -> np.ndarray:
    """(T, 2, 2, 6) actions that curl arm 1 toward +x and arm 2 toward −x in pulses (press,
    release, press, ...), with a slow binormal sway so the contacts are 3-D."""
    t = np.arange(n_steps) * 0.002
    pulse = amplitude * (0.5 - 0.5 * np.cos(2 * np.pi * t / period_s))
    actions = np.zeros((n_steps, 2, 2, 6))
    actions[:, 0, 0] = -pulse[:, None] * np.array([1, 1, 0.8, 0.5, 0.3, 0.2])
    actions[:, 1, 0] = pulse[:, None] * np.array([1, 0.9, 0.8, 0.6, 0.3, 0.1])
    actions[:, 0, 1] = 0.05 * np.sin(2 * np.pi * t / 1.3)[:, None]
    actions[:, 1, 1] = -0.04 * np.sin(2 * np.pi * t / 0.9)[:, None]
    return actions


def _segment_distance(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> float:
    """Distance between segments p0p1 and q0q1 (m), by dense sampling (test oracle)."""
    s = np.linspace(0.0, 1.0, 41)
    a = p0[None] + s[:, None] * (p1 - p0)[None]
    b = q0[None] + s[:, None] * (q1 - q0)[None]
    return float(np.min(np.linalg.norm(a[:, None] - b[None], axis=-1)))


def _clearance(nodes: np.ndarray, radius: float) -> float:
    """Smallest surface-to-surface distance of the two arms (m; < 0: overlap)."""
    best = np.inf
    for i in range(nodes.shape[-1] - 1):
        for j in range(nodes.shape[-1] - 1):
            if np.linalg.norm(nodes[0, :, i] - nodes[1, :, j]) > 0.25:
                continue
            best = min(
                best,
                _segment_distance(
                    nodes[0, :, i], nodes[0, :, i + 1], nodes[1, :, j], nodes[1, :, j + 1]
                ),
            )
    return best - 2 * radius


# ---- validation -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"contact_k": -1.0}, "contact_k=-1.0 must be a finite number ≥ 0"),
        ({"contact_nu": 5.0}, "contact_nu=5.0 needs contact_k > 0"),
        ({"contact_k": 1e6, "base_positions": ((0.0, 0.0, 0.0),)}, "needs two arms"),
        ({"contact_k": 1e8}, "use contact_k ≤ 1.68e+07 N/m"),
        ({"contact_k": 1e6, "contact_nu": 1e4}, "unstable at dt=0.0002 s whatever contact_k"),
        ({"contact_k": float("nan")}, "must be a finite number"),
    ],
)
def test_bad_contact_parameters_are_rejected(overrides: dict, message: str) -> None:
    with pytest.raises(InvalidParameterError, match=message.replace("+", r"\+")):
        SimParams.from_overrides(**overrides)


def test_contact_off_by_default_and_on_values_valid() -> None:
    assert SimParams().contact_k == 0.0 and SimParams().contact_nu == 0.0
    on = SimParams.from_overrides(**CONTACT_ON)
    assert contact_stiffness_limit(on) > 5 * on.contact_k


def test_stability_limit_bounds_the_engine() -> None:
    """The engine stays finite at the stated limit and diverges a few times above it."""
    base = SimParams(contact_nu=0.0)
    limit = contact_stiffness_limit(dataclasses.replace(base, contact_k=1.0))
    press = np.zeros((1, 2, 2, 6))
    press[0, 0, 0], press[0, 1, 0] = -1.0, 1.0

    def stays_finite(k: float) -> bool:
        batch = RodBatch(1, dataclasses.replace(base, contact_k=min(k, limit)))
        batch.params = dataclasses.replace(base, contact_k=k)  # past validation on purpose
        batch.set_actions(press)
        for _ in range(60):
            batch.advance()
            if not batch.finite()[0]:
                return False
        return True

    assert stays_finite(0.99 * limit)
    assert not stays_finite(6.0 * limit)


# ---- physics ------------------------------------------------------------------------------


def test_no_touch_is_bit_identical_to_no_contact() -> None:
    """With contact on, steps in which the arms do not touch are the contact-free engine's,
    bit for bit (the contact forces live in their own array)."""
    away = np.zeros((100, 2, 2, 6))
    away[:, 0, 0], away[:, 1, 0] = 0.1, -0.1  # each arm curls away from the other
    away[:, :, 1] = 0.05 * np.sin(np.arange(100) / 10.0)[:, None, None]
    with_contact = RodBatch(1, SimParams(**CONTACT_ON))
    without = RodBatch(1, SimParams())
    for k in range(100):
        for batch in (with_contact, without):
            batch.set_actions(away[k][None])
            batch.advance()
        assert with_contact.contact_state()[1][0] == 0.0
    assert np.array_equal(with_contact.position, without.position)
    assert np.array_equal(with_contact.directors, without.directors)


def test_pressed_arms_stop_at_their_surfaces() -> None:
    """Every control value pressing the arms together (±1, the largest torques): without
    contact they pass through each other, with the defaults they overlap by ≤ 5 mm."""
    press = np.zeros((150, 2, 2, 6))
    press[:, 0, 0], press[:, 1, 0] = -1.0, 1.0
    radius = SimParams().radius
    ghost = rollout(actions=press)
    assert min(_clearance(n, radius) for n in ghost["nodes"][::5]) < -0.05

    params = SimParams(**CONTACT_ON)
    batch = RodBatch(1, params)
    deepest, touching = 0.0, 0
    for k in range(len(press)):
        batch.set_actions(press[k][None])
        batch.advance()
        penetration, force = batch.contact_state()
        deepest = max(deepest, float(penetration[0]))
        touching += int(force[0] > 0)
        if k % 10 == 0:
            assert _clearance(batch.position[0], radius) > -0.005
    assert 0.0 < deepest <= 0.005
    assert touching > 50


def test_contact_forces_are_equal_and_opposite() -> None:
    """Contact only exchanges momentum between the arms: over an integration step in which
    they press, each arm's momentum changes by the contact impulse and the two changes cancel."""
    params = SimParams(**CONTACT_ON)
    actions = _press_actions(300, 0.15)
    touching = RodBatch(1, params)
    free = RodBatch(1, dataclasses.replace(params, contact_k=0.0, contact_nu=0.0))
    mass = touching.constants.mass
    for k in range(3000):
        touching.set_actions(actions[k // 10][None])
        before = touching.get_state()
        touching.advance(1)
        if touching.contact_state()[1][0] > 20.0:
            break
    else:
        pytest.fail("the arms never pressed")
    free.set_state(before)
    free.advance(1)
    impulse = np.einsum("n,ain->ai", mass, touching.velocity[0] - free.velocity[0])  # (arm, 3)
    # node 0 is clamped (its velocity is zeroed), so its share of the impulse is not seen
    assert np.linalg.norm(impulse[0]) > 1e-4
    np.testing.assert_allclose(impulse[0], -impulse[1], atol=1e-9 * np.linalg.norm(impulse[0]))


# ---- PyElastica parity ------------------------------------------------------------------------


@pytest.mark.pyelastica
@pytest.mark.parametrize(
    "overrides",
    [
        dict(CONTACT_ON),
        dict(CONTACT_ON, gravity=9.81),
        {"contact_k": 1e5, "contact_nu": 100.0, "youngs_modulus": 8e6, "density": 1200.0},
    ],
    ids=["defaults", "gravity", "softer-heavier"],
)
def test_matches_pyelastica_rod_rod_contact(overrides: dict) -> None:
    """The arms pressed together in pulses for 2 s (several contact episodes): softtrack's node
    positions equal PyElastica 1.0.0's with RodRodContact(k, nu) to ≤ 1e-10 m."""
    pytest.importorskip("elastica")
    from softtrack.sim.pyelastica_backend import rollout_pyelastica

    actions = _press_actions(1000, 0.15)
    ours = rollout(actions=actions, **overrides)
    theirs = rollout_pyelastica(actions=actions, **overrides)
    radius = SimParams().radius
    contact_steps = sum(_clearance(n, radius) < 1e-4 for n in ours["nodes"][::20])
    assert contact_steps >= 5  # the arms really touch, in more than one episode
    worst = float(np.max(np.abs(ours["nodes"] - theirs["nodes"])))
    print(f"worst node difference {worst:.1e} m")  # shown by pytest -rP (docs/physics.md)
    assert worst <= PARITY_TOL
