"""The cooperative transport task (softtrack.env.transport_env, docs/environment.md "Transport")."""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
import yaml

import softtrack.env  # noqa: F401  (registers the environments)
from softtrack.env.core import TrackingCore
from softtrack.env.settings import make_config
from softtrack.env.targets import BatchedTargets, TargetConfig, trajectory_position
from softtrack.sim.params import InvalidParameterError
from softtrack.spec.fields import SpecError
from softtrack.spec.models import ExperimentSpec
from softtrack.spec.spec_io import parse_spec, spec_hash

SQUEEZE = np.zeros(24)
SQUEEZE[0:6] = -0.03  # arm 1's normal values: negative curls toward +x, onto the sphere
SQUEEZE[12:18] = 0.03  # arm 2's: positive curls toward −x


def _transport_env(**kwargs: object) -> gym.Env:
    return gym.make("softtrack/DualArmTransport-v0", **kwargs)


def test_spaces_and_defaults() -> None:
    env = _transport_env()
    core = env.unwrapped.core
    assert env.observation_space.shape == (88,)
    assert env.action_space.shape == (24,)
    assert core.config.sim.contact_k == 1e6 and core.config.sim.sphere is not None
    assert core.max_steps == 6000  # 2 s of approach + one 10-s lap
    obs, info = env.reset(seed=0)
    np.testing.assert_allclose(obs[74:77], core.config.sim.sphere.center, atol=1e-6)
    np.testing.assert_allclose(obs[81:84], core.config.sim.sphere.center, atol=1e-6)
    np.testing.assert_array_equal(info["goal_position"], info["object_position"])


def test_goal_approaches_then_follows_the_path() -> None:
    """The goal leaves the sphere's start with zero speed, reaches the path's start after
    ``approach`` seconds (smoothstep: halfway at half the time) and then follows the path from
    its t = 0 point."""
    env = _transport_env(target="circle", approach=1.0)
    core = env.unwrapped.core
    env.reset(seed=0)
    start = np.asarray(core.config.sim.sphere.center)
    path = TargetConfig(name="circle")
    path_start = trajectory_position(path, np.zeros(1))[0]
    control_dt = core.config.sim.control_dt
    goals = []
    for _ in range(750):
        goals.append(env.step(SQUEEZE)[4]["goal_position"])
    goals_array = np.array(goals)  # goal after 1, 2, … control steps
    np.testing.assert_allclose(goals_array[249], 0.5 * (start + path_start), atol=1e-12)
    np.testing.assert_allclose(goals_array[499], path_start, atol=1e-12)
    later = trajectory_position(path, np.array([250 * control_dt]))[0]
    np.testing.assert_allclose(goals_array[749], later, atol=1e-9)
    assert np.linalg.norm(goals_array[0] - start) < 1e-4  # leaves slowly


def test_a_squeezing_policy_carries_and_an_idle_one_drops() -> None:
    held = _transport_env(gravity=True)
    held.reset(seed=0)
    for _ in range(500):
        _, reward, terminated, _, info = held.step(SQUEEZE)
        assert not terminated
    assert info["touching"].all() and not info["dropped"]
    assert reward > 2 * 0.25 - 1.0  # the hold bonus of both arms, a bounded distance term
    assert (info["object_force"] > 1.0).all()

    idle = _transport_env()
    idle.reset(seed=0)
    grace_steps = round(0.5 / 0.002)
    steps = 0
    for _ in range(grace_steps + 10):
        _, reward, terminated, truncated, info = idle.step(np.zeros(24))
        steps += 1
        if terminated:
            break
    assert steps == grace_steps and terminated and not truncated and info["dropped"]
    assert reward < -99.0  # the drop penalty


def test_batched_transport_equals_single_environments() -> None:
    """Two environments of one core, reset at different times (one in its approach while the
    other follows the path), compute the transitions of two single ones."""
    config = make_config(task="transport", sphere={}, contact_k=1e6, contact_nu=600.0)
    batched = TrackingCore(2, config)
    singles = [TrackingCore(1, config), TrackingCore(1, config)]
    rng = [np.random.default_rng(s) for s in (1, 2, 1, 2)]
    batched.reset([0, 1], rng[:2])
    singles[0].reset([0], [rng[2]])
    singles[1].reset([0], [rng[3]])
    actions = np.tile(SQUEEZE, (2, 1))
    for step in range(1200):
        if step == 700:  # environment 1 restarts: it approaches while environment 0 tracks
            batched.reset([1], [np.random.default_rng(5)])
            singles[1].reset([0], [np.random.default_rng(5)])
        result = batched.step(actions)
        for k, single in enumerate(singles):
            alone = single.step(actions[k : k + 1])
            np.testing.assert_array_equal(result.observation[k], alone.observation[0])
            np.testing.assert_array_equal(result.reward[k], alone.reward[0])


