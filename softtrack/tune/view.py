"""A study read for the report (``softtrack report --study NAME``): its search space, trials
and the parameters' importance by Optuna's own evaluator, as the plain
:class:`~softtrack.report.tune_view.TuneView` the report draws."""

from __future__ import annotations

import math
import os
from typing import Any

from softtrack.report.tune_view import TuneAxis, TuneTrial, TuneView
from softtrack.spec.tune_models import choice_key
from softtrack.tune.study import TuneStudy, default_storage, load_study, optuna_module, trial_runs

__all__ = ["load_view", "study_view"]

#: Complete trials Optuna's importance evaluator needs before its answer means something.
MIN_TRIALS_FOR_IMPORTANCE = 4


def _axes(ts: TuneStudy) -> tuple[TuneAxis, ...]:
    axes = []
    for path, p in ts.tune.params.items():
        choices = (
            tuple(str(choice_key(c)) for c in p.choices or ()) if p.type == "categorical" else ()
        )
        low = None if p.low is None else float(p.low)
        high = None if p.high is None else float(p.high)
        axes.append(TuneAxis(path, p.type, bool(p.log), low, high, choices))
    return tuple(axes)


def _trial(t: Any, axes: tuple[TuneAxis, ...]) -> TuneTrial:
    score = t.value
    step = max(t.intermediate_values) if t.intermediate_values else None
    if score is None and step is not None:
        score = t.intermediate_values[step]
    values: dict[str, float | str] = {}
    for axis in axes:
        if axis.path not in t.params:
            continue
        raw = t.params[axis.path]
        values[axis.path] = str(raw) if axis.kind == "categorical" else float(raw)
    finite = score is not None and math.isfinite(score)
    return TuneTrial(
        number=int(t.number),
        state=t.state.name,
        score=float(score) if finite else None,
        step=None if step is None else int(step),
        values=values,
        run_id=trial_runs(t).get("run_id"),
    )


def _importance(ts: TuneStudy) -> tuple[tuple[tuple[str, float], ...], str, str]:
    """(path, share) largest first, the evaluator's description, and why there is none."""
    optuna = optuna_module()
    method = "Optuna's PedAnovaImportanceEvaluator over the complete trials"
    complete = ts.trials("COMPLETE")
    if len(complete) < MIN_TRIALS_FOR_IMPORTANCE:
        return (
            (),
            method,
            (
                f"needs at least {MIN_TRIALS_FOR_IMPORTANCE} complete trials "
                f"(the study has {len(complete)})"
            ),
        )
    try:
        shares = optuna.importance.get_param_importances(
            ts.study, evaluator=optuna.importance.PedAnovaImportanceEvaluator()
        )
    except (ValueError, RuntimeError) as exc:
        return (), method, f"Optuna could not compute it ({str(exc).splitlines()[0]})"
    total = sum(shares.values())
    if not shares or not total > 0:
        return (), method, "every parameter scored zero (the scores do not vary)"
    ranked = sorted(((p, float(v) / total) for p, v in shares.items()), key=lambda x: -x[1])
    return tuple(ranked), method, ""


def study_view(ts: TuneStudy) -> TuneView:
    """The study ``ts`` as the report draws it."""
    tune = ts.tune
    objective = "best validation score (mean 3-D RMSE over held-out random targets, m)"
    if tune.seeds_per_trial > 1:
        objective += f", {tune.aggregate} over {tune.seeds_per_trial} seeds"
    axes = _axes(ts)
    importance, method, note = _importance(ts)
    return TuneView(
        name=ts.name,
        objective=objective,
        axes=axes,
        trials=tuple(_trial(t, axes) for t in ts.trials()),
        importance=importance,
        importance_method=method,
        importance_note=note,
    )


def load_view(name: str, *, storage: str | None, runs_dir: str | os.PathLike[str]) -> TuneView:
    """The study ``name`` in ``storage`` (default: ``<runs dir>/optuna.db``) for the report."""
    return study_view(load_study(storage or default_storage(runs_dir), name))
