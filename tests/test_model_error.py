"""Model error, ``env.realism`` (docs/environment.md, "Model error"): fixed or per-episode random
factors on Young's modulus, density, radius, damping and torque scale, and gravity.

* off (every factor 1), the engine and the environments compute exactly what they computed
  before (bit for bit), draw nothing new and keep their spec hash;
* a factor gives the physics of a rod built with the scaled value: PyElastica 1.0.0 rods built
  here with the altered parameters (and with gravity on) agree with the numba engine to the
  tolerances of the stored-reference tests (tests/test_engine_reference.py);
* N environments with different factors stepped together equal N single ones, bit for bit;
* ranges are drawn per episode and environment from a generator of their own (the target's
  random stream is untouched), reproducibly, and reported in ``info["parameters"]``;
* the time step is checked against the worst case of the ranges.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from softtrack.env import DualArmTrackingEnv, TrackingCore, make_config
from softtrack.env.realism import RealismConfig
from softtrack.env.vec_env import TrackingVecEnv
from softtrack.sim import InvalidParameterError, SimParams
from softtrack.sim.actuation import actions_to_element_torques
from softtrack.sim.engine import RodBatch
from softtrack.sim.params import (
    MODEL_PARAMETERS,
    RodConstants,
    model_error_stability,
    scaled_params,
)
from softtrack.spec import SpecError, parse_spec, spec_hash
from softtrack.spec.env_config import env_config, env_kwargs

STATE = ("position", "velocity", "directors", "omega")
# tolerances of tests/test_engine_reference.py (the engine against PyElastica 1.0.0)
TIP_TOL_M = 1e-6
NODE_TOL_M = 1e-6
DIRECTOR_TOL = 1e-6
VELOCITY_TOL = 1e-5  # m/s
OMEGA_TOL = 1e-4  # rad/s

ALTERED = {  # the brief's example, plus a torque factor; stable at the default dt
    "youngs_modulus_scale": 0.7,
    "density_scale": 1.3,
    "radius_scale": 1.1,
    "damping_scale": 2.0,
    "torque_scale_factor": 0.9,
}
OTHER = {
    "youngs_modulus_scale": 1.3,
    "density_scale": 0.85,
    "radius_scale": 0.97,
    "damping_scale": 0.5,
    "torque_scale_factor": 1.15,
}


def _actions(n_steps: int, n_envs: int, seed: int = 0, scale: float = 0.7) -> np.ndarray:
    """(T, E, 2, 2, 6) smooth-ish control values (a random walk, clipped)."""
    rng = np.random.default_rng(seed)
    steps = rng.normal(0.0, 0.15, (n_steps, n_envs, 2, 2, 6))
    return np.clip(np.cumsum(steps, axis=0), -scale, scale)


def _run(batch: RodBatch, actions: np.ndarray) -> list[dict[str, np.ndarray]]:
    """The state after every control step."""
    out = []
    for a in actions:
        batch.set_actions(a)
        batch.advance()
        out.append({name: getattr(batch, name).copy() for name in (*STATE, "torques")})
    return out


# ---- off: nothing changes -----------------------------------------------------------------------


def test_unit_factors_are_the_nominal_engine_bit_for_bit() -> None:
    p = SimParams()
    actions = _actions(60, 3, seed=1)
    plain = _run(RodBatch(3, p), actions)
    ones = RodBatch(3, p)
    ones.set_parameters(None, dict.fromkeys(MODEL_PARAMETERS, 1.0))
    # env 1 scaled then scaled back: its constants are the nominal ones again
    back = RodBatch(3, p)
    back.set_parameters([1], ALTERED)
    back.set_parameters([1], {})
    for batch in (ones, back):
        for got, want in zip(_run(batch, actions), plain, strict=True):
            for name, value in want.items():
                assert np.array_equal(got[name], value), name
        assert np.array_equal(batch.factors, np.ones((3, 5)))
    assert scaled_params(p, dict.fromkeys(MODEL_PARAMETERS, 1.0)) is p


def test_default_env_has_no_model_error_and_no_parameters_info() -> None:
    env = DualArmTrackingEnv()
    _, info = env.reset(seed=0)
    assert not env.core.model_error and "parameters" not in info
    assert not RealismConfig().model_error_active
    spec = parse_spec({"env": {"realism": {"radius_scale": 1.0, "damping_scale": [1, 1]}}})
    assert spec_hash(spec) == spec_hash(parse_spec({}))
    assert "realism" not in env_kwargs(spec)
    ranged = parse_spec(
        {
            "env": {
                "physics": {"dt": 1e-4, "steps_per_action": 20},
                "realism": {"radius_scale": [0.9, 1.1]},
            }
        }
    )
    fixed = parse_spec(
        {"env": {"physics": {"dt": 1e-4, "steps_per_action": 20}, "realism": {"radius_scale": 0.9}}}
    )
    hashes = {spec_hash(s) for s in (ranged, fixed, parse_spec({}))}
    assert len(hashes) == 3
    assert ranged.env.realism.radius_scale == (0.9, 1.1)
    assert (
        parse_spec({"env": {"realism": {"density_scale": [1.1, 1.1]}}}).env.realism.density_scale
        == 1.1
    )  # a point range is a fixed factor


# ---- the physics of a scaled rod ---------------------------------------------------------------


def test_scaled_constants_are_those_of_the_scaled_rod() -> None:
    """Radius, density and modulus change area, second moments, masses, inertias and
    stiffnesses together: the engine's constants equal those built from the scaled SimParams
    and those PyElastica 1.0.0 computes for a rod built with the scaled values."""
    elastica = pytest.importorskip("elastica")
    p = SimParams()
    batch = RodBatch(2, p)
    batch.set_parameters([1], ALTERED)
    q = scaled_params(p, ALTERED)
    assert q.youngs_modulus == p.youngs_modulus * 0.7 and q.radius == p.radius * 1.1
    assert q.density == p.density * 1.3 and q.damping == p.damping * 2.0
    assert q.torque_scale == p.torque_scale * 0.9
    c = RodConstants.build(q)
    assert np.array_equal(batch._mass[1], c.mass)
    assert np.array_equal(batch._inertia[1], c.inertia)
    assert np.array_equal(batch._shear[1], c.shear_stiffness)
    assert np.array_equal(batch._bend[1], c.bend_stiffness)
    assert batch._damping[1] == q.damping and batch._damping[0] == p.damping
    rod = elastica.CosseratRod.straight_rod(
        q.n_elem,
        np.zeros(3),
        np.array(q.direction),
        np.array(q.normal),
        q.length,
        q.radius,
        q.density,
        youngs_modulus=q.youngs_modulus,
        shear_modulus=q.shear_modulus,
    )
    np.testing.assert_allclose(batch._mass[1], rod.mass, rtol=1e-12)
    np.testing.assert_allclose(
        batch._inertia[1], np.diagonal(rod.mass_second_moment_of_inertia).T, rtol=1e-12
    )
    np.testing.assert_allclose(batch._shear[1], np.diagonal(rod.shear_matrix).T, rtol=1e-12)
    np.testing.assert_allclose(batch._bend[1], np.diagonal(rod.bend_matrix).T, rtol=1e-12)
    # env 0 kept the nominal rod
    assert np.array_equal(batch._mass[0], batch.constants.mass)


def _pyelastica_run(params: SimParams, torques: np.ndarray) -> list[dict[str, np.ndarray]]:
    """PyElastica 1.0.0 rods built with ``params``, driven by (T, A, 2, N) element torques."""
    from softtrack.sim.pyelastica_backend import PyElasticaDualArm

    arm = PyElasticaDualArm(params)
    out = []
    for tau in torques:
        arm.set_element_torques(tau)
        arm.advance(params.steps_per_action)
        out.append(
            {
                "position": arm.positions,
                "velocity": arm.velocities,
                "directors": arm.directors,
                "omega": arm.omegas,
            }
        )
    return out


def _assert_parity(
    ours: list[dict[str, np.ndarray]], env: int, reference: list[dict[str, np.ndarray]]
) -> None:
    for k, (got, want) in enumerate(zip(ours, reference, strict=True)):
        tip = np.linalg.norm(got["position"][env, :, :, -1] - want["position"][:, :, -1], axis=-1)
        assert tip.max() <= TIP_TOL_M, f"tip error {tip.max():.3e} m at control step {k}"
    got, want = ours[-1], reference[-1]
    nodes = np.linalg.norm(got["position"][env] - want["position"], axis=1).max()
    assert nodes <= NODE_TOL_M, f"node error {nodes:.3e} m"
    assert np.abs(got["directors"][env] - want["directors"]).max() <= DIRECTOR_TOL
    assert np.abs(got["velocity"][env] - want["velocity"]).max() <= VELOCITY_TOL
    assert np.abs(got["omega"][env] - want["omega"]).max() <= OMEGA_TOL


@pytest.mark.pyelastica
def test_gravity_on_matches_pyelastica() -> None:
    """env.physics.gravity (9.81 m/s² along −y when true) against PyElastica's GravityForces."""
    pytest.importorskip("elastica")
    p = SimParams.from_overrides(gravity=True)
    assert p.gravity == 9.81
    actions = _actions(150, 1, seed=2, scale=0.4)
    ours = _run(RodBatch(1, p), actions)
    torques = np.stack(
        [actions_to_element_torques(a[0], p.n_elem, p.torque_scale) for a in actions]
    )
    _assert_parity(ours, 0, _pyelastica_run(p, torques))
    # gravity really acts: the same actions without it end elsewhere
    free = _run(RodBatch(1, SimParams()), actions)
    assert np.abs(free[-1]["position"] - ours[-1]["position"]).max() > 1e-3


