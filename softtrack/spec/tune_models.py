"""The optional ``tune:`` section of a spec: the search space of ``softtrack tune`` (Optuna).

::

    tune:
      metric: validation   # the objective: the run's best validation score (mean 3-D RMSE, m)
      params:              # spec field path → distribution
        algo.learning_rate: {type: float, low: 1.0e-4, high: 3.0e-3, log: true}
        algo.batch_size: {type: categorical, choices: [128, 256, 512]}
        algo.gradient_steps: {type: int, low: 4, high: 32, log: true}
        algo.policy_kwargs.net_arch: {type: categorical, choices: [[64, 64], [128, 128]]}

Every key of ``params`` must be a field of the spec (not a section, and not ``name``, ``seeds``,
``cluster`` or ``tune``); every value the distribution can give must make a valid spec: the
ends of each range (and a fractional value inside a float range), each choice, and, while there
are at most :data:`MAX_COMBINATIONS` of them, every combination of those values across the
params are validated with the spec (:func:`check_tune`). The section is left out of
:func:`~softtrack.spec.spec_hash` (it says how to search, not what a run is) and out of the
spec of every trial's run. See ``docs/tuning.md``.
"""

from __future__ import annotations

import copy
import json
import math
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, Field, model_validator

from softtrack.spec.fields import (
    Float,
    Int,
    Seed,
    SpecModel,
    custom_error,
    section_field,
    unit_field,
)
from softtrack.spec.parsing import _suggest

__all__ = [
    "MAX_COMBINATIONS",
    "PrunerSpec",
    "TuneParamSpec",
    "TuneSpec",
    "choice_key",
    "trial_data",
]

#: Up to this many combinations of the params' extreme values are each validated as a spec.
MAX_COMBINATIONS = 512
_NOT_TUNABLE = {
    "name": "the trials' runs are named <name>-t<trial number>",
    "seeds": "every trial trains the spec's first seed",
    "cluster": "the cluster section says where runs execute, not what they are",
    "tune": "the search space cannot tune itself",
}
_PARAM_KEYS = {
    "float": ("type", "low", "high", "log", "step"),
    "int": ("type", "low", "high", "log", "step"),
    "categorical": ("type", "choices"),
}


def choice_key(value: Any) -> Any:
    """How Optuna stores a categorical choice: scalars as they are, lists and mappings as
    compact JSON text (Optuna's choices are ``None``, bool, int, float or str)."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return json.dumps(value, separators=(",", ":"), sort_keys=True)


def _check_path(path: str) -> str:
    """A ``params`` key: a dotted path outside the fields that cannot be tuned (that it names a
    field of the spec is checked with the whole spec: :func:`softtrack.spec.models.check_tune`)."""
    parts = path.split(".")
    if not all(parts):
        raise custom_error(f"malformed field path {path!r}; write it dotted, e.g. algo.batch_size")
    if parts[0] in _NOT_TUNABLE:
        raise custom_error(f"{parts[0]!r} cannot be tuned ({_NOT_TUNABLE[parts[0]]}); remove it")
    return path


ParamPath = Annotated[str, AfterValidator(_check_path)]


class TuneParamSpec(SpecModel):
    """One searched field: ``{type: float|int, low, high, log, step}`` or
    ``{type: categorical, choices: [...]}``."""

    type: Literal["float", "int", "categorical"] = unit_field(
        "float", "distribution: float or int (a range), categorical (a list of choices)", "-"
    )
    low: Float | None = unit_field(None, "lower end of the range (float, int)", "field's unit")
    high: Float | None = unit_field(None, "upper end of the range (float, int)", "field's unit")
    log: bool = unit_field(False, "sample the range on a log scale (low > 0)", "-")
    step: Float | None = unit_field(
        None, "spacing of the values in the range (float, int; not with log)", "field's unit"
    )
    choices: list[Any] | None = unit_field(None, "the values to choose from (categorical)", "-")

    @model_validator(mode="before")
    @classmethod
    def _check_keys(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        kind = data.get("type")
        if kind not in _PARAM_KEYS:
            shown = "no type" if kind is None else f"type {kind!r}"
            raise custom_error(
                f"{shown}; write type: float, int or categorical, e.g. "
                "{type: float, low: 1.0e-4, high: 1.0e-3, log: true}"
            )
        allowed = _PARAM_KEYS[kind]
        for key, value in data.items():
            if key not in allowed and value is not None and not (key == "log" and not value):
                # (another type's keys left unset, as a dumped spec writes them, are fine)
                hint = (
                    _suggest(str(key), allowed)
                    if key not in sum(_PARAM_KEYS.values(), ())
                    else f"a {kind} param takes {', '.join(allowed[1:])}"
                )
                raise custom_error(f"unknown key {key!r} for type {kind}; {hint}")
        return data

    @model_validator(mode="after")
    def _check_distribution(self) -> TuneParamSpec:
        if self.type == "categorical":
            if not self.choices:
                raise custom_error("categorical needs choices; write e.g. choices: [128, 256]")
            keys = [choice_key(c) for c in self.choices]
            if len(set(map(json.dumps, keys))) != len(keys):
                raise custom_error(f"duplicate choices in {self.choices}; list each once")
            return self
        if self.low is None or self.high is None:
            raise custom_error(
                f"a {self.type} range needs low and high; write e.g. "
                "{type: " + self.type + ", low: 4, high: 32}"
            )
        if self.type == "int":
            for name in ("low", "high", "step"):
                value = getattr(self, name)
                if value is not None and value != int(value):
                    raise custom_error(
                        f"{name} {value:g} of an int range is not a whole number; "
                        "write whole numbers or use type: float"
                    )
                if value is not None:
                    setattr(self, name, int(value))
        if not self.low < self.high:
            raise custom_error(f"low {self.low:g} ≥ high {self.high:g}; make low < high")
        if self.log and self.low <= 0:
            raise custom_error(
                f"log scale needs low > 0, got {self.low:g}; raise low or set log: false"
            )
        if self.step is not None:
            if self.log:
                raise custom_error("step and log cannot be combined; remove one of them")
            if self.step <= 0:
                raise custom_error(f"step {self.step:g} ≤ 0; use a positive step")
        return self

    def check_values(self) -> list[Any]:
        """The values validated with the spec: each choice, or both ends of the range (and,
        for a float range, a fractional value inside it, which an int field rejects)."""
        if self.type == "categorical":
            return list(self.choices or [])
        assert self.low is not None and self.high is not None
        if self.type == "int":
            return [int(self.low), int(self.high)]
        inside = self.low + (self.high - self.low) / math.pi
        if self.log:
            inside = math.exp(
                math.log(self.low) + (math.log(self.high) - math.log(self.low)) / math.pi
            )
        return [self.low, self.high, inside]


class PrunerSpec(SpecModel):
    """When a trial stops early: its validation score at a checkpoint compared with the other
    trials' scores at the same step (median) or with a fixed bound (threshold)."""

    type: Literal["median", "threshold", "none"] = unit_field(
        "median",
        "median: stop a trial whose validation score is worse than the median of the earlier "
        "trials' at the same step; threshold: stop one whose score is above upper; none: never",
        "-",
    )
    n_startup_trials: Int = unit_field(
        5, "median: trials that finish before any is pruned", "trials", ge=0
    )
    n_warmup_steps: Int = unit_field(
        0,
        "no pruning before this many env steps of a run (median, threshold)",
        "env steps",
        ge=0,
    )
    upper: Float | None = unit_field(
        None, "threshold: prune a trial whose validation score exceeds this", "m"
    )

    @model_validator(mode="after")
    def _check_threshold(self) -> PrunerSpec:
        if self.type == "threshold" and self.upper is None:
            raise custom_error("a threshold pruner needs upper (m); write e.g. upper: 0.1", "upper")
        return self


