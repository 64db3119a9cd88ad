"""The experiment spec: defaults, one-line errors with exit code 2, overrides, YAML round trip."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.sim.params import SimParams
from softtrack.spec import (
    AlgoSpec,
    ExperimentSpec,
    SpecError,
    load_spec,
    parse_spec,
    spec_hash,
    spec_json_schema,
    spec_to_yaml,
)

REPO = Path(__file__).resolve().parents[1]
EXPERIMENTS = sorted((REPO / "experiments").glob("*.yaml"))
runner = CliRunner()


def write(tmp_path: Path, text: str, name: str = "exp.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# ---- defaults -----------------------------------------------------------------------------
def test_defaults_equal_spec_md() -> None:
    s = ExperimentSpec()
    p = s.env.physics
    assert (p.n_elem, p.length, p.radius, p.density) == (20, 1.0, 0.05, 1000.0)
    assert (p.youngs_modulus, p.poisson_ratio, p.shear_correction) == (1e7, 0.5, 27 / 28)
    assert (p.damping, p.dt, p.steps_per_action, p.gravity, p.torque_scale) == (
        30.0,
        2e-4,
        10,
        0.0,
        75.0,
    )
    assert p.base_positions == ((-0.1, 0.0, 0.0), (0.1, 0.0, 0.0))
    t = s.env.target
    assert (t.name, t.sphere_radius, t.speed, t.redirect_interval) == ("random", 0.05, 0.3, 1.0)
    assert (t.box_low, t.box_high, t.center) == (
        (-0.6, 0.3, -0.6),
        (0.6, 0.9, 0.6),
        (0.0, 0.6, 0.0),
    )
    assert (t.circle_radius, t.rectangle_size, t.figure8_amplitude, t.period) == (
        0.3,
        (0.6, 0.4),
        (0.3, 0.15),
        10.0,
    )
    assert t.fixed_position == (0.3, 0.6, 0.0)
    r = s.env.reward
    assert (r.arm_weights, r.bonus_thresholds, r.bonus_values) == (
        (1.0, 1.0),
        (0.10, 0.075),
        (0.5, 1.0),
    )
    assert (r.cooperative_threshold, r.cooperative_bonus, r.nonfinite_reward) == (
        0.05,
        1.5,
        -1000.0,
    )
    assert (r.collision_penalty, r.collision_margin) == (0.0, 0.0)
    assert s.env.episode_duration == 10.0 and s.env.max_episode_steps == 5000
    a = s.algo
    assert (a.name, a.backend, a.policy) == ("td3", "sb3", "MlpPolicy")
    assert (a.policy_kwargs.net_arch, a.policy_kwargs.activation_fn) == ([64, 64], "relu")
    assert (a.learning_rate, a.batch_size, a.gamma, a.tau) == (3e-4, 128, 0.99, 0.005)
    assert (a.policy_delay, a.target_policy_noise, a.target_noise_clip) == (2, 0.2, 0.5)
    assert (a.buffer_size, a.learning_starts, a.train_freq, a.gradient_steps) == (
        2_000_000,
        50_000,
        1,
        1,
    )
    assert (a.noise_type, a.noise_std) == ("normal", 0.1)
    assert (a.n_steps, a.n_epochs, a.gae_lambda, a.clip_range) == (2048, 10, 0.95, 0.2)
    tr = s.training
    assert (tr.total_timesteps, tr.n_envs, tr.checkpoint_interval, tr.torch_threads) == (
        10_000_000,
        1,
        100_000,
        1,
    )
    assert tr.final_stage_fraction == 0.1
    assert s.seeds == [0, 1, 2] and s.controller == "centralized"


def test_physics_section_mirrors_simparams() -> None:
    sim_fields = {f.name for f in dataclasses.fields(SimParams)} - {"direction", "normal"}
    assert set(ExperimentSpec().env.sim_kwargs()) == sim_fields
    assert ExperimentSpec().env.sim_params() == SimParams()


def test_env_kwargs_are_plain_dicts_with_exact_names() -> None:
    env = ExperimentSpec().env
    assert list(env.target_kwargs()) == [
        "name",
        "sphere_radius",
        "speed",
        "speed_min",
        "redirect_interval",
        "box_low",
        "box_high",
        "center",
        "circle_radius",
        "rectangle_size",
        "figure8_amplitude",
        "period",
        "fixed_position",
    ]
    assert list(env.reward_kwargs()) == [
        "arm_weights",
        "bonus_thresholds",
        "bonus_values",
        "cooperative_threshold",
        "cooperative_bonus",
        "nonfinite_reward",
        "collision_penalty",
        "collision_margin",
    ]
    assert env.target_kwargs()["box_low"] == (-0.6, 0.3, -0.6)
    assert type(env.sim_kwargs()) is dict


def test_every_field_has_a_description_with_a_unit() -> None:
    schema = spec_json_schema()
    missing = []

    def walk(props: dict, where: str) -> None:
        for name, prop in props.items():
            desc = prop.get("description", "")
            if "$ref" in prop or "allOf" in prop:
                ref = prop.get("$ref") or prop["allOf"][0]["$ref"]
                walk(schema["$defs"][ref.split("/")[-1]]["properties"], f"{where}{name}.")
                if not desc:
                    missing.append(where + name)
            elif not (desc and desc.rstrip().endswith("]") and "[" in desc):
                missing.append(where + name)

    walk(schema["properties"], "")
    assert not missing


# ---- errors -------------------------------------------------------------------------------
ERROR_CASES = {
    # id: (file text or None for a missing file, overrides, expected fragments)
    "missing-file": (None, [], ["no such file"]),
    "malformed-yaml": ("env:\n  physics:\n    dt: [1\n", [], [":4:", "malformed YAML"]),
    "duplicate-key": ("seeds: 1\nseeds: 2\n", [], [":2:", "duplicate key 'seeds'"]),
    "not-a-mapping": ("- a\n- b\n", [], ["top level must be a mapping"]),
    "empty": ("", [], ["top level must be a mapping"]),
    "unknown-key": (
        "algo:\n  learnig_rate: 0.001\n",
        [],
        [":2:", "algo.learnig_rate", "did you mean 'learning_rate'"],
    ),
    "unknown-section": ("trainig: {}\n", [], ["trainig", "did you mean 'training'"]),
    "wrong-type": (
        "training:\n  total_timesteps: lots\n",
        [],
        [":2:", "training.total_timesteps", "whole number"],
    ),
    "wrong-literal": ("algo: {name: td4}\n", [], ["algo.name", "did you mean 'td3'"]),
    "negative-steps": (
        "training:\n  total_timesteps: -5\n",
        [],
        ["training.total_timesteps", "out of range", "> 0"],
    ),
    "dt-unstable": (
        "env:\n  physics:\n    dt: 3e-4\n",
        [],
        [":3:", "env.physics.dt", "stability limit", "use dt ≤"],
    ),
    "vector-length": (
        "env:\n  target:\n    box_low: [0, 1]\n",
        [],
        ["env.target.box_low", "expected 3 values"],
    ),
    "speed-range": (
        "env:\n  target:\n    speed_min: 0.5\n",
        [],
        ["env.target.speed_min", "exceeds speed=0.3", "make speed_min <= speed"],
    ),
    "bool-as-number": ("training: {n_envs: yes}\n", [], ["training.n_envs", "expected a number"]),
    "per-arm-critic-sb3": (
        "algo: {critic: per_arm}\n",
        [],
        ["algo.critic", "td3 with backend sbx", "not td3 with backend sb3"],
    ),
    "per-arm-critic-independent": (
        "controller: independent\nalgo: {critic: per_arm, backend: sbx}\n",
        [],
        ["algo.critic", "needs controller: centralized"],
    ),
    "per-arm-critic-reward-normalisation": (
        "algo: {critic: per_arm, backend: sbx, normalize: true, normalize_reward: true}\n",
        [],
        ["algo.critic", "set algo.normalize_reward: false"],
    ),
    "per-arm-networks-joint-critic": (
        "algo: {per_arm_networks: true, backend: sbx}\n",
        [],
        ["algo.per_arm_networks", "set algo.critic: per_arm"],
    ),
    "own-arm-actors-without-per-arm-networks": (
        "algo: {actor_observation: own_arm, critic: per_arm, backend: sbx}\n",
        [],
        ["algo.actor_observation", "set algo.per_arm_networks: true"],
    ),
    "mirror-replay-ppo": (
        "algo: {name: ppo, mirror_replay: true}\n",
        [],
        ["algo.mirror_replay", "needs an off-policy algo", "set algo.mirror_replay: false"],
    ),
    "mirror-replay-independent": (
        "controller: independent\nalgo: {mirror_replay: true}\n",
        [],
        ["algo.mirror_replay", "controller: centralized"],
    ),
    "mirror-replay-normalize": (
        "algo: {mirror_replay: true, normalize: true}\n",
        [],
        ["algo.mirror_replay", "set algo.normalize: false"],
    ),
    "mirror-replay-asymmetric-bases": (
        "env: {physics: {base_positions: [[-0.1, 0, 0], [0.2, 0, 0]]}}\nalgo: {mirror_replay: true}\n",
        [],
        ["algo.mirror_replay", "mirror images in x = 0", "(0.2, 0.0, 0.0)"],
    ),
    "mirror-replay-unequal-weights": (
        "env: {reward: {arm_weights: [1.0, 2.0]}}\nalgo: {mirror_replay: true}\n",
        [],
        ["algo.mirror_replay", "equal env.reward.arm_weights", "(1, 2)"],
    ),
    "best-validated-without-validation": (
        "training: {final_policy: best_validated}\n",
        [],
        ["training.final_policy", "set training.validation_episodes to at least 1"],
    ),
    "best-validated-without-checkpoints": (
        "training: {final_policy: best_validated, validation_episodes: 5, checkpoint_interval: 0}\n",
        [],
        ["training.checkpoint_interval", "checkpoint_interval 0 gives none"],
    ),
    "confirm-without-best-validated": (
        "training: {validation_episodes: 5, confirm_episodes: 20}\n",
        [],
        ["training.confirm_episodes", "set final_policy: best_validated or confirm_episodes: 0"],
    ),
    "bad-name": ("name: 'a b/c'\n", [], ["name", "invalid name"]),
    "never-learns": (
        "training: {total_timesteps: 1000}\n",
        [],
        ["algo.learning_starts", "never learn"],
    ),
    "override-syntax": (
        "{}\n",
        ["training.total_timesteps"],
        ["--set training.total_timesteps", "dotted.path=value"],
    ),
    "override-unknown": (
        "{}\n",
        ["training.totl=3"],
        ["--set training.totl=3", "training.totl", "did you mean 'total_timesteps'"],
    ),
    "override-type": (
        "{}\n",
        ["training.n_envs=many"],
        ["--set training.n_envs=many", "training.n_envs", "whole number"],
    ),
    "override-range": (
        "{}\n",
        ["env.physics.dt=1e-3"],
        ["--set env.physics.dt=1e-3", "env.physics.dt", "stability limit"],
    ),
    "override-yaml": ("{}\n", ["seeds=[0"], ["--set seeds=[0", "seeds", "not valid YAML"]),
}


def _case(tmp_path: Path, case: str) -> tuple[Path, list[str], list[str]]:
    text, overrides, fragments = ERROR_CASES[case]
    path = tmp_path / "exp.yaml"
    if text is not None:
        path.write_text(text, encoding="utf-8")
    return path, overrides, fragments


@pytest.mark.parametrize("case", sorted(ERROR_CASES))
def test_error_is_one_line_naming_file_and_field(tmp_path: Path, case: str) -> None:
    path, overrides, fragments = _case(tmp_path, case)
    with pytest.raises(SpecError) as info:
        load_spec(path, overrides)
    message = str(info.value)
    assert "\n" not in message
    assert str(path) in message or "--set" in message
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    assert "; " in message  # problem; fix


@pytest.mark.parametrize("case", sorted(ERROR_CASES))
def test_cli_validate_error_exit_code_2(tmp_path: Path, case: str) -> None:
    path, overrides, fragments = _case(tmp_path, case)
    before = sorted(tmp_path.iterdir())
    args = ["validate", str(path)] + [a for o in overrides for a in ("--set", o)]
    result = runner.invoke(app, args)
    assert result.exit_code == 2, result.output
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert fragments[-1] in lines[0]
    assert "Traceback" not in result.output
    assert sorted(tmp_path.iterdir()) == before  # nothing written


def test_subprocess_error_has_no_traceback(tmp_path: Path) -> None:
    path = write(tmp_path, "algo:\n  learnig_rate: 0.001\n")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.run(
        [sys.executable, "-m", "softtrack.cli", "validate", str(path)],
        check=False,
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert f"{path}:2: algo.learnig_rate:" in proc.stderr


def test_error_counts_further_problems(tmp_path: Path) -> None:
    path = write(tmp_path, "algo: {name: td4, batch_size: 0}\ntraining: {n_envs: 0}\n")
    with pytest.raises(SpecError, match=r"\(and 2 more errors\)"):
        load_spec(path)


# ---- loading and overrides ----------------------------------------------------------------
def test_yaml12_floats_and_name_from_file(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        "training: {total_timesteps: 1e7}\nalgo: {learning_rate: 1e-3}\nseeds: 4\n",
        "my-exp.yaml",
    )
    spec = load_spec(path)
    assert spec.name == "my-exp"
    assert spec.training.total_timesteps == 10_000_000 and isinstance(
        spec.training.total_timesteps, int
    )
    assert spec.algo.learning_rate == 1e-3
    assert spec.seeds == [4]


def test_gravity_switch(tmp_path: Path) -> None:
    assert (
        load_spec(write(tmp_path, "env: {physics: {gravity: true}}\n")).env.physics.gravity == 9.81
    )
    assert (
        load_spec(write(tmp_path, "env: {physics: {gravity: false}}\n")).env.physics.gravity == 0.0
    )


def test_overrides(tmp_path: Path) -> None:
    path = write(tmp_path, "name: base\ntraining: {total_timesteps: 100000}\n")
    spec = load_spec(
        path,
        [
            "training.total_timesteps=2000",
            "algo.learning_starts=100",
            "env.physics.dt=1e-4",
            "seeds=[0,1]",
            "env.target={name: circle, period: 5}",
            "algo.policy_kwargs.net_arch=[32, 32, 32]",
            "algo.noise_type=null",
            "name=renamed",
        ],
    )
    assert spec.training.total_timesteps == 2000
    assert spec.env.physics.dt == 1e-4
    assert spec.seeds == [0, 1]
    assert spec.env.target.name == "circle" and spec.env.target.period == 5.0
    assert spec.algo.policy_kwargs.net_arch == [32, 32, 32]
    assert spec.algo.noise_type is None
    assert spec.name == "renamed"
    assert path.read_text() == "name: base\ntraining: {total_timesteps: 100000}\n"  # file untouched


def test_override_into_scalar_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(SpecError, match="seeds.*no sub-fields"):
        load_spec(write(tmp_path, "{}\n"), ["seeds.first=1"])


def test_cross_field_error_mentions_overrides(tmp_path: Path) -> None:
    with pytest.raises(SpecError) as info:
        load_spec(write(tmp_path, "{}\n"), ["training.total_timesteps=2000"])
    assert "(with --set training.total_timesteps=2000)" in str(info.value)
    assert "algo.learning_starts" in str(info.value)


def test_parse_spec_without_file() -> None:
    spec = parse_spec({"algo": {"name": "ppo", "batch_size": 64}}, ["seeds=7"])
    assert spec.algo.name == "ppo" and spec.seeds == [7]


# ---- YAML round trip, hash, schema --------------------------------------------------------
@pytest.mark.parametrize("comments", [False, True])
def test_yaml_round_trip(tmp_path: Path, comments: bool) -> None:
    spec = parse_spec(
        {
            "name": "rt",
            "env": {
                "physics": {"dt": 1e-4, "gravity": 9.81},
                "target": {"name": "figure8"},
                "reward": {"bonus_thresholds": [0.1], "bonus_values": [2.0]},
            },
            "algo": {
                "name": "sac",
                "ent_coef": "auto_0.1",
                "policy_kwargs": {"net_arch": {"pi": [8], "qf": [16, 16]}},
            },
            "training": {"total_timesteps": 123456, "eval_trajectories": ["circle"]},
            "seeds": [5, 3],
            "controller": "independent",
        }
    )
    text = spec_to_yaml(spec, comments=comments)
    assert yaml.safe_load(text) is not None
    path = write(tmp_path, text, "rt.yaml")
    assert load_spec(path) == spec
    assert spec_to_yaml(load_spec(path), comments=comments) == text


def test_default_yaml_from_cli_loads_back(tmp_path: Path) -> None:
    result = runner.invoke(app, ["spec", "--defaults"])
    assert result.exit_code == 0
    path = write(tmp_path, result.stdout, "experiment.yaml")
    assert load_spec(path) == ExperimentSpec()


def test_cli_schema_and_resolved_spec(tmp_path: Path) -> None:
    import json

    result = runner.invoke(app, ["spec", "--schema"])
    assert result.exit_code == 0
    assert json.loads(result.stdout)["title"] == "ExperimentSpec"
    path = write(tmp_path, "seeds: 1\n")
    result = runner.invoke(app, ["spec", str(path), "--set", "algo.name=ddpg"])
    assert result.exit_code == 0
    data = yaml.safe_load(result.stdout)
    assert data["algo"]["name"] == "ddpg" and data["seeds"] == [1] and data["name"] == "exp"
    assert runner.invoke(app, ["spec"]).exit_code == 2


def test_spec_hash() -> None:
    base = ExperimentSpec()
    assert spec_hash(base) == spec_hash(ExperimentSpec())
    assert len(spec_hash(base)) == 64
    assert spec_hash(base.with_seed(7)) == spec_hash(base)  # seed-independent
    assert spec_hash(parse_spec({"algo": {"tau": 0.01}})) != spec_hash(base)
    assert spec_hash(parse_spec({"env": {"target": {"speed_min": 0.1}}})) != spec_hash(base)
    per_arm = parse_spec({"algo": {"backend": "sbx", "critic": "per_arm"}})
    assert spec_hash(per_arm) != spec_hash(parse_spec({"algo": {"backend": "sbx"}}))
    nets = {"backend": "sbx", "critic": "per_arm", "per_arm_networks": True}
    assert spec_hash(parse_spec({"algo": nets})) != spec_hash(per_arm)
    own_arm = {**nets, "actor_observation": "own_arm"}
    assert spec_hash(parse_spec({"algo": own_arm})) != spec_hash(parse_spec({"algo": nets}))
    assert spec_hash(parse_spec({"algo": {**nets, "actor_observation": "full"}})) == spec_hash(
        parse_spec({"algo": nets})
    )
    mirrored = parse_spec({"algo": {"mirror_replay": True}})
    assert spec_hash(mirrored) != spec_hash(base)
    assert spec_hash(parse_spec({"algo": {"mirror_replay": False}})) == spec_hash(base)
    nets["per_arm_networks"] = False
    assert spec_hash(parse_spec({"algo": nets})) == spec_hash(per_arm)
    neutral = {"validation_episodes": 0, "final_policy": "last"}
    assert spec_hash(parse_spec({"training": neutral})) == spec_hash(base)
    validated = parse_spec({"training": {"validation_episodes": 10}})
    assert spec_hash(validated) != spec_hash(base)
    best = parse_spec({"training": {"validation_episodes": 10, "final_policy": "best_validated"}})
    assert spec_hash(best) != spec_hash(validated)


@pytest.mark.parametrize("run_dir", sorted((REPO / "models").glob("*/")), ids=lambda p: p.name)
def test_spec_hash_of_shipped_runs_is_stable(run_dir: Path) -> None:
    """Fields added to the spec after these runs were trained keep their recorded hash."""
    recorded = json.loads((run_dir / "run.json").read_text())["spec_hash"]
    assert spec_hash(load_spec(run_dir / "spec.yaml")) == recorded


# ---- algo kwargs --------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["td3", "ddpg", "sac", "ppo"])
def test_sb3_kwargs_are_accepted_by_the_constructor(name: str) -> None:
    sb3 = pytest.importorskip("stable_baselines3")
    import inspect

    algo = AlgoSpec(name=name, ent_coef=0.01 if name in ("sac", "ppo") else None)
    kwargs = algo.sb3_kwargs(resolve_activation=False)
    cls = getattr(sb3, name.upper())
    accepted = set(inspect.signature(cls.__init__).parameters)
    assert set(kwargs) <= accepted
    assert ("policy_delay" in kwargs) == (name == "td3")
    assert ("n_steps" in kwargs) == (name == "ppo")
    assert ("buffer_size" in kwargs) == (name != "ppo")
    assert kwargs["policy_kwargs"] == {"net_arch": [64, 64], "activation_fn": "relu"}


def test_sb3_kwargs_resolve_activation() -> None:
    torch = pytest.importorskip("torch")
    kwargs = AlgoSpec().sb3_kwargs()
    assert kwargs["policy_kwargs"]["activation_fn"] is torch.nn.ReLU


# ---- shipped experiments ------------------------------------------------------------------
def test_experiments_exist() -> None:
    names = {p.name for p in EXPERIMENTS}
    assert {"quickstart.yaml", "td3.yaml", "ddpg.yaml", "ppo.yaml", "independent-td3.yaml"} <= names


@pytest.mark.parametrize("path", EXPERIMENTS, ids=lambda p: p.name)
def test_shipped_experiment_validates(path: Path) -> None:
    assert path.read_text(encoding="utf-8").startswith("#")  # explained at the top
    spec = load_spec(path)
    assert spec.name == path.stem
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 0 and result.stdout.startswith(f"ok: {spec.name}, ")


def test_study_protocol_files() -> None:
    for stem, algo in [
        ("td3", "td3"),
        ("ddpg", "ddpg"),
        ("ppo", "ppo"),
        ("independent-td3", "td3"),
    ]:
        spec = load_spec(REPO / "experiments" / f"{stem}.yaml")
        assert spec.algo.name == algo
        assert spec.seeds == [0, 1, 2]
        assert spec.training.total_timesteps == 10_000_000
        assert spec.env == ExperimentSpec().env
        assert spec.controller == (
            "independent" if stem.startswith("independent") else "centralized"
        )
    quick = load_spec(REPO / "experiments" / "quickstart.yaml")
    assert quick.seeds == [0] and quick.training.total_timesteps <= 100_000