@pytest.mark.pyelastica
@pytest.mark.parametrize("factors", [ALTERED, OTHER], ids=["altered", "other"])
def test_altered_materials_match_pyelastica_rods_built_with_them(factors: dict) -> None:
    """Env 1 of a batch gets the factors (env 0 stays nominal); PyElastica rods built with the
    scaled E, ρ, r, ν_d and torque scale give the same motion; gravity on as well."""
    pytest.importorskip("elastica")
    p = SimParams.from_overrides(gravity=True)
    q = scaled_params(p, factors)
    actions = _actions(150, 2, seed=3, scale=0.6)
    batch = RodBatch(2, p)
    batch.set_parameters([1], factors)
    ours = _run(batch, actions)
    torques = np.stack(
        [actions_to_element_torques(a[1], q.n_elem, q.torque_scale) for a in actions]
    )
    np.testing.assert_allclose(
        np.stack([s["torques"][1] for s in ours]), torques, rtol=1e-13, atol=1e-12
    )
    _assert_parity(ours, 1, _pyelastica_run(q, torques))
    # the factors matter: the nominal rod with the same actions ends centimetres away
    nominal = _run(RodBatch(1, p), actions[:, 1:2])
    assert np.abs(nominal[-1]["position"][0] - ours[-1]["position"][1]).max() > 1e-2