def test_resting_random_target_draws_nothing() -> None:
    targets = BatchedTargets(TargetConfig(name="random"), 2)
    targets.reset([0, 1], [np.random.default_rng(0), np.random.default_rng(1)])
    before = targets.position[1].copy(), targets.velocity[1].copy()
    for _ in range(1000):  # 2 s: two redirects are due for a moving target
        targets.step(0.002, np.array([True, False]))
    np.testing.assert_array_equal(targets.position[1], before[0])
    np.testing.assert_array_equal(targets.velocity[1], before[1])
    assert targets.time[1] == 0.0 and targets.time[0] == pytest.approx(2.0)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"task": "transport"}, "task transport needs a sphere"),
        ({"sphere": {}}, "a sphere belongs to the transport task"),
        (
            {"task": "transport", "sphere": {}, "squeeze_penalty": 1.0},
            "squeeze_penalty=1.0 needs a squeeze_band",
        ),
        (
            {"task": "transport", "sphere": {"radius": -1.0}},
            "sphere radius=-1.0 must be a finite number > 0 m",
        ),
        ({"task": "transport", "sphere": {}, "drop_grace": -1.0}, "drop_grace=-1.0 must be"),
    ],
)
def test_bad_transport_settings_are_rejected(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameterError, match=message):
        make_config(**kwargs)


_TRANSPORT_SPEC = """
name: transport-test
algo: {name: td3}
env:
  physics: {contact_k: 1.0e6, contact_nu: 600.0, sphere: {}}
  task: {name: transport}
"""


def load_spec_text(text: str) -> ExperimentSpec:
    return parse_spec(yaml.safe_load(text))


def test_transport_spec_validates_and_old_specs_keep_their_hash() -> None:
    spec = load_spec_text(_TRANSPORT_SPEC)
    assert spec.env.physics.sim_params().sphere is not None
    plain = load_spec_text("name: transport-test\nalgo: {name: td3}\n")
    explicit = load_spec_text(
        "name: transport-test\nalgo: {name: td3}\n"
        "env: {physics: {sphere: null}, task: {approach: 2.0, drop_penalty: 100.0}}\n"
    )
    assert spec_hash(plain) == spec_hash(explicit) != spec_hash(spec)
    with pytest.raises(SpecError, match="task transport needs a sphere"):
        load_spec_text(_TRANSPORT_SPEC.replace(", sphere: {}", ""))
    with pytest.raises(SpecError, match="belongs to the transport task"):
        load_spec_text(_TRANSPORT_SPEC.replace("{name: transport}", "{name: shared}"))


def test_mirror_and_arm_views_cover_the_transport_observation() -> None:
    from softtrack.env.observation import arm_view_columns
    from softtrack.rl.variants.mirror import mirror_observation

    obs = np.arange(88, dtype=np.float64)
    mirrored = mirror_observation(obs)
    np.testing.assert_array_equal(mirror_observation(mirrored), obs)
    np.testing.assert_array_equal(mirrored[[74, 78, 81, 85]], -obs[[74, 78, 81, 85]])
    np.testing.assert_array_equal(mirrored[[75, 82]], obs[[75, 82]])
    arm2 = arm_view_columns(1, 2, 88)
    np.testing.assert_array_equal(arm2, np.r_[37:74, 74:88])
    np.testing.assert_array_equal(arm_view_columns(0, 2, 81), np.r_[0:37, 74:81])


def test_independent_controller_cannot_carry() -> None:
    with pytest.raises(SpecError, match="cannot hold the sphere"):
        load_spec_text(_TRANSPORT_SPEC + "controller: independent\n")


