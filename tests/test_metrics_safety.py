"""Smoothness and safety metrics of an evaluation episode against closed forms: the torque
rate of a linear ramp, the peak torque, the clearance of straight arms at a known
separation, the count of steps below the margin; and a short real episode."""

from __future__ import annotations

import numpy as np
import pytest

from softtrack.env import make_config
from softtrack.env.reward import RewardConfig, collision_penalty
from softtrack.evaluation import Episode, metrics_table, moment_peaks_table, run_episode
from softtrack.evaluation.metrics import (
    ACTION_STATISTICS,
    SAFETY_STATISTICS,
    TORQUE_STATISTICS,
    arm_clearance,
    safety_statistics,
    torque_statistics,
)

DT = 0.002  # s: the default control step
N_ELEM = 20


def _episode(
    torques: np.ndarray, clearance: np.ndarray | None = None, margin: float = 0.0
) -> Episode:
    n, n_arms = torques.shape[:2]
    return Episode(
        trajectory="circle",
        t=DT * np.arange(1, n + 1),
        tips=np.zeros((n, n_arms, 3)),
        target=np.ones((n, 3)),
        element_torques=torques,
        actions=np.zeros((n, 12 * n_arms)),
        terminated=False,
        clearance=clearance,
        collision_margin=margin,
    )


def _straight_arms(
    separation: float, n_nodes: int = N_ELEM + 1, length: float = 1.0, tilt: float = 0.0
) -> np.ndarray:
    """(2, 3, n_nodes): two vertical arms from (∓separation/2, 0, 0), the second tilted by
    ``tilt`` rad towards +x (so its base stays the closest point)."""
    s = np.linspace(0.0, length, n_nodes)
    nodes = np.zeros((2, 3, n_nodes))
    nodes[0, 0] = -separation / 2
    nodes[0, 2] = s
    nodes[1, 0] = separation / 2 + np.sin(tilt) * s
    nodes[1, 2] = np.cos(tilt) * s
    return nodes


# ---- torque smoothness and peak -------------------------------------------------------------
def test_linear_torque_ramp_has_its_slope_as_rate() -> None:
    n = 50
    t = DT * np.arange(1, n + 1)
    slopes = np.linspace(-40.0, 60.0, 2 * N_ELEM).reshape(2, N_ELEM)  # N·m/s per element
    torques = 3.0 + slopes[None] * t[:, None, None]  # (N, 2, n_elem)
    stats = torque_statistics(torques, t)
    assert set(stats) == set(TORQUE_STATISTICS)
    assert stats["torque_rate_rms"] == pytest.approx(np.sqrt(np.mean(slopes**2)), rel=1e-9)
    uniform = torque_statistics(7.5 * t[:, None, None] * np.ones((1, 2, N_ELEM)), t)
    assert uniform["torque_rate_rms"] == pytest.approx(7.5, rel=1e-9)
    # constant torques do not change; one step has no change at all
    assert torque_statistics(np.full((n, 2, N_ELEM), 80.0), t)["torque_rate_rms"] == 0.0
    assert torque_statistics(torques[:1], t[:1])["torque_rate_rms"] == 0.0


def test_bang_bang_torque_rate_and_peak() -> None:
    n = 10
    t = DT * np.arange(1, n + 1)
    torques = np.where(np.arange(n) % 2 == 0, 100.0, -100.0)[:, None, None] * np.ones(
        (1, 2, N_ELEM)
    )
    stats = torque_statistics(torques, t)
    assert stats["torque_rate_rms"] == pytest.approx(200.0 / DT, rel=1e-9)
    assert stats["peak_moment"] == 100.0


def test_peak_moment_is_the_largest_absolute_torque() -> None:
    rng = np.random.default_rng(1)
    torques = rng.normal(0.0, 20.0, size=(30, 2, 2, N_ELEM))
    torques[17, 1, 0, 4] = -138.9  # arm 2's peak, negative
    torques[3, 0, 1, 19] = 121.7  # arm 1's peak
    table = metrics_table("run", _episode(torques)).set_index("arm")
    assert table.loc[0, "peak_moment"] == 121.7
    assert table.loc[1, "peak_moment"] == 138.9
    # the maximum of the arm's eval_moment_peaks rows (stored as float32)
    peaks = moment_peaks_table("run", _episode(torques))
    for arm in (0, 1):
        stored = peaks.loc[peaks["arm"] == arm, "peak_abs_moment"].max()
        assert stored == np.float32(table.loc[arm, "peak_moment"])