# ---- batching -----------------------------------------------------------------------------------


def test_batch_with_per_env_factors_equals_single_batches_bit_for_bit() -> None:
    p = SimParams()
    per_env = [ALTERED, {}, OTHER, {"radius_scale": 1.05, "torque_scale_factor": 0.8}]
    n = len(per_env)
    table = {name: np.array([f.get(name, 1.0) for f in per_env]) for name in MODEL_PARAMETERS}
    batch = RodBatch(n, p)
    batch.set_parameters(np.arange(n), table)
    singles = []
    for f in per_env:
        single = RodBatch(1, p)
        single.set_parameters([0], f)
        singles.append(single)
    actions = _actions(80, n, seed=4)
    for a in actions:
        batch.set_actions(a)
        batch.advance()
        for i, single in enumerate(singles):
            single.set_actions(a[i : i + 1])
            single.advance()
    for i, single in enumerate(singles):
        for name in (*STATE, "torques", "time", "factors"):
            assert np.array_equal(getattr(batch, name)[i], getattr(single, name)[0]), (i, name)
    assert batch.finite().all()
    # a reset keeps the factors
    batch.reset([0])
    assert batch.factors[0].tolist() == list(ALTERED.values())


def test_set_parameters_rejects_bad_factors() -> None:
    batch = RodBatch(2, SimParams())
    with pytest.raises(InvalidParameterError, match="unknown model-error factor 'radius'"):
        batch.set_parameters(None, {"radius": 1.1})
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(InvalidParameterError, match="finite numbers > 0"):
            batch.set_parameters([0], {"density_scale": bad})
    with pytest.raises(InvalidParameterError, match=r"environment 1 .*stability limit"):
        batch.set_parameters([1], {"youngs_modulus_scale": 3.0})
    assert np.array_equal(batch.factors, np.ones((2, 5)))  # nothing was changed


