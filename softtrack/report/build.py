"""Assemble a report directory from the stored tables of selected runs.

Layout of ``out_dir``::

    index.md       the report: tables, embedded figures, each controller's provenance once
                   (*Behind these numbers*) and a one-line provenance footer in every figure
    index.html     the same content as a standalone HTML page (figures by relative path)
    report.json    manifest: files written, command, runs, generation time
    figures/*.png  the figures (110 dpi)

Every controller is in the tables; the per-run trajectory, error and moment figures are drawn
for a few chosen controllers only (:mod:`softtrack.report.featured`: the study protocol, the
best centralized and the best independent controller, side by side in one figure per
trajectory), or for every controller with ``all_figures=True``.

Each file is written atomically (temporary file + rename), figures first and the index last,
so an index never points at a missing figure. Nothing outside ``out_dir`` is touched; inside
it only files this module wrote before (listed in the previous ``report.json``) are removed
when a rebuild no longer produces them.

The document model and shared formatting are in :mod:`softtrack.report.document`; the sections
are in :mod:`softtrack.report.training_sections` and :mod:`softtrack.report.evaluation_sections`.
"""

from __future__ import annotations

import json
import os
import shlex
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path

from softtrack.evaluation.run_evaluation import PolicyLoader
from softtrack.report.across_seeds import across_seeds_section
from softtrack.report.contact_section import contact_section
from softtrack.report.data import group_runs, load_runs, trajectories_in
from softtrack.report.document import (
    FIGURES_DIR,
    NOT_IN_STUDY,
    Context,
    Doc,
    provenance_section,
)
from softtrack.report.evaluation_sections import (
    actions_section,
    errors_section,
    moments_section,
    random_targets_section,
    trajectories_section,
)
from softtrack.report.featured import featured_groups
from softtrack.report.group_summaries import metrics_summary
from softtrack.report.interactive_build import INTERACTIVE_PAGE, write_interactive
from softtrack.report.mpc_section import planning_section
from softtrack.report.plan import plan_figures
from softtrack.report.robustness_section import robustness_section
from softtrack.report.training_sections import (
    final_section,
    runs_section,
    training_section,
    validation_section,
)
from softtrack.report.transport_section import transport_section
from softtrack.report.tune_view import TuneView, tune_section
from softtrack.store.atomic import atomic_write_json, atomic_write_text
from softtrack.store.runs import RunRecord, RunStore, RunStoreError, resolve_runs_dir
from softtrack.store.selection import EmptySelectionError, select_runs

__all__ = ["build_report", "report_selection"]

MANIFEST = "report.json"


def _remove_stale(out_dir: Path, keep: set[str]) -> None:
    """Delete figures listed in the previous manifest that this build did not write."""
    manifest = out_dir / MANIFEST
    try:
        old = json.loads(manifest.read_text(encoding="utf-8")).get("files", [])
    except (OSError, ValueError, AttributeError):
        return
    figures = (out_dir / FIGURES_DIR).resolve()
    for name in old if isinstance(old, list) else []:
        if not isinstance(name, str) or name in keep:
            continue
        path = (out_dir / name).resolve()
        if path.parent == figures and path.suffix == ".png" and path.is_file():
            path.unlink()


