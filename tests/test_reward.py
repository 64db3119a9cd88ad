"""Reward and safety penalty (docs/environment.md, "Reward")."""

from __future__ import annotations

import numpy as np
import pytest

from softtrack.env.reward import (
    RewardConfig,
    action_penalty,
    collision_penalty,
    reward_shares,
    tip_distances,
    tracking_reward,
)

EPS = 1e-9


def _reward(d1: float, d2: float, config: RewardConfig | None = None) -> float:
    return float(tracking_reward(np.array([[d1, d2]]), config or RewardConfig())[0])


def test_defaults_match_spec() -> None:
    c = RewardConfig()
    c.validate()
    assert c.arm_weights == (1.0, 1.0)
    assert c.bonus_thresholds == (0.10, 0.075) and c.bonus_values == (0.5, 1.0)
    assert (c.cooperative_threshold, c.cooperative_bonus) == (0.05, 1.5)
    assert (c.nonfinite_reward, c.collision_penalty) == (-1000.0, 0.0)
    s = RewardConfig.single_arm()
    s.validate()
    assert s.arm_weights == (1.0,) and s.bonus_thresholds == (0.10, 0.05)
    assert s.bonus_values == (0.5, 1.5) and s.cooperative_bonus == 0.0


@pytest.mark.parametrize(
    "d1, d2, expected",
    [
        (0.3, 0.4, -(0.09 + 0.16)),
        (0.10, 0.2, -(0.01 + 0.04) + 0.5),  # at 0.10: inside (≤)
        (0.10 + EPS, 0.2, -((0.10 + EPS) ** 2 + 0.04)),  # just outside
        (0.2, 0.10, -(0.04 + 0.01) + 0.5),  # either arm
        (0.075, 0.2, -(0.075**2 + 0.04) + 1.5),  # both individual bonuses
        (0.075 + EPS, 0.2, -((0.075 + EPS) ** 2 + 0.04) + 0.5),
        (0.09, 0.08, -(0.0081 + 0.0064) + 1.0),
        (0.06, 0.07, -(0.0036 + 0.0049) + 3.0),
        (0.05, 0.05, -(0.0025 + 0.0025) + 3.0 + 1.5),  # cooperative: both ≤ 0.05
        (0.05, 0.05 + EPS, -(0.0025 + (0.05 + EPS) ** 2) + 3.0),
        (0.01, 0.5, -(0.0001 + 0.25) + 1.5),  # one arm close: no cooperative
        (0.0, 0.0, 4.5),  # the maximum
    ],
)
def test_dual_arm_reward(d1: float, d2: float, expected: float) -> None:
    assert _reward(d1, d2) == pytest.approx(expected, abs=1e-12)


def test_weights() -> None:
    c = RewardConfig(arm_weights=(2.0, 0.5))
    assert _reward(0.3, 0.4, c) == pytest.approx(-(2 * 0.09 + 0.5 * 0.16))
    assert _reward(0.06, 0.2, c) == pytest.approx(-(2 * 0.0036 + 0.5 * 0.04) + 1.5)


def test_cooperative_bonus_can_be_disabled_or_changed() -> None:
    assert _reward(0.0, 0.0, RewardConfig(cooperative_bonus=0.0)) == pytest.approx(3.0)
    c = RewardConfig(cooperative_threshold=0.08, cooperative_bonus=2.0)
    assert _reward(0.078, 0.079, c) == pytest.approx(-(0.078**2 + 0.079**2) + 1.0 + 2.0)


@pytest.mark.parametrize(
    "d, expected",
    [
        (0.11, -0.0121),
        (0.10, -0.01 + 0.5),
        (0.07, -0.0049 + 0.5),
        (0.05 + EPS, -((0.05 + EPS) ** 2) + 0.5),
        (0.05, -0.0025 + 2.0),
        (0.0, 2.0),
    ],
)
def test_single_arm_reward(d: float, expected: float) -> None:
    r = tracking_reward(np.array([[d]]), RewardConfig.single_arm())
    assert r.shape == (1,)
    assert r[0] == pytest.approx(expected, abs=1e-12)


