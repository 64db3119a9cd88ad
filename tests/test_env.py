"""The Gymnasium environments and the SB3 vectorised env (docs/environment.md, "The environment").

The pure pieces (targets, observation layout, reward formula) have their own tests; these
check the environments built from them against the engine state they expose.
"""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

import softtrack.env  # noqa: F401  (registers the Gymnasium ids)
from softtrack.env import (
    DualArmTrackingEnv,
    NonFiniteActionError,
    SingleArmTrackingEnv,
    TrackingCore,
    make_config,
)
from softtrack.env.vec_env import TrackingVecEnv
from softtrack.sim import InvalidParameterError, spline_matrix

CONTROL_DT = 0.002  # s, 10 integration steps of 2e-4 s


def _env(kind: str, **kwargs) -> gym.Env:
    if kind == "dual":
        return DualArmTrackingEnv(**kwargs)
    return SingleArmTrackingEnv(arm=int(kind[-1]), **kwargs)


ENV_KINDS = ["dual", "single0", "single1"]
N_ARMS = {"dual": 2, "single0": 1, "single1": 1}


def _actions(n_steps: int, dim: int, seed: int = 0, scale: float = 0.4) -> np.ndarray:
    """Moderate random actions (float32, like a policy's), reproducible."""
    return np.random.default_rng(seed).uniform(-scale, scale, (n_steps, dim)).astype(np.float32)


def _expected_reward(d: np.ndarray, n_arms: int) -> float:
    """The docs/environment.md reward written out by hand from the tip distances."""
    if n_arms == 2:
        d1, d2 = float(d[0]), float(d[1])
        r = -(1.0 * d1**2 + 1.0 * d2**2)
        for di in (d1, d2):
            r += 0.5 * (di <= 0.10) + 1.0 * (di <= 0.075)
        r += 1.5 * (d1 <= 0.05 and d2 <= 0.05)
        return r
    (d1,) = (float(v) for v in d)
    return -(d1**2) + 0.5 * (d1 <= 0.10) + 1.5 * (d1 <= 0.05)


# ---- API conformance -------------------------------------------------------------------------


def _only_infinite_bound_warnings(caught: list[warnings.WarningMessage]) -> None:
    others = [str(w.message) for w in caught if "infinity" not in str(w.message)]
    assert not others, others


@pytest.mark.parametrize("kind", ENV_KINDS)
def test_gymnasium_env_checker(kind: str) -> None:
    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(_env(kind), skip_render_check=True)
    _only_infinite_bound_warnings(caught)


@pytest.mark.parametrize("kind", ENV_KINDS)
def test_sb3_env_checker(kind: str) -> None:
    from stable_baselines3.common.env_checker import check_env

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(_env(kind), warn=True)
    _only_infinite_bound_warnings(caught)


@pytest.mark.parametrize("kind", ENV_KINDS)
def test_spaces(kind: str) -> None:
    env = _env(kind)
    n_arms = N_ARMS[kind]
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (12 * n_arms,), np.float32)
    assert env.observation_space.shape == ({2: 81, 1: 44}[n_arms],)
    assert env.observation_space.dtype == np.float32
    assert np.all(np.isinf(env.observation_space.low)) and np.all(env.observation_space.low < 0)
    assert np.all(np.isinf(env.observation_space.high)) and np.all(env.observation_space.high > 0)


def test_gymnasium_make_registered_ids() -> None:
    env = gym.make("softtrack/DualArmTracking-v0", target="circle")
    obs, info = env.reset(seed=0)
    assert obs.shape == (81,)
    np.testing.assert_allclose(info["target_position"], [0.3, 0.6, 0.0], atol=1e-15)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert np.isfinite(reward) and not terminated and not truncated
    single = gym.make("softtrack/SingleArmTracking-v0", arm=1, target="figure8")
    obs, info = single.reset(seed=0)
    assert obs.shape == (44,) and info["tip_positions"].shape == (1, 3)
    np.testing.assert_array_equal(info["tip_positions"][0], [0.1, 1.0, 0.0])


