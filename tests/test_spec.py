"""The experiment spec: defaults, one-line errors with exit code 2, overrides, YAML round trip."""

from __future__ import annotations

import dataclasses
import functools
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
    spec_chain,
    spec_hash,
    spec_json_schema,
    spec_to_yaml,
)
from softtrack.spec.bases import read_spec_file

REPO = Path(__file__).resolve().parents[1]
EXPERIMENTS = sorted((REPO / "experiments").rglob("*.yaml"))
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
        "action_rate_penalty",
        "action_penalty",
    ]
    assert env.target_kwargs()["box_low"] == (-0.6, 0.3, -0.6)
    assert type(env.sim_kwargs()) is dict


def test_every_field_has_a_description_with_a_unit() -> None:
    schema = spec_json_schema()
    missing = []

    def walk(props: dict, where: str) -> None:
        for name, prop in props.items():
            desc = prop.get("description", "")
            optional_section = [a for a in prop.get("anyOf", []) if "$ref" in a]
            if "$ref" in prop or "allOf" in prop or optional_section:
                ref = (
                    prop.get("$ref")
                    or (optional_section[0]["$ref"] if optional_section else None)
                    or prop["allOf"][0]["$ref"]
                )
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
    "realism-negative-std": (
        "env:\n  realism:\n    obs_noise_node_position: -0.01\n",
        [],
        [":3:", "env.realism.obs_noise_node_position", "out of range", "use a value ≥ 0"],
    ),
    "realism-probability": (
        "env: {realism: {obs_drop_probability: 1.0}}\n",
        [],
        ["env.realism.obs_drop_probability", "out of range", "use a value < 1"],
    ),
    "realism-delay": (
        "env: {realism: {action_delay: -1}}\n",
        [],
        ["env.realism.action_delay", "out of range", "use a value ≥ 0"],
    ),
    "realism-tau": (
        "env: {realism: {actuator_time_constant: 0}}\n",
        [],
        ["env.realism.actuator_time_constant", "out of range", "use a value > 0"],
    ),
    "model-error-range-order": (
        "env:\n  realism:\n    radius_scale: [1.1, 0.9]\n",
        [],
        [":3:", "env.realism.radius_scale", "low > high", "write it as [0.9, 1.1]"],
    ),
    "model-error-factor": (
        "env: {realism: {density_scale: 0}}\n",
        [],
        ["env.realism.density_scale", "finite number > 0", "write a factor such as 1.2"],
    ),
    "model-error-range-length": (
        "env: {realism: {damping_scale: [0.5, 1, 2]}}\n",
        [],
        ["env.realism.damping_scale", "a range has 2 values", "[low, high]"],
    ),
    "model-error-unstable": (
        "env:\n  realism:\n    youngs_modulus_scale: [0.8, 2.0]\n",
        [],
        [
            ":3:",
            "env.realism.youngs_modulus_scale",
            "up to 2 needs dt ≤",
            "lower env.physics.dt to",
            "or narrow the range",
        ],
    ),
    "model-error-unstable-override": (
        "{}\n",
        ["env.realism.radius_scale=[0.8, 1.2]"],
        [
            "--set env.realism.radius_scale",
            "env.realism.radius_scale",
            "down to 0.8 needs dt",
            "or narrow the range",
        ],
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
    "validation-trajectories-without-validation": (
        "training: {validation_trajectories: true}\n",
        [],
        ["training.validation_trajectories", "set training.validation_episodes to at least 1"],
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


@pytest.mark.faults("held")
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


@pytest.mark.faults("held")
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


@pytest.mark.faults("held")
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
    with pytest.raises(SpecError, match=r"seeds.*no sub-fields"):
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
    assert spec_hash(parse_spec({"env": {"realism": {"obs_delay": 0}}})) == spec_hash(base)
    assert spec_hash(parse_spec({"env": {"realism": {"obs_delay": 1}}})) != spec_hash(base)
    assert spec_hash(parse_spec({"env": {"realism": {"radius_scale": 1}}})) == spec_hash(base)
    ranged = parse_spec({"env": {"realism": {"torque_scale_factor": [0.8, 1.2]}}})
    assert spec_hash(ranged) != spec_hash(base)
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


@pytest.mark.parametrize(
    "run_dir", sorted(p.parent for p in (REPO / "models").glob("*/run.json")), ids=lambda p: p.name
)
def test_spec_hash_of_shipped_runs_is_stable(run_dir: Path) -> None:
    """Fields added to the spec after these runs were trained keep their recorded hash."""
    recorded = json.loads((run_dir / "run.json").read_text())["spec_hash"]
    assert spec_hash(load_spec(run_dir / "spec.yaml")) == recorded


SHIPPED_RUNS = sorted(p.parent for p in (REPO / "models").glob("*/run.json"))


@functools.cache
def _experiment_files_by_name() -> dict[str, Path]:
    """Experiment name (the spec's ``name``, run.json's ``name``) → its file in experiments/."""
    return {load_spec(path).name: path for path in EXPERIMENTS}


def _spec_of_command(command: list[str]) -> tuple[Path, list[str]]:
    """The spec file and the ``--set`` overrides of a recorded ``softtrack train`` command (or
    ``softtrack evaluate SPEC``, which creates a planner's runs)."""
    assert command[:2] in (["softtrack", "train"], ["softtrack", "evaluate"]), command
    args, overrides, spec = command[2:], [], None
    i = 0
    while i < len(args):
        arg = args[i]
        if arg in ("--set", "-s"):
            overrides.append(args[i + 1])
            i += 2
            continue
        if arg.startswith("--set="):
            overrides.append(arg.partition("=")[2])
        elif arg.startswith("-"):
            i += 1  # an option with a value (--seed N, --runs-dir DIR)
        elif spec is None:
            spec = arg
        i += 1
    assert spec is not None, command
    return REPO / spec, overrides


def test_every_shipped_run_has_a_spec_hash() -> None:
    assert len(SHIPPED_RUNS) >= 50
    for run_dir in SHIPPED_RUNS:
        info = json.loads((run_dir / "run.json").read_text(encoding="utf-8"))
        assert len(info.get("spec_hash") or "") == 64, run_dir.name


@pytest.mark.parametrize("run_dir", SHIPPED_RUNS, ids=lambda p: p.name)
def test_experiment_file_of_shipped_run_gives_its_hash(run_dir: Path) -> None:
    """The experiment file a shipped run came from (found by the run's name; its recorded
    command names the file's path) still resolves, with the command's ``--set`` overrides, to
    the run's recorded spec hash: a change to any file of a ``base:`` chain that alters a
    shipped experiment fails here. A run derived from another (``notes.derived_from``, e.g.
    the ``-confirm`` runs) records its base run's training command, whose spec gives the base
    run's hash; one derived from a ``softtrack tune`` trial records the tune's command, and its
    own experiment file under the trial's name gives the trial's hash (the same spec values)."""
    info = json.loads((run_dir / "run.json").read_text(encoding="utf-8"))
    command = info["command"]
    assert not any(Path(arg).is_absolute() for arg in command), command
    derived = info["notes"].get("derived_from")
    by_name = _experiment_files_by_name()
    assert info["name"] in by_name, f"no experiment file named {info['name']!r}"
    named = by_name[info["name"]]
    if command[:2] == ["softtrack", "tune"]:
        assert derived is not None, f"{run_dir.name}: a tune trial's run shipped as it is"
        assert (REPO / command[2]).is_file(), f"{run_dir.name}: no tuned spec {command[2]}"
        spec_file, overrides = named, [f"name={derived['name']}"]
    else:
        spec_file, overrides = _spec_of_command(command)
    assert spec_file.is_file(), f"{run_dir.name}: recorded command names a missing {spec_file}"
    want = derived["spec_hash"] if derived else info["spec_hash"]
    assert spec_hash(load_spec(spec_file, overrides)) == want
    if derived is None:
        assert named == spec_file
    own_overrides = overrides if named == spec_file and command[1] != "tune" else []
    assert spec_hash(load_spec(named, own_overrides)) == info["spec_hash"]


# ---- base: specs that state only what differs ---------------------------------------------
ROOT_SPEC = """\
name: root
seeds: [0, 1, 2]
algo:
  name: td3
  gradient_steps: 1
  policy_kwargs: {net_arch: [64, 64], activation_fn: relu}
training:
  total_timesteps: 100000
  checkpoint_interval: 50000
"""


def _chain(tmp_path: Path) -> tuple[Path, Path, Path]:
    """study/root.yaml ← variants/mid.yaml ← variants/leaf.yaml."""
    (tmp_path / "study").mkdir()
    (tmp_path / "variants").mkdir()
    root = write(tmp_path / "study", ROOT_SPEC, "root.yaml")
    mid = write(
        tmp_path / "variants",
        "base: ../study/root.yaml\nname: mid\nseeds: [0]\n"
        "algo:\n  policy_kwargs: {net_arch: [128, 128]}\n",
        "mid.yaml",
    )
    leaf = write(
        tmp_path / "variants",
        "# the leaf\nbase: mid.yaml\ntraining:\n  total_timesteps: 200000\n",
        "leaf.yaml",
    )
    return root, mid, leaf


def test_base_chain_deep_merges(tmp_path: Path) -> None:
    root, mid, leaf = _chain(tmp_path)
    spec = load_spec(leaf)
    assert spec.name == "leaf"  # name is not inherited: the file's own stem
    assert spec.seeds == [0]  # lists replace
    assert spec.algo.policy_kwargs.net_arch == [128, 128]
    assert spec.algo.policy_kwargs.activation_fn == "relu"  # mappings merge
    assert spec.training.total_timesteps == 200_000 and spec.training.checkpoint_interval == 50_000
    assert spec_chain(leaf) == [str(leaf), str(mid), str(root)]
    assert spec_chain(root) == [str(root)]
    flat = parse_spec(
        {
            "name": "leaf",
            "seeds": [0],
            "algo": {
                "name": "td3",
                "gradient_steps": 1,
                "policy_kwargs": {"net_arch": [128, 128], "activation_fn": "relu"},
            },
            "training": {"total_timesteps": 200_000, "checkpoint_interval": 50_000},
        }
    )
    assert load_spec(leaf) == flat and spec_hash(load_spec(leaf)) == spec_hash(flat)


def test_base_overrides_apply_after_the_chain(tmp_path: Path) -> None:
    _, _, leaf = _chain(tmp_path)
    spec = load_spec(leaf, ["training.total_timesteps=300000", "algo.policy_kwargs.net_arch=[32]"])
    assert spec.training.total_timesteps == 300_000 and spec.algo.policy_kwargs.net_arch == [32]


def test_base_relative_to_the_file_not_the_cwd(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, _, leaf = _chain(tmp_path)
    monkeypatch.chdir(tmp_path / "study")
    assert load_spec(Path("..") / "variants" / "leaf.yaml").algo.policy_kwargs.net_arch == [
        128,
        128,
    ]
    assert load_spec(leaf).name == "leaf"


BASE_ERRORS = {
    # name: (leaf text, mid text or None (keep), fragments, (file, line) of the error)
    "missing": (
        "base: nowhere.yaml\n",
        None,
        ["base:", "'nowhere.yaml'", "no such file", "relative to this file's directory"],
        ("variants/leaf.yaml", 1),
    ),
    "directory": ("base: ../study\n", None, ["base:", "is a directory"], ("variants/leaf.yaml", 1)),
    "not-a-path": (
        "base: [mid.yaml]\n",
        None,
        ["base:", "expected the path of another spec file"],
        ("variants/leaf.yaml", 1),
    ),
    "cycle": (
        "base: mid.yaml\n",
        "base: leaf.yaml\n",
        ["base:", "closes a cycle", "leaf.yaml → ", "remove base:"],
        ("variants/mid.yaml", 1),
    ),
    "self": (
        "name: x\nbase: leaf.yaml\n",
        None,
        ["base:", "closes a cycle"],
        ("variants/leaf.yaml", 2),
    ),
    "base-not-mapping": (
        "base: mid.yaml\n",
        "- 1\n- 2\n",
        ["top level must be a mapping", "got a list", "the base of"],
        ("variants/mid.yaml", 1),
    ),
    "base-empty": (
        "base: mid.yaml\n",
        "# nothing\n",
        ["top level must be a mapping", "empty document"],
        ("variants/mid.yaml", None),
    ),
    "bad-key-in-base": (
        "base: mid.yaml\n",
        "base: ../study/root.yaml\nalgo:\n  learnig_rate: 1\n",
        ["algo.learnig_rate:", "unknown field", "did you mean 'learning_rate'?"],
        ("variants/mid.yaml", 3),
    ),
    "bad-value-in-leaf": (
        "base: mid.yaml\nalgo:\n  tau: 2\n",
        None,
        ["algo.tau:", "out of range"],
        ("variants/leaf.yaml", 3),
    ),
    "malformed-base": (
        "base: mid.yaml\n",
        "algo: [\n",
        ["malformed YAML"],
        ("variants/mid.yaml", None),
    ),
    "misspelt-base": (
        "bsae: mid.yaml\n",
        None,
        ["bsae:", "did you mean 'base'?"],
        ("variants/leaf.yaml", 1),
    ),
}


@pytest.mark.faults("held")
@pytest.mark.parametrize("case", sorted(BASE_ERRORS))
def test_base_errors_are_one_line_naming_file_field_and_fix(tmp_path: Path, case: str) -> None:
    leaf_text, mid_text, fragments, (file, line) = BASE_ERRORS[case]
    _, mid, leaf = _chain(tmp_path)
    leaf.write_text(leaf_text, encoding="utf-8")
    if mid_text is not None:
        mid.write_text(mid_text, encoding="utf-8")
    with pytest.raises(SpecError) as info:
        load_spec(leaf)
    error, message = info.value, str(info.value)
    assert "\n" not in message and "; " in message
    assert error.file == str(tmp_path / file)
    if line is not None:
        assert error.line == line, message
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    result = runner.invoke(app, ["validate", str(leaf)])
    assert result.exit_code == 2 and result.stderr.strip() == f"error: {message}"


def test_parse_spec_rejects_base_in_data() -> None:
    with pytest.raises(SpecError, match="only a spec file can have a base"):
        parse_spec({"base": "x.yaml"})


def test_cli_validate_and_spec_show_the_chain(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _chain(tmp_path)
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["validate", "variants/leaf.yaml"])
    assert result.exit_code == 0
    assert result.stdout.splitlines() == [
        "ok: leaf, 1 run (seed 0): td3/centralized, 200,000 env steps each",
        "   base: variants/mid.yaml → study/root.yaml",
    ]
    result = runner.invoke(app, ["spec", "variants/leaf.yaml", "--set", "seeds=[4]"])
    assert result.exit_code == 0
    assert result.stdout.startswith(
        "# from variants/leaf.yaml\n#   base: variants/mid.yaml\n#   base: study/root.yaml\nname: leaf\n"
    )
    resolved = write(tmp_path, result.stdout, "resolved.yaml")  # stand-alone, without the bases
    assert load_spec(resolved) == load_spec("variants/leaf.yaml", ["seeds=[4]"])
    plain = runner.invoke(app, ["spec", "study/root.yaml"])
    assert plain.exit_code == 0 and plain.stdout.startswith("name: root\n")  # no chain, no comment


def test_run_spec_names_the_chain_and_loads_alone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from softtrack.store import RunStore

    _chain(tmp_path)
    monkeypatch.chdir(tmp_path)
    spec = load_spec("variants/leaf.yaml")
    record = RunStore(tmp_path / "runs").create_run(
        spec,
        0,
        [
            str(tmp_path / ".venv" / "bin" / "softtrack"),
            "train",
            str(tmp_path / "variants" / "leaf.yaml"),
            "--seed",
            "0",
        ],
        spec_files=[str(tmp_path / p) for p in spec_chain("variants/leaf.yaml")],
    )
    text = record.spec_path.read_text(encoding="utf-8")
    assert text.splitlines()[1:4] == [
        "# from variants/leaf.yaml",
        "#   base: variants/mid.yaml",
        "#   base: study/root.yaml",
    ]
    assert str(tmp_path) not in text
    info = json.loads(record.run_json_path.read_text(encoding="utf-8"))
    assert info["command"] == ["softtrack", "train", "variants/leaf.yaml", "--seed", "0"]
    for path in (tmp_path / "study" / "root.yaml", tmp_path / "variants" / "mid.yaml"):
        path.unlink()  # e.g. the run directory copied to another machine
    alone = load_spec(record.spec_path)
    assert alone == spec.with_seed(0) and spec_hash(alone) == info["spec_hash"] == spec_hash(spec)


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
def _rel(path: Path) -> str:
    return path.relative_to(REPO / "experiments").as_posix()


def test_experiments_exist() -> None:
    names = {_rel(p) for p in EXPERIMENTS}
    assert {
        "quickstart.yaml",
        "study/td3-64-1e7.yaml",
        "study/ddpg-64-1e7.yaml",
        "study/ppo-64-1e7.yaml",
        "study/independent-td3-64-1e7.yaml",
    } <= names
    assert {p.parent.name for p in EXPERIMENTS} == {"experiments", "study", "variants"}
    assert (REPO / "experiments" / "README.md").is_file()


def _budget(steps: int) -> str:
    """4000000 → "4e6", 1500000 → "15e5" (the budgets of the naming scheme)."""
    mantissa, exponent = f"{steps:e}".split("e")
    value, power = float(mantissa), int(exponent)
    while value != int(value):
        value, power = round(value * 10, 9), power - 1
    return f"{int(value)}e{power}"


def expected_file_stem(spec: ExperimentSpec) -> str:
    """The naming scheme of experiments/README.md: [independent-]algorithm[-backend]-network-
    budget, then the tags of the experiment's name that these do not already say; an MPC
    planner: mpc-method-samples x horizon."""
    if spec.controller == "mpc":
        head = ["mpc", spec.mpc.method, f"{spec.mpc.samples}x{spec.mpc.horizon}"]
        return "-".join(head + [t for t in spec.name.split("-") if t not in head])
    net = spec.algo.policy_kwargs.net_arch
    assert len(set(net)) == 1, net  # one width for every hidden layer
    head = [
        *(["independent"] if spec.controller == "independent" else []),
        spec.algo.name,
        *([spec.algo.backend] if spec.algo.backend != "sb3" else []),
        str(net[0]),
        _budget(spec.training.total_timesteps),
    ]
    tags = [t for t in spec.name.split("-") if t not in head]
    return "-".join(head + tags)


@pytest.mark.parametrize("path", EXPERIMENTS, ids=_rel)
def test_shipped_experiment_validates(path: Path) -> None:
    assert path.read_text(encoding="utf-8").startswith("#")  # explained at the top
    spec = load_spec(path)
    if path.name != "quickstart.yaml":
        assert path.stem == expected_file_stem(spec)
    result = runner.invoke(app, ["validate", str(path)])
    assert result.exit_code == 0 and result.stdout.startswith(f"ok: {spec.name}, ")
    assert _rel(path) in (REPO / "experiments" / "README.md").read_text(encoding="utf-8")


def test_experiment_names_are_unique() -> None:
    names = [load_spec(p).name for p in EXPERIMENTS]
    assert len(names) == len(set(names))


def _leaves(data: object, prefix: tuple[str, ...] = ()) -> dict[tuple[str, ...], object]:
    if isinstance(data, dict):
        out: dict[tuple[str, ...], object] = {}
        for key, value in data.items():
            out.update(_leaves(value, (*prefix, key)))
        return out
    return {prefix: data}


@pytest.mark.parametrize("path", EXPERIMENTS, ids=_rel)
def test_shipped_experiment_states_only_what_differs(path: Path) -> None:
    """A variant extends another spec and every value it sets differs from its base's; a
    study-protocol spec never extends a variant."""
    own, _ = read_spec_file(path)
    chain = [Path(p) for p in spec_chain(path)]
    if path.parent.name == "variants":
        assert "base" in own, "a variant states only what differs from its base"
    if path.parent.name == "study":
        assert all(p.parent.name == "study" for p in chain)
    if "base" not in own:
        return
    base = load_spec(chain[1]).model_dump(mode="json")
    stated = {k: v for k, v in own.items() if k not in ("base", "name", "tune")}  # tune: a search
    for key, value in _leaves(stated).items():
        resolved = base
        for part in key:
            resolved = resolved[part]
        assert value != resolved, f"{'.'.join(key)} restates its base's value {value!r}"


def test_study_protocol_files() -> None:
    for stem, algo in [
        ("td3-64-1e7", "td3"),
        ("ddpg-64-1e7", "ddpg"),
        ("ppo-64-1e7", "ppo"),
        ("independent-td3-64-1e7", "td3"),
    ]:
        spec = load_spec(REPO / "experiments" / "study" / f"{stem}.yaml")
        assert spec.algo.name == algo
        assert spec.seeds == [0, 1, 2]
        assert spec.training.total_timesteps == 10_000_000
        assert spec.env == ExperimentSpec().env
        assert spec.controller == (
            "independent" if stem.startswith("independent") else "centralized"
        )
    quick = load_spec(REPO / "experiments" / "quickstart.yaml")
    assert quick.seeds == [0] and quick.training.total_timesteps <= 100_000


def _hostile_spec(tmp_path: Path, kind: str) -> Path:
    """A spec path that is not a regular text file of spec size (or whose base is not)."""
    if kind == "fifo":
        path = tmp_path / "fifo.yaml"
        os.mkfifo(path)
        return path
    if kind == "device":
        return Path("/dev/zero")
    if kind == "proc":
        return Path("/proc/self/environ")
    if kind == "huge":
        path = tmp_path / "huge.yaml"
        path.write_text("name: x\n" + "# padding\n" * 120_000)
        return path
    path = tmp_path / "child.yaml"
    path.write_text("base: /dev/zero\nname: x\n")
    return path


@pytest.mark.faults("traceback")
@pytest.mark.parametrize(
    ("kind", "message"),
    [
        ("fifo", "is a FIFO, not a spec file"),
        ("device", "is a device, not a spec file"),
        ("proc", "holds NUL characters"),
        ("huge", "is larger than 1000 kB"),
        ("base-device", "is a device, not a spec file"),
    ],
)
def test_a_spec_that_is_no_regular_file_is_one_line_without_reading_it(
    tmp_path: Path, kind: str, message: str
) -> None:
    """A FIFO without a writer (hung `validate`), /dev/zero as a spec or a base (grew to
    ~20 GB), /proc/self/environ (a traceback), an oversized file: one line, exit 2, quickly,
    nothing of the file quoted."""
    path = _hostile_spec(tmp_path, kind)
    result = subprocess.run(
        [sys.executable, "-m", "softtrack.cli", "validate", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], lines
    assert "PATH=" not in result.stderr and "HOME=" not in result.stderr