# ---- time-step stability ------------------------------------------------------------------------


def test_worst_case_of_the_ranges_is_the_smallest_limit() -> None:
    """The limit falls with E and ν_d and rises with ρ and r, so the stiffest, lightest,
    thinnest, most damped corner bounds every point of the box."""
    p = SimParams()
    names = ("youngs_modulus_scale", "density_scale", "radius_scale", "damping_scale")
    low = (0.7, 0.8, 0.9, 0.5)
    high = (1.4, 1.3, 1.2, 1.5)
    worst = scaled_params(p, dict(zip(names, (high[0], low[1], low[2], high[3]), strict=True)))
    corners = [
        scaled_params(p, dict(zip(names, c, strict=True))).dt_limit
        for c in itertools.product(*zip(low, high, strict=True))
    ]
    assert min(corners) == worst.dt_limit
    rng = np.random.default_rng(0)
    for _ in range(10):
        point = dict(zip(names, rng.uniform(low, high), strict=True))
        assert scaled_params(p, point).dt_limit >= worst.dt_limit
    ranges = dict(zip(names, zip(low, high, strict=True), strict=True))
    fine = dataclasses.replace(p, dt=0.99 * worst.dt_limit)
    assert model_error_stability(fine, ranges) is None
    coarse = dataclasses.replace(p, dt=1.01 * worst.dt_limit)
    result = model_error_stability(coarse, ranges)
    assert result is not None
    field, problem, fix = result
    assert field in names and "needs dt ≤" in problem and "or narrow the range" in fix
    suggested = float(fix.split("lower dt to ")[1].split(" s")[0])
    assert suggested <= worst.dt_limit
    # the torque factor does not enter the limit
    assert model_error_stability(p, {"torque_scale_factor": (0.1, 10.0)}) is None


def test_unstable_range_is_a_config_error_and_a_spec_error() -> None:
    with pytest.raises(
        InvalidParameterError, match=r"youngs_modulus_scale: up to 3 needs dt ≤ .* lower dt to"
    ):
        make_config(realism={"youngs_modulus_scale": [1.0, 3.0]})
    with pytest.raises(SpecError) as info:
        parse_spec({"env": {"realism": {"youngs_modulus_scale": [1.0, 3.0]}}})
    message = str(info.value)
    assert "env.realism.youngs_modulus_scale: up to 3 needs dt ≤" in message
    assert "lower env.physics.dt to" in message and "or narrow the range" in message
    # a smaller dt makes the same range valid
    spec = parse_spec(
        {
            "env": {
                "physics": {"dt": 1e-4, "steps_per_action": 20},
                "realism": {"youngs_modulus_scale": [1.0, 3.0]},
            }
        }
    )
    assert env_config(spec).realism.youngs_modulus_scale == (1.0, 3.0)


