"""Specs as text for people: the one-line validation summary, the commented defaults, the
JSON Schema, a spec with its ``base:`` chain resolved."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence

from softtrack.spec.models import ExperimentSpec
from softtrack.spec.spec_io import (
    chain_comment,
    load_spec,
    spec_chain,
    spec_json_schema,
    spec_to_yaml,
)


def validation_summary(spec: ExperimentSpec, chain: Sequence[str] = ()) -> str:
    """``ok: td3, 3 runs (seeds 0, 1, 2): td3/centralized, 10,000,000 env steps each``, and
    for a spec with a ``base:`` a second line naming the chain (``chain``: :func:`spec_chain`),
    e.g. ``   base: experiments/study/td3-sbx-64-4e6.yaml → experiments/study/td3-64-1e7.yaml``.
    """
    seeds = ", ".join(str(s) for s in spec.seeds)
    runs = f"{spec.n_runs} run{'s' if spec.n_runs != 1 else ''}"
    seed_word = "seeds" if spec.n_runs != 1 else "seed"
    if spec.controller == "mpc":
        m = spec.mpc
        what = (
            f"{m.method}/mpc, {m.samples} samples × {m.horizon} steps, replanning every "
            f"{m.replan_interval} steps (nothing to train: `softtrack evaluate SPEC`)"
        )
    else:
        what = (
            f"{spec.algo.name}/{spec.controller}, {spec.training.total_timesteps:,} env steps each"
        )
    text = f"ok: {spec.name}, {runs} ({seed_word} {seeds}): {what}"
    if len(chain) > 1:
        text += "\n   base: " + " → ".join(chain[1:])
    if spec.tune is not None:
        text += (
            f"\n   tune: {len(spec.tune.params)} params ({', '.join(spec.tune.params)}), "
            f"metric {spec.tune.metric}, pruner {spec.tune.pruner.type}"
        )
    return text


def spec_defaults_yaml() -> str:
    """The default spec as commented YAML (a template to copy)."""
    header = (
        "# softtrack experiment spec: every field with its default (the study's setting).\n"
        "# Units are in brackets. Validate a copy with `softtrack validate FILE`.\n\n"
    )
    return header + spec_to_yaml(ExperimentSpec(), comments=True)


def spec_schema_json() -> str:
    """The JSON Schema of the spec, indented."""
    return json.dumps(spec_json_schema(), indent=2, ensure_ascii=False)


def resolved_spec_yaml(path: str | os.PathLike[str], overrides: Sequence[str] = ()) -> str:
    """A spec file with its ``base:`` chain merged, defaults filled in and overrides applied, as
    YAML; a spec with a base starts with comments naming the file and its bases
    (:func:`softtrack.spec.chain_comment`), which leave it loadable on its own."""
    spec = load_spec(path, overrides)
    chain = spec_chain(path)
    return (chain_comment(chain) if len(chain) > 1 else "") + spec_to_yaml(spec)