def test_keywords_reach_every_part_of_the_config() -> None:
    env = gym.make(
        "softtrack/DualArmTracking-v0",
        target="circle",
        dt=1e-4,
        gravity=True,
        damping=20.0,
        period=5.0,
        center=(0.1, 0.5, -0.1),
        bonus_thresholds=(0.3, 0.2),
        collision_penalty=2.0,
        episode_duration=1.0,
    )
    config = env.unwrapped.config
    assert (config.sim.dt, config.sim.gravity, config.sim.damping) == (1e-4, 9.81, 20.0)
    assert config.sim.control_dt == pytest.approx(1e-3)
    assert (config.target.name, config.target.period) == ("circle", 5.0)
    assert config.target.center == (0.1, 0.5, -0.1)
    assert config.reward.bonus_thresholds == (0.3, 0.2)
    assert config.reward.collision_penalty == 2.0
    assert config.episode_duration == 1.0 and config.max_episode_steps == 1000


def test_target_keywords_change_the_target_motion() -> None:
    env = DualArmTrackingEnv(
        target="circle", period=5.0, center=(0.1, 0.5, -0.1), circle_radius=0.2
    )
    env.reset(seed=0)
    for k in range(1, 6):
        obs, _, _, _, info = env.step(np.zeros(24, np.float32))
        t = k * CONTROL_DT
        w = 2 * np.pi / 5.0
        expected = [0.1 + 0.2 * np.cos(w * t), 0.5, -0.1 + 0.2 * np.sin(w * t)]
        np.testing.assert_allclose(info["target_position"], expected, atol=1e-12)
        assert obs[77] == pytest.approx(0.2 * w, rel=1e-6)


def test_gravity_keyword_changes_the_physics() -> None:
    tips = {}
    for gravity in (0.0, True):
        env = DualArmTrackingEnv(target="fixed", gravity=gravity)
        env.reset(seed=0)
        for _ in range(20):
            _, _, _, _, info = env.step(np.zeros(24, np.float32))
        tips[gravity] = info["tip_positions"]
    np.testing.assert_allclose(tips[0.0], [[-0.1, 1.0, 0.0], [0.1, 1.0, 0.0]], atol=1e-12)
    assert np.all(tips[True][:, 1] < 1.0 - 1e-6)  # pulled along −y


def test_reward_keywords_change_the_reward() -> None:
    # Straight arms at rest, fixed target: d = ‖(±0.1, 1, 0) − (0, 0.8, 0)‖ = √0.05 ≈ 0.224 m.
    env = DualArmTrackingEnv(
        target="fixed",
        fixed_position=(0.0, 0.8, 0.0),
        bonus_thresholds=(0.3, 0.2),
        collision_penalty=2.0,
        collision_margin=0.15,
    )
    env.reset(seed=0)
    _, reward, _, _, info = env.step(np.zeros(24, np.float32))
    d = info["distances"]
    np.testing.assert_allclose(d, np.sqrt(0.05), rtol=1e-9)
    # −Σd² + 0.5 per arm within 0.3 m, nothing within 0.2 m, and −2 because the arms
    # (0.2 m apart) are closer than 2·0.05 + 0.15 = 0.25 m.
    assert reward == pytest.approx(-(d @ d) + 2 * 0.5 - 2.0, abs=1e-12)


@pytest.mark.parametrize(
    "factory",
    [
        lambda **kw: DualArmTrackingEnv(**kw),
        lambda **kw: SingleArmTrackingEnv(arm=0, **kw),
        lambda **kw: gym.make("softtrack/DualArmTracking-v0", **kw),
        lambda **kw: TrackingVecEnv(2, **kw),
    ],
)
def test_unknown_keyword_is_named(factory) -> None:
    with pytest.raises(InvalidParameterError, match="'dampening'") as excinfo:
        factory(target="circle", dampening=30.0)
    assert isinstance(excinfo.value, ValueError)
    assert "damping" in str(excinfo.value)  # the valid names are listed


def test_invalid_values_are_rejected() -> None:
    with pytest.raises(InvalidParameterError, match="episode_duration"):
        DualArmTrackingEnv(episode_duration=-1.0)
    with pytest.raises(InvalidParameterError, match="arm"):
        SingleArmTrackingEnv(arm=2)
    with pytest.raises(InvalidParameterError, match="target"):
        DualArmTrackingEnv(target="spiral")


# ---- observation, reward, info ---------------------------------------------------------------