class TuneSpec(SpecModel):
    """The search space and objective of ``softtrack tune`` (docs/tuning.md)."""

    metric: Literal["validation"] = unit_field(
        "validation",
        "the objective, minimised: the best validation score of the trial's run, the mean 3-D "
        "RMSE of training.validation_episodes held-out episodes at its best checkpoint "
        "(independent: the mean over the arms' best); with seeds_per_trial > 1 the mean or "
        "IQM over the trial's runs",
        "m",
    )
    params: dict[ParamPath, TuneParamSpec] = Field(
        description="spec field path → distribution, e.g. algo.learning_rate: {type: float, "
        "low: 1.0e-4, high: 3.0e-3, log: true} [-]",
        min_length=1,
    )
    seeds_per_trial: Int = unit_field(
        1,
        "runs per trial, seeds spec.seeds[0], +1, …: the objective aggregates their scores, so "
        "a tuned optimum is not one seed's luck (the pruner watches the first seed's run)",
        "runs",
        ge=1,
        le=32,
    )
    aggregate: Literal["mean", "iqm"] = unit_field(
        "mean",
        "how a trial's runs' scores combine: their mean, or their interquartile mean (the "
        "mean of the middle 50 %, robust to one bad seed; docs/statistics.md)",
        "-",
    )
    seed: Seed = unit_field(
        0, "seed of the TPE sampler (each trial's draw is seeded by it and the trial number)", "-"
    )
    n_startup_trials: Int = unit_field(
        10, "trials drawn at random before TPE models the search space", "trials", ge=0
    )
    pruner: PrunerSpec = section_field(PrunerSpec, "stopping unpromising trials early")

    @model_validator(mode="before")
    @classmethod
    def _check_keys(cls, data: Any) -> Any:
        """An unknown key (``parms``) is reported before the ``params`` it lacks."""
        if isinstance(data, dict):
            for key in data:
                if key not in cls.model_fields:
                    raise custom_error(
                        f"unknown field {key!r}; " + _suggest(str(key), cls.model_fields)
                    )
            if not data.get("params"):
                raise custom_error(
                    "no params to search; add at least one field path with its distribution, "
                    "e.g. algo.learning_rate: {type: float, low: 1.0e-4, high: 3.0e-3, log: true}",
                    "params",
                )
        return data


# ------------------------------------------------------------------------------------------
# Trials
# ------------------------------------------------------------------------------------------
def trial_data(base: dict[str, Any], values: dict[str, Any]) -> dict[str, Any]:
    """``base`` (a spec as plain data, without ``tune``) with each ``path: value`` set."""
    data = copy.deepcopy(base)
    for path, value in values.items():
        node = data
        *parents, leaf = path.split(".")
        for key in parents:
            node = node.setdefault(key, {})
        node[leaf] = copy.deepcopy(value)
    return data
