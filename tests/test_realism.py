"""Imperfect sensing and actuation, ``env.realism`` (softtrack.env.realism; docs/environment.md,
"Realism: sensing and actuation").

Off, the environment computes exactly the transitions it did before the section existed; on,
each effect is measured against its closed form.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from stable_baselines3.common.vec_env import DummyVecEnv

from softtrack.env import DualArmTrackingEnv, SingleArmTrackingEnv, TrackingCore, make_config
from softtrack.env.observation import build_observation, observation_size
from softtrack.env.realism import (
    OBSERVATION_GROUPS,
    RealismConfig,
    RealismModel,
    observation_groups,
)
from softtrack.env.targets import BatchedTargets
from softtrack.env.vec_env import TrackingVecEnv
from softtrack.evaluation.episodes import run_episode
from softtrack.sim import InvalidParameterError, spline_matrix
from softtrack.sim.engine import RodBatch
from softtrack.spec import RealismSpec, SpecError, parse_spec, spec_hash
from softtrack.spec.env_config import env_config, env_kwargs
from softtrack.spec.spec_io import _FIELDS_ADDED_LATER

CONTROL_DT = 0.002  # s


def _actions(n_steps: int, dim: int, seed: int = 0, scale: float = 0.6) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-scale, scale, (n_steps, dim))


def _trace(env, actions: np.ndarray, seed: int = 3) -> list[np.ndarray]:
    """Every observation, reward, flag and info value of an episode, in order."""
    obs, info = env.reset(seed=seed)
    out = [obs, *(np.asarray(v) for v in info.values())]
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        out += [obs, np.float64(reward), np.bool_(terminated), np.bool_(truncated)]
        out += [np.asarray(v) for v in info.values()]
    return out


def _same(a: list[np.ndarray], b: list[np.ndarray]) -> None:
    assert len(a) == len(b)
    for k, (x, y) in enumerate(zip(a, b, strict=True)):
        assert x.dtype == y.dtype and x.shape == y.shape, k
        np.testing.assert_array_equal(x, y, err_msg=f"item {k}")


def _core(realism: dict | None = None, n_envs: int = 1, seed: int = 3, **kwargs) -> TrackingCore:
    core = TrackingCore(n_envs, make_config(realism=realism, **kwargs))
    core.reset(np.arange(n_envs), [np.random.default_rng(seed + i) for i in range(n_envs)])
    return core


# ---- off: nothing changes ----------------------------------------------------------------------


@pytest.mark.parametrize("target", ["random", "circle"])
def test_off_is_bit_identical_and_builds_no_model(target: str) -> None:
    actions = _actions(40, 24, scale=1.2)  # some clipped
    defaults = {name: getattr(RealismConfig(), name) for name in OBSERVATION_GROUPS.values()}
    spec = parse_spec(
        {
            "env": {
                "target": {"name": target},
                "realism": {
                    "obs_delay": 0,
                    "action_delay": 0,
                    "torque_limit": None,
                    "obs_stuck_steps": 1,
                },
            }
        }
    )
    envs = [
        DualArmTrackingEnv(target=target),
        DualArmTrackingEnv(target=target, realism=RealismConfig()),
        DualArmTrackingEnv(target=target, realism=defaults),
        DualArmTrackingEnv(**env_kwargs(spec)),
    ]
    assert "realism" not in env_kwargs(spec)  # a default spec's env kwargs are unchanged
    assert all(env.core.realism is None for env in envs)
    traces = [_trace(env, actions) for env in envs]
    for trace in traces[1:]:
        _same(trace, traces[0])
    # the random streams advanced alike (a realism-off env draws nothing new)
    states = {repr(env.np_random.bit_generator.state) for env in envs}
    assert len(states) == 1


def test_off_matches_the_plain_pipeline() -> None:
    """The default step is still clip → spline torques → engine → target → observation."""
    config = make_config()
    core = TrackingCore(1, config)
    rng = np.random.default_rng(4)
    obs = core.reset([0], [rng])
    engine = RodBatch(1, config.sim)
    targets = BatchedTargets(config.target, 1)
    targets.reset(np.array([0]), [np.random.default_rng(4)])
    expected = build_observation(
        engine.position, engine.tip_velocity, targets.position, targets.velocity
    )
    np.testing.assert_array_equal(obs, expected)
    for action in _actions(20, 24, scale=1.3):
        result = core.step(action[None])
        engine.set_actions(np.clip(action, -1, 1).reshape(1, 2, 2, 6))
        engine.advance()
        targets.step(CONTROL_DT)
        expected = build_observation(
            engine.position, engine.tip_velocity, targets.position, targets.velocity
        )
        np.testing.assert_array_equal(result.observation, expected)
        np.testing.assert_array_equal(core.engine.torques, engine.torques)


def test_every_realism_field_is_a_later_field_at_its_default() -> None:
    for name, field in RealismSpec.model_fields.items():
        assert _FIELDS_ADDED_LATER[("env", "realism", name)] == field.default, name
    assert _FIELDS_ADDED_LATER[("env", "realism")] == {}
    assert [f for f in RealismSpec.model_fields] == [f for f in RealismConfig.__dataclass_fields__]
    assert RealismConfig(**RealismSpec().realism_kwargs()) == RealismConfig()


def test_spec_hash_is_unchanged_off_and_changes_on() -> None:
    base = parse_spec({})
    assert spec_hash(parse_spec({"env": {"realism": {}}})) == spec_hash(base)
    neutral = {"obs_noise_speed": 0.0, "obs_delay": 0, "actuator_time_constant": None}
    assert spec_hash(parse_spec({"env": {"realism": neutral}})) == spec_hash(base)
    delayed = parse_spec({"env": {"realism": {"obs_delay": 2}}})
    assert spec_hash(delayed) != spec_hash(base)
    noisy = parse_spec({"env": {"realism": {"obs_noise_speed": 0.01}}})
    assert spec_hash(noisy) not in (spec_hash(base), spec_hash(delayed))


def test_spec_reaches_training_and_evaluation_config() -> None:
    spec = parse_spec({"env": {"realism": {"obs_delay": 2, "torque_limit": 30.0}}})
    assert env_kwargs(spec)["realism"]["obs_delay"] == 2
    for arm in (None, 0, 1):
        config = env_config(spec, arm)
        assert config.realism == RealismConfig(obs_delay=2, torque_limit=30.0)
        assert TrackingCore(1, config).realism is not None
    assert env_config(parse_spec({})).realism == RealismConfig()


# ---- observations ------------------------------------------------------------------------------


def test_observation_groups_cover_every_column_once() -> None:
    for n_arms in (1, 2):
        groups = observation_groups(n_arms)
        columns = np.sort(np.concatenate(list(groups.values())))
        np.testing.assert_array_equal(columns, np.arange(observation_size(n_arms)))
    groups = observation_groups(2)
    np.testing.assert_array_equal(groups["speed"], [33, 70, 77])
    np.testing.assert_array_equal(groups["target_position"], [74, 75, 76])
    assert len(groups["node_position"]) == 66 and len(groups["direction"]) == 9


def test_noise_std_per_group() -> None:
    stds = {"node_position": 0.01, "target_position": 0.02, "speed": 0.03, "direction": 0.05}
    core = _core({OBSERVATION_GROUPS[g]: s for g, s in stds.items()})
    groups = observation_groups(2)
    residuals = []
    for action in _actions(1500, 24, scale=0.3):
        result = core.step(action[None])
        residuals.append(result.observation[0].astype(np.float64) - core.observe()[0])
    residual = np.array(residuals)
    for group, std in stds.items():
        values = residual[:, groups[group]].ravel()
        n = values.size
        assert abs(values.std() / std - 1) < 4 / math.sqrt(2 * n) + 1e-3, (group, values.std())
        assert abs(values.mean()) < 4 * std / math.sqrt(n), group


def test_noise_leaves_the_dynamics_and_target_stream_alone() -> None:
    actions = _actions(30, 24)
    plain = _trace(DualArmTrackingEnv(), actions)
    noisy = _trace(
        DualArmTrackingEnv(realism={"obs_noise_node_position": 0.01, "obs_drop_probability": 0.1}),
        actions,
    )
    # item 0 is the observation; then, per step: observation, reward, flags, info values
    per_step = 4 + 5
    assert not np.array_equal(noisy[0], plain[0])
    for k in range(6, len(plain)):
        if (k - 6) % per_step != 0:  # everything but the observations
            np.testing.assert_array_equal(noisy[k], plain[k], err_msg=str(k))


def test_dropped_values_read_zero_at_their_rate() -> None:
    p = 0.2
    core = _core({"obs_drop_probability": p})
    zeros = total = 0
    for action in _actions(400, 24):
        result = core.step(action[None])
        obs, true = result.observation[0], core.observe()[0]
        kept = obs != 0
        np.testing.assert_array_equal(obs[kept], true[kept])  # no noise: kept values are exact
        nonzero = true != 0
        zeros += int(np.count_nonzero(~kept & nonzero))
        total += int(np.count_nonzero(nonzero))
    assert abs(zeros / total - p) < 4 * math.sqrt(p * (1 - p) / total)


def test_stuck_values_repeat_their_last_reading_for_the_stuck_steps() -> None:
    p, steps = 0.05, 3
    core = _core({"obs_stuck_probability": p, "obs_stuck_steps": steps})
    outs, trues = [], []
    for action in _actions(600, 24):
        result = core.step(action[None])
        outs.append(result.observation[0])
        trues.append(core.observe()[0])
    out, true = np.array(outs), np.array(trues)
    moving = np.all(np.diff(true, axis=0) != 0, axis=0)  # columns whose true value always changes
    assert moving.sum() > 40
    out, true = out[:, moving], true[:, moving]
    stuck = out != true
    # a stuck value is exactly the value reported on the step before
    np.testing.assert_array_equal(out[1:][stuck[1:]], out[:-1][stuck[1:]])
    # it stays stuck a whole number of stuck periods (a new period may follow at once)
    for column in range(stuck.shape[1]):
        padded = np.concatenate([[0], stuck[:, column].astype(int), [0]])
        starts, ends = np.flatnonzero(np.diff(padded) == 1), np.flatnonzero(np.diff(padded) == -1)
        lengths = (ends - starts)[ends < len(stuck)]  # runs that ended in the window
        assert np.all(lengths % steps == 0), lengths
    # stationary stuck fraction of the chain: steps·p / (1 + (steps − 1)·p)
    expected = steps * p / (1 + (steps - 1) * p)
    assert abs(stuck[50:].mean() / expected - 1) < 0.1


@pytest.mark.parametrize("k", [1, 3])
def test_observation_delay_returns_the_observation_of_k_steps_ago(k: int) -> None:
    actions = _actions(25, 24)
    plain = DualArmTrackingEnv()
    delayed = DualArmTrackingEnv(realism={"obs_delay": k})
    seen, _ = delayed.reset(seed=5)
    history = [plain.reset(seed=5)[0]]
    np.testing.assert_array_equal(seen, history[0])
    for t, action in enumerate(actions, start=1):
        obs, reward, *_ = plain.step(action)
        history.append(obs)
        seen, delayed_reward, *_ = delayed.step(action)
        np.testing.assert_array_equal(seen, history[max(0, t - k)])
        assert delayed_reward == reward


@pytest.mark.parametrize("k", [1, 4])
def test_action_delay_equals_the_same_actions_k_steps_later(k: int) -> None:
    actions = _actions(30, 24)
    delayed = _trace(DualArmTrackingEnv(realism={"action_delay": k}), actions)
    shifted = np.concatenate([np.zeros((k, 24)), actions[:-k]])
    _same(delayed, _trace(DualArmTrackingEnv(), shifted))


def test_a_random_action_delay_is_drawn_per_episode_and_applied() -> None:
    core = _core({"action_delay": 1, "action_delay_max": 3}, n_envs=16)
    delays = core.realism.action_delays.copy()
    assert set(delays.tolist()) <= {1, 2, 3} and len(set(delays.tolist())) > 1
    again = _core({"action_delay": 1, "action_delay_max": 3}, n_envs=16)
    np.testing.assert_array_equal(again.realism.action_delays, delays)  # from the seeds
    actions = _actions(6, 24)
    applied = [core.realism.filter_actions(np.tile(a, (16, 1))) for a in actions]
    for env, d in enumerate(delays.tolist()):
        for step in range(6):
            want = actions[step - d] if step >= d else np.zeros(24)
            np.testing.assert_array_equal(applied[step][env], want)
    fixed = _core({"action_delay": 2, "action_delay_max": 2}, n_envs=2)
    assert fixed.realism.action_delays.tolist() == [2, 2]


def test_action_delay_max_below_the_delay_is_an_error() -> None:
    with pytest.raises(ValueError, match="action_delay_max"):
        RealismConfig(action_delay=2, action_delay_max=1).validate()


# ---- actuation ---------------------------------------------------------------------------------


def _applied_controls(torques: np.ndarray) -> np.ndarray:
    """(…, A, 2, N) element torques → (…, A, 2, 6) control values (least squares; exact)."""
    b = 75.0 * spline_matrix(20)
    return (
        np.linalg.lstsq(b, np.moveaxis(torques, -1, 0).reshape(20, -1), rcond=None)[0]
        .reshape((6, *torques.shape[:-1]))
        .transpose(*range(1, torques.ndim), 0)
    )


def test_first_order_lag_step_response() -> None:
    tau = 0.01
    env = DualArmTrackingEnv(realism={"actuator_time_constant": tau})
    env.reset(seed=0)
    for n in range(1, 31):
        *_, info = env.step(np.full(24, 0.5))
        applied = _applied_controls(info["element_torques"])
        expected = 0.5 * (1 - math.exp(-n * CONTROL_DT / tau))
        np.testing.assert_allclose(applied, expected, rtol=1e-12, atol=1e-13)


def test_rate_limit_caps_the_change_exactly() -> None:
    rate = 40.0  # control units/s: 0.08 per control step
    limit = rate * CONTROL_DT
    model = RealismModel(RealismConfig(action_rate_limit=rate), 2, 2, 21, CONTROL_DT)
    model.reset(
        [0, 1], [np.random.default_rng(0), np.random.default_rng(1)], np.zeros((2, 81), np.float32)
    )
    previous = np.zeros((2, 24))
    limited = free = 0
    for command in np.clip(_actions(200, 48, scale=1.3).reshape(200, 2, 24), -1, 1):
        applied = model.filter_actions(command)
        change = applied - previous
        assert np.all(np.abs(change) <= limit * (1 + 1e-12))
        capped = np.abs(command - previous) > limit
        np.testing.assert_allclose(np.abs(change[capped]), limit, rtol=1e-12)
        np.testing.assert_allclose(np.sign(change[capped]), np.sign((command - previous)[capped]))
        np.testing.assert_array_equal(applied[~capped], command[~capped])
        limited += int(capped.sum())
        free += int((~capped).sum())
        previous = applied
    assert limited > 100 and free > 100
    # the env applies exactly those values
    env = DualArmTrackingEnv(realism={"action_rate_limit": rate})
    env.reset(seed=0)
    replay = RealismModel(RealismConfig(action_rate_limit=rate), 1, 2, 21, CONTROL_DT)
    replay.reset([0], [np.random.default_rng(0)], np.zeros((1, 81), np.float32))
    for action in _actions(10, 24, scale=1.0):
        *_, info = env.step(action)
        expected = replay.filter_actions(action[None]).reshape(2, 2, 6)
        np.testing.assert_allclose(
            _applied_controls(info["element_torques"]), expected, rtol=0, atol=1e-12
        )


def test_torque_saturation_caps_each_element_torque_exactly() -> None:
    limit = 20.0
    actions = _actions(20, 24, scale=1.0)
    env = DualArmTrackingEnv(realism={"torque_limit": limit})
    plain = DualArmTrackingEnv()
    env.reset(seed=0)
    plain.reset(seed=0)
    reached = 0
    for action in actions:
        *_, info = env.step(action)
        torques = info["element_torques"]
        assert np.abs(torques).max() <= limit
        reached += int(np.count_nonzero(np.abs(torques) == limit))
        unsaturated = plain.core.engine.torques[0].copy()
        plain.core.engine.set_actions(action.reshape(1, 2, 2, 6))
        np.testing.assert_array_equal(torques, np.clip(plain.core.engine.torques[0], -limit, limit))
        plain.core.engine.torques[0] = unsaturated
    assert reached > 0
    # the evaluation episodes record the saturated torques
    episode = run_episode(
        lambda obs: np.ones(24),
        make_config(realism={"torque_limit": limit}),
        "circle",
        duration=0.02,
    )
    assert np.abs(episode.element_torques).max() == limit


# ---- reproducibility ---------------------------------------------------------------------------

ALL_ON = {
    "obs_noise_node_position": 0.005,
    "obs_noise_target_position": 0.01,
    "obs_noise_speed": 0.02,
    "obs_noise_direction": 0.05,
    "obs_drop_probability": 0.05,
    "obs_stuck_probability": 0.05,
    "obs_stuck_steps": 2,
    "obs_delay": 1,
    "action_delay": 1,
    "actuator_time_constant": 0.02,
    "action_rate_limit": 100.0,
    "torque_limit": 50.0,
}


def test_same_seed_same_episode_different_seed_different() -> None:
    actions = _actions(40, 24)
    first = _trace(DualArmTrackingEnv(realism=ALL_ON), actions, seed=7)
    _same(_trace(DualArmTrackingEnv(realism=ALL_ON), actions, seed=7), first)
    other = _trace(DualArmTrackingEnv(realism=ALL_ON), actions, seed=8)
    assert not np.array_equal(other[-9], first[-9])
    # single-arm scene too
    single = [
        _trace(SingleArmTrackingEnv(arm=1, realism=ALL_ON), actions[:, :12], seed=2)
        for _ in range(2)
    ]
    _same(*single)


def test_vec_env_matches_single_envs_with_realism() -> None:
    n_envs, kwargs = 3, {"episode_duration": 0.03, "realism": ALL_ON}
    actions = np.random.default_rng(5).uniform(-0.6, 0.6, (40, n_envs, 24)).astype(np.float32)
    dummy = DummyVecEnv([lambda: DualArmTrackingEnv(**kwargs)] * n_envs)
    vec = TrackingVecEnv(n_envs, **kwargs)
    for venv in (dummy, vec):
        venv.seed(17)
    results = []
    for venv in (dummy, vec):
        out = [venv.reset()]
        for action in actions:
            obs, reward, done, infos = venv.step(action)
            out += [obs, reward, done]
            out += [
                info["terminal_observation"] for info in infos if "terminal_observation" in info
            ]
        results.append(out)
    _same(*results)


def test_evaluation_episode_is_reproducible_with_realism() -> None:
    config = make_config(realism=ALL_ON)
    policy = lambda obs: np.tanh(obs[:24])  # noqa: E731  (depends on what it sees)
    a = run_episode(policy, config, "random", duration=0.05, seed=3)
    b = run_episode(policy, config, "random", duration=0.05, seed=3)
    c = run_episode(policy, config, "random", duration=0.05, seed=4)
    np.testing.assert_array_equal(a.actions, b.actions)
    np.testing.assert_array_equal(a.tips, b.tips)
    assert not np.array_equal(a.actions, c.actions)


# ---- bad values --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("field", "value", "fix"),
    [
        ("obs_noise_node_position", -0.01, "≥ 0"),
        ("obs_noise_direction", -1.0, "≥ 0"),
        ("obs_drop_probability", 1.0, "< 1"),
        ("obs_stuck_probability", -0.1, "≥ 0"),
        ("obs_stuck_steps", 0, "≥ 1"),
        ("obs_delay", -1, "≥ 0"),
        ("action_delay", -2, "≥ 0"),
        ("actuator_time_constant", 0.0, "> 0"),
        ("action_rate_limit", -5.0, "> 0"),
        ("torque_limit", 0.0, "> 0"),
    ],
)
def test_bad_values_are_spec_errors_and_config_errors(field: str, value: float, fix: str) -> None:
    with pytest.raises(SpecError) as info:
        parse_spec({"env": {"realism": {field: value}}})
    message = str(info.value)
    assert f"env.realism.{field}" in message and fix in message and "\n" not in message
    with pytest.raises(InvalidParameterError, match=field):
        make_config(realism={field: value})


def test_unknown_realism_name_is_named() -> None:
    with pytest.raises(InvalidParameterError, match="unknown realism setting 'obs_dealy'"):
        make_config(realism={"obs_dealy": 1})
