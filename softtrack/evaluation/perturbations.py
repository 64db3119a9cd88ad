"""Robustness evaluation: a run's controller under perturbed sensing, actuation and physics.

A *factor* names what is perturbed: a field of ``env.realism`` (docs/environment.md, "Realism"),
e.g. ``action_delay`` or ``youngs_modulus_scale``; one of the shorthands in
:data:`FACTOR_ALIASES` (``obs_noise``: the same noise std on the node and target positions, m;
``gravity``: ``env.physics.gravity``, m/s² or on/off; ``contact``: the arms touch, on/off or a
stiffness in N/m, docs/physics.md "Contact"); or any dotted ``env.`` spec path. A
*setting* gives one or more factors a level (:class:`Setting`); :func:`expand_settings` makes
the settings of ``--grid`` axes, one factor at a time (every other factor nominal) or as their
full Cartesian product.

Each setting is evaluated in the run's own environment with the setting applied as ``--set``
overrides (:func:`perturbed_spec`), so an unstable combination (a stiffer rod than the time
step allows, say) fails validation before any episode runs. By default the run's own
``env.realism`` is switched off first: the baseline is the idealised environment, so a
domain-randomized policy and a nominal one meet the same perturbation. ``keep_realism=True``
keeps the run's realism settings as the baseline instead.

The rows (:func:`evaluate_setting`) are those of
:func:`softtrack.evaluation.episode_tables.metrics_table` (one per trajectory, episode and arm) with
the setting in front: ``perturbation`` (the factor names joined by ``+``, or ``nominal``),
``level`` (the level of a one-factor numeric setting, else NaN), ``setting`` (e.g.
``action_delay=2`` or ``obs_noise=0.005 action_delay=2``), ``baseline`` (``idealised`` or
``run``), ``episode`` and ``seed``. Episode k of every setting draws its noise from seed
:data:`ROBUSTNESS_SEED` + k. They are stored in the run's ``eval_robustness`` table
(:func:`store_rows`: rows of the same setting, baseline and trajectory are replaced).
"""

from __future__ import annotations

import hashlib
import itertools
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import yaml

from softtrack.evaluation.episode_tables import metrics_table
from softtrack.evaluation.episodes import Policy, iter_episodes
from softtrack.sim.params import CONTACT_ON
from softtrack.spec import ExperimentSpec, SpecError
from softtrack.spec.env_config import env_config
from softtrack.spec.env_models import RealismSpec
from softtrack.spec.spec_io import parse_spec
from softtrack.store.provenance import cpu_kind
from softtrack.store.runs import RunRecord
from softtrack.store.tables import read_table, write_table

__all__ = [
    "FACTOR_ALIASES",
    "ROBUSTNESS_SEED",
    "ROBUSTNESS_TABLE",
    "Setting",
    "copy_nominal",
    "done_settings",
    "evaluate_setting",
    "expand_settings",
    "factor_axis_label",
    "factor_paths",
    "merge_parts",
    "part_path",
    "perturbed_spec",
    "store_rows",
]

ROBUSTNESS_TABLE = "eval_robustness"
#: Episode k of a robustness setting draws its random numbers from ROBUSTNESS_SEED + k.
ROBUSTNESS_SEED = 4_000_000

#: Shorthand factors and the spec fields each sets to its level.
FACTOR_ALIASES: dict[str, tuple[str, ...]] = {
    "obs_noise": ("env.realism.obs_noise_node_position", "env.realism.obs_noise_target_position"),
    "gravity": ("env.physics.gravity",),
    "contact": ("env.physics.contact_k", "env.physics.contact_nu"),
}


def _contact_levels(level: str) -> tuple[str, str]:
    """The (contact_k, contact_nu) texts of a ``contact`` level: ``on`` (the "contact on"
    defaults, :data:`softtrack.sim.params.CONTACT_ON`), ``off``, or a stiffness in N/m with
    the default damping."""
    value = yaml.safe_load(level)
    if value is True:
        return repr(CONTACT_ON["contact_k"]), repr(CONTACT_ON["contact_nu"])
    if value is False or value == 0:
        return "0.0", "0.0"
    return level, repr(CONTACT_ON["contact_nu"])


_KEY = ["setting", "baseline", "trajectory"]
_PARTS_DIR = "eval_robustness-parts"


def factor_paths(factor: str) -> tuple[str, ...]:
    """The spec fields a factor sets: an alias's, ``env.realism.<factor>``, or the path itself.

    Raises:
        SpecError: an unknown factor.
    """
    if factor in FACTOR_ALIASES:
        return FACTOR_ALIASES[factor]
    if factor in RealismSpec.model_fields:
        return (f"env.realism.{factor}",)
    if factor.startswith("env."):
        return (factor,)
    known = ", ".join([*FACTOR_ALIASES, *RealismSpec.model_fields])
    raise SpecError(
        f"--grid {factor}",
        f"unknown perturbation {factor!r}",
        f"use one of {known}, or a spec path such as env.physics.damping",
    )