def test_torque_rate_is_per_arm_in_the_metrics_table() -> None:
    n = 20
    t = DT * np.arange(1, n + 1)
    torques = np.zeros((n, 2, 2, N_ELEM))
    torques[:, 1] = 25.0 * t[:, None, None]  # arm 2 ramps at 25 N·m/s, arm 1 stays at 0
    table = metrics_table("run", _episode(torques)).set_index("arm")
    assert table.loc[0, "torque_rate_rms"] == 0.0
    assert table.loc[1, "torque_rate_rms"] == pytest.approx(25.0, rel=1e-9)


def test_torque_statistics_reject_bad_shapes() -> None:
    with pytest.raises(ValueError, match="shape"):
        torque_statistics(np.zeros((3, 2, N_ELEM)), np.zeros(4))
    with pytest.raises(ValueError, match="time step"):
        torque_statistics(np.zeros((0, 2, N_ELEM)), np.zeros(0))


# ---- inter-arm clearance --------------------------------------------------------------------
@pytest.mark.parametrize("separation", [0.2, 0.1, 0.35, 0.07])
def test_straight_arms_clearance_is_separation_minus_radii(separation: float) -> None:
    clearance = arm_clearance(_straight_arms(separation), 0.05)
    assert clearance == pytest.approx(separation - 0.1, abs=1e-15)
    # a tilted second arm moves away from the first: the bases stay the closest pair
    assert arm_clearance(_straight_arms(separation, tilt=0.3), 0.04) == pytest.approx(
        separation - 0.08, abs=1e-15
    )


def test_clearance_of_crossing_arms_is_minus_both_radii() -> None:
    nodes = _straight_arms(0.2)
    nodes[1, 0] = -0.1  # the second arm on top of the first: distance 0
    assert arm_clearance(nodes, 0.05) == pytest.approx(-0.1)


def test_clearance_batches_and_undefined_cases() -> None:
    batch = np.stack([_straight_arms(s) for s in (0.2, 0.3, 0.15)])  # (3, 2, 3, n)
    assert np.allclose(arm_clearance(batch, 0.05), [0.1, 0.2, 0.05], rtol=0, atol=1e-15)
    assert np.isnan(arm_clearance(_straight_arms(0.2)[:1], 0.05))  # one arm: no other arm
    broken = _straight_arms(0.2)
    broken[1, 2, 7] = np.nan
    assert np.isnan(arm_clearance(broken, 0.05))
    # three arms at x = −0.2, 0.2 and −0.125: the closest pair is 0.075 m apart
    three = np.concatenate([_straight_arms(0.4), _straight_arms(0.25)[:1]])
    assert arm_clearance(three, 0.05) == pytest.approx(0.075 - 0.1)
    with pytest.raises(ValueError, match="shape"):
        arm_clearance(np.zeros((2, 2, 21)), 0.05)


@pytest.mark.parametrize("margin", [0.0, 0.05, 0.11])
def test_clearance_below_margin_is_the_reward_collision_test(margin: float) -> None:
    """collision_steps counts the steps on which the reward's collision penalty applies."""
    config = RewardConfig(collision_penalty=1.0, collision_margin=margin, arm_radius=0.05)
    nodes = np.stack([_straight_arms(s) for s in (0.05, 0.1, 0.14, 0.2, 0.25, 0.5)])
    penalised = collision_penalty(nodes, config) < 0
    clearance = np.asarray(arm_clearance(nodes, 0.05))
    assert list(clearance < margin) == list(penalised)
    assert safety_statistics(clearance, margin)["collision_steps"] == int(penalised.sum())


def test_safety_statistics_count_exactly() -> None:
    clearance = np.array([0.10, 0.04, -0.01, 0.0, 0.02, -0.003, 0.09, np.nan])
    stats = safety_statistics(clearance)  # margin 0: contact only (clearance < 0)
    assert set(stats) == set(SAFETY_STATISTICS)
    assert stats == {"min_arm_distance": -0.01, "collision_steps": 2}
    assert safety_statistics(clearance, 0.02)["collision_steps"] == 3  # 0.02 is not below
    assert safety_statistics(clearance, 0.05)["collision_steps"] == 5
    undefined = safety_statistics(np.full(5, np.nan), 0.05)
    assert np.isnan(undefined["min_arm_distance"]) and undefined["collision_steps"] == 0