@pytest.mark.parametrize("kind", ENV_KINDS)
def test_observation_layout_against_engine_state(kind: str) -> None:
    env = _env(kind)
    n_arms = N_ARMS[kind]
    obs, _ = env.reset(seed=5)
    for action in _actions(6, 12 * n_arms, seed=1):
        obs, *_ = env.step(action)
    core: TrackingCore = env.unwrapped.core
    engine, targets = core.engine, core.targets
    assert obs.shape == (37 * n_arms + 7,) and obs.dtype == np.float32
    assert np.any(engine.velocity != 0.0)  # the arms do move
    for arm in range(n_arms):
        base = 37 * arm
        for c in range(3):  # x block, then y block, then z block
            for j in range(11):  # nodes 0, 2, …, 20
                assert obs[base + 11 * c + j] == np.float32(engine.position[0, arm, c, 2 * j]), (
                    arm,
                    c,
                    j,
                )
        v_tip = engine.velocity[0, arm, :, 20]
        speed = np.linalg.norm(v_tip)
        assert speed > 0
        assert obs[base + 33] == pytest.approx(speed, rel=1e-6)
        np.testing.assert_allclose(obs[base + 34 : base + 37], v_tip / speed, rtol=1e-6, atol=1e-7)
    tail = 37 * n_arms
    np.testing.assert_array_equal(obs[tail : tail + 3], targets.position[0].astype(np.float32))
    target_speed = np.linalg.norm(targets.velocity[0])
    assert obs[tail + 3] == pytest.approx(0.3, rel=1e-6)  # random target, default speed
    assert obs[tail + 3] == pytest.approx(target_speed, rel=1e-6)
    np.testing.assert_allclose(
        obs[tail + 4 : tail + 7], targets.velocity[0] / target_speed, rtol=1e-6, atol=1e-7
    )
    # node 0 is the clamped base, node 20 the tip
    bases = {"dual": [-0.1, 0.1], "single0": [-0.1], "single1": [0.1]}[kind]
    for arm, x in enumerate(bases):
        np.testing.assert_array_equal(
            obs[37 * arm + np.array([0, 11, 22])], np.float32([x, 0.0, 0.0])
        )
        np.testing.assert_array_equal(
            obs[37 * arm + np.array([10, 21, 32])], engine.tip_position[0, arm].astype(np.float32)
        )


def test_initial_observation_straight_arms_at_rest() -> None:
    env = DualArmTrackingEnv(target="circle")
    obs, info = env.reset(seed=0)
    s = np.linspace(0.0, 1.0, 11)
    for arm, x in enumerate((-0.1, 0.1)):
        block = obs[37 * arm : 37 * arm + 37]
        np.testing.assert_array_equal(block[0:11], np.float32(x))
        np.testing.assert_allclose(block[11:22], s, atol=1e-7)
        np.testing.assert_array_equal(block[22:37], 0.0)  # z = 0, speed 0, direction zeros
    np.testing.assert_allclose(obs[74:77], [0.3, 0.6, 0.0], atol=1e-7)
    assert obs[77] == pytest.approx(0.3 * 2 * np.pi / 10, rel=1e-6)
    np.testing.assert_allclose(obs[78:81], [0.0, 0.0, 1.0], atol=1e-7)
    assert info["time"] == 0.0


@pytest.mark.parametrize("kind", ENV_KINDS)
def test_reward_and_info_every_step(kind: str) -> None:
    n_arms = N_ARMS[kind]
    # A fixed target near the (first) arm's tip so that the bonuses are exercised as well.
    target = (0.1 if kind == "single1" else -0.1, 0.93, 0.0)
    env = _env(kind, target="fixed", fixed_position=target)
    env.reset(seed=0)
    B = spline_matrix(20)
    actions = _actions(40, 12 * n_arms, seed=2, scale=1.3)  # also beyond [−1, 1]
    bonus_seen = False
    for k, action in enumerate(actions, start=1):
        _, reward, terminated, truncated, info = env.step(action)
        assert not terminated and not truncated
        assert set(info) == {
            "tip_positions",
            "target_position",
            "distances",
            "element_torques",
            "time",
        }
        tips = info["tip_positions"]
        assert tips.shape == (n_arms, 3)
        assert info["target_position"].shape == (3,)
        assert info["distances"].shape == (n_arms,)
        assert info["element_torques"].shape == (n_arms, 2, 20)
        np.testing.assert_array_equal(tips, env.unwrapped.core.engine.tip_position[0])
        np.testing.assert_array_equal(info["target_position"], target)
        np.testing.assert_allclose(
            info["distances"],
            np.linalg.norm(tips - info["target_position"], axis=1),
            rtol=1e-14,
            atol=1e-15,
        )
        assert reward == pytest.approx(_expected_reward(info["distances"], n_arms), abs=1e-12)
        bonus_seen |= bool(np.any(info["distances"] <= 0.10))
        control = np.clip(action.astype(np.float64), -1, 1).reshape(n_arms, 2, 6)
        expected_torques = 75.0 * np.einsum("ej,adj->ade", B, control)
        np.testing.assert_allclose(
            info["element_torques"], expected_torques, rtol=1e-12, atol=1e-12
        )
        assert info["time"] == pytest.approx(CONTROL_DT * k, rel=1e-12)
    assert bonus_seen


