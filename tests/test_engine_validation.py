"""Invalid simulation parameters and inputs fail early with a clear InvalidParameterError, and
the closed-form time-step limit matches where the engine actually diverges.

Empirical divergence thresholds (random actions held 10 steps, 0.5 s; bisection to 0.2 %),
against the closed-form limit with the coupled bending mode (``softtrack.sim.stability``):

    damping ν_d   dt_limit     diverges at
    0            4.202e-4 s   1.001–1.002× (actions ±0.01; undamped, larger forcing blows up)
    10           3.434e-4 s   1.001–1.002×
    30 (default)    2.323e-4 s   1.001–1.002×
    60           1.453e-4 s   1.001–1.002×

(An earlier closed form treated the alternating element rotation as a mode of its own and was
3.2 % optimistic at ν_d = 0; shear couples it to the alternating transverse node motion. The
linearised engine has ω_max = 4748 rad/s, i.e. 2/ω_max = 4.21e-4 s at ν_d = 0.)
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from softtrack.sim import InvalidParameterError, RodBatch, SimParams, rollout

NAN, INF = float("nan"), float("inf")


# ---- parameters ---------------------------------------------------------------------------
def test_invalid_parameter_error_is_a_value_error() -> None:
    assert issubclass(InvalidParameterError, ValueError)


def test_default_dt_limit_value() -> None:
    p = SimParams()
    assert 2.2e-4 < p.dt_limit < 2.4e-4  # 2.32e-4 s
    assert p.dt < p.dt_limit


@pytest.mark.parametrize("dt", [3e-4, 2.4e-4, 1e-3])
def test_dt_above_stability_limit_is_rejected_with_the_limit_and_the_fix(dt: float) -> None:
    limit = SimParams().dt_limit
    with pytest.raises(InvalidParameterError) as info:
        SimParams.from_overrides(dt=dt)
    message = str(info.value)
    assert message.startswith("dt=")
    assert "stability limit" in message
    stated = re.search(r"limit ([0-9.eE+-]+) s", message)
    assert stated is not None, message
    assert float(stated.group(1)) == pytest.approx(limit, rel=5e-3)  # "0.000233"
    fix = re.search(r"use dt ≤ ([0-9.eE+-]+)", message)
    assert fix is not None, message
    assert float(fix.group(1)) == pytest.approx(limit, rel=5e-3)
    # The same error through rollout() and RodBatch.
    with pytest.raises(InvalidParameterError, match=r"^dt="):
        rollout(actions=np.zeros((1, 2, 2, 6)), dt=dt)
    with pytest.raises(InvalidParameterError, match=r"^dt="):
        RodBatch(1, SimParams(dt=dt))


def test_dt_just_below_the_limit_is_accepted() -> None:
    p = SimParams.from_overrides(dt=0.99 * SimParams().dt_limit)
    RodBatch(1, p)


def test_dt_limit_depends_on_damping_and_discretisation_in_the_message() -> None:
    with pytest.raises(InvalidParameterError, match=r"n_elem=40, damping=30"):
        SimParams.from_overrides(n_elem=40)
    assert SimParams(n_elem=40).dt_limit < SimParams().dt_limit
    assert SimParams(damping=60).dt_limit < SimParams().dt_limit < SimParams(damping=0).dt_limit


INVALID = [
    # (overrides, field named first in the message)
    ({"dt": 0.0}, "dt"),
    ({"dt": -1e-4}, "dt"),
    ({"dt": NAN}, "dt"),
    ({"dt": INF}, "dt"),
    ({"n_elem": 1}, "n_elem"),
    ({"n_elem": 0}, "n_elem"),
    ({"n_elem": -5}, "n_elem"),
    ({"n_elem": 2.5}, "n_elem"),
    ({"steps_per_action": 0}, "steps_per_action"),
    ({"radius": -0.05}, "radius"),
    ({"radius": 0.0}, "radius"),
    ({"radius": NAN}, "radius"),
    ({"radius": "0.05"}, "radius"),
    ({"density": -1000.0}, "density"),
    ({"density": 0.0}, "density"),
    ({"density": INF}, "density"),
    ({"youngs_modulus": -1e7}, "youngs_modulus"),
    ({"youngs_modulus": 0.0}, "youngs_modulus"),
    ({"youngs_modulus": NAN}, "youngs_modulus"),
    ({"youngs_modulus": INF}, "youngs_modulus"),
    ({"length": -1.0}, "length"),
    ({"length": NAN}, "length"),
    ({"damping": -1.0}, "damping"),
    ({"damping": NAN}, "damping"),
    ({"damping": INF}, "damping"),
    ({"gravity": NAN}, "gravity"),
    ({"gravity": -INF}, "gravity"),
    ({"torque_scale": NAN}, "torque_scale"),
    ({"shear_correction": 0.0}, "shear_correction"),
    ({"shear_correction": NAN}, "shear_correction"),
    ({"poisson_ratio": 0.7}, "poisson_ratio"),
    ({"poisson_ratio": -1.0}, "poisson_ratio"),
    ({"poisson_ratio": NAN}, "poisson_ratio"),
    ({"base_positions": []}, "base_positions"),
    ({"base_positions": [(0.0, 0.0)]}, "base_positions"),
    ({"base_positions": [(NAN, 0.0, 0.0), (0.1, 0.0, 0.0)]}, "base_positions"),
    ({"base_positions": [(-0.1, 0.0, 0.0), (0.1, INF, 0.0)]}, "base_positions"),
    ({"direction": (0.0, NAN, 0.0)}, "direction"),
    ({"direction": (0.0, 2.0, 0.0)}, "direction"),
    ({"normal": (0.0, 1.0, 0.0)}, "normal"),
    ({"normal": (1.0, 0.0)}, "normal"),
]


@pytest.mark.parametrize(
    "overrides, field", INVALID, ids=[f"{f}={next(iter(o.values()))!r}" for o, f in INVALID]
)
def test_invalid_value_names_the_field(overrides: dict, field: str) -> None:
    with pytest.raises(InvalidParameterError) as info:
        SimParams.from_overrides(**overrides)
    assert field in str(info.value), str(info.value)
    # rollout() passes its keyword arguments through the same validation.
    with pytest.raises(InvalidParameterError) as info:
        rollout(actions=np.zeros((1, 2, 2, 6)), **overrides)
    assert field in str(info.value)


def test_invalid_params_object_is_rejected_by_rod_batch() -> None:
    with pytest.raises(InvalidParameterError, match="radius"):
        RodBatch(1, SimParams(radius=-1.0))
    with pytest.raises(InvalidParameterError, match="n_elem"):
        RodBatch(1, SimParams(n_elem=1))


@pytest.mark.parametrize("name", ["youngs", "elements", "dT"])
def test_unknown_parameter_name(name: str) -> None:
    with pytest.raises(InvalidParameterError) as info:
        SimParams.from_overrides(**{name: 1.0})
    message = str(info.value)
    assert repr(name) in message
    assert "valid names" in message and "youngs_modulus" in message and "n_elem" in message
    with pytest.raises(InvalidParameterError, match=re.escape(repr(name))):
        rollout(actions=np.zeros((1, 2, 2, 6)), **{name: 1.0})


# ---- rollout inputs ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "shape", [(10, 2, 2, 5), (10, 2, 6), (10, 1, 2, 6), (10, 2, 3, 6), (0, 2, 2, 6), (2, 2, 6)]
)
def test_wrong_action_shape_shows_the_expected_shape(shape: tuple) -> None:
    with pytest.raises(InvalidParameterError) as info:
        rollout(actions=np.zeros(shape))
    message = str(info.value)
    assert message.startswith("actions")
    assert str(tuple(shape)) in message
    assert "(T, 2, 2, 6)" in message


def test_wrong_action_shape_follows_the_number_of_arms() -> None:
    with pytest.raises(InvalidParameterError, match=re.escape("(T, 1, 2, 6)")):
        rollout(actions=np.zeros((5, 2, 2, 6)), base_positions=[(0.0, 0.0, 0.0)])


@pytest.mark.parametrize("shape", [(10, 2, 2, 6), (10, 2, 2, 19), (10, 2, 1, 20)])
def test_wrong_element_torque_shape_shows_the_expected_shape(shape: tuple) -> None:
    with pytest.raises(InvalidParameterError) as info:
        rollout(element_torques=np.zeros(shape))
    assert "element_torques" in str(info.value)
    assert "(T, 2, 2, 20)" in str(info.value)


def test_exactly_one_input() -> None:
    with pytest.raises(InvalidParameterError, match="exactly one"):
        rollout()
    with pytest.raises(InvalidParameterError, match="exactly one"):
        rollout(actions=np.zeros((1, 2, 2, 6)), element_torques=np.zeros((1, 2, 2, 20)))


@pytest.mark.parametrize("bad", [NAN, INF, -INF])
def test_non_finite_actions_are_rejected_with_their_index(bad: float) -> None:
    actions = np.zeros((7, 2, 2, 6))
    actions[3, 1, 0, 4] = bad
    expected = re.escape("non-finite value at index (3, 1, 0, 4)")
    with pytest.raises(InvalidParameterError, match=expected):
        rollout(actions=actions)
    torques = np.zeros((7, 2, 2, 20))
    torques[5, 0, 1, 19] = bad
    with pytest.raises(InvalidParameterError, match=r"element_torques.*\(5, 0, 1, 19\)"):
        rollout(element_torques=torques)


# ---- the stability limit, empirically -------------------------------------------------------
@pytest.fixture
def no_validation(monkeypatch: pytest.MonkeyPatch) -> None:
    """Let RodBatch accept an unstable dt (validate() is called in RodBatch.__init__)."""
    monkeypatch.setattr(SimParams, "validate", lambda self: None)


# Undamped, random forcing pumps energy without bound and the (physical) state itself blows up
# at any dt: at ±0.5 within ~0.4 s even at dt = 2.5e-5 s, at ±0.05 within 2 s at 0.25×dt_limit.
# So ν_d = 0 uses ±0.01, whose threshold (0.968×) is the same as for ±0.0005 and over 2 s.
AMPLITUDE = {0.0: 0.01, 10.0: 0.5, 30.0: 0.5, 60.0: 0.5}


def diverges(damping: float, factor: float, duration: float = 0.5, seed: int = 0) -> bool:
    """True if random actions (uniform ±amplitude, seeded, held 10 steps) over ``duration``
    seconds at dt = factor·dt_limit give a non-finite or absurd state (a node > 10 m away)."""
    base = SimParams(damping=damping)
    p = dataclasses.replace(base, dt=factor * base.dt_limit)
    rng = np.random.default_rng(seed)
    amplitude = AMPLITUDE[damping]
    n_control = math.ceil(duration / p.control_dt)
    batch = RodBatch(1, p)
    with np.errstate(all="ignore"):
        for _ in range(n_control):
            batch.set_actions(rng.uniform(-amplitude, amplitude, size=(1, p.n_arms, 2, 6)))
            batch.advance()
            if not (batch.finite().all() and np.isfinite(batch.position).all()):
                return True
            if np.abs(batch.position).max() > 10.0:
                return True
    return False


def divergence_threshold(damping: float, lo: float = 0.5, hi: float = 2.0) -> tuple[float, float]:
    """(last stable, first diverging) multiple of dt_limit, by bisection to 0.2 %."""
    assert not diverges(damping, lo) and diverges(damping, hi)
    while hi - lo > 2e-3:
        mid = 0.5 * (lo + hi)
        if diverges(damping, mid):
            hi = mid
        else:
            lo = mid
    return lo, hi


def test_default_dt_stays_finite_under_random_actions() -> None:
    assert not diverges(SimParams().damping, SimParams().dt / SimParams().dt_limit)


@pytest.mark.parametrize("damping", [0.0, 10.0, 30.0, 60.0])
def test_dt_below_limit_stays_finite_and_above_diverges(no_validation, damping: float) -> None:
    assert not diverges(damping, 0.95)
    assert diverges(damping, 1.2)


@pytest.mark.parametrize("damping", [0.0, 10.0, 30.0, 60.0])
def test_empirical_divergence_threshold_is_close_to_the_closed_form(
    no_validation, damping: float, record_property
) -> None:
    stable, unstable = divergence_threshold(damping)
    record_property("stable_factor", stable)
    record_property("diverging_factor", unstable)
    assert 0.95 <= stable and unstable <= 1.05, (stable, unstable)


@pytest.mark.parametrize("damping", [0.0, 10.0, 30.0, 60.0])
def test_closed_form_limit_is_conservative(no_validation, damping: float) -> None:
    """The coupled bending mode makes the closed-form limit safe: 0.99 of it stays finite."""
    assert not diverges(damping, 0.99)