def test_metrics_table_safety_columns() -> None:
    n = 6
    clearance = np.array([0.1, 0.05, -0.02, 0.01, -0.01, 0.08])
    table = metrics_table("run", _episode(np.zeros((n, 2, 2, N_ELEM)), clearance, 0.02))
    # the same per-episode values in both arms' rows
    assert list(table["min_arm_distance"]) == [-0.02, -0.02]
    assert list(table["collision_steps"]) == [3, 3]
    # the new columns follow every existing one, whose order is unchanged
    columns = list(table.columns)
    assert columns[-4:] == [*TORQUE_STATISTICS, *SAFETY_STATISTICS]
    assert columns[columns.index("action_rms") - 2 : columns.index("action_rms") + 3] == [
        *ACTION_STATISTICS,
        "terminated",
        "duration",
    ]
    # not recorded (None) and a single arm: no clearance
    for episode in (
        _episode(np.zeros((n, 2, 2, N_ELEM))),
        _episode(np.zeros((n, 1, 2, N_ELEM)), np.full(n, np.nan)),
    ):
        rows = metrics_table("run", episode)
        assert rows["min_arm_distance"].isna().all()
        assert (rows["collision_steps"] == 0).all()


# ---- real episodes --------------------------------------------------------------------------
def test_short_real_episode_has_finite_smoothness_and_safety() -> None:
    config = make_config()
    assert config.reward.collision_margin == 0.0  # default: collision_steps counts contact

    steps = iter(range(10**6))

    def policy(observation: np.ndarray) -> np.ndarray:  # slowly varying actions
        return np.full(24, 0.3 * np.sin(next(steps) / 5.0))

    episode = run_episode(policy, config, "circle", duration=0.1)
    n = len(episode.t)
    assert n == 50 and episode.clearance is not None and episode.clearance.shape == (n,)
    assert episode.collision_margin == 0.0
    # the straight arms stand 0.2 m apart, radius 0.05 m: 0.1 m between their surfaces
    assert episode.clearance[0] == pytest.approx(0.1, abs=1e-3)
    assert np.isfinite(episode.clearance).all() and (episode.clearance > 0).all()
    rows = metrics_table("run", episode)
    for key in (*TORQUE_STATISTICS, *SAFETY_STATISTICS):
        assert np.isfinite(rows[key].to_numpy(float)).all(), key
    assert (rows["torque_rate_rms"] > 0).all()
    assert (rows["peak_moment"] > 0).all()
    assert (rows["min_arm_distance"] == episode.clearance.min()).all()
    assert (rows["min_arm_distance"] > 0).all() and (rows["collision_steps"] == 0).all()
    # the clearance recomputed from the engine's reset state: its exact start
    assert arm_clearance(_straight_arms(0.2), config.sim.radius) == pytest.approx(0.1)


def test_short_single_arm_episode_has_no_clearance() -> None:
    config = make_config(n_arms=1, arm=0)
    episode = run_episode(lambda observation: np.full(12, 0.3), config, "random", 0.02, seed=1)
    assert episode.clearance is not None and np.isnan(episode.clearance).all()
    rows = metrics_table("run", episode)
    assert len(rows) == 1
    assert np.isnan(rows.loc[0, "min_arm_distance"]) and rows.loc[0, "collision_steps"] == 0
    assert np.isfinite(rows.loc[0, "torque_rate_rms"]) and rows.loc[0, "peak_moment"] > 0


def test_clearance_uses_the_episodes_radius_under_model_error() -> None:
    """A model-error radius factor thickens the rods: 1.2 × 0.05 m leaves 0.2 − 0.12 m."""
    config = make_config(realism={"radius_scale": 1.2})
    episode = run_episode(lambda observation: np.zeros(24), config, "circle", duration=0.004)
    assert episode.clearance is not None
    assert episode.clearance[0] == pytest.approx(0.08, abs=1e-4)
