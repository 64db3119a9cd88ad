"""The runs shipped under models/ stay lean: within 60 MB, and per-step tables
only where the report draws them (experiments/reproduce_study.py ``KEEP_STEPS``)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "experiments"))
from reproduce_study import FEATURED, KEEP_STEPS, lean, lean_validation  # noqa: E402

from softtrack.evaluation import EVAL_TRAJECTORIES  # noqa: E402
from softtrack.evaluation.episode_tables import VALIDATION_SCORED_COLUMNS, validation_score  # noqa: E402
from softtrack.report.data import Group, episode_rmse, load_runs, representative_run  # noqa: E402
from softtrack.store.runs import RunStore  # noqa: E402
from softtrack.store.selection import select_one_run  # noqa: E402
from softtrack.store.tables import read_table, write_table  # noqa: E402

MODELS_BUDGET = 60 * 1000 * 1000  # bytes of models/ in the tree
PER_STEP_TABLES = ("eval_trajectories", "eval_moments")


def _shipped_runs() -> list[Path]:
    return sorted(p.parent for p in (ROOT / "models").glob("*/run.json"))


def _tracked_models_bytes() -> int:
    listed = subprocess.run(
        ["git", "ls-files", "-z", "models"], cwd=ROOT, capture_output=True, check=True
    ).stdout
    paths = [ROOT / name for name in listed.decode().split("\0") if name]
    return sum(p.stat().st_size for p in paths if p.is_file())


def test_models_fit_their_budget() -> None:
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    assert _tracked_models_bytes() <= MODELS_BUDGET


def test_per_step_tables_only_where_the_report_draws_them() -> None:
    """A shipped run outside ``KEEP_STEPS`` has no per-step tables; every run of a featured
    experiment (the report's trajectory and moment figures) has both."""
    runs = _shipped_runs()
    assert runs, "no shipped runs under models/"
    for run in runs:
        name = json.loads((run / "run.json").read_text(encoding="utf-8"))["name"]
        present = {t for t in PER_STEP_TABLES if (run / "tables" / f"{t}.parquet").is_file()}
        if name not in KEEP_STEPS:
            assert not present, f"{run.name}: {sorted(present)} (run `lean` on it)"
        elif name in FEATURED:
            assert present == set(PER_STEP_TABLES), f"{run.name} lacks per-step tables"


def test_lean_drops_the_per_step_tables_of_undrawn_experiments(tmp_path: Path) -> None:
    for name, kept in (("some-undrawn-experiment", False), (FEATURED[0], True)):
        tables = tmp_path / name / "tables"
        tables.mkdir(parents=True)
        for table in (*PER_STEP_TABLES, "eval_metrics", "eval_moment_peaks"):
            (tables / f"{table}.parquet").write_bytes(b"x")
        lean(tmp_path / name, name)
        left = {p.stem for p in tables.iterdir()}
        expected = {"eval_metrics", "eval_moment_peaks"} | (set(PER_STEP_TABLES) if kept else set())
        assert left == expected


LEAN_VALIDATION_COLUMNS = {"run_id", "seed", "wall_time", *VALIDATION_SCORED_COLUMNS}


def test_shipped_validation_tables_are_lean() -> None:
    """Every shipped validation table holds only what scores and the report read (the full
    per-axis, action and contact columns stay in the run under ``runs/``)."""
    for run in _shipped_runs():
        path = run / "tables" / "validation.parquet"
        if path.is_file():
            extra = set(read_table(path).columns) - LEAN_VALIDATION_COLUMNS
            assert not extra, f"{run.name}: {sorted(extra)} (run `lean_validation` on it)"


def test_lean_validation_keeps_what_scores_and_the_report_read(tmp_path: Path) -> None:
    """A shipped transport run's validation table with the per-axis and contact columns a
    training writes, trimmed to the scored columns: the same validation score at every
    checkpoint and the same report rows, in a fraction of the bytes."""
    source = ROOT / "models" / "td3-sbx-128-mirror-fast-transport-fine-10ms-long-gravity-3e6-seed2"
    run = tmp_path / source.name
    shutil.copytree(source, run)
    path = run / "tables" / "validation.parquet"
    shipped = read_table(path)
    rng = np.random.default_rng(0)
    extra = ("rmse_x", "rmse_y", "rmse_z", "mae_x", "mae_y", "mae_z", "max_contact_force")
    full = shipped.assign(**{c: rng.random(len(shipped)) for c in extra})
    write_table(path, full)
    full_bytes = path.stat().st_size
    lean_validation(run)
    trimmed = read_table(path)
    assert set(trimmed.columns) == LEAN_VALIDATION_COLUMNS
    assert path.stat().st_size < full_bytes / 2
    pd.testing.assert_frame_equal(trimmed, shipped[list(trimmed.columns)])
    for step, rows in full.groupby("global_step"):
        kept = trimmed[trimmed["global_step"] == step]
        assert validation_score(kept, 12.0) == validation_score(rows, 12.0)
    original, lean_run = load_runs([select_one_run(str(source)), select_one_run(str(run))])
    assert lean_run.validation is not None and original.validation is not None
    pd.testing.assert_frame_equal(lean_run.validation, original.validation)


def test_an_independent_run_with_contact_is_derived_from_its_nominal_training() -> None:
    """Contact acts in an independent run's dual-arm evaluation only, so its training fields
    are the nominal run's; a centralized run with contact trains differently."""
    from reproduce_study import _evaluation_only_changes, _training_fields, load_experiment

    nominal = load_experiment("variants/independent-td3-sbx-128-15e5-tta.yaml")
    solid = load_experiment("variants/independent-td3-sbx-128-15e5-tta-solid.yaml")
    assert solid.env.physics.contact_k > 0 == nominal.env.physics.contact_k
    assert _training_fields(solid) == _training_fields(nominal)
    assert _evaluation_only_changes(solid, nominal) == [
        "env.physics.contact_k",
        "env.physics.contact_nu",
    ]
    centralized = load_experiment("variants/td3-sbx-128-3e6-mirror-tta.yaml")
    centralized_solid = load_experiment("variants/td3-sbx-128-3e6-mirror-tta-solid.yaml")
    assert _training_fields(centralized_solid) != _training_fields(centralized)
    assert _evaluation_only_changes(centralized_solid, centralized) == []


def test_shipped_policies_list_the_other_models_they_have() -> None:
    """Each shipped ``policy.json`` names exactly the other models beside the policy, and only
    the experiments whose models a derived run confirmed keep any (``lean``)."""
    from reproduce_study import keeps_other_models

    for manifest in sorted((ROOT / "models").rglob("policy.json")):
        listed = json.loads(manifest.read_text(encoding="utf-8")).get("other_models", {})
        present = sorted(p.name for p in (manifest.parent / "other_models").glob("*"))
        assert sorted(listed) == present, manifest
        for entry in listed.values():
            assert (manifest.parent / entry["path"]).is_file(), manifest
        run = next(p for p in manifest.parents if (p / "run.json").is_file())
        name = json.loads((run / "run.json").read_text(encoding="utf-8"))["name"]
        assert not present or keeps_other_models(name), manifest
    assert keeps_other_models("td3-sbx-128-mirror-val") and not keeps_other_models(
        "td3-sbx-128-mirror-fast"
    )


def test_an_unknown_only_name_is_one_line_and_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    from reproduce_study import main

    with pytest.raises(SystemExit) as stop:
        main(["--only", "no-such-experiment", "--list"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "no-such-experiment" in err and len(err.strip().splitlines()) == 1


def test_the_runs_the_report_draws_keep_their_per_step_tables() -> None:
    """Where only some runs of an experiment keep their per-step tables (reproduce_study's
    ``lean_undrawn_steps``), the median seed of every trajectory, over all its runs, is one of
    them: the report draws the same run as with every table present."""
    by_name: dict[str, list[Path]] = {}
    for run in _shipped_runs():
        name = json.loads((run / "run.json").read_text(encoding="utf-8"))["name"]
        if name in KEEP_STEPS and name not in FEATURED:
            by_name.setdefault(name, []).append(run)
    assert by_name
    for name, dirs in by_name.items():
        runs = load_runs(select_one_run(str(d)) for d in dirs)
        group = Group("", "", name, "", name, name, tuple(runs))
        for trajectory in EVAL_TRAJECTORIES:
            scored = sorted(
                (v, r.seed) for r in runs if np.isfinite(v := episode_rmse(r, trajectory))
            )
            drawn = representative_run(group, trajectory)
            if not scored or drawn is None:
                continue
            assert drawn.seed == scored[(len(scored) - 1) // 2][1], (name, trajectory)


def test_a_job_that_a_tune_trial_trained_is_derived_from_it(tmp_path: Path) -> None:
    """The tuned transport recipe's seed 0 trains exactly like the tune's trial 0 (the tune's
    seed), so the script derives it from that completed run, without its checkpoints and its
    study notes; a run that trained otherwise, or one not completed, is not a twin."""
    import reproduce_study as rs

    from softtrack.spec import spec_hash
    from softtrack.store.runs import RunStore

    dest = "td3-sbx-128-mirror-fast-transport-fine-10ms-tuned-15e5-seed"
    job0, job1 = (next(j for j in rs.JOBS if j.dest == f"{dest}{s}") for s in (0, 1))
    spec = rs.load_experiment(job0.spec)
    store = RunStore(tmp_path / "runs")
    trial = spec.model_copy(update={"name": f"{spec.name}-tune-t0"})
    storage = {"study": "transport-10ms", "trial": 0, "storage": "sqlite:////abs/optuna.db"}
    twin = store.create_run(trial, 0, status="completed", notes={"tune": storage})
    (twin.path / "checkpoints" / "step-000001500000").mkdir(parents=True)
    (twin.path / "model.zip").write_bytes(b"model")
    store.create_run(trial, 1, status="interrupted")
    other_values = spec.model_copy(
        update={"name": f"{spec.name}-tune-t1", "algo": spec.algo.model_copy(update={"tau": 0.01})}
    )
    store.create_run(other_values, 1, status="completed")

    found = rs._trained_twin(job0, store.root)
    assert found is not None and found.run_id == twin.run_id
    assert rs._trained_twin(job1, store.root) is None  # the seed-1 trial is not completed
    run_id = rs.derive_run(job0, store.root, found)
    derived = store.get_run(run_id)
    assert derived.info.name == spec.name and derived.info.status == "completed"
    assert derived.info.spec_hash == spec_hash(spec.with_seed(0))
    assert (derived.path / "model.zip").read_bytes() == b"model"
    assert not (derived.path / "checkpoints").exists()
    assert "tune" not in derived.info.notes
    assert derived.info.notes["derived_from"] == {
        "run_id": twin.run_id,
        "name": trial.name,
        "spec_hash": twin.info.spec_hash,
        "why": "the same training under another name",
    }
    assert rs._existing_run(job0, store.root) == (run_id, "completed")
    assert rs._trained_twin(job0, store.root) is not None  # still, but the job now has its run


def test_every_shipped_run_is_finished_or_says_why_not() -> None:
    """A shipped run is completed, or its run.json's ``notes.incomplete`` says why it stopped
    early (and ``softtrack resume`` leaves it alone)."""
    from softtrack.executors.dispatch import resumable

    store = RunStore(ROOT / "models")
    unexplained = [
        (r.path.name, r.info.status)
        for r in store.list_runs()
        if r.info.status != "completed" and not (r.info.notes or {}).get("incomplete")
    ]
    assert unexplained == []
    assert not [r.path.name for r in store.list_runs() if resumable(r)]