def test_transport_statistics_hand_computed() -> None:
    from softtrack.evaluation.transport_metrics import transport_statistics

    position = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    goal = np.array([[0.3, 0.0, 0.0], [0.0, 0.4, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    force = np.array([[10.0, 0.0], [20.0, 5.0], [30.0, 5.0], [40.0, 0.0]])
    touching = force > 0
    t = np.array([0.002, 0.004, 0.006, 0.008])
    scene, arms = transport_statistics(position, goal, force, touching, True, t)
    assert scene["object_rmse_3d"] == pytest.approx(np.sqrt((0.09 + 0.16) / 4))
    assert scene["object_max_error"] == pytest.approx(0.4)
    assert scene["object_rmse_x"] == pytest.approx(np.sqrt(0.09 / 4))
    assert scene["dropped"] is True and scene["drop_time"] == pytest.approx(0.008)
    assert scene["two_arm_contact"] == pytest.approx(0.5)
    assert arms[0] == {"object_contact": 1.0, "object_force_mean": 25.0, "object_force_max": 40.0}
    assert arms[1]["object_contact"] == pytest.approx(0.5)


def test_evaluation_rows_measure_the_sphere() -> None:
    """An evaluation episode of the transport task stores the sphere's metrics (against the
    goal the episode recorded as its target), the hold and no drop for a squeezing policy;
    the validation score is the sphere's 3-D RMSE."""
    from softtrack.evaluation.episode_tables import (
        metrics_table,
        trajectory_table,
        validation_score,
    )
    from softtrack.evaluation.episodes import run_episode

    config = make_config(task="transport", sphere={}, contact_k=1e6, contact_nu=600.0)
    episode = run_episode(lambda obs: SQUEEZE, config, "circle", duration=1.0)
    rows = metrics_table("run", episode)
    assert not episode.dropped and not rows["dropped"].any()
    errors = np.linalg.norm(episode.object_position - episode.target, axis=1)
    assert rows["object_rmse_3d"].iloc[0] == pytest.approx(np.sqrt(np.mean(errors**2)))
    assert (rows["object_contact"] > 0.9).all() and rows["two_arm_contact"].iloc[0] > 0.9
    assert (rows["object_force_mean"] > 1.0).all()
    positions = trajectory_table("run", episode)
    assert {"object_x", "object_y", "object_z"} <= set(positions)
    random_rows = rows.assign(trajectory="random")
    assert validation_score(random_rows) == pytest.approx(rows["object_rmse_3d"].iloc[0])


def test_train_evaluate_and_report_a_transport_run(tmp_path: Path) -> None:
    """The command line end to end on the transport task: a tiny training, an evaluation that
    prints the sphere's error and the drop, and a report with the transport section."""
    from typer.testing import CliRunner

    from softtrack.cli import app

    runner = CliRunner()
    spec = (
        Path(__file__).parents[1]
        / "experiments/variants/td3-sbx-128-1e6-mirror-fast-transport.yaml"
    )
    settings = {
        "training.total_timesteps": 200,
        "algo.learning_starts": 100,
        "algo.batch_size": 32,
        "training.checkpoint_interval": 200,
        "training.validation_episodes": 0,
        "training.validation_trajectories": "false",
        "training.final_policy": "last",
        "training.confirm_episodes": 0,
        "training.n_envs": 1,
    }
    overrides = [arg for key, value in settings.items() for arg in ("--set", f"{key}={value}")]
    runs = ["--runs-dir", str(tmp_path / "runs")]
    trained = runner.invoke(app, ["train", str(spec), "--seed", "0", *runs, *overrides])
    assert trained.exit_code == 0, trained.output
    run_id = trained.stdout.strip()
    evaluated = runner.invoke(app, ["evaluate", run_id, *runs])
    assert evaluated.exit_code == 0, evaluated.output
    assert "sphere 3-D RMSE" in evaluated.output and "circle" in evaluated.output
    out = tmp_path / "report"
    reported = runner.invoke(app, ["report", run_id, *runs, "--out", str(out)])
    assert reported.exit_code == 0, reported.output
    text = (out / "index.md").read_text(encoding="utf-8")
    assert "### Cooperative transport" in text and "seeds that dropped it" in text
    assert (out / "figures" / "transport.png").read_bytes()[:4] == b"\x89PNG"


def test_goal_ahead_is_the_goal_the_episode_reaches() -> None:
    """The MPC's look-ahead goal (TransportModel.goal_ahead) equals the goal the environment
    reaches, across the end of the approach, for a closed-form path and a random target."""
    for target in ("circle", "random"):
        config = make_config(
            task="transport",
            sphere={},
            target=target,
            approach=0.5,
            contact_k=1e6,
            contact_nu=600.0,
        )
        core = TrackingCore(1, config)
        core.reset([0], [np.random.default_rng(3)])
        for _ in range(200):
            core.step(SQUEEZE[None])
        assert core.transport is not None
        ahead = core.transport.goal_ahead(
            int(core.step_count[0]), core.targets, 0, np.arange(1, 101)
        )
        reached = []
        for _ in range(100):
            core.step(SQUEEZE[None])
            reached.append(core.transport.goal_position[0].copy())
        tolerance = 1e-12 if target == "circle" else 1e-9  # random: until its next redirect
        np.testing.assert_allclose(ahead[:50], np.array(reached)[:50], atol=tolerance)


def test_mpc_with_the_sphere_in_its_model_holds_it() -> None:
    """The sampling planner scores plans by the sphere's distance and the hold it would lose:
    from the start it squeezes, and the sphere is held by both arms without a drop."""
    from softtrack.evaluation.episodes import run_episode
    from softtrack.mpc.controller import MpcController
    from softtrack.mpc.planner_config import PlannerConfig

    config = make_config(task="transport", sphere={}, contact_k=1e6, contact_nu=600.0)
    controller = MpcController(PlannerConfig(samples=32, horizon=30, knots=3, replan_interval=5))
    episode = run_episode(controller, config, "circle", duration=0.6)
    assert not episode.dropped and episode.object_touching is not None
    assert episode.object_touching[-100:].all()


def test_per_arm_reward_shares_credit_each_arm_its_hold() -> None:
    from softtrack.env.vec_env import REWARD_SHARES_KEY, TrackingVecEnv

    env = TrackingVecEnv(
        2, reward_shares=True, task="transport", sphere={}, contact_k=1e6, contact_nu=600.0
    )
    env.seed(0)
    env.reset()
    one_arm = SQUEEZE.copy()
    one_arm[12:18] = 0.0  # arm 2 does not squeeze
    for _ in range(30):
        _, rewards, _, infos = env.step(np.stack([SQUEEZE, one_arm]))
    shares = np.stack([info[REWARD_SHARES_KEY] for info in infos])
    np.testing.assert_allclose(shares.sum(axis=1), rewards, rtol=1e-6)
    assert shares[0, 0] == pytest.approx(shares[0, 1], abs=1e-6)  # both hold: equal shares


def _episode_return(action: np.ndarray, steps: int, **kwargs: object) -> tuple[float, int]:
    env = _transport_env(**kwargs)
    env.reset(seed=0)
    total = 0.0
    for step in range(1, steps + 1):
        _, reward, terminated, _, _ = env.step(action)
        total += float(reward)
        if terminated:
            return total, step
    return total, steps


def test_letting_go_earns_less_than_holding() -> None:
    """With the default reward (distance bonuses only while both arms grip, the reach term),
    a policy that lets the sphere go at once loses reward on every step, while a squeeze earns
    it; without them letting go earned the distance bonuses of a sphere left at the goal's
    start (docs/results.md, "Cooperative transport")."""
    steps = 400
    idle, idle_steps = _episode_return(np.zeros(24), steps)
    held, held_steps = _episode_return(SQUEEZE, steps)
    assert idle_steps == 250 and held_steps == steps  # the idle arms drop it after 0.5 s
    assert idle < -100.0 < 0.0 < held
    old_idle, _ = _episode_return(np.zeros(24), steps, reach_penalty=0.0, bonus_needs_grip=False)
    assert old_idle > 0.0  # the bonuses of the untouched sphere outweigh the drop penalty


def test_reach_term_measures_each_arms_gap() -> None:
    from softtrack.env.transport_env import TransportModel

    config = make_config(task="transport", sphere={}, contact_k=1e6, contact_nu=600.0)
    core = TrackingCore(1, config)
    core.reset(np.array([0]), [np.random.default_rng(0)])
    model = core.transport
    assert isinstance(model, TransportModel)
    engine = core.engine
    assert (model.arm_gaps(engine) < 0.005).all()  # the tips' elements touch it at rest
    engine.sphere[:, 0:3] += np.array([0.0, 0.3, 0.0])  # lift it 0.3 m above the tips
    tips = engine.tip_position[0]  # (2, 3)
    expected = np.linalg.norm(tips - engine.sphere_position[0], axis=1) - 0.1
    np.testing.assert_allclose(model.arm_gaps(engine)[0], expected, rtol=1e-12)


def test_grip_makes_the_zero_action_hold() -> None:
    from softtrack.env.tasks import TaskConfig

    offset = TaskConfig(name="transport", grip=0.03).action_offset()
    np.testing.assert_array_equal(offset, SQUEEZE)  # arm 1 −grip, arm 2 +grip on the normals
    steps = 400
    gripped, gripped_steps = _episode_return(np.zeros(24), steps, grip=0.03)
    squeezed, _ = _episode_return(SQUEEZE, steps)
    assert gripped_steps == steps and gripped == pytest.approx(squeezed, rel=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"task": "shared", "grip": 0.03}, "only the transport task"),
        ({"task": "transport", "sphere": {}, "contact_k": 1e6, "grip": 1.5}, "grip=1.5"),
    ],
)
def test_bad_grip_is_rejected(kwargs: dict, message: str) -> None:
    with pytest.raises((InvalidParameterError, ValueError), match=message):
        make_config(**kwargs)


