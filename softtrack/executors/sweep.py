"""Grids of runs: expand ``--grid key=v1,v2`` over spec files, and follow a set of runs.

The grid is a Cartesian product of ``--set`` overrides (any spec field, e.g.
``algo.name=td3,ddpg,ppo``), applied to each spec file; every point is validated before a
single run is written. A point's experiment name is the spec's name followed by its grid
values (``td3-ddpg-0.001``) unless the grid sets ``name`` itself; each run records its sweep
id and grid point under run.json's ``notes`` (``sweep``, ``grid``).
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from softtrack.spec import ExperimentSpec, SpecError, load_spec

__all__ = ["GridPoint", "expand_grid", "parse_grid", "parse_seeds", "split_values"]

_NAME_BAD = re.compile(r"[^A-Za-z0-9_.-]+")


def split_values(text: str) -> list[str]:
    """Split ``text`` at the commas outside brackets and quotes: ``[16,16],[64,64]`` → 2."""
    out: list[str] = []
    current: list[str] = []
    depth, quote = 0, ""
    for ch in text:
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch in "[{(":
            depth += 1
        elif ch in "]})":
            depth -= 1
        elif ch == "," and depth == 0:
            out.append("".join(current).strip())
            current = []
            continue
        current.append(ch)
    out.append("".join(current).strip())
    return out


def parse_grid(items: Sequence[str]) -> list[tuple[str, list[str]]]:
    """``["algo.name=td3,ddpg"]`` → ``[("algo.name", ["td3", "ddpg"])]`` (raises SpecError)."""
    grid: list[tuple[str, list[str]]] = []
    for item in items:
        key, sep, raw = item.partition("=")
        key = key.strip()
        values = split_values(raw) if sep else []
        if not key or not sep or not all(values):
            raise SpecError(
                f"--grid {item}",
                "malformed grid axis",
                "write it as dotted.path=v1,v2,..., e.g. --grid algo.name=td3,ddpg",
            )
        if key in {k for k, _ in grid}:
            raise SpecError(f"--grid {item}", f"{key!r} is given twice", "list it once")
        if key == "seeds":
            raise SpecError(
                f"--grid {item}",
                "seeds are not a grid axis",
                "use --seeds 0,1,2 (every grid point gets every seed)",
            )
        grid.append((key, values))
    return grid


def parse_seeds(text: str | None) -> list[int] | None:
    """``"0,1,2"`` or ``"0-4"`` (or a mix) → a list of seeds; ``None`` stays ``None``."""
    if text is None:
        return None
    seeds: list[int] = []
    try:
        for part in (p.strip() for p in text.split(",")):
            lo, dash, hi = part.partition("-")
            seeds += list(range(int(lo), int(hi) + 1)) if dash else [int(part)]
    except ValueError:
        raise SpecError(
            f"--seeds {text}", "malformed seed list", "write seeds as 0,1,2 or as a range 0-4"
        ) from None
    if not seeds:
        raise SpecError(f"--seeds {text}", "no seed given", "write seeds as 0,1,2 or 0-4")
    return seeds


@dataclass(frozen=True)
class GridPoint:
    """One experiment of a sweep: a spec file, its overrides and the validated spec."""

    path: str
    overrides: tuple[str, ...]
    spec: ExperimentSpec
    grid: dict[str, str] = field(default_factory=dict)

    @property
    def n_runs(self) -> int:
        return self.spec.n_runs


def _point_name(base: str, values: Sequence[str]) -> str:
    suffix = "-".join(_NAME_BAD.sub("_", v).strip("_") or "x" for v in values)
    return f"{base}-{suffix}"[:64].rstrip("._-") if suffix else base


def expand_grid(
    paths: Sequence[str],
    grid: Sequence[tuple[str, list[str]]] = (),
    *,
    seeds: Sequence[int] | None = None,
    overrides: Sequence[str] = (),
    check: Callable[[ExperimentSpec, str], None] | None = None,
) -> list[GridPoint]:
    """Every (spec file × grid point), validated and, with ``check`` (e.g.
    ``softtrack.rl.factory.check_supported``), checked to be supported.

    Raises:
        SpecError: a spec, an override or a grid value is invalid (nothing is written).
    """
    if not paths:
        raise SpecError(
            "sweep",
            "no spec file given",
            "e.g. `softtrack sweep experiments/study/td3-64-1e7.yaml`",
        )
    keys = [k for k, _ in grid]
    points: list[GridPoint] = []
    names: dict[str, str] = {}
    for path in paths:
        for values in itertools.product(*(v for _, v in grid)) if grid else [()]:
            sets = [*overrides, *(f"{k}={v}" for k, v in zip(keys, values, strict=True))]
            if seeds is not None:
                sets.append(f"seeds=[{', '.join(str(s) for s in seeds)}]")
            spec = load_spec(path, sets)
            if values and "name" not in keys:
                name = _point_name(spec.name, values)
                spec = spec.model_copy(update={"name": name})
            if check is not None:
                check(spec, str(path))
            where = f"{path} {' '.join(sets)}".strip()
            if spec.name in names and names[spec.name] != where:
                raise SpecError(
                    path,
                    f"two grid points share the experiment name {spec.name!r}",
                    "give the spec files different names (name: ...)",
                    field="name",
                )
            names[spec.name] = where
            points.append(
                GridPoint(str(path), tuple(sets), spec, dict(zip(keys, values, strict=True)))
            )
    return points


def progress_counts(records: Sequence[Any], status_of: Any) -> dict[str, Any]:
    """``{"completed": n, "running": n, ..., "steps_per_second": sum over running runs}``."""
    counts: dict[str, Any] = {
        s: 0 for s in ("completed", "running", "queued", "interrupted", "failed", "lost")
    }
    sps = 0.0
    for record in records:
        status = status_of(record)
        counts[status] = counts.get(status, 0) + 1
        if status == "running" and record.info.steps_per_second:
            sps += float(record.info.steps_per_second)
    counts["steps_per_second"] = sps
    counts["global_step"] = sum(int(r.info.global_step) for r in records)
    return counts
