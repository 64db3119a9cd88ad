"""The public spec functions: parse, load, dump, hash, schema."""

from __future__ import annotations

import copy
import hashlib
import json
import os
import re
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml
from pydantic import (
    BaseModel,
    ValidationError,
)

from softtrack.spec.bases import BASE_KEY, resolve_spec_file
from softtrack.spec.fields import SpecError
from softtrack.spec.models import ExperimentSpec
from softtrack.spec.parsing import _apply_override, _convert, _parse_override


# ------------------------------------------------------------------------------------------
# Public functions
# ------------------------------------------------------------------------------------------
def parse_spec(
    data: Any,
    overrides: Sequence[str] = (),
    *,
    source: str = "<spec>",
    default_name: str | None = None,
    _lines: dict[tuple[Any, ...], int] | None = None,
    _files: dict[tuple[Any, ...], str] | None = None,
) -> ExperimentSpec:
    """Validate already-parsed spec data (a mapping) with ``overrides`` applied.

    Raises:
        SpecError: one line naming ``source``, the field path and the fix.
    """
    if data is None or not isinstance(data, dict):
        got = "an empty document" if data is None else f"a {type(data).__name__}"
        raise SpecError(
            source,
            f"the top level must be a mapping of sections, got {got}",
            "start from `softtrack spec --defaults` (keys: "
            + ", ".join(ExperimentSpec.model_fields)
            + ")",
            line=1 if data is not None else None,
        )
    if BASE_KEY in data:
        raise SpecError(
            source,
            "only a spec file can have a base (its path is relative to the file)",
            "load the file with load_spec(path), or merge the base into the data yourself",
            field=BASE_KEY,
        )
    data = copy.deepcopy(data)
    applied: dict[tuple[str, ...], str] = {}
    for text in overrides:
        parts, value = _parse_override(text, ExperimentSpec)
        _apply_override(data, parts, value, f"--set {text}")
        applied[parts] = text
    if "name" not in data and default_name is not None:
        stem = re.sub(r"[^A-Za-z0-9_.-]", "_", default_name)[:64].lstrip("._-")
        data["name"] = stem or "experiment"
    try:
        return ExperimentSpec.model_validate(data)
    except ValidationError as exc:
        raise _convert(exc, ExperimentSpec, source, _lines or {}, applied, _files or {}) from None


def load_spec(path: str | os.PathLike[str], overrides: Sequence[str] = ()) -> ExperimentSpec:
    """Read, override and validate a spec file.

    Args:
        path: a YAML file. Its ``base:`` (a path relative to the file's directory) names a spec
            file it extends, which may have a base of its own: the chain is deep-merged first
            (mappings merge, the extending file wins, lists and scalars replace; ``name`` is
            not inherited), see :mod:`softtrack.spec.bases`.
        overrides: ``"dotted.path=value"`` strings, applied after the chain; values are parsed
            as YAML, e.g. ``training.total_timesteps=2000``, ``env.physics.dt=1e-4``,
            ``seeds=[0,1]``. A path that is not a field of the spec is an error.

    Returns:
        The validated spec. A missing ``name`` defaults to the file's stem.

    Raises:
        SpecError: missing/unreadable file, malformed YAML, a top level that is not a mapping,
            a bad ``base`` (missing file, cycle), an unknown field, a wrong type, an
            out-of-range value or a malformed override -- in any file of the chain.
    """
    source = resolve_spec_file(path)
    return parse_spec(
        source.data,
        overrides,
        source=str(path),
        default_name=Path(path).stem,
        _lines=source.lines,
        _files=source.files,
    )


def spec_chain(path: str | os.PathLike[str]) -> list[str]:
    """The spec file and the files its ``base:`` chain goes through: the file itself first,
    then its base, its base's base, ... (paths as the loader reads them: relative to the
    current directory when ``path`` is). Raises :class:`SpecError` like :func:`load_spec`."""
    return list(resolve_spec_file(path).chain)


def chain_comment(chain: Sequence[str]) -> str:
    """YAML comment lines that name a resolved spec's file and its bases, e.g.::

        # from experiments/variants/td3-sbx-128-4e6.yaml
        #   base: experiments/study/td3-sbx-64-4e6.yaml
        #   base: experiments/study/td3-64-1e7.yaml

    ``""`` for an empty chain. The lines are comments, so the spec loads without the files.
    """
    if not chain:
        return ""
    lines = [f"# from {chain[0]}"] + [f"#   base: {file}" for file in chain[1:]]
    return "\n".join(lines) + "\n"


