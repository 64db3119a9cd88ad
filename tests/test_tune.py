"""``softtrack tune`` (Optuna) with tiny trials on SQLite: the ``tune:`` section and its errors,
trials as runs, ``--status`` and ``--best``, continuing a study, pruning, two worker processes
pulling from one study, an interrupted study, and a trial whose worker died."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import optuna
import pytest
import yaml
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.executors.dispatch import select_resumable_runs
from softtrack.rl.validation import best_model
from softtrack.spec import load_spec, parse_spec, spec_hash, spec_to_yaml
from softtrack.store.runs import RunRecord, RunStore
from softtrack.store.tables import read_table
from softtrack.tune.study import (
    create_or_continue,
    default_storage,
    suggest,
    take_trial,
    top_up,
    trial_spec,
)

runner = CliRunner()

TUNE: dict[str, Any] = {
    "params": {
        "algo.learning_rate": {"type": "float", "low": 1.0e-4, "high": 3.0e-3, "log": True},
        "algo.batch_size": {"type": "categorical", "choices": [8, 16]},
        "algo.gradient_steps": {"type": "int", "low": 1, "high": 2},
        "algo.policy_kwargs.net_arch": {"type": "categorical", "choices": [[8, 8], [16, 16]]},
    },
}


def _data(tune: dict[str, Any] | None = None, **training: Any) -> dict[str, Any]:
    data: dict[str, Any] = {
        "name": "tiny",
        "seeds": [0],
        "env": {"episode_duration": 0.1},
        "algo": {
            "name": "td3",
            "device": "cpu",
            "batch_size": 16,
            "learning_starts": 50,
            "buffer_size": 5000,
            "policy_kwargs": {"net_arch": [16, 16]},
        },
        "training": {
            "total_timesteps": 400,
            "n_envs": 2,
            "checkpoint_interval": 200,
            "heartbeat_interval": 0.5,
            "validation_episodes": 1,
            "eval_duration": 0.1,
            **training,
        },
    }
    if tune is not None:
        data["tune"] = tune
    return data


def _spec(
    tmp_path: Path, tune: dict[str, Any] | None = None, name: str = "tiny", **training: Any
) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(
        yaml.safe_dump(_data(TUNE if tune is None else tune, **training)), encoding="utf-8"
    )
    return path


def _tune(*args: str) -> Any:
    return runner.invoke(app, ["tune", *args], env={"CI": "1"})


def _study(runs_dir: Path, name: str) -> Any:
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna.load_study(study_name=name, storage=default_storage(runs_dir))


def _states(study: Any) -> list[str]:
    return [t.state.name for t in study.get_trials()]


def _run_of(trial: Any, runs_dir: Path) -> RunRecord:
    return RunStore(runs_dir).get_run(trial.user_attrs["run_id"])


# ---- the tune: section (no training) ---------------------------------------------------------
def test_tune_section_leaves_the_hash_and_round_trips() -> None:
    plain = parse_spec(_data())
    tuned = parse_spec(_data(TUNE))
    assert tuned.tune is not None and spec_hash(tuned) == spec_hash(plain)
    assert "tune" not in spec_to_yaml(plain)  # no `tune: null` in every run's spec.yaml
    assert parse_spec(yaml.safe_load(spec_to_yaml(tuned))) == tuned
    assert tuned.tune.params["algo.gradient_steps"].low == 1  # an int range's ends are ints


@pytest.mark.parametrize(
    ("entry", "expected"),
    [
        (
            {"algo.learnig_rate": {"type": "float", "low": 1, "high": 2}},
            "tune.params.algo.learnig_rate: not a spec field",
        ),
        ({"algo.policy_kwargs": {"type": "categorical", "choices": [1]}}, "is a section"),
        ({"algo.learning_rate": {"type": "float", "low": 3e-3, "high": 1e-4}}, "low 0.003 ≥ high"),
        ({"algo.learning_rate": {"type": "flaot", "low": 1e-4, "high": 1e-3}}, "type 'flaot'"),
        ({"algo.learning_rate": {"type": "float", "lw": 1e-4, "high": 1e-3}}, "did you mean 'low'"),
        (
            {"algo.batch_size": {"type": "categorical", "choices": [8, 100000]}},
            "value 100000 makes an invalid spec",
        ),
        ({"algo.batch_size": {"type": "float", "low": 8, "high": 32}}, "expected a whole number"),
        ({"seeds": {"type": "int", "low": 0, "high": 3}}, "'seeds' cannot be tuned"),
        (
            {"training.validation_episodes": {"type": "int", "low": 0, "high": 2}},
            "training.validation_episodes is 0",
        ),
        ({}, "no params to search"),
    ],
)
def test_bad_tune_entries_are_one_line_errors(
    tmp_path: Path, entry: dict[str, Any], expected: str
) -> None:
    spec = _spec(tmp_path, {"params": entry})
    runs_dir = tmp_path / "runs"
    result = _tune(str(spec), "--trials", "1", "--runs-dir", str(runs_dir))
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0] and "Traceback" not in result.stderr
    assert lines[0].startswith(f"error: {spec}:")
    assert not runs_dir.exists()  # nothing written


def test_tune_needs_a_tune_section_and_a_mode(tmp_path: Path) -> None:
    plain = tmp_path / "plain.yaml"
    plain.write_text(yaml.safe_dump(_data()), encoding="utf-8")
    for args in (
        [str(plain), "--trials", "1"],
        [str(_spec(tmp_path))],
        [],
        ["--status", "x", "--best", "x"],
    ):
        result = _tune(*args, "--runs-dir", str(tmp_path / "runs"))
        assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1, args
    result = _tune("--status", "nope", "--runs-dir", str(tmp_path / "runs"))
    assert result.exit_code == 2 and "no study database" in result.stderr


# ---- trials are runs; status, best, continuing ------------------------------------------------
def test_trials_are_runs_and_the_best_spec_trains(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    spec = _spec(tmp_path)
    runs_dir = tmp_path / "runs"
    result = _tune(str(spec), "--trials", "2", "--study", "s", "--runs-dir", str(runs_dir))
    assert result.exit_code == 0, result.output
    study = _study(runs_dir, "s")
    assert _states(study) == ["COMPLETE", "COMPLETE"]
    tuned = load_spec(spec)
    for trial in study.get_trials():
        record = _run_of(trial, runs_dir)
        assert record.info.status == "completed" and record.info.name == f"tiny-t{trial.number}"
        assert record.info.notes["tune"]["study"] == "s"
        assert record.info.notes["tune"]["trial"] == trial.number
        assert trial.value == best_model(record.policy_dir()).score  # the objective
        assert sorted(trial.intermediate_values) == [200, 400]  # reported at each checkpoint
        # the run's spec: the tuned spec with the sampled values, without the tune section
        assert "tune" not in record.raw_spec()
        run_spec = record.load_spec()
        assert run_spec.algo.learning_rate == trial.params["algo.learning_rate"]
        assert run_spec.algo.batch_size == trial.params["algo.batch_size"]
        assert (
            json.dumps(run_spec.algo.policy_kwargs.net_arch, separators=(",", ":"))
            == trial.params["algo.policy_kwargs.net_arch"]
        )
        expected = tuned.model_copy(
            update={"name": record.info.name, "tune": None, "algo": run_spec.algo}
        )
        assert record.info.spec_hash == spec_hash(expected) == spec_hash(run_spec)

    status = _tune("--status", "s", "--runs-dir", str(runs_dir))
    assert status.exit_code == 0, status.output
    assert "2/2 finished" in status.stdout
    assert all(t.user_attrs["run_id"] in status.stdout for t in study.get_trials())

    out = tmp_path / "best" / "s-best.yaml"
    best = _tune("--best", "s", "--out", str(out), "--runs-dir", str(runs_dir))
    assert best.exit_code == 0, best.output
    text = out.read_text(encoding="utf-8")
    assert text.startswith("# Best trial of study s") and "base: ../tiny.yaml" in text
    winner = min(study.get_trials(), key=lambda t: t.value)
    assert f"): trial {winner.number}, run {winner.user_attrs['run_id']}," in text
    best_spec = load_spec(out)
    assert best_spec.tune is None
    assert spec_hash(best_spec) == _run_of(winner, runs_dir).info.spec_hash
    trained = runner.invoke(
        app, ["train", str(out), "--runs-dir", str(tmp_path / "again")], env={"CI": "1"}
    )
    assert trained.exit_code == 0, trained.output
    again = RunStore(tmp_path / "again").get_run(trained.stdout.strip())
    assert again.info.status == "completed"
    assert again.info.spec_hash == _run_of(winner, runs_dir).info.spec_hash

    # from another checkout (a clone holding the same tuned spec): the best spec names the
    # clone's file, and the study's database relative to the working directory, so that the
    # written file has no machine path and stays valid where it is committed
    clone = tmp_path / "clone"
    clone.mkdir()
    (clone / spec.name).write_text(spec.read_text(encoding="utf-8"), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    best = _tune("--best", "s", "--out", "clone/s-best.yaml", "--runs-dir", "runs")
    assert best.exit_code == 0, best.output
    text = (clone / "s-best.yaml").read_text(encoding="utf-8")
    assert f"base: {spec.name}" in text and "# storage: sqlite:///runs/optuna.db" in text
    assert str(tmp_path) not in text
    assert spec_hash(load_spec(clone / "s-best.yaml")) == _run_of(winner, runs_dir).info.spec_hash

    # continuing the study: one more trial, exactly
    result = _tune(str(spec), "--trials", "3", "--study", "s", "--runs-dir", str(runs_dir))
    assert result.exit_code == 0, result.output
    assert _states(_study(runs_dir, "s")) == ["COMPLETE"] * 3
    # ... but not with another search space
    other = _spec(
        tmp_path,
        {"params": {"algo.tau": {"type": "float", "low": 0.01, "high": 0.02}}},
        name="other",
    )
    result = _tune(str(other), "--trials", "3", "--study", "s", "--runs-dir", str(runs_dir))
    assert result.exit_code == 2 and "tunes another spec" in result.stderr


def test_a_trial_of_several_seeds_scores_their_aggregate(tmp_path: Path) -> None:
    """``tune.seeds_per_trial: 2`` trains seeds 0 and 1 with the trial's values; the trial's
    value is the mean (or IQM) of the two runs' best validation scores, and only the first run
    reports to the pruner."""
    tune = {**TUNE, "seeds_per_trial": 2, "aggregate": "iqm"}
    spec = _spec(tmp_path, tune)
    runs_dir = tmp_path / "runs"
    result = _tune(str(spec), "--trials", "1", "--study", "m", "--runs-dir", str(runs_dir))
    assert result.exit_code == 0, result.output
    (trial,) = _study(runs_dir, "m").get_trials()
    assert trial.state.name == "COMPLETE"
    store = RunStore(runs_dir)
    runs = [store.get_run(trial.user_attrs[k]) for k in ("run_id", "run_id_1")]
    assert [r.info.seed for r in runs] == [0, 1]
    assert runs[0].info.spec_hash == runs[1].info.spec_hash  # the same values
    scores = [best_model(r.policy_dir()).score for r in runs]
    assert trial.value == pytest.approx(sum(scores) / 2)  # the IQM of two values is their mean
    assert sorted(trial.intermediate_values) == [200, 400]  # the first run's checkpoints only
    assert "run 2 of 2" in result.output


def test_multi_seed_fields_leave_old_studies_continuable() -> None:
    from softtrack.tune.study import _search_key

    plain = parse_spec(_data(TUNE))
    explicit = parse_spec(_data({**TUNE, "seeds_per_trial": 1, "aggregate": "mean"}))
    assert _search_key(plain) == _search_key(explicit)
    assert _search_key(parse_spec(_data({**TUNE, "seeds_per_trial": 3}))) != _search_key(plain)


def test_pruned_trials_stop_their_runs(tmp_path: Path) -> None:
    """A pruner that prunes at the first report (every score is above 1e-9 m)."""
    tune = {**TUNE, "pruner": {"type": "threshold", "upper": 1e-9}}
    runs_dir = tmp_path / "runs"
    result = _tune(
        str(_spec(tmp_path, tune)), "--trials", "2", "--study", "p", "--runs-dir", str(runs_dir)
    )
    assert result.exit_code == 0, result.output
    study = _study(runs_dir, "p")
    assert _states(study) == ["PRUNED", "PRUNED"]
    for trial in study.get_trials():
        assert list(trial.intermediate_values) == [200]
        record = _run_of(trial, runs_dir)
        assert record.info.status == "interrupted" and record.info.global_step < 400
        assert record.info.notes["pruned"]["global_step"] == 200
        assert record.list_checkpoints()  # stopped cleanly: resumable by id
        assert set(read_table(record.table_path("validation"))["global_step"]) == {200}
    assert select_resumable_runs(RunStore(runs_dir), []) == []  # not resumed by default
    status = _tune("--status", "p", "--runs-dir", str(runs_dir))
    assert "pruned at step 200" in status.stdout


# ---- workers ------------------------------------------------------------------------------------
def test_two_workers_pull_from_one_study(tmp_path: Path) -> None:
    runs_dir = tmp_path / "runs"
    result = _tune(
        str(_spec(tmp_path)),
        "--trials",
        "3",
        "--study",
        "w",
        "--workers",
        "2",
        "--runs-dir",
        str(runs_dir),
    )
    assert result.exit_code == 0, result.output
    study = _study(runs_dir, "w")
    assert _states(study) == ["COMPLETE"] * 3  # exactly the trials asked for
    run_ids = {t.user_attrs["run_id"] for t in study.get_trials()}
    assert len(run_ids) == 3 and {r.run_id for r in RunStore(runs_dir).list_runs()} == run_ids
    pids = {int(t.user_attrs["worker"].split(":")[1]) for t in study.get_trials()}
    assert os.getpid() not in pids  # trained by the worker processes
    logs = [(runs_dir / f"tune-w-w{k}.log").read_text(encoding="utf-8") for k in (0, 1)]
    finished = [line for log in logs for line in log.splitlines() if " finished: " in line]
    assert len(finished) == 3  # each trial's training reports its progress in its worker's log
    assert "3/3 finished" in result.stderr


@pytest.mark.faults("held")
def test_interrupted_study_resumes_its_run(tmp_path: Path) -> None:
    """SIGINT during a trial: the trial fails as interrupted, its run is interrupted with a
    checkpoint, and `softtrack tune` again resumes that run under a retry trial."""
    spec = _spec(tmp_path, total_timesteps=1600, n_envs=4)
    runs_dir = tmp_path / "runs"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "softtrack.cli",
            "tune",
            str(spec),
            "--trials",
            "1",
            "--study",
            "i",
            "--runs-dir",
            str(runs_dir),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "CI": "1"},
        start_new_session=True,
    )
    deadline = time.monotonic() + 120
    record = None
    while time.monotonic() < deadline and record is None:
        assert proc.poll() is None, proc.communicate()
        for r in RunStore(runs_dir).list_runs():
            if r.info.status == "running" and r.list_checkpoints():
                record = r
        time.sleep(0.05)
    assert record is not None
    os.kill(proc.pid, signal.SIGINT)
    _out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    study = _study(runs_dir, "i")
    first, retry = study.get_trials()
    assert first.state.name == "FAIL" and "interrupted" in first.user_attrs["interrupted"]
    assert retry.state.name == "WAITING" and retry.user_attrs["retry_of"] == 0
    assert retry.user_attrs["run_id"] == record.run_id
    assert RunStore(runs_dir).get_run(record.run_id).info.status == "interrupted"

    result = _tune(str(spec), "--trials", "1", "--study", "i", "--runs-dir", str(runs_dir))
    assert result.exit_code == 0, result.output
    assert _states(_study(runs_dir, "i")) == ["FAIL", "COMPLETE"]
    done = RunStore(runs_dir).get_run(record.run_id)
    assert done.info.status == "completed" and done.info.global_step >= 1600
    assert done.info.notes["tune"]["trials"] == [0, 1]
    rows = read_table(done.table_path("validation"))
    assert rows.groupby(["global_step", "episode", "arm"]).size().max() == 1  # validated once
    assert set(rows["global_step"]) == set(range(200, 1601, 200))
    assert len(RunStore(runs_dir).list_runs()) == 1
    best = _tune("--best", "i", "--out", str(tmp_path / "i-best.yaml"), "--runs-dir", str(runs_dir))
    assert best.exit_code == 0, best.output
    header = (tmp_path / "i-best.yaml").read_text(encoding="utf-8").splitlines()[0]
    assert header.endswith(
        f"(softtrack tune, 1 trial): trial 1 (a retry of trial 0), run {record.run_id},"
    )


def _trial_with_running_run(
    spec_path: Path, runs_dir: Path, study: str
) -> tuple[Any, RunStore, Any, RunRecord]:
    """A one-trial study whose only trial a worker took and whose run it marked running, as
    a worker does before training: the study, the run store, the trial and its run."""
    spec = load_spec(spec_path)
    ts = create_or_continue(
        default_storage(runs_dir), study, spec, [str(spec_path)], str(spec_path)
    )
    store = RunStore(runs_dir)
    assert top_up(ts, store, 1) == 1
    trial = take_trial(ts, store)
    assert trial is not None
    record = store.create_run(trial_spec(ts, suggest(trial, ts.tune), "tiny-t0"), 0)
    trial.set_user_attr("run_id", record.run_id)
    store.mark_running(record.run_id)
    return ts, store, trial, record


@pytest.mark.faults("held")
def test_dead_workers_trial_is_failed_and_retried(tmp_path: Path) -> None:
    """A trial left RUNNING by a killed worker (its run `lost`: the pid is gone) is failed and
    retried by the next `softtrack tune`, which resumes its run; it is not counted."""
    spec_path = _spec(tmp_path)
    runs_dir = tmp_path / "runs"
    ts, store, trial, record = _trial_with_running_run(spec_path, runs_dir, "d")  # a worker's
    assert take_trial(ts, store) is None  # no second ticket
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    store.update_run(record.run_id, pid=dead.pid)
    trial.set_user_attr("worker", f"{socket.gethostname()}:{dead.pid}")  # it died

    result = _tune(str(spec_path), "--trials", "1", "--study", "d", "--runs-dir", str(runs_dir))
    assert result.exit_code == 0, result.output
    study = _study(runs_dir, "d")
    first, retry = study.get_trials()
    assert first.state.name == "FAIL" and "worker died" in first.user_attrs["failure"]
    assert retry.state.name == "COMPLETE" and retry.user_attrs["retry_of"] == 0
    assert retry.user_attrs["run_id"] == record.run_id and retry.user_attrs["deaths"] == 1
    assert store.get_run(record.run_id).info.status == "completed"
    assert len(store.list_runs()) == 1
    status = _tune("--status", "d", "--runs-dir", str(runs_dir))
    assert status.exit_code == 0, status.output
    row = next(line for line in status.stdout.splitlines() if line.startswith("0 "))
    assert row.split()[1] == "fail" and row.endswith(
        f"its worker died (run {record.run_id} lost); retried as 1"
    )


def test_status_shows_how_far_a_running_trial_has_trained(tmp_path: Path) -> None:
    spec_path = _spec(tmp_path)
    runs_dir = tmp_path / "runs"
    _, store, _, record = _trial_with_running_run(spec_path, runs_dir, "s")
    store.heartbeat(record.run_id, global_step=1234)
    status = _tune("--status", "s", "--runs-dir", str(runs_dir))
    assert status.exit_code == 0, status.output
    row = next(line for line in status.stdout.splitlines() if line.startswith("0 "))
    total = load_spec(spec_path).training.total_timesteps
    assert row.split()[1] == "running" and row.endswith(f"training at step 1,234 of {total:,}")


@pytest.mark.slow
def test_slurm_preempted_worker_is_requeued_and_resumes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """submitit's local executor: the preemption signal stops the worker (its trial fails as
    interrupted, with a retry); the requeued job takes the retry and resumes the run."""
    pytest.importorskip("submitit")
    monkeypatch.setenv("SOFTTRACK_SUBMITIT_CLUSTER", "local")
    runs_dir = tmp_path / "runs"
    spec = _spec(tmp_path, total_timesteps=3000, n_envs=4)
    result = _tune(
        str(spec),
        "--trials",
        "1",
        "--study",
        "q",
        "--executor",
        "slurm",
        "--detach",
        "--time",
        "10",
        "--runs-dir",
        str(runs_dir),
    )
    assert result.exit_code == 0, result.output
    deadline = time.monotonic() + 120
    record = None
    while record is None and time.monotonic() < deadline:
        record = next(
            (
                r
                for r in RunStore(runs_dir).list_runs()
                if r.info.status == "running" and r.list_checkpoints()
            ),
            None,
        )
        time.sleep(0.1)
    assert record is not None
    stat = Path(f"/proc/{record.info.pid}/stat").read_text()
    os.kill(int(stat.rsplit(")", 1)[1].split()[1]), signal.SIGUSR2)  # to the submitit task
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and "COMPLETE" not in _states(_study(runs_dir, "q")):
        time.sleep(0.5)
    study = _study(runs_dir, "q")
    assert _states(study) == ["FAIL", "COMPLETE"]
    assert study.get_trials()[1].user_attrs["run_id"] == record.run_id
    done = RunStore(runs_dir).get_run(record.run_id)
    assert done.info.status == "completed" and done.info.global_step >= 3000
    assert [s["status"] for s in done.info.sessions] == ["interrupted", "completed"]