def factor_axis_label(factor: str) -> str:
    """``obs_noise (m)``, ``youngs_modulus_scale (× nominal)``, ``action_delay (control
    steps)``: a factor with the unit of the first spec field it sets (the ``[unit]`` that ends
    the field's description); the factor alone where it has none or is unknown."""
    try:
        path = factor_paths(factor)[0].split(".")
    except SpecError:
        return factor
    model: Any = ExperimentSpec
    info = None
    for part in path:
        fields = getattr(model, "model_fields", {})
        if part not in fields:
            return factor
        info = fields[part]
        model = info.annotation
    match = re.search(r"\[([^\]]+)\]$", (info.description or "") if info else "")
    if not match:
        return factor
    unit = match.group(1)
    if unit in ("-", "–"):
        return f"{factor} (× nominal)" if factor.endswith("_scale") else f"{factor} (–)"
    return f"{factor} ({unit})"


@dataclass(frozen=True)
class Setting:
    """Levels of one or more factors: ``((factor, level text), ...)``; empty = nominal."""

    levels: tuple[tuple[str, str], ...]

    @property
    def key(self) -> str:
        """``action_delay=2``, ``obs_noise=0.005 action_delay=2``, or ``nominal``."""
        return " ".join(f"{f}={v}" for f, v in self.levels) or "nominal"

    @property
    def perturbation(self) -> str:
        """The factor names joined by ``+`` (``nominal`` when there is none)."""
        return "+".join(f for f, _ in self.levels) or "nominal"

    @property
    def level(self) -> float:
        """The level of a one-factor setting as a number (on/off: 1/0); NaN otherwise."""
        if len(self.levels) != 1:
            return math.nan
        value = yaml.safe_load(self.levels[0][1])
        if isinstance(value, bool | int | float):
            return float(value)
        return math.nan

    def overrides(self) -> list[str]:
        """The ``--set`` overrides of this setting (``dotted.path=level``; ``contact=on``
        sets both contact fields, :func:`_contact_levels`)."""
        out = []
        for factor, value in self.levels:
            paths = factor_paths(factor)
            values = _contact_levels(value) if factor == "contact" else (value,) * len(paths)
            out += [f"{path}={text}" for path, text in zip(paths, values, strict=True)]
        return out


def expand_settings(grid: Sequence[tuple[str, Sequence[str]]], full: bool = False) -> list[Setting]:
    """The settings of ``--grid`` axes ``[(factor, [level, ...]), ...]``.

    Args:
        grid: factors and their levels (level texts as written, parsed as YAML later).
        full: the Cartesian product of all axes; otherwise one factor at a time, in the order
            given (duplicates removed).

    Returns:
        The ``nominal`` setting (no factor: the baseline every ratio refers to), then the
        grid's settings.

    Raises:
        SpecError: an unknown factor, or no axis.
    """
    if not grid:
        raise SpecError(
            "--grid",
            "no perturbation given",
            "add e.g. --grid obs_noise=0,0.005 --grid action_delay=0,2",
        )
    for factor, _ in grid:
        factor_paths(factor)
    if full:
        names = [f for f, _ in grid]
        combos = itertools.product(*[list(levels) for _, levels in grid])
        settings = [Setting(tuple(zip(names, combo, strict=True))) for combo in combos]
    else:
        settings = [Setting(((f, v),)) for f, levels in grid for v in levels]
    return list(dict.fromkeys([Setting(()), *settings]))


def perturbed_spec(
    spec: ExperimentSpec, setting: Setting, keep_realism: bool = False
) -> ExperimentSpec:
    """The run's spec with ``setting`` applied (``env.realism`` reset first unless
    ``keep_realism``; a training curriculum, ``training.randomisation_warmup_steps``, is
    dropped: evaluation sees the full perturbations).

    Raises:
        SpecError: the setting makes the spec invalid (one line naming the setting).
    """
    data = spec.model_dump(mode="json")
    data["training"].pop("randomisation_warmup_steps", None)
    if not keep_realism:
        data["env"].pop("realism", None)
    try:
        return parse_spec(data, setting.overrides(), source=f"robustness {setting.key}")
    except SpecError as exc:
        raise SpecError(f"--grid {setting.key}", exc.problem, exc.fix, field=exc.field) from None