def test_mpc_plans_with_the_grip_the_environment_adds() -> None:
    from softtrack.mpc.controller import MpcController
    from softtrack.mpc.planner import PlannerConfig

    config = make_config(
        task="transport", sphere={}, contact_k=1e6, contact_nu=600.0, grip=0.03, target="circle"
    )
    core = TrackingCore(1, config)
    core.reset(np.array([0]), [np.random.default_rng(0)])
    controller = MpcController(PlannerConfig(samples=8, horizon=5, knots=2, replan_interval=5))
    controller.start_episode(core)
    assert controller._planner is not None
    np.testing.assert_array_equal(controller._planner.action_offset, SQUEEZE)


def _carry_rows(errors: list[float], drops: list[float | None]) -> pd.DataFrame:
    """Validation rows of a transport checkpoint: one episode per error, both arms' rows, a
    drop time (s) or None for an episode carried through."""
    rows = []
    for episode, (error, drop) in enumerate(zip(errors, drops, strict=True)):
        for arm in (0, 1):
            rows.append(
                {
                    "trajectory": "random",
                    "episode": episode,
                    "arm": arm,
                    "rmse_3d": 0.5,
                    "object_rmse_3d": error,
                    "dropped": drop is not None,
                    "drop_time": math.nan if drop is None else drop,
                    "terminated": drop is not None,
                }
            )
    return pd.DataFrame(rows)