def test_each_arm_moves_only_with_its_own_actions() -> None:
    """The arms share no force: arm 1's state is the same whatever arm 2 does, and the same as
    in arm 1's single-arm environment (why a centralized policy has no physical coupling to use).
    """
    own = _actions(60, 12, seed=4, scale=1.0)
    arm1_blocks, arm1_tips = [], []
    for other_seed in (5, 6):
        env = DualArmTrackingEnv(target="circle")
        env.reset(seed=0)
        other = _actions(60, 12, seed=other_seed, scale=1.0)
        blocks, tips = [], []
        for a1, a2 in zip(own, other, strict=False):
            obs, _, _, _, info = env.step(np.concatenate([a1, a2]))
            blocks.append(obs[:37])
            tips.append(info["tip_positions"])
        arm1_blocks.append(np.array(blocks))
        arm1_tips.append(np.array(tips))
    np.testing.assert_array_equal(arm1_blocks[0], arm1_blocks[1])
    assert np.abs(arm1_tips[0][:, 1] - arm1_tips[1][:, 1]).max() > 0.01  # arm 2 did differ
    single = SingleArmTrackingEnv(arm=0, target="circle")
    single.reset(seed=0)
    single_blocks = np.array([single.step(a1)[0][:37] for a1 in own])
    np.testing.assert_array_equal(single_blocks, arm1_blocks[0])


def test_info_holds_copies() -> None:
    env = DualArmTrackingEnv()
    env.reset(seed=0)
    _, _, _, _, info = env.step(_actions(1, 24)[0])
    before = {k: np.copy(v) for k, v in info.items()}
    env.step(_actions(1, 24, seed=9)[0])
    for key, value in before.items():
        np.testing.assert_array_equal(info[key], value)


# ---- actions ---------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["dual", "single1"])
def test_out_of_range_actions_are_clipped(kind: str) -> None:
    dim = 12 * N_ARMS[kind]
    raw = _actions(8, dim, seed=3, scale=3.0)
    assert np.any(np.abs(raw) > 1)
    results = []
    for actions in (raw, np.clip(raw, -1.0, 1.0)):
        env = _env(kind)
        obs, _ = env.reset(seed=11)
        trace = [obs]
        for action in actions:
            obs, reward, _, _, info = env.step(action)
            trace += [obs, reward, info["element_torques"]]
        results.append(trace)
    for a, b in zip(*results, strict=True):
        np.testing.assert_array_equal(a, b)
    assert (
        np.max(np.abs(results[0][-1])) > 75.0
    )  # spline overshoot is not clipped (docs/physics.md)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("kind", ["dual", "single0"])
def test_non_finite_action_raises(kind: str, bad: float) -> None:
    env = _env(kind)
    env.reset(seed=0)
    action = np.zeros(env.action_space.shape, np.float32)
    action[5] = bad
    with pytest.raises(NonFiniteActionError) as excinfo:
        env.step(action)
    assert isinstance(excinfo.value, ValueError)
    vec = TrackingVecEnv(3)
    vec.reset()
    actions = np.zeros((3, 24), np.float32)
    actions[2, 0] = bad
    with pytest.raises(NonFiniteActionError, match="environment 2"):
        vec.step(actions)


def test_wrong_action_shape_raises() -> None:
    env = DualArmTrackingEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(12, np.float32))