@pytest.mark.parametrize(
    ("value", "fix"),
    [
        (0.0, "finite number > 0"),
        (-1.0, "finite number > 0"),
        ([1.2, 0.9], "write it as [0.9, 1.2]"),
        ([0.9, 1.0, 1.1], "a range has 2 values"),
        (True, "expected a number, got true"),
    ],
)
def test_bad_factors_are_spec_errors_and_config_errors(value, fix: str) -> None:
    with pytest.raises(SpecError) as info:
        parse_spec({"env": {"realism": {"density_scale": value}}})
    message = str(info.value)
    assert "env.realism.density_scale" in message and fix in message and "\n" not in message
    with pytest.raises(InvalidParameterError, match="density_scale"):
        make_config(realism={"density_scale": value})


# ---- environments -------------------------------------------------------------------------------


def _trace(env: DualArmTrackingEnv, actions: np.ndarray, seed: int) -> list[np.ndarray]:
    obs, info = env.reset(seed=seed)
    out = [obs, info["tip_positions"], info["target_position"]]
    for action in actions:
        obs, reward, terminated, truncated, info = env.step(action)
        out += [
            obs,
            np.float64(reward),
            np.bool_(terminated),
            np.bool_(truncated),
            info["tip_positions"],
            info["target_position"],
            info["element_torques"],
        ]
    return out


def test_fixed_factors_equal_the_changed_physics_bit_for_bit() -> None:
    """realism={E: 1.2, ...} is the env whose physics holds the products, step for step (the
    torque factor is applied after the spline, so it is left at 1 here)."""
    p = SimParams()
    factors = {
        "youngs_modulus_scale": 1.2,
        "density_scale": 1.3,
        "radius_scale": 1.1,
        "damping_scale": 0.8,
    }
    actions = np.random.default_rng(5).uniform(-1, 1, (40, 24))
    realism_env = DualArmTrackingEnv(realism=factors)
    physics_env = DualArmTrackingEnv(
        youngs_modulus=p.youngs_modulus * 1.2,
        density=p.density * 1.3,
        radius=p.radius * 1.1,
        damping=p.damping * 0.8,
    )
    a, b = _trace(realism_env, actions, 7), _trace(physics_env, actions, 7)
    for k, (x, y) in enumerate(zip(a, b, strict=True)):
        np.testing.assert_array_equal(x, y, err_msg=f"item {k}")
    _, info = realism_env.reset(seed=8)
    assert info["parameters"] == {**dict.fromkeys(MODEL_PARAMETERS, 1.0), **factors}


def test_torque_factor_scales_the_applied_torques() -> None:
    env = DualArmTrackingEnv(realism={"torque_scale_factor": 0.5})
    plain = DualArmTrackingEnv()
    env.reset(seed=0)
    plain.reset(seed=0)
    action = np.random.default_rng(6).uniform(-1, 1, 24)
    _, _, _, _, info = env.step(action)
    _, _, _, _, plain_info = plain.step(action)
    np.testing.assert_array_equal(info["element_torques"], 0.5 * plain_info["element_torques"])


def _factor_config(**extra) -> object:
    return make_config(
        realism={
            "youngs_modulus_scale": [0.8, 1.2],
            "radius_scale": [1.0, 1.1],
            "torque_scale_factor": [0.7, 1.3],
            **extra,
        }
    )


def test_ranges_are_drawn_per_episode_and_env_reproducibly() -> None:
    config = _factor_config()
    core = TrackingCore(4, config)
    core.reset(np.arange(4), [np.random.default_rng(s) for s in range(4)])
    first = core.engine.factors.copy()
    assert np.all((first[:, 0] >= 0.8) & (first[:, 0] <= 1.2))
    assert np.all((first[:, 2] >= 1.0) & (first[:, 2] <= 1.1))
    assert np.all((first[:, 4] >= 0.7) & (first[:, 4] <= 1.3))
    assert np.all(first[:, [1, 3]] == 1.0)
    assert len(set(first[:, 0].tolist())) == 4  # every env draws its own
    # a new episode draws new factors (the env's generator moves on)
    core.reset([2], [core.rngs[2]])
    assert np.all(core.engine.factors[2, [0, 2, 4]] != first[2, [0, 2, 4]])
    assert np.array_equal(core.engine.factors[[0, 1, 3]], first[[0, 1, 3]])
    # same seed, same factors
    again = TrackingCore(4, config)
    again.reset(np.arange(4), [np.random.default_rng(s) for s in range(4)])
    assert np.array_equal(again.engine.factors, first)
    # the info reports the episode's factors
    info = core.info(1, np.zeros((4, 2)))
    assert info["parameters"] == dict(zip(MODEL_PARAMETERS, first[1].tolist(), strict=True))