def _dump_scalar(value: Any) -> str:
    text = yaml.safe_dump(
        value, default_flow_style=True, width=10_000, sort_keys=False, allow_unicode=True
    )
    text = text.strip()
    if text.endswith("\n..."):
        text = text[: -len("\n...")].strip()
    elif text.endswith("..."):
        text = text[:-3].strip()
    return text


def _emit(
    model: BaseModel, data: dict[str, Any], indent: int, comments: bool, out: list[str]
) -> None:
    pad = " " * indent
    for name, field in type(model).model_fields.items():
        value = data[name]
        child = getattr(model, name)
        if indent == 0 and name in _LEFT_OUT_WHEN_NONE and child is None:
            continue
        if comments and field.description:
            if indent == 0 and out:
                out.append("")
            for line in textwrap.wrap(field.description, width=max(40, 96 - indent)):
                out.append(f"{pad}# {line}")
        if isinstance(child, BaseModel):
            out.append(f"{pad}{name}:")
            _emit(child, value, indent + 2, comments, out)
        elif (
            isinstance(child, dict)
            and child
            and all(isinstance(v, BaseModel) for v in child.values())
        ):  # e.g. tune.params: one line per entry, without the settings left at their defaults
            out.append(f"{pad}{name}:")
            for key, entry in child.items():
                shown = {
                    first: value[key][first] for first in list(type(entry).model_fields)[:1]
                } | entry.model_dump(mode="json", exclude_defaults=True)
                out.append(f"{pad}  {key}: {_dump_scalar(shown)}")
        else:
            out.append(f"{pad}{name}: {_dump_scalar(value)}")


# Optional top-level sections that a spec without them does not write (no ``tune: null`` line
# in every run's spec.yaml).
_LEFT_OUT_WHEN_NONE = frozenset({"tune"})


def spec_to_yaml(spec: ExperimentSpec, *, comments: bool = False) -> str:
    """The fully resolved spec as YAML (every field, in declaration order).

    With ``comments=True`` every field is preceded by its description and unit, which makes a
    self-documenting template (``softtrack spec --defaults``). Either form loads back to an
    equal spec.
    """
    out: list[str] = []
    _emit(spec, spec.model_dump(mode="json"), 0, comments, out)
    return "\n".join(out) + "\n"