# ---- episode end -----------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ENV_KINDS)
def test_non_finite_state_terminates(kind: str) -> None:
    env = _env(kind)
    env.reset(seed=0)
    zero = np.zeros(env.action_space.shape, np.float32)
    for _ in range(3):
        env.step(zero)
    env.unwrapped.core.engine.velocity[0, 0, 1, 7] = np.nan
    obs, reward, terminated, truncated, _ = env.step(zero)
    assert terminated is True and truncated is False
    assert reward == -1000.0
    assert obs.dtype == np.float32 and obs.shape == env.observation_space.shape
    assert np.all(np.isfinite(obs))  # NaNs are not passed on to the policy
    # a reset brings the arms back, straight and at rest
    obs, _ = env.reset(seed=0)
    obs2, reward, terminated, truncated, _ = env.step(zero)
    assert not terminated and reward > -1000.0 and np.all(np.isfinite(obs2))


def test_infinite_state_terminates_even_at_the_time_limit() -> None:
    env = DualArmTrackingEnv(episode_duration=0.004)  # 2 steps
    env.reset(seed=0)
    env.step(np.zeros(24, np.float32))
    env.unwrapped.core.engine.position[0, 1, 0, 12] = np.inf
    _, reward, terminated, truncated, _ = env.step(np.zeros(24, np.float32))
    assert (reward, terminated, truncated) == (-1000.0, True, False)


@pytest.mark.parametrize("kind", ENV_KINDS)
def test_truncation_after_episode_duration(kind: str) -> None:
    env = _env(kind, episode_duration=0.02)  # 10 control steps
    env.reset(seed=0)
    for k, action in enumerate(_actions(10, env.action_space.shape[0]), start=1):
        _, _, terminated, truncated, info = env.step(action)
        assert terminated is False
        assert truncated is (k == 10)
    assert info["time"] == pytest.approx(0.02, rel=1e-12)
    env.reset()
    _, _, _, truncated, info = env.step(np.zeros(env.action_space.shape, np.float32))
    assert truncated is False and info["time"] == pytest.approx(CONTROL_DT)


def test_default_episode_is_5000_steps() -> None:
    assert make_config().max_episode_steps == 5000
    assert DualArmTrackingEnv().core.max_steps == 5000


# ---- seeding ---------------------------------------------------------------------------------


def _episode(env: gym.Env, seed: int | None, actions: np.ndarray) -> list[np.ndarray]:
    obs, _ = env.reset(seed=seed)
    trace = [obs]
    for action in actions:
        obs, reward, *_ = env.step(action)
        trace += [obs, np.float64(reward)]
    return trace


@pytest.mark.parametrize("kind", ["dual", "single0"])
def test_same_seed_same_episode_different_seed_different(kind: str) -> None:
    actions = _actions(120, 12 * N_ARMS[kind], seed=4)
    first = _episode(_env(kind), 7, actions)
    reused = _env(kind)
    _episode(reused, 3, actions[:30])  # an unrelated episode before
    second = _episode(reused, 7, actions)
    for a, b in zip(first, second, strict=True):
        np.testing.assert_array_equal(a, b)  # bit for bit
    other = _episode(_env(kind), 8, actions)
    assert not np.array_equal(first[0][-7:-4], other[0][-7:-4])  # another target start
    assert not np.array_equal(first[-2], other[-2])


def test_same_seed_same_random_target_past_redirects() -> None:
    """1.2 s of random target: one direction change; still identical for equal seeds."""
    actions = np.zeros((600, 24), np.float32)
    runs = [_episode(DualArmTrackingEnv(), 21, actions) for _ in range(2)]
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)
    # the direction was drawn anew at 1.0 s, i.e. by control step 500 (walls may flip it too)
    direction = [runs[0][2 * k - 1][78:81] for k in range(1, 601)]  # obs after step k = 1…600
    changed = [
        k for k in range(2, 601) if not np.allclose(direction[k - 1], direction[k - 2], atol=1e-3)
    ]
    assert 500 in changed


# ---- the vectorised env ----------------------------------------------------------------------


def _collect(venv, actions: np.ndarray) -> list:
    """obs, rewards, dones and the finished episodes' info of every step (after a reset)."""
    trace = [venv.reset()]
    for action in actions:
        obs, rewards, dones, infos = venv.step(action)
        trace += [obs, rewards, dones]
        for i, info in enumerate(infos):
            trace.append(bool(info.get("TimeLimit.truncated", False)))
            if dones[i]:
                trace.append(info["terminal_observation"])
            else:
                assert "terminal_observation" not in info
    return trace