def test_randomisation_leaves_the_target_and_noise_streams_alone() -> None:
    """The factors come from a generator spawned from the realism generator: the random target
    and the observation noise are those of the same env without model error."""
    actions = np.random.default_rng(9).uniform(-1, 1, (30, 24))
    noisy = {"obs_noise_speed": 0.05}
    envs = [
        DualArmTrackingEnv(realism=noisy),
        DualArmTrackingEnv(
            realism={**noisy, "youngs_modulus_scale": [0.8, 1.2], "density_scale": [1.0, 1.2]}
        ),
    ]
    traces = []
    for env in envs:
        obs, _ = env.reset(seed=11)
        targets, speeds = [], []
        for action in actions:
            obs, *_, info = env.step(action)
            targets.append(info["target_position"])
            speeds.append(obs[33] - np.linalg.norm(env.core.engine.tip_velocity[0, 0]))
        traces.append((np.array(targets), np.array(speeds), obs))
    np.testing.assert_array_equal(traces[0][0], traces[1][0])  # the target moved alike
    np.testing.assert_allclose(traces[0][1], traces[1][1], atol=1e-6)  # the same noise draws
    assert np.abs(traces[0][2] - traces[1][2]).max() > 1e-4  # but the arms moved differently
    states = {repr(env.np_random.bit_generator.state) for env in envs}
    assert len(states) == 1  # nothing drawn from the env's own generator


def test_vec_env_with_ranges_equals_single_envs_and_reports_parameters() -> None:
    config = _factor_config()
    n = 3
    vec = TrackingVecEnv(n, config, full_info=True)
    vec.seed(20)
    vec.reset()
    singles = [DualArmTrackingEnv(realism=config.realism) for _ in range(n)]
    for i, env in enumerate(singles):
        _, info = env.reset(seed=20 + i)
        assert vec.reset_infos[i]["parameters"] == info["parameters"]
    actions = np.random.default_rng(12).uniform(-1, 1, (25, n, 24))
    for a in actions:
        obs, rewards, _, infos = vec.step(a)
        for i, env in enumerate(singles):
            o, r, *_, info = env.step(a[i])
            np.testing.assert_array_equal(obs[i], o)
            assert np.float32(r) == rewards[i]
            assert infos[i]["parameters"] == info["parameters"]
    # a finished episode reports its factors even without full_info
    short = TrackingVecEnv(2, make_config(realism=config.realism, episode_duration=0.004))
    short.seed(0)
    short.reset()
    before = [short.core.parameters(i) for i in range(2)]
    _, _, dones, infos = short.step(np.zeros((2, 24)))
    _, _, dones, infos = short.step(np.zeros((2, 24)))
    assert dones.all()
    assert [info["parameters"] for info in infos] == before
    assert [short.core.parameters(i) for i in range(2)] != before  # new episodes, new draws


def test_spec_reaches_the_environment() -> None:
    spec = parse_spec(
        {"env": {"realism": {"torque_scale_factor": [0.8, 1.2], "youngs_modulus_scale": 1.1}}}
    )
    kwargs = env_kwargs(spec)
    assert kwargs["realism"]["torque_scale_factor"] == (0.8, 1.2)
    for arm in (None, 0):
        config = env_config(spec, arm)
        assert config.realism.model_error_ranges == {
            "youngs_modulus_scale": (1.1, 1.1),
            "torque_scale_factor": (0.8, 1.2),
        }
        core = TrackingCore(1, config)
        core.reset([0], [np.random.default_rng(0)])
        assert core.engine.factors[0, 0] == 1.1
        assert 0.8 <= core.engine.factors[0, 4] <= 1.2