# Fields added after runs had been recorded, with the value that reproduces the behaviour from
# before they existed. At that value they are left out of the hash, so that adding an optional
# field keeps the hash (and the spec matching) of every existing run and experiment file.
_FIELDS_ADDED_LATER: dict[tuple[str, ...], Any] = {
    ("env", "target", "speed_min"): None,
    ("env", "physics", "contact_k"): 0.0,
    ("env", "physics", "contact_nu"): 0.0,
    ("env", "physics", "sphere"): None,
    ("env", "task", "name"): "shared",
    ("env", "task", "standoff"): 0.1,
    ("env", "task", "approach"): 2.0,
    ("env", "task", "drop_grace"): 0.5,
    ("env", "task", "hold_bonus"): 0.25,
    ("env", "task", "squeeze_band"): [0.0, 0.0],
    ("env", "task", "squeeze_penalty"): 0.0,
    ("env", "task", "drop_penalty"): 100.0,
    ("env", "task", "reach_penalty"): 2.0,
    ("env", "task", "bonus_needs_grip"): True,
    ("env", "task", "grip"): 0.0,
    ("env", "task"): {},
    ("algo", "critic"): "joint",
    ("algo", "per_arm_networks"): False,
    ("algo", "actor_observation"): "full",
    ("algo", "mirror_replay"): False,
    ("algo", "actor_preactivation_penalty"): 0.0,
    ("algo", "n_step_returns"): 1,
    ("algo", "act_with_target_actor"): False,
    ("algo", "learning_rate_final"): None,
    ("algo", "learning_rate_decay_from"): 0.0,
    ("algo", "policy_kwargs", "layer_norm"): False,
    ("algo", "policy_kwargs", "log_std_init"): 0.0,
    ("training", "validation_episodes"): 0,
    ("training", "validation_trajectories"): False,
    ("training", "validation_paths"): 0,
    ("training", "stop_score"): None,
    ("training", "validation_score"): "random_and_paths",
    ("training", "final_policy"): "last",
    ("training", "confirm_episodes"): 0,
    ("training", "randomisation_warmup_steps"): 0,
    ("training", "goal_warmup_steps"): 0,
    ("algo", "target_entropy"): "auto",
    ("algo", "top_quantiles_to_drop_per_net"): 2,
    ("algo", "policy_kwargs", "n_quantiles"): 25,
    ("algo", "policy_kwargs", "n_critics"): 2,
    ("algo", "policy_kwargs", "batch_norm"): True,
    ("algo", "policy_kwargs", "batch_norm_actor"): True,
    ("algo", "policy_kwargs", "batch_norm_momentum"): 0.99,
    ("algo", "policy_kwargs", "renorm_warmup_steps"): 100_000,
    ("env", "reward", "action_rate_penalty"): 0.0,
    ("env", "reward", "action_penalty"): 0.0,
    # env.realism: every field at its "off" value, then the section itself once emptied (so a
    # field added to it later only needs its own line here)
    ("env", "realism", "action_delay_max"): None,
    ("env", "realism", "obs_noise_node_position"): 0.0,
    ("env", "realism", "obs_noise_target_position"): 0.0,
    ("env", "realism", "obs_noise_speed"): 0.0,
    ("env", "realism", "obs_noise_direction"): 0.0,
    ("env", "realism", "obs_drop_probability"): 0.0,
    ("env", "realism", "obs_stuck_probability"): 0.0,
    ("env", "realism", "obs_stuck_steps"): 1,
    ("env", "realism", "obs_delay"): 0,
    ("env", "realism", "action_delay"): 0,
    ("env", "realism", "actuator_time_constant"): None,
    ("env", "realism", "action_rate_limit"): None,
    ("env", "realism", "torque_limit"): None,
    ("env", "realism", "youngs_modulus_scale"): 1.0,
    ("env", "realism", "density_scale"): 1.0,
    ("env", "realism", "radius_scale"): 1.0,
    ("env", "realism", "damping_scale"): 1.0,
    ("env", "realism", "torque_scale_factor"): 1.0,
    ("env", "realism"): {},
    # mpc: every field at its default, then the section itself once emptied
    ("mpc", "method"): "mppi",
    ("mpc", "samples"): 64,
    ("mpc", "horizon"): 50,
    ("mpc", "knots"): 5,
    ("mpc", "iterations"): 1,
    ("mpc", "noise_std"): 0.3,
    ("mpc", "temperature"): 0.05,
    ("mpc", "elite_fraction"): 0.1,
    ("mpc", "replan_interval"): 5,
    ("mpc", "warm_start"): True,
    ("mpc", "action_rate_weight"): 0.0,
    ("mpc", "action_weight"): 0.0,
    ("mpc", "model"): "true",
    ("mpc", "model_scales"): {},
    ("mpc",): {},
}


def spec_hash(spec: ExperimentSpec) -> str:
    """SHA-256 (hex) of the canonical JSON of the spec *without* ``seeds``.

    The runs of one experiment therefore share the hash across seeds; any other change
    (including ``name``) changes it, except the ``cluster`` section (where it runs, not what),
    the ``tune`` section (how ``softtrack tune`` searches, not what a run is: a spec with a
    search space hashes as the same spec without it), ``training.tensorboard`` (logging) and
    a later-added field left at its neutral value (``_FIELDS_ADDED_LATER``).
    """
    data = spec.model_dump(mode="json", exclude={"seeds", "cluster", "tune"})
    data["training"].pop("tensorboard", None)  # where it logs, not what a run is
    for (*parents, leaf), neutral in _FIELDS_ADDED_LATER.items():
        section = data
        for key in parents:
            section = section[key]
        if section.get(leaf, neutral) == neutral:
            section.pop(leaf, None)
    canonical = json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


def spec_json_schema() -> dict[str, Any]:
    """JSON Schema of :class:`ExperimentSpec` (descriptions carry the units)."""
    return ExperimentSpec.model_json_schema()
