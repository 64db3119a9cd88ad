"""The measured floors of the transport paths, kept per physics and path geometry, so that
``softtrack train`` and ``evaluate`` warn about a path out of the sphere's reach at once.

Measuring a held region takes minutes (:mod:`softtrack.evaluation.workspace`), too long for
every command. ``softtrack workspace SPEC`` therefore records its floors in a small JSON file
named by :func:`workspace_key`, under :func:`floors_dir` (``$SOFTTRACK_CACHE_DIR/workspace``,
else ``~/.cache/softtrack/workspace``); the floors of the shipped transport specs ship with
the package (``softtrack/data/workspace``). :func:`reach_warning` reads them back: a path
whose floor exceeds :data:`REACH_TOLERANCE` gets one warning line naming its floor; a spec
whose floors were never measured gets one line saying how to measure them.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from softtrack.env.settings import TrackingConfig
from softtrack.env.targets import EVAL_TRAJECTORIES
from softtrack.numbers import is_finite_number
from softtrack.store.atomic import atomic_write_text

__all__ = [
    "REACH_TOLERANCE",
    "floors_dir",
    "known_floors",
    "reach_warning",
    "record_floors",
    "workspace_key",
]

#: A path whose floor exceeds this (m) is out of the held sphere's reach: the transport
#: task's accuracy target (a quarter of the reachable paths' 0.1-m radius).
REACH_TOLERANCE = 0.025
SHIPPED_FLOORS = Path(__file__).resolve().parents[1] / "data" / "workspace"
# the target settings that shape the paths (their speed and period do not move a point)
_PATH_FIELDS = ("center", "circle_radius", "rectangle_size", "figure8_amplitude")


def workspace_key(config: TrackingConfig) -> str:
    """16 hex digits naming the held region's physics (every engine and sphere setting and the
    grip) and the paths' geometry; equal configs give equal keys on every machine."""
    described = {
        "sim": dataclasses.asdict(config.sim),
        "grip": config.task.grip,
        "paths": {name: getattr(config.target, name) for name in _PATH_FIELDS},
    }
    text = json.dumps(described, sort_keys=True, default=list)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def floors_dir() -> Path:
    """Where ``softtrack workspace`` records floors: ``$SOFTTRACK_CACHE_DIR/workspace``, else
    ``~/.cache/softtrack/workspace``."""
    root = os.environ.get("SOFTTRACK_CACHE_DIR") or Path.home() / ".cache" / "softtrack"
    return Path(root) / "workspace"


def record_floors(
    config: TrackingConfig, floors: Mapping[str, float], samples: int, spec_name: str
) -> Path:
    """Record each path's floor (m; inf when no sample held the sphere at rest) of ``config``,
    measured with ``samples`` samples, in :func:`floors_dir`; returns the file. An earlier
    record of the same key is replaced."""
    path = floors_dir() / f"{workspace_key(config)}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    record = {
        "spec": spec_name,
        "torque_scale": float(config.sim.torque_scale),
        "samples": int(samples),
        "floors": {  # null: nothing held (JSON has no inf)
            name: float(value) if math.isfinite(value) else None for name, value in floors.items()
        },
    }
    atomic_write_text(path, json.dumps(record, indent=1) + "\n")
    return path


def _read_record(path: Path) -> dict[str, float] | None:
    """The floors of one record file; None when it is missing or not a valid record."""
    try:
        if not path.is_file() or path.stat().st_size > 2**16:
            return None
        floors = json.loads(path.read_text(encoding="utf-8"))["floors"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not isinstance(floors, dict) or not all(
        v is None or is_finite_number(v) for v in floors.values()
    ):
        return None
    return {str(name): math.inf if v is None else float(v) for name, v in floors.items()}


def known_floors(config: TrackingConfig) -> dict[str, float] | None:
    """Each path's recorded floor (m; inf where the sphere was held nowhere) for ``config``:
    the user's record, else the shipped one; None when neither exists (or a file is
    unreadable: it is then ignored)."""
    name = f"{workspace_key(config)}.json"
    for folder in (floors_dir(), SHIPPED_FLOORS):
        floors = _read_record(folder / name)
        if floors is not None:
            return floors
    return None


def reach_warning(
    config: TrackingConfig,
    spec: str,
    paths: Sequence[str] = EVAL_TRAJECTORIES,
    unmeasured_note: bool = True,
) -> str | None:
    """One line for a transport config: the paths whose recorded floor exceeds
    :data:`REACH_TOLERANCE`, or (with ``unmeasured_note``) how to measure them when none is
    recorded; None for another task or when every path is within reach. ``spec`` is the spec
    as the user gave it."""
    if not config.task.carries_object:
        return None
    floors = known_floors(config)
    if floors is None and not unmeasured_note:
        return None
    if floors is None:
        return (
            f"note: the transport paths' floors are not measured for this physics; "
            f"`softtrack workspace {spec}` measures them (minutes on one core)"
        )
    far: dict[str, Any] = {p: floors[p] for p in paths if floors.get(p, 0.0) > REACH_TOLERANCE}
    if not far:
        return None
    if all(math.isinf(floor) for floor in floors.values()):
        return (
            "warning: out of reach: `softtrack workspace` found no action that holds the sphere "
            "at rest with this physics (it cannot be gripped where it starts); raise "
            'env.task.grip or move env.physics.sphere (docs/environment.md, "The workspace")'
        )
    listed = ", ".join(f"{name} {floor:.3f} m" for name, floor in far.items())
    return (
        f"warning: out of the held sphere's reach: {listed} (each path's floor, the least RMSE "
        f"of any controller that holds the sphere; at most {REACH_TOLERANCE} m is within "
        'reach); move the paths into the held region (docs/environment.md, "The workspace")'
    )
