"""Run selection, the same in every command: an item is a run directory, a spec file, an
experiment name or a run id (or a unique prefix of one). :func:`select_runs` gives every run an
item names; :func:`select_one_run` the single run a command that works on one run needs (an
experiment of several runs is one line naming them)."""

from __future__ import annotations

import difflib
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from softtrack.spec import load_spec, spec_hash
from softtrack.store.catalog import read_catalog
from softtrack.store.runs import (
    RunNotFoundError,
    RunRecord,
    RunStore,
    RunStoreError,
    UnreadableRun,
    resolve_runs_dir,
)

__all__ = ["EmptySelectionError", "RunIndex", "select_one_run", "select_runs"]

_SPEC_SUFFIXES = (".yaml", ".yml")


class EmptySelectionError(RunStoreError):
    """The selection names no run; the message is one line with the fix."""


def _looks_like_spec(item: str) -> bool:
    return item.lower().endswith(_SPEC_SUFFIXES) or Path(item).is_file()


def select_runs(
    store: RunStore, selection: Sequence[str], index: RunIndex | None = None
) -> list[RunRecord]:
    """The runs ``selection`` names, in selection order, each once.

    Each item of ``selection`` is, in this order of precedence:

    * a run directory (any directory holding ``run.json``, e.g. ``models/td3-sbx-1e7-seed0``
      or one copied from another machine), read where it is;
    * a spec file (``*.yaml``/``*.yml`` or an existing file): every run whose ``spec_hash``
      equals the hash of that spec (:func:`softtrack.spec.spec_hash`, seed-independent);
    * an experiment name (``run.json`` ``name``): every run of that experiment;
    * a run id or a unique, case-insensitive prefix of one.

    Runs of one item are ordered by (experiment name, seed, id). ``index``: the store's
    :class:`RunIndex`, read once by a caller that selects several times.

    Raises:
        EmptySelectionError: ``selection`` is empty, or an item matches no run.
        RunNotFoundError: an id prefix is ambiguous.
        SpecError: a spec file is missing or invalid.
    """
    items = [str(item).strip() for item in selection if str(item).strip()]
    if not items:
        raise EmptySelectionError(
            "nothing selected: give one or more experiment names, run ids, run directories or "
            "spec files "
            f"(list the runs with `softtrack runs --runs-dir {store.root}`)"
        )
    chosen: dict[str, RunRecord] = {}
    for item in items:
        directory = _run_directory(item)
        if directory is not None:
            chosen.setdefault(directory.run_id, directory)
            continue
        index = index or RunIndex.of(store)
        found = _match(store, index, item)
        for record in sorted(found, key=lambda r: (r.info.name, r.info.seed, r.run_id)):
            chosen.setdefault(record.run_id, record)
    return list(chosen.values())


@dataclass(frozen=True)
class RunIndex:
    """The catalog's columns that select runs (:mod:`softtrack.store.catalog`): reading the
    chosen runs' ``run.json`` only, not every run's."""

    dirs: list[str]
    run_ids: list[str | None]
    names: list[str | None]
    spec_hashes: list[str | None]

    @classmethod
    def of(cls, store: RunStore) -> RunIndex:
        if not store.root.is_dir():
            return cls([], [], [], [])
        columns = read_catalog(store.root).columns(
            ["dir", "run_id", "name", "spec_hash", "unreadable"]
        )
        readable = [i for i, bad in enumerate(columns["unreadable"]) if bad is None]
        return cls(
            *([columns[key][i] for i in readable] for key in ("dir", "run_id", "name", "spec_hash"))
        )

    def records(self, store: RunStore, where: list[bool]) -> list[RunRecord]:
        found = []
        for directory, chosen in zip(self.dirs, where, strict=True):
            if chosen:
                try:
                    found.append(store.read_record(store.root / directory))
                except RunStoreError:
                    continue  # changed since the catalog saw it: unreadable now
        return found


def _run_directory(item: str) -> RunRecord | None:
    """The run in directory ``item`` (``None`` if it is not one; an id is not a path).

    Raises:
        RunStoreError: the directory holds a run whose ``run.json`` is missing.
    """
    path = Path(item)
    if (path / "run.json").is_file():
        path = path.resolve()
        return RunStore(path.parent).get_run(path.name)
    if path.is_dir() and (path / "spec.yaml").is_file():
        raise RunStoreError(
            f"{path / 'run.json'}: the run record is missing, so the run cannot be used; "
            f"{UnreadableRun(path, '').fix}"
        )
    return None


def select_one_run(item: str, runs_dir: str | os.PathLike[str] | None = None) -> RunRecord:
    """The one run ``item`` names (a run directory, a run id or unique prefix, or an experiment
    or spec with a single run) under ``runs_dir`` (default :func:`resolve_runs_dir`).

    Raises:
        EmptySelectionError, RunNotFoundError: ``item`` names no run.
        RunStoreError: it names several (one line listing them and how to pick one).
    """
    store = RunStore(resolve_runs_dir(runs_dir))
    found = select_runs(store, [item])
    if len(found) > 1:
        listed = ", ".join(f"{r.run_id} (seed {r.info.seed})" for r in found[:4])
        more = f" and {len(found) - 4} more" if len(found) > 4 else ""
        raise RunStoreError(
            f"{item!r} names {len(found)} runs ({listed}{more}); this command takes one: "
            "give its run id or run directory"
        )
    return found[0]


def _match(store: RunStore, index: RunIndex, item: str) -> list[RunRecord]:
    if _looks_like_spec(item):
        spec = load_spec(item)
        digest = spec_hash(spec)
        found = index.records(store, [h == digest for h in index.spec_hashes])
        if not found:
            raise EmptySelectionError(
                f"{item}: no run in {store.root} has this spec (hash {digest[:12]}); "
                f"train it with `softtrack train {item}` or select runs by name or id"
            )
        return found
    by_name = index.records(store, [n == item for n in index.names])
    if by_name:
        return by_name
    try:
        return [store.get_run(item)]
    except RunNotFoundError as exc:
        if "matches" in str(exc):  # an ambiguous prefix: its message already says what to do
            raise
        names = sorted({n for n in index.names if n})
        close = difflib.get_close_matches(item, names, n=5, cutoff=0.5)
        known = (
            f"closest names: {', '.join(close)}"
            if close
            else f"known: {', '.join(names[:5]) or 'none'}"
            + (f" and {len(names) - 5} more" if len(names) > 5 else "")
        )
        raise EmptySelectionError(
            f"{store.root}: no run {item!r}: it is neither an experiment name ({known}), a run "
            f"id, a run directory nor a spec file; list the runs with `softtrack runs "
            f"--runs-dir {store.root}`"
        ) from None