def test_batch_and_nonfinite() -> None:
    d = np.array([[0.3, 0.4], [np.nan, 0.01], [0.05, np.inf], [0.0, 0.0]])
    r = tracking_reward(d, RewardConfig())
    assert r.shape == (4,) and r.dtype == np.float64
    np.testing.assert_allclose(r, [-0.25, -1000.0, -1000.0, 4.5])
    with pytest.raises(ValueError, match="arm_weights"):
        tracking_reward(np.zeros((3, 1)), RewardConfig())
    with pytest.raises(ValueError, match="arm_weights"):
        tracking_reward(np.zeros(3), RewardConfig())


def test_tip_distances() -> None:
    tips = np.array([[[0.3, 0.6, 0.0], [0.0, 0.0, 0.0]]])
    target = np.array([[0.0, 0.2, 0.0]])
    np.testing.assert_allclose(tip_distances(tips, target), [[0.5, 0.2]])


@pytest.mark.parametrize(
    "overrides, field",
    [
        ({"arm_weights": ()}, "arm_weights"),
        ({"arm_weights": (1.0, -1.0)}, "arm_weights"),
        ({"bonus_thresholds": (0.1,)}, "bonus_thresholds"),
        ({"bonus_thresholds": (0.1, 0.0)}, "bonus_thresholds"),
        ({"bonus_values": (0.5, float("nan"))}, "bonus_values"),
        ({"cooperative_threshold": 0.0}, "cooperative_threshold"),
        ({"nonfinite_reward": float("-inf")}, "nonfinite_reward"),
        ({"collision_penalty": -1.0}, "collision_penalty"),
        ({"collision_margin": -0.1}, "collision_margin"),
        ({"arm_radius": 0.0}, "arm_radius"),
        ({"action_rate_penalty": -0.1}, "action_rate_penalty"),
        ({"action_penalty": float("nan")}, "action_penalty"),
    ],
)
def test_validate_names_the_field(overrides: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        RewardConfig(**overrides).validate()


# ---- collision penalty -----------------------------------------------------------------------


def _straight_arms(gap: float = 0.2, n: int = 1) -> np.ndarray:
    """(n, 2, 3, 21) two straight arms along +y, bases at x = ∓gap/2."""
    s = np.linspace(0.0, 1.0, 21)
    nodes = np.zeros((n, 2, 3, 21))
    nodes[:, 0, 0] = -gap / 2
    nodes[:, 1, 0] = gap / 2
    nodes[:, :, 1] = s
    return nodes


def test_collision_penalty_straight_arms() -> None:
    c = RewardConfig(collision_penalty=5.0)
    np.testing.assert_array_equal(collision_penalty(_straight_arms(0.2), c), [0.0])  # 0.2 ≥ 0.1
    np.testing.assert_array_equal(collision_penalty(_straight_arms(0.0999), c), [-5.0])
    np.testing.assert_array_equal(collision_penalty(_straight_arms(0.1001), c), [0.0])
    margin = RewardConfig(collision_penalty=5.0, collision_margin=0.11)  # clearance 0.21
    np.testing.assert_array_equal(collision_penalty(_straight_arms(0.2), margin), [-5.0])
    thin = RewardConfig(collision_penalty=5.0, arm_radius=0.04)  # clearance 0.08
    np.testing.assert_array_equal(collision_penalty(_straight_arms(0.09), thin), [0.0])


def test_collision_penalty_bent_arm_and_batch() -> None:
    nodes = _straight_arms(0.2, n=3)
    # env 1: arm 2's tip bends to 3 cm from arm 1's node 12 (y = 0.6)
    nodes[1, 1, :, 20] = [-0.1 + 0.03, 0.6, 0.0]
    # env 2: arm 2's tip 11 cm from arm 1's node 12, clear of it
    nodes[2, 1, :, 20] = [-0.1, 0.6, 0.11]
    c = RewardConfig(collision_penalty=2.5)
    np.testing.assert_array_equal(collision_penalty(nodes, c), [0.0, -2.5, 0.0])
    # disabled: zeros even where the arms overlap
    np.testing.assert_array_equal(collision_penalty(nodes, RewardConfig()), [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="nodes"):
        collision_penalty(nodes[:, :1], c)


@pytest.mark.parametrize(
    "d1, d2, expected",
    [
        (0.3, 0.4, (-0.09, -0.16)),
        (0.09, 0.2, (-0.0081 + 0.5, -0.04)),  # the other arm earns nothing
        (0.06, 0.07, (-0.0036 + 1.5, -0.0049 + 1.5)),
        (0.05, 0.01, (-0.0025 + 1.5 + 0.75, -0.0001 + 1.5 + 0.75)),  # cooperative: half each
        (0.01, 0.5, (-0.0001 + 1.5, -0.25)),
    ],
)
def test_reward_shares_are_each_arms_own_terms(d1: float, d2: float, expected: tuple) -> None:
    d = np.array([[d1, d2]])
    shares = reward_shares(d, tracking_reward(d, RewardConfig()), RewardConfig())
    assert shares.shape == (1, 2)
    np.testing.assert_allclose(shares[0], expected, atol=1e-12)


def test_reward_shares_split_penalties_and_nonfinite_rewards_equally() -> None:
    config = RewardConfig(arm_weights=(2.0, 0.5), collision_penalty=5.0)
    d = np.array([[0.06, 0.2], [np.nan, 0.01], [0.04, 0.03]])
    total = tracking_reward(d, config) + np.array([-5.0, 0.0, -5.0])  # a penalty on rows 0, 2
    shares = reward_shares(d, total, config)
    np.testing.assert_allclose(shares.sum(axis=1), total, atol=1e-12)
    np.testing.assert_allclose(shares[0], [-2 * 0.0036 + 1.5 - 2.5, -0.5 * 0.04 - 2.5])
    np.testing.assert_allclose(shares[1], [-500.0, -500.0])  # the non-finite reward, halved
    assert np.isfinite(shares).all()


# ---- action penalties (smooth actuation) ---------------------------------------------------


def test_action_penalty_is_the_weighted_mean_squares() -> None:
    actions = np.array([[1.0, -1.0, 0.5, 0.0], [0.0, 0.0, 0.0, 0.0]])
    previous = np.array([[0.0, -1.0, 1.0, 0.0], [1.0, 1.0, 1.0, 1.0]])
    config = RewardConfig(action_rate_penalty=2.0, action_penalty=0.5)
    expected_rate = np.array([(1 + 0 + 0.25 + 0) / 4, 1.0])
    expected_size = np.array([(1 + 1 + 0.25 + 0) / 4, 0.0])
    np.testing.assert_allclose(
        action_penalty(actions, previous, config), -2.0 * expected_rate - 0.5 * expected_size
    )
    assert not RewardConfig().penalises_actions
    np.testing.assert_array_equal(action_penalty(actions, previous, RewardConfig()), 0.0)


def test_the_env_subtracts_the_action_penalties_from_the_step_after_reset() -> None:
    from softtrack.env.core import TrackingCore
    from softtrack.env.settings import make_config

    plain = TrackingCore(1, make_config(target="circle"))
    smooth = TrackingCore(
        1, make_config(target="circle", action_rate_penalty=1.0, action_penalty=0.25)
    )
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1.5, 1.5, (4, 1, 24))
    for core in (plain, smooth):
        core.reset([0], [np.random.default_rng(1)])
    previous = np.zeros((1, 24))
    for action in actions:
        clipped = np.clip(action, -1, 1)
        want = (
            plain.step(action).reward
            - np.mean((clipped - previous) ** 2)
            - 0.25 * np.mean(clipped**2)
        )
        np.testing.assert_allclose(smooth.step(action).reward, want, rtol=1e-12)
        previous = clipped
    smooth.reset([0], [np.random.default_rng(1)])
    plain.reset([0], [np.random.default_rng(1)])
    clipped = np.clip(actions[0], -1, 1)
    np.testing.assert_allclose(
        smooth.step(actions[0]).reward,
        plain.step(actions[0]).reward - 1.25 * np.mean(clipped**2),
        rtol=1e-12,
    )