def evaluate_setting(
    run_id: str,
    policy: Policy,
    spec: ExperimentSpec,
    setting: Setting,
    trajectories: Sequence[str],
    episodes: int = 1,
    *,
    keep_realism: bool = False,
    on_episode: Callable[[str, pd.DataFrame], None] | None = None,
) -> pd.DataFrame:
    """Run ``policy`` under ``setting`` for ``episodes`` episodes per trajectory.

    Args:
        run_id: the run the rows belong to.
        policy: the run's deterministic policy, observation (81,) → action (24,).
        spec: the run's spec (``training.eval_duration`` sets the episode length, s).
        setting: the perturbation.
        trajectories: circle, rectangle, figure8 (or random).
        episodes: episodes per trajectory (k draws from :data:`ROBUSTNESS_SEED` + k).
        keep_realism: keep the run's own ``env.realism`` as the baseline.
        on_episode: called with (trajectory, metrics rows) after each episode.

    Returns:
        The rows described in the module docstring.
    """
    config = env_config(perturbed_spec(spec, setting, keep_realism))
    duration = float(spec.training.eval_duration)
    front = {
        "perturbation": setting.perturbation,
        "level": setting.level,
        "setting": setting.key,
        "baseline": "run" if keep_realism else "idealised",
    }
    cpu = cpu_kind()
    parts = []
    seeds = [ROBUSTNESS_SEED + k for k in range(episodes)]
    for trajectory in trajectories:
        for k, episode in enumerate(iter_episodes(policy, config, trajectory, duration, seeds)):
            rows = metrics_table(run_id, episode)
            for i, (name, value) in enumerate(
                {**front, "episode": k, "seed": ROBUSTNESS_SEED + k}.items()
            ):
                rows.insert(1 + i, name, value)
            rows["cpu"] = cpu
            parts.append(rows)
            if on_episode is not None:
                on_episode(trajectory, rows)
    return pd.concat(parts, ignore_index=True)


def store_rows(record: RunRecord, rows: pd.DataFrame) -> None:
    """Write ``rows`` into the run's ``eval_robustness`` table, replacing its rows of the same
    setting, baseline and trajectory (atomically)."""
    path = record.table_path(ROBUSTNESS_TABLE)
    if path.is_file():
        old = read_table(path)
        replaced = old.set_index(_KEY).index.isin(rows.set_index(_KEY).index)
        rows = pd.concat([old[~replaced], rows], ignore_index=True)
    write_table(path, rows.reset_index(drop=True))


def copy_nominal(
    record: RunRecord, setting: Setting, trajectories: Sequence[str], keep_realism: bool = False
) -> bool:
    """Store the run's ``nominal`` rows again under ``setting``, a setting whose perturbed spec
    equals the nominal one (e.g. ``obs_noise=0`` for a run without observation noise), so the
    episodes run once. False when the nominal rows of ``trajectories`` are not stored."""
    path = record.table_path(ROBUSTNESS_TABLE)
    if not path.is_file():
        return False
    table = read_table(path)
    baseline = "run" if keep_realism else "idealised"
    rows = table[
        (table["setting"] == "nominal")
        & (table["baseline"] == baseline)
        & table["trajectory"].isin(trajectories)
    ].copy()
    if set(rows["trajectory"]) != set(trajectories):
        return False
    rows["perturbation"] = setting.perturbation
    rows["level"] = setting.level
    rows["setting"] = setting.key
    store_rows(record, rows)
    return True


def done_settings(
    record: RunRecord, trajectories: Sequence[str], episodes: int, keep_realism: bool = False
) -> set[str]:
    """Keys of the settings whose rows in ``eval_robustness`` cover every trajectory with at
    least ``episodes`` episodes under this baseline."""
    path = record.table_path(ROBUSTNESS_TABLE)
    if not path.is_file():
        return set()
    table = read_table(path, columns=["setting", "baseline", "trajectory", "episode"])
    table = table[table["baseline"] == ("run" if keep_realism else "idealised")]
    counts = table.groupby(["setting", "trajectory"])["episode"].nunique()
    done = set()
    for key, per_trajectory in counts.groupby(level="setting"):
        got = {t: n for (_, t), n in per_trajectory.items()}
        if all(got.get(t, 0) >= episodes for t in trajectories):
            done.add(str(key))
    return done


def part_path(
    record: RunRecord,
    setting: Setting,
    trajectories: Sequence[str],
    episodes: int,
    keep_realism: bool,
) -> Path:
    """Where a worker process stores one setting's rows until :func:`merge_parts` merges them."""
    ident = "|".join([setting.key, ",".join(trajectories), str(episodes), str(keep_realism)])
    digest = hashlib.sha1(ident.encode()).hexdigest()[:16]
    return record.path / "tables" / _PARTS_DIR / f"{digest}.parquet"


def merge_parts(record: RunRecord) -> int:
    """Merge the rows worker processes left in the run (:func:`part_path`) into its
    ``eval_robustness`` table and remove them; returns how many parts were merged."""
    folder = record.path / "tables" / _PARTS_DIR
    parts = sorted(folder.glob("*.parquet")) if folder.is_dir() else []
    for part in parts:
        store_rows(record, read_table(part))
        part.unlink()
    if folder.is_dir() and not any(folder.iterdir()):
        folder.rmdir()
    return len(parts)
