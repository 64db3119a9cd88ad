"""A tuning study in the report (``softtrack report --study NAME``): the study read into the
report's view (axes, trials, Optuna's parameter importance), its Markdown section, the
parallel-coordinates data, and the command end to end on a study whose trials were told their
scores without training (no training here: the trials' runs are created, not trained)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml
from typer.testing import CliRunner

from softtrack.cli import app
from softtrack.report.document import Doc
from softtrack.report.tune_view import TuneAxis, _payload, _position, tune_section
from softtrack.spec import load_spec
from softtrack.store.runs import RunStore
from softtrack.tune.study import create_or_continue, default_storage, suggest
from softtrack.tune.view import MIN_TRIALS_FOR_IMPORTANCE, load_view

runner = CliRunner()

PARAMS: dict[str, Any] = {
    "algo.learning_rate": {"type": "float", "low": 1.0e-4, "high": 1.0e-2, "log": True},
    "algo.batch_size": {"type": "categorical", "choices": [8, 16, 32]},
    "algo.policy_kwargs.net_arch": {"type": "categorical", "choices": [[8, 8], [16, 16]]},
}


def _spec_file(tmp_path: Path) -> Path:
    data = {
        "name": "tiny",
        "seeds": [0],
        "env": {"episode_duration": 0.1},
        "algo": {"name": "td3", "batch_size": 16, "learning_starts": 50, "buffer_size": 5000},
        "training": {
            "total_timesteps": 400,
            "checkpoint_interval": 200,
            "validation_episodes": 1,
            "eval_duration": 0.1,
        },
        "tune": {"seed": 0, "n_startup_trials": 20, "params": PARAMS},
    }
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _told_study(tmp_path: Path, complete: int, pruned: int = 1) -> tuple[Path, list[float]]:
    """A study ``s`` in ``tmp_path/runs`` with ``complete`` trials told a score that depends on
    the learning rate only, ``pruned`` pruned ones, one failed; each trial has a created run."""
    import optuna

    runs_dir = tmp_path / "runs"
    spec = load_spec(_spec_file(tmp_path))
    ts = create_or_continue(default_storage(runs_dir), "s", spec, [], None)
    store = RunStore(runs_dir)
    scores = []
    for k in range(complete + pruned + 1):
        trial = ts.study.ask()
        values = suggest(trial, ts.tune)
        record = store.create_run(spec, 0)
        trial.set_user_attr("run_id", record.run_id)
        score = 0.05 + abs(float(values["algo.learning_rate"]) - 1e-3) * 10
        if k < complete:
            ts.study.tell(trial, score)
            scores.append(score)
        elif k < complete + pruned:
            trial.report(score + 0.1, 200)
            ts.study.tell(trial, state=optuna.trial.TrialState.PRUNED)
        else:
            ts.study.tell(trial, state=optuna.trial.TrialState.FAIL)
    return runs_dir, scores


def test_the_view_holds_every_trial_and_ranks_the_parameter_that_matters(
    tmp_path: Path,
) -> None:
    runs_dir, scores = _told_study(tmp_path, complete=12)
    view = load_view("s", storage=None, runs_dir=runs_dir)
    axes = {a.path: a for a in view.axes}
    assert sorted(axes) == sorted(PARAMS)
    assert axes["algo.batch_size"].choices == ("8", "16", "32")
    assert axes["algo.policy_kwargs.net_arch"].choices == ("[8,8]", "[16,16]")
    assert [view.count(s) for s in ("COMPLETE", "PRUNED", "FAIL")] == [12, 1, 1]
    assert view.best()[0].score == pytest.approx(min(scores))
    pruned = next(t for t in view.trials if t.state == "PRUNED")
    assert pruned.step == 200 and pruned.score is not None
    # the score depends on the learning rate alone: Optuna ranks it first
    assert view.importance[0][0] == "algo.learning_rate"
    assert sum(share for _, share in view.importance) == pytest.approx(1.0)

    doc = Doc()
    tune_section(doc, [view])
    text = doc.markdown()
    assert "## Tuning study s" in text and "12 complete, 1 pruned, 1 failed" in text
    assert f"| {view.best()[0].number} | {min(scores):.4f} |" in text

    payload = _payload(view)
    assert [a["label"] for a in payload["axes"]] == [
        *(a.path.rsplit(".", 1)[-1] for a in view.axes),
        "score (m)",
    ]
    drawn = payload["trials"]
    assert len(drawn) == 13  # complete and pruned; the failed trial has no score
    best = next(t for t in drawn if t["number"] == view.best()[0].number)
    assert best["points"][-1] == 1.0 and best["shade"] == 0.0


def test_too_few_trials_for_importance_say_so(tmp_path: Path) -> None:
    runs_dir, _ = _told_study(tmp_path, complete=MIN_TRIALS_FOR_IMPORTANCE - 1)
    view = load_view("s", storage=None, runs_dir=runs_dir)
    assert view.importance == ()
    assert f"at least {MIN_TRIALS_FOR_IMPORTANCE} complete trials" in view.importance_note


def test_axis_positions() -> None:
    log_axis = TuneAxis("algo.learning_rate", "float", True, 1e-4, 1e-2)
    assert _position(log_axis, 1e-3) == pytest.approx(0.5)
    assert _position(log_axis, 1e-4) == 0.0 and _position(log_axis, 1.0) == 1.0
    choices = TuneAxis("algo.batch_size", "categorical", False, None, None, ("8", "16", "32"))
    assert [_position(choices, c) for c in ("8", "16", "32", "64")] == [0.0, 0.5, 1.0, None]


def test_report_of_a_study(tmp_path: Path) -> None:
    runs_dir, _ = _told_study(tmp_path, complete=5)
    out = tmp_path / "report"
    result = runner.invoke(
        app, ["report", "--study", "s", "--runs-dir", str(runs_dir), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    text = (out / "index.md").read_text(encoding="utf-8")
    assert "## Tuning study s" in text and "Parameter importance" in text
    # every trial's run is in the report's runs table
    for record in RunStore(runs_dir).list_runs():
        assert record.run_id in text


def test_an_unknown_study_is_one_line(tmp_path: Path) -> None:
    runs_dir, _ = _told_study(tmp_path, complete=1)
    result = runner.invoke(
        app, ["report", "--study", "nope", "--runs-dir", str(runs_dir), "--out", str(tmp_path)]
    )
    assert result.exit_code == 2
    assert "no study 'nope'" in result.output and "studies there: s" in result.output
    assert len(result.output.strip().splitlines()) == 1