def _assert_same_traces(a: list, b: list) -> None:
    assert len(a) == len(b)
    for k, (x, y) in enumerate(zip(a, b, strict=True)):
        x, y = np.asarray(x), np.asarray(y)
        assert x.shape == y.shape and x.dtype == y.dtype, (k, x.shape, y.shape, x.dtype, y.dtype)
        np.testing.assert_array_equal(x, y, err_msg=f"item {k}")


@pytest.mark.parametrize("target", ["random", "circle"])
def test_vec_env_matches_dummy_vec_env(target: str) -> None:
    n_envs, kwargs = 3, {"target": target, "episode_duration": 0.03}  # 15-step episodes
    actions = np.random.default_rng(5).uniform(-0.6, 0.6, (50, n_envs, 24)).astype(np.float32)
    dummy = DummyVecEnv([lambda: DualArmTrackingEnv(**kwargs)] * n_envs)
    vec = TrackingVecEnv(n_envs, **kwargs)
    assert vec.observation_space == dummy.observation_space
    assert vec.action_space == dummy.action_space
    assert dummy.seed(17) == vec.seed(17) == [17, 18, 19]
    expected = _collect(dummy, actions)
    got = _collect(vec, actions)
    _assert_same_traces(got, expected)
    n_finished = sum(
        int(np.count_nonzero(venv_dones))
        for venv_dones in got
        if isinstance(venv_dones, np.ndarray) and venv_dones.dtype == np.bool_
    )
    assert n_finished == 9  # 50 steps: three auto-resets of each of the 3 environments
    # reset again without a new seed: both continue their random streams
    _assert_same_traces(_collect(vec, actions[:20]), _collect(dummy, actions[:20]))


def test_vec_env_constructs_without_warnings() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        vec = TrackingVecEnv(2, target="circle")
    assert vec.render_mode is None and vec.num_envs == 2
    assert vec.get_attr("config") == [vec.config, vec.config]
    assert vec.env_is_wrapped(gym.Wrapper) == [False, False]


def test_vec_env_auto_resets_and_truncates() -> None:
    vec = TrackingVecEnv(2, episode_duration=0.02)
    vec.seed(0)
    vec.reset()
    zero = np.zeros((2, 24), np.float32)
    for k in range(1, 21):
        obs, rewards, dones, infos = vec.step(zero)
        assert rewards.shape == (2,) and rewards.dtype == np.float32
        assert obs.shape == (2, 81) and obs.dtype == np.float32
        if k % 10 == 0:
            assert dones.tolist() == [True, True]
            for info in infos:
                assert info["TimeLimit.truncated"] is True
                assert info["terminal_observation"].shape == (81,)
            # the returned observation is the new episode's first one: arms straight again
            np.testing.assert_allclose(
                obs[:, 11:22], np.tile(np.linspace(0, 1, 11), (2, 1)), atol=1e-7
            )
        else:
            assert not dones.any()


def test_vec_env_non_finite_state_matches_dummy_vec_env() -> None:
    """A forced NaN in env 1 terminates it (−1000, not truncated) and it is reset."""
    n_envs, kwargs = 3, {"episode_duration": 0.02}
    actions = np.random.default_rng(6).uniform(-0.5, 0.5, (14, n_envs, 24)).astype(np.float32)
    dummy = DummyVecEnv([lambda: DualArmTrackingEnv(**kwargs)] * n_envs)
    vec = TrackingVecEnv(n_envs, **kwargs)
    # velocity arrays (env, arm, axis, node) in which to plant the NaN of environment 1
    velocity_of_env1 = {
        id(dummy): lambda: dummy.envs[1].unwrapped.core.engine.velocity[0],
        id(vec): lambda: vec.core.engine.velocity[1],
    }
    traces = []
    for venv in (dummy, vec):
        venv.seed(2)
        trace = [venv.reset()]
        for step, action in enumerate(actions):
            if step == 4:
                velocity_of_env1[id(venv)]()[0, 0, 5] = np.nan
            obs, rewards, dones, infos = venv.step(action)
            trace += [obs, rewards, dones]
            trace += [bool(info.get("TimeLimit.truncated", False)) for info in infos]
            trace += [
                info["terminal_observation"] for info in infos if "terminal_observation" in info
            ]
            if step == 4:
                assert rewards[1] == -1000.0 and dones.tolist() == [False, True, False]
                assert infos[1]["TimeLimit.truncated"] is False
                assert np.all(np.isfinite(infos[1]["terminal_observation"]))
        traces.append(trace)
    _assert_same_traces(traces[1], traces[0])