def build_report(
    records: Sequence[RunRecord],
    out_dir: str | os.PathLike[str],
    command_line: str | Sequence[str],
    *,
    all_figures: bool = False,
    figures_for: Sequence[str] = (),
    load: PolicyLoader | None = None,
    tune_views: Sequence[TuneView] = (),
    on_problem: Callable[[str], None] | None = None,
) -> Path:
    """Write the report of ``records`` into ``out_dir``; return the path of ``index.md``.

    Reads only the runs' stored files. Missing tables give "no data" figures and table cells.

    Args:
        records: the runs (see :func:`softtrack.store.selection.select_runs`).
        out_dir: the report directory (created if needed; may already hold an older report).
        command_line: the command that built the report, shown in *Behind these numbers*.
        all_figures: draw the trajectory, error and moment figures of every controller (one
            figure per controller and trajectory) instead of those of the chosen few
            (:func:`softtrack.report.featured.featured_groups`).
        figures_for: experiment names whose controllers get those figures, instead of the
            automatic choice.
        load: with a policy loader, also ``interactive.html``: the answers first, the
            featured controllers replayed in a 3-D viewer, toggleable training curves, the
            runs last (:mod:`softtrack.report.interactive`).
        tune_views: tuning studies shown after the answers: their trials (parallel coordinates
            on the interactive page), parameter importance and best trials
            (:mod:`softtrack.report.tune_view`).
        on_problem: told each table that could not be read (the report leaves it out and
            lists it with the runs).

    Raises:
        EmptySelectionError: ``records`` is empty.
        RunStoreError: ``out_dir`` exists and is not a directory, or a ``figures_for`` name
            is no experiment of ``records``.
    """
    if not records:
        raise EmptySelectionError("nothing to report: the selection contains no runs")
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise RunStoreError(f"{out_dir}: exists and is not a directory; choose another --out")
    command = command_line if isinstance(command_line, str) else shlex.join(command_line)
    runs = load_runs(records)
    if on_problem is not None:
        for problem in (p for run in runs for p in run.problems):
            on_problem(problem)
    groups = group_runs(runs)
    summary = metrics_summary(groups)
    featured = featured_groups(groups, summary, all_groups=all_figures, names=figures_for)
    trajectories = trajectories_in(groups)
    figures_dir = out_dir / FIGURES_DIR
    figures_dir.mkdir(parents=True, exist_ok=True)
    ctx = Context(groups, command, figures_dir, all_figures, plan_figures(groups, summary))

    names = ", ".join(dict.fromkeys(g.name for g in groups))
    title = f"softtrack report: {names}"
    generated = datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")
    doc = Doc()
    doc.h(1, title)
    doc.p(
        f"Generated {generated} by `{command}` from the stored tables of {len(runs)} run(s); "
        "rebuild it at any time with the same command. Beside each measured number is the "
        f"study's published value ({NOT_IN_STUDY} where it gives none)."
    )
    # the answers first (the best controllers per task with their intervals, then every
    # controller beside the study), then one section per question, the runs table last
    across_seeds_section(doc, ctx, trajectories)
    tune_section(doc, tune_views)
    errors_section(doc, ctx, summary, trajectories)
    training_section(doc, ctx)
    final_section(doc, ctx)
    validation_section(doc, ctx)
    random_targets_section(doc, ctx)
    robustness_section(doc, ctx)
    contact_section(doc, ctx)
    transport_section(doc, ctx)
    planning_section(doc, ctx)
    actions_section(doc, ctx, summary, trajectories)
    trajectories_section(doc, ctx, trajectories, featured)
    moments_section(doc, ctx, trajectories, featured)
    provenance_section(doc, ctx)
    runs_section(doc, ctx, runs)

    index = out_dir / "index.md"
    atomic_write_text(out_dir / "index.html", doc.html(title), fsync=False)
    atomic_write_text(index, doc.markdown(), fsync=False)
    if load is not None:
        intro = (
            f"Generated {generated} by `{command}` from {len(runs)} run(s). The featured "
            "controllers are replayed from their policies; every number is from the stored tables."
        )
        write_interactive(
            out_dir, title, intro, ctx, runs, featured, trajectories, load, tune_views
        )
        ctx.written.append(INTERACTIVE_PAGE)
    keep = set(ctx.written)
    _remove_stale(out_dir, keep)
    atomic_write_json(
        out_dir / MANIFEST,
        {
            "generated": generated,
            "command": command,
            "runs": [r.run_id for r in runs],
            "files": ["index.md", "index.html", *ctx.written],
        },
        fsync=False,
    )
    return index


def report_selection(
    selection: Sequence[str],
    out_dir: str | os.PathLike[str],
    *,
    runs_dir: str | os.PathLike[str] | None = None,
    command_line: str | Sequence[str] | None = None,
    all_figures: bool = False,
    figures_for: Sequence[str] = (),
) -> Path:
    """Select runs (:func:`select_runs`) under ``runs_dir`` and :func:`build_report` them."""
    store = RunStore(resolve_runs_dir(runs_dir))
    records = select_runs(store, selection)
    if command_line is None:
        command_line = ["softtrack", "report", *selection, "--out", str(out_dir)]
    return build_report(
        records, out_dir, command_line, all_figures=all_figures, figures_for=figures_for
    )
