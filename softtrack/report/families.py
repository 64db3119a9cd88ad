"""Families of controllers, the series a figure draws, and one colour per controller.

A report of many experiments cannot draw every controller in every figure. Its controllers
(:class:`~softtrack.report.data.Group`) fall into families, and figures compare controllers
within a family or a chosen few across families:

* the **task** a controller was trained and evaluated on (:func:`task_of`): the study's
  shared target without contact, the shared target with contact, the viewpoints task. Numbers
  of different tasks are never drawn on one axis;
* the **kind** (:func:`kind_of`): ``study protocol`` (a centralized controller whose spec
  differs from the study's settings only in the algorithm, its budget and how the work is
  spread over processes: :data:`PROTOCOL_NEUTRAL`), ``centralized variants`` (every other
  centralized controller), ``independent`` and ``planners``.

A figure draws at most :data:`MAX_SERIES` controllers; the rest stay in the tables.
:func:`assign_colors` gives every controller drawn anywhere in a report one colour, the same
in every figure, distinct among the controllers of each figure.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from pydantic import ValidationError

from softtrack.report.data import Group
from softtrack.spec import ExperimentSpec

__all__ = [
    "KINDS",
    "MAX_SERIES",
    "PROTOCOL_NEUTRAL",
    "Family",
    "assign_colors",
    "best_first",
    "families",
    "kind_of",
    "task_of",
    "training_groups",
]

MAX_SERIES = 8
"""The most controllers one figure (or one panel of small multiples) draws."""

KINDS = ("study protocol", "centralized variants", "independent", "planners")

PROTOCOL_NEUTRAL = frozenset(
    {
        "name",
        "seeds",
        "controller",
        "algo.name",
        "algo.backend",
        "algo.gradient_steps",
        "algo.n_steps",
        "algo.batch_size",
        "algo.ent_coef",
        "training.total_timesteps",
        "training.n_envs",
        "training.checkpoint_interval",
        "training.keep_checkpoints",
    }
)
"""Spec fields a study-protocol controller may set as it likes: the algorithm, its batch
shape, the budget and the process layout (dotted paths of :class:`ExperimentSpec`)."""

STUDY_TASK = "shared target, no contact"

# Colours in the order they are handed out: tab10, then ten darker or stronger tones (no light
# tints, which are hard to tell apart on white); 20 in all.
PALETTE = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
    "#393b79",
    "#e6ab02",
    "#637939",
    "#843c39",
    "#7b4173",
    "#1b9e77",
    "#a6761d",
    "#66a61e",
    "#e7298a",
    "#3182bd",
)


@dataclass(frozen=True)
class Family:
    """Controllers of one task and kind, in report order."""

    task: str
    kind: str
    groups: tuple[Group, ...]

    @property
    def title(self) -> str:
        """``study protocol · shared target, no contact``."""
        return f"{self.kind} · {self.task}"


def _flatten(data: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in data.items():
        if isinstance(value, Mapping):
            out.update(_flatten(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def _study_defaults() -> dict[str, Any]:
    return _flatten(ExperimentSpec(name="study").model_dump(mode="json"))


def _spec_fields(group: Group) -> dict[str, Any] | None:
    """The group's spec as dotted fields, ``None`` when it does not validate."""
    try:
        spec = ExperimentSpec.model_validate(group.runs[0].record.raw_spec())
    except (ValidationError, IndexError, ValueError):
        return None
    return _flatten(spec.model_dump(mode="json"))


def _section(data: Mapping[str, Any], key: str) -> Mapping[str, Any]:
    value = data.get(key)
    return value if isinstance(value, Mapping) else {}


def task_of(group: Group) -> str:
    """``shared target, no contact`` (the study's), ``shared target, contact on``,
    ``viewpoints, contact on`` … from ``env.task.name`` and ``env.physics.contact_k``."""
    spec = group.runs[0].record.raw_spec() if group.runs else {}
    env = _section(spec, "env")
    task, physics = _section(env, "task"), _section(env, "physics")
    name = str(task.get("name", "shared"))
    k = physics.get("contact_k", 0.0)
    on = isinstance(k, int | float) and not isinstance(k, bool) and k > 0
    label = "shared target" if name == "shared" else name
    return f"{label}, {'contact on' if on else 'no contact'}"


def kind_of(group: Group) -> str:
    """One of :data:`KINDS` (module docstring)."""
    if group.controller == "mpc":
        return "planners"
    if group.controller == "independent":
        return "independent"
    fields = _spec_fields(group)
    if fields is None:
        return "centralized variants"
    defaults = _study_defaults()
    differs = {k for k in set(fields) | set(defaults) if fields.get(k) != defaults.get(k)}
    return "study protocol" if differs <= PROTOCOL_NEUTRAL else "centralized variants"


def families(groups: Sequence[Group]) -> list[Family]:
    """The groups by (task, kind): the study's task first, then the others by name; kinds in
    the order of :data:`KINDS`; groups in report order within a family."""
    buckets: dict[tuple[str, str], list[Group]] = {}
    for group in groups:
        buckets.setdefault((task_of(group), kind_of(group)), []).append(group)
    order = sorted(buckets, key=lambda k: (k[0] != STUDY_TASK, k[0], KINDS.index(k[1])))
    return [Family(task, kind, tuple(buckets[(task, kind)])) for task, kind in order]


def training_groups(groups: Sequence[Group]) -> list[Group]:
    """``groups`` without those whose every run is the source of a derived run in ``groups``
    (run.json ``notes.derived_from`` of the derived run: the same training with a changed
    spec), so each training is drawn once, under the name of the run derived from it."""
    sources = {
        str(source.get("run_id"))
        for g in groups
        for r in g.runs
        if isinstance(source := r.record.info.notes.get("derived_from"), dict)
    }

    def is_source(group: Group) -> bool:
        return bool(group.runs) and all(
            r.record.info.run_id in sources or r.run_id in sources for r in group.runs
        )

    return [g for g in groups if not is_source(g)]


def best_first(
    groups: Iterable[Group], score: Callable[[Group], float], *, higher: bool = False
) -> list[Group]:
    """``groups`` ordered best score first (ties and NaN scores last, in report order)."""
    indexed = list(enumerate(groups))

    def key(item: tuple[int, Group]) -> tuple[bool, float, int]:
        value = score(item[1])
        missing = not math.isfinite(value)
        return missing, (-value if higher else value) if not missing else 0.0, item[0]

    return [g for _, g in sorted(indexed, key=key)]


def assign_colors(figures: Iterable[Sequence[str]]) -> dict[str, str]:
    """One colour per controller label, the same in every figure: each label (those of the
    first figures first) gets, among the colours of :data:`PALETTE` that no label it shares a
    figure with has, the least used so far (the earliest in the palette on ties), so labels
    share a colour only when the palette runs out. Beyond 20 labels in one figure, colours
    repeat."""
    figures = [list(dict.fromkeys(f)) for f in figures]
    neighbours: dict[str, set[str]] = {}
    order: list[str] = []
    for labels in figures:
        for label in labels:
            if label not in neighbours:
                neighbours[label] = set()
                order.append(label)
            neighbours[label].update(other for other in labels if other != label)
    colors: dict[str, str] = {}
    uses = dict.fromkeys(PALETTE, 0)
    for i, label in enumerate(order):
        taken = {colors[n] for n in neighbours[label] if n in colors}
        free = [c for c in PALETTE if c not in taken]
        color = min(free, key=lambda c: uses[c]) if free else PALETTE[i % len(PALETTE)]
        colors[label] = color
        uses[color] += 1
    return colors