def test_a_transport_validation_counts_the_steps_after_a_drop() -> None:
    """With the episodes' planned length, a dropped sphere counts 1 m for every second after its
    drop (hand-computed), a longer hold scores lower, an episode carried through scores its
    error, and a non-finite episode ∞; without the length any drop is ∞."""
    from softtrack.evaluation.episode_tables import LOST_OBJECT_ERROR, validation_score

    assert LOST_OBJECT_ERROR == 1.0
    held = _carry_rows([0.04, 0.06], [None, None])
    assert validation_score(held, 10.0) == pytest.approx(0.05)
    dropped = _carry_rows([0.04, 0.2], [None, 2.5])
    # episode 2: sqrt((0.2² · 2.5 + 1² · 7.5) / 10) = sqrt(0.76)
    assert validation_score(dropped, 10.0) == pytest.approx((0.04 + math.sqrt(0.76)) / 2)
    later = _carry_rows([0.04, 0.2], [None, 5.0])
    assert validation_score(later, 10.0) < validation_score(dropped, 10.0)
    assert validation_score(held, 10.0) < validation_score(later, 10.0)
    assert validation_score(dropped) == math.inf
    diverged = held.assign(terminated=True)
    assert validation_score(diverged, 10.0) == math.inf
    trajectory_rows = _carry_rows([5.0], [1.0]).assign(trajectory="circle", episode=7)
    assert validation_score(pd.concat([held, trajectory_rows]), 10.0) == pytest.approx(0.05)


def test_evaluate_random_prints_the_carried_rate_with_its_interval() -> None:
    """Issue 62's metrics people compare: episodes carried through, hold time, squeeze."""
    import pandas as pd

    from softtrack.evaluation.transport_summary import carried_summary

    rows = pd.DataFrame(
        {
            "episode": [0, 0, 1, 1, 2, 2, 3, 3],
            "arm": [0, 1] * 4,
            "object_rmse_3d": [0.02, 0.02, 0.04, 0.04, 0.5, 0.5, 0.03, 0.03],
            "dropped": [False, False, False, False, True, True, False, False],
            "duration": [12.0, 12.0, 12.0, 12.0, 3.0, 3.0, 12.0, 12.0],
            "two_arm_contact": [1.0, 1.0, 0.9, 0.9, 0.2, 0.2, 1.0, 1.0],
            "object_force_mean": [10.0, 12.0, 10.0, 12.0, 10.0, 12.0, 10.0, 12.0],
        }
    )
    line = carried_summary(rows)
    assert "sphere 3-D RMSE 0.1475 m (mean over 4 episodes)" in line
    assert "carried 3 of 4 (75%, 95 % [30%, 95%])" in line
    assert "held 9.8 s on average (episodes of 12.0 s)" in line
    assert "by both arms 78% of the steps" in line and "squeeze 10.0 / 12.0 N" in line