def test_vec_env_full_info_matches_single_env_info() -> None:
    n_envs, kwargs = 2, {"target": "circle", "episode_duration": 0.01}
    actions = np.random.default_rng(8).uniform(-0.5, 0.5, (8, n_envs, 24)).astype(np.float32)
    dummy = DummyVecEnv([lambda: DualArmTrackingEnv(**kwargs)] * n_envs)
    vec = TrackingVecEnv(n_envs, full_info=True, **kwargs)
    for venv in (dummy, vec):
        venv.seed(0)
        venv.reset()
    for action in actions:
        _, _, _, expected = dummy.step(action)
        _, _, _, got = vec.step(action)
        for e, g in zip(expected, got, strict=True):
            for key in ("tip_positions", "target_position", "distances", "element_torques", "time"):
                np.testing.assert_array_equal(g[key], e[key], err_msg=key)
    # by default the per-step info keys are left out (training speed)
    lean = TrackingVecEnv(2)
    lean.reset()
    _, _, _, infos = lean.step(np.zeros((2, 24), np.float32))
    assert infos == [{}, {}]


def test_vec_env_reports_reward_shares_that_sum_to_the_reward() -> None:
    vec = TrackingVecEnv(3, reward_shares=True, target="circle", episode_duration=0.01)
    vec.seed(0)
    vec.reset()
    rng = np.random.default_rng(4)
    for _ in range(6):  # past the end of the 5-step episodes, whose infos gain reset keys
        _, rewards, _, infos = vec.step(rng.uniform(-1, 1, (3, 24)).astype(np.float32))
        shares = np.stack([info["reward_shares"] for info in infos])
        assert shares.shape == (3, 2) and shares.dtype == np.float32
        np.testing.assert_allclose(shares.sum(axis=1), rewards, rtol=1e-6, atol=1e-6)


def test_vec_env_single_arm_config() -> None:
    config = make_config(n_arms=1, arm=1, target="circle")
    vec = TrackingVecEnv(2, config)
    single = SingleArmTrackingEnv(arm=1, target="circle")
    assert vec.observation_space.shape == (44,) and vec.action_space.shape == (12,)
    obs = vec.reset()
    first, _ = single.reset(seed=0)
    np.testing.assert_array_equal(obs[0], first)
    action = _actions(1, 12, seed=3)[0]
    obs, rewards, _, _ = vec.step(np.stack([action, action]))
    expected, reward, *_ = single.step(action)
    np.testing.assert_array_equal(obs[1], expected)
    assert rewards[1] == np.float32(reward)


def test_vec_monitor_reports_episode_returns() -> None:
    venv = VecMonitor(TrackingVecEnv(3, episode_duration=0.02))
    venv.seed(1)
    venv.reset()
    actions = np.random.default_rng(2).uniform(-0.3, 0.3, (10, 3, 24)).astype(np.float32)
    returns = np.zeros(3)
    for k, action in enumerate(actions, start=1):
        _, rewards, dones, infos = venv.step(action)
        returns += rewards
        if k < 10:
            assert not dones.any() and all("episode" not in info for info in infos)
    assert dones.all()
    for i, info in enumerate(infos):
        assert info["episode"]["l"] == 10
        assert info["episode"]["r"] == pytest.approx(returns[i], abs=1e-4)
    assert all(np.isfinite(returns)) and np.all(returns < 0)


def test_td3_learns_on_vec_env_smoke() -> None:
    from stable_baselines3 import TD3

    venv = VecMonitor(TrackingVecEnv(4, episode_duration=0.1))
    model = TD3(
        "MlpPolicy",
        venv,
        learning_starts=100,
        batch_size=32,
        policy_kwargs={"net_arch": [64, 64]},
        seed=0,
        device="cpu",
    )
    model.learn(total_timesteps=300)
    assert model.num_timesteps >= 300
    assert len(model.ep_info_buffer) >= 4  # 50-step episodes finished and were logged
    action, _ = model.predict(venv.reset(), deterministic=True)
    assert action.shape == (4, 24) and np.all(np.abs(action) <= 1)
