"""Assemble a report directory from the stored tables of selected runs.

Layout of ``out_dir``::

    index.md       the report: tables, embedded figures, provenance under every table/figure
    index.html     the same content as a standalone HTML page (figures by relative path)
    report.json    manifest: files written, command, runs, generation time
    figures/*.png  the figures (150 dpi)

Each file is written atomically (temporary file + rename), figures first and the index last,
so an index never points at a missing figure. Nothing outside ``out_dir`` is touched; inside
it only files this module wrote before (listed in the previous ``report.json``) are removed
when a rebuild no longer produces them.
"""

from __future__ import annotations

import html
import json
import math
import os
import re
import shlex
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import pandas as pd

from softtrack.report import figures as fg
from softtrack.report.actions import ACTIONS_HEADER, actions_caption, actions_rows
from softtrack.report.data import (
    DIRECTIONS,
    Group,
    RunData,
    final_stage_table,
    group_runs,
    load_runs,
    metrics_summary,
    moment_peaks,
    representative_run,
    training_curves,
    trajectories_in,
)
from softtrack.report.reference import (
    STUDY_BUDGET_TEXT,
    STUDY_PEAK_MOMENTS,
    STUDY_RMSE_3D,
    TRAJECTORY_TITLES,
    study_peak_moment,
    study_rmse_3d,
)
from softtrack.report.select import EmptySelectionError, select_runs
from softtrack.report.text import mean_pm_std
from softtrack.store.atomic import atomic_write_json, atomic_write_text
from softtrack.store.runs import RunRecord, RunStore, RunStoreError, resolve_runs_dir

__all__ = ["build_report", "report_selection"]

FIGURES_DIR = "figures"
MANIFEST = "report.json"
NOT_IN_SPEC = "—"


# ---- a minimal document model rendered to Markdown and HTML ---------------------------------
@dataclass
class _Doc:
    """Blocks: ("h", level, text), ("p", text), ("table", header, rows), ("img", src, alt)."""

    blocks: list[tuple[object, ...]] = field(default_factory=list)

    def h(self, level: int, text: str) -> None:
        self.blocks.append(("h", level, text))

    def p(self, text: str) -> None:
        self.blocks.append(("p", text))

    def table(self, header: Sequence[str], rows: Iterable[Sequence[str]]) -> None:
        self.blocks.append(("table", list(header), [list(r) for r in rows]))

    def img(self, src: str, alt: str) -> None:
        self.blocks.append(("img", src, alt))

    def markdown(self) -> str:
        out: list[str] = []
        for block in self.blocks:
            kind = block[0]
            if kind == "h":
                out.append(f"{'#' * int(block[1])} {block[2]}")  # type: ignore[call-overload]
            elif kind == "p":
                out.append(str(block[1]))
            elif kind == "table":
                header, rows = block[1], block[2]
                cell = lambda s: str(s).replace("|", "\\|").replace("\n", " ")
                out.append(
                    "\n".join(
                        [
                            "| " + " | ".join(cell(h) for h in header) + " |",  # type: ignore[attr-defined]
                            "|" + "---|" * len(header),
                        ]  # type: ignore[arg-type]
                        + ["| " + " | ".join(cell(c) for c in r) + " |" for r in rows]  # type: ignore[attr-defined]
                    )
                )
            elif kind == "img":
                out.append(f"![{block[2]}]({block[1]})")
        return "\n\n".join(out) + "\n"

    def html(self, title: str) -> str:
        def inline(text: object) -> str:
            escaped = html.escape(str(text))
            escaped = re.sub(r"`([^`]+)`", r"<code>\1</code>", escaped)
            escaped = re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", escaped)
            return re.sub(r"\*([^*]+)\*", r"<em>\1</em>", escaped)

        body: list[str] = []
        for block in self.blocks:
            kind = block[0]
            if kind == "h":
                body.append(f"<h{block[1]}>{inline(block[2])}</h{block[1]}>")
            elif kind == "p":
                body.append(f"<p>{inline(block[1])}</p>")
            elif kind == "table":
                head = "".join(f"<th>{inline(h)}</th>" for h in block[1])  # type: ignore[attr-defined]
                rows = "".join(
                    "<tr>" + "".join(f"<td>{inline(c)}</td>" for c in r) + "</tr>"
                    for r in block[2]  # type: ignore[attr-defined]
                )
                body.append(f"<table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>")
            elif kind == "img":
                src, alt = html.escape(str(block[1]), quote=True), html.escape(str(block[2]))
                body.append(f'<p><img src="{src}" alt="{alt}"></p>')
        style = (
            "body{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;"
            "line-height:1.45}table{border-collapse:collapse;margin:1em 0;font-size:0.9em}"
            "th,td{border:1px solid #bbb;padding:3px 7px;text-align:left}th{background:#eee}"
            "img{max-width:100%;border:1px solid #ddd}code{background:#f4f4f4;padding:0 3px}"
        )
        return (
            '<!DOCTYPE html>\n<html lang="en">\n<head><meta charset="utf-8">'
            f"<title>{html.escape(title)}</title><style>{style}</style></head>\n<body>\n"
            + "\n".join(body)
            + "\n</body>\n</html>\n"
        )


# ---- formatting -----------------------------------------------------------------------------
def _num(value: float | None, digits: int) -> str:
    if value is None or not math.isfinite(value):
        return "no data"
    return f"{value:.{digits}f}"


def _study(value: float | None, digits: int) -> str:
    return NOT_IN_SPEC if value is None else f"{value:.{digits}f}"


def _seeds(seeds: Iterable[int]) -> str:
    return ", ".join(str(s) for s in sorted(set(seeds))) or "none"


def _commit(run: RunData) -> str:
    info = run.record.info
    if not info.git_commit:
        return "unknown"
    return info.git_commit[:12] + (" (+ uncommitted changes)" if info.git_dirty else "")


def _group_provenance(group: Group) -> str:
    budgets = ", ".join(group.budgets)
    reached = ", ".join(f"{r.last_step:,}" for r in group.runs)
    commits = "; ".join(sorted({_commit(r) for r in group.runs}))
    hashes = ", ".join(sorted({r.record.info.spec_hash[:12] for r in group.runs}))
    commands = sorted(
        {shlex.join(r.record.info.command) for r in group.runs if r.record.info.command}
    )
    text = (
        f"**{group.label}**: experiment `{group.name}`, spec `{hashes}`, seeds "
        f"{_seeds(group.seeds)}, budget {budgets} (reached {reached}), "
        f"commit `{commits}`"
    )
    if commands:
        text += "; trained by " + ", ".join(f"`{c}`" for c in commands)
    return text


class _Context:
    """What every section needs: the groups, the report command and the figure list."""

    def __init__(self, groups: list[Group], command: str, figures_dir: Path) -> None:
        self.groups = groups
        self.command = command
        self.figures_dir = figures_dir
        self.written: list[str] = []

    def provenance(self, groups: Sequence[Group] | None = None) -> str:
        groups = self.groups if groups is None else groups
        parts = [f"Command: `{self.command}`."]
        parts += [_group_provenance(g) + "." for g in groups]
        parts.append(f"Study: {STUDY_BUDGET_TEXT}.")
        return "*Behind these numbers* — " + " ".join(parts)

    def footer(self, groups: Sequence[Group] | None = None) -> str:
        groups = self.groups if groups is None else groups
        names = ", ".join(sorted({g.name for g in groups}))
        seeds = _seeds(s for g in groups for s in g.seeds)
        budgets = ", ".join(sorted({b for g in groups for b in g.budgets}))
        hashes = ", ".join(sorted({r.record.info.spec_hash[:8] for g in groups for r in g.runs}))
        commits = ", ".join(
            sorted({(r.record.info.git_commit or "unknown")[:8] for g in groups for r in g.runs})
        )
        return (
            f"experiment {names} · spec {hashes} · seeds {seeds} · budget {budgets} · "
            f"commit {commits}"
        )

    def figure(self, name: str) -> tuple[Path, str]:
        """(path to write, path relative to the report) of figure ``name``."""
        self.written.append(f"{FIGURES_DIR}/{name}")
        return self.figures_dir / name, f"{FIGURES_DIR}/{name}"


# ---- sections -------------------------------------------------------------------------------
def _runs_section(doc: _Doc, ctx: _Context, runs: Sequence[RunData]) -> None:
    doc.h(2, "Runs")
    rows = []
    for g in ctx.groups:
        for r in g.runs:
            info = r.record.info
            tables = [
                name
                for name, df in (
                    ("train", r.train),
                    ("trajectories", r.trajectories),
                    ("metrics", r.metrics),
                    ("moments", r.moments),
                )
                if df is not None
            ]
            rows.append(
                [
                    f"`{r.run_id}`",
                    info.name,
                    info.algo,
                    info.controller,
                    str(info.seed),
                    info.status,
                    f"{r.last_step:,} / {info.total_timesteps:,}",
                    *_training_speed(r),
                    info.cpu or "—",
                    info.spec_hash[:12],
                    _commit(r),
                    ", ".join(tables) or "none",
                ]
            )
    doc.table(
        [
            "run",
            "experiment",
            "algorithm",
            "controller",
            "seed",
            "status",
            "env steps / budget",
            "training time",
            "env steps/s",
            "CPU (speed depends on it)",
            "spec hash",
            "commit",
            "stored tables",
        ],
        rows,
    )
    doc.p(ctx.provenance())
    problems = [p for r in runs for p in r.problems]
    if problems:
        doc.p("Problems: " + "; ".join(problems) + ".")


def _training_speed(run: RunData) -> tuple[str, str]:
    """(training wall time, env steps per second) of a run from its training clock, summed over
    sessions (the ``wall_time`` of its last logged episode); "—" without training episodes."""
    if run.train is None or not len(run.train) or "wall_time" not in run.train:
        return "—", "—"
    seconds = float(run.train["wall_time"].max())
    if not seconds > 0:
        return "—", "—"
    duration = f"{seconds / 60:.0f} min" if seconds < 5400 else f"{seconds / 3600:.2f} h"
    return duration, f"{run.last_step / seconds:,.0f}"


def _training_section(doc: _Doc, ctx: _Context) -> None:
    doc.h(2, "Training curves (study Fig. 3)")
    curves, smoothing = training_curves(ctx.groups)
    path, rel = ctx.figure("training_curves.png")
    fg.training_curves_figure(curves, smoothing, path, ctx.footer())
    doc.img(rel, "Training curves: episode return against environment steps")
    if curves:
        doc.p(
            f"Episode return against environment steps, mean ± 1 sample std across seeds; "
            f"smoothing: {smoothing.describe()}. The study's curves are not in the SPEC."
        )
    else:
        doc.p("No data: no selected run has stored training episodes.")
    doc.p(ctx.provenance())


def _final_section(doc: _Doc, ctx: _Context) -> None:
    doc.h(2, "Final-stage return (study Table 3)")
    table = final_stage_table(ctx.groups)
    rows = []
    for row in table.itertuples():
        group = next(g for g in ctx.groups if g.label == row.group)
        per_seed = ", ".join(f"{s}: {v:.2f}" for s, v in sorted(row.values.items())) or "none"
        if row.missing:
            per_seed += f" (no final stage: seed {_seeds(row.missing)})"
        rows.append(
            [
                row.group,
                "both arms" if row.arm < 0 else f"arm {int(row.arm) + 1} policy",
                f"{row.n} of {len(row.seeds)}",
                mean_pm_std(row.mean, row.std, 2),
                per_seed,
                NOT_IN_SPEC,
                ", ".join(group.budgets),
                "10,000,000 env steps per run",
            ]
        )
    doc.table(
        [
            "algorithm",
            "policy",
            "seeds with data",
            "final-stage return (mean ± std)",
            "per seed",
            "study",
            "budget",
            "study budget",
        ],
        rows,
    )
    doc.p(
        "Final-stage return: the mean episode return over the last 10 % of a run's training "
        "budget (SPEC §4; the run's `training.final_stage_fraction`), then mean ± sample std "
        f"across seeds. Study values: {NOT_IN_SPEC} = the SPEC does not state them."
    )
    doc.p(ctx.provenance())
    path, rel = ctx.figure("final_returns.png")
    fg.final_returns_figure(table, path, ctx.footer())
    doc.img(rel, "Final-stage return per algorithm")


def _cell(row: pd.Series, metric: str) -> str:
    """``mean ± std`` of ``metric`` in a :func:`metrics_summary` row (m, 4 decimals)."""
    return mean_pm_std(row.get(f"{metric}_mean"), row.get(f"{metric}_std"), 4)


def _metric_rows(
    summary: pd.DataFrame, group: Group, trajectories: Sequence[str]
) -> list[list[str]]:
    part = summary[summary["group"] == group.label] if not summary.empty else summary
    rows = []
    for trajectory in trajectories:
        for arm in (0, 1):
            sel = (
                part[(part["trajectory"] == trajectory) & (part["arm"] == arm)]
                if not part.empty
                else part
            )
            study = _study(study_rmse_3d(group.algo, group.controller, trajectory, arm), 3)
            name = TRAJECTORY_TITLES.get(trajectory, trajectory)
            if sel.empty:
                rows.append([name, f"arm {arm + 1}"] + ["no data"] * 8 + [study, "no data", "0"])
                continue
            r = sel.iloc[0]
            rows.append(
                [name, f"arm {arm + 1}"]
                + [
                    _cell(r, c)
                    for c in (
                        "rmse_x",
                        "rmse_y",
                        "rmse_z",
                        "mae_x",
                        "mae_y",
                        "mae_z",
                        "mean_spatial_error",
                        "rmse_3d",
                    )
                ]
                + [study, _cell(r, "rmse_3d_steady"), str(r["n"])]
            )
    return rows


def _errors_section(
    doc: _Doc, ctx: _Context, summary: pd.DataFrame, trajectories: Sequence[str]
) -> None:
    doc.h(2, "Tracking error (study Table 4)")
    header = [
        "trajectory",
        "arm",
        "RMSE x (m)",
        "RMSE y (m)",
        "RMSE z (m)",
        "MAE x (m)",
        "MAE y (m)",
        "MAE z (m)",
        "mean spatial error (m)",
        "3-D RMSE (m)",
        "study 3-D RMSE (m)",
        "3-D RMSE, t ≥ 1 s (m)",
        "seeds",
    ]
    for group in ctx.groups:
        doc.h(3, f"{group.label}")
        doc.table(header, _metric_rows(summary, group, trajectories))
        doc.p(
            "Mean ± sample std across seeds of one deterministic evaluation episode per "
            "trajectory (SPEC §5). The SPEC gives the study's 3-D RMSE only (centralized TD3 "
            f"and the independent TD3 baseline); {NOT_IN_SPEC}: no study value."
        )
        doc.p(ctx.provenance([group]))
    doc.h(3, "Centralized against independent controllers")
    header = ["trajectory", "arm"]
    for group in ctx.groups:
        header.append(f"{group.label} 3-D RMSE (m)")
    header += ["study centralized TD3 (m)", "study independent TD3 (m)"]
    rows = []
    for trajectory in trajectories:
        for arm in (0, 1):
            row = [TRAJECTORY_TITLES.get(trajectory, trajectory), f"arm {arm + 1}"]
            for group in ctx.groups:
                sel = (
                    summary[
                        (summary["group"] == group.label)
                        & (summary["trajectory"] == trajectory)
                        & (summary["arm"] == arm)
                    ]
                    if not summary.empty
                    else summary
                )
                row.append(
                    "no data"
                    if sel.empty
                    else mean_pm_std(sel.iloc[0]["rmse_3d_mean"], sel.iloc[0]["rmse_3d_std"], 4)
                )
            row.append(_study(study_rmse_3d("td3", "centralized", trajectory, arm), 3))
            row.append(_study(study_rmse_3d("td3", "independent", trajectory, arm), 3))
            rows.append(row)
    doc.table(header, rows)
    doc.p(ctx.provenance())
    study = {
        f"study {controller} TD3": {(t, a): v[a] for t, v in values.items() for a in (0, 1)}
        for controller, values in STUDY_RMSE_3D.items()
    }
    path, rel = ctx.figure("rmse_comparison.png")
    fg.rmse_comparison_figure(summary, study, trajectories, path, ctx.footer())
    doc.img(rel, "3-D RMSE per trajectory and arm against the study")


def _actions_section(
    doc: _Doc, ctx: _Context, summary: pd.DataFrame, trajectories: Sequence[str]
) -> None:
    doc.h(3, "Policy actions")
    doc.table(ACTIONS_HEADER, actions_rows(summary, ctx.groups, trajectories))
    doc.p(actions_caption())
    doc.p(ctx.provenance())


def _run_caption(group: Group, run: RunData, trajectory: str) -> str:
    n = sum(
        1
        for r in group.runs
        if r.trajectories is not None and (r.trajectories["trajectory"] == trajectory).any()
    )
    seeds = "1 seed" if n == 1 else f"{n} seeds"
    return f"{group.label}, seed {run.seed}, run {run.run_id} (median 3-D RMSE of {seeds})"


def _trajectories_section(doc: _Doc, ctx: _Context, trajectories: Sequence[str]) -> None:
    doc.h(2, "Trajectories and errors over time (study Figs. 4–9)")
    doc.p(
        "For each trajectory and controller, the seed with the median 3-D RMSE: the 3-D paths "
        "of the target and both tips, then per-axis error tip − target and spatial error "
        "against time for both arms."
    )
    for trajectory in trajectories:
        doc.h(3, TRAJECTORY_TITLES.get(trajectory, trajectory))
        for group in ctx.groups:
            run = representative_run(group, trajectory)
            traj = None
            rmse: dict[int, float] = {}
            if run is not None and run.trajectories is not None:
                traj = run.trajectories[run.trajectories["trajectory"] == trajectory]
                if run.metrics is not None:
                    m = run.metrics[run.metrics["trajectory"] == trajectory]
                    rmse = {int(a): float(v) for a, v in zip(m["arm"], m["rmse_3d"])}
            caption = _run_caption(group, run, trajectory) if run is not None else group.label
            footer = ctx.footer([group])
            path, rel = ctx.figure(f"trajectory_{group.slug}_{trajectory}.png")
            fg.trajectory_3d_figure(
                traj, trajectory, path, subtitle=caption, rmse=rmse, footer=footer
            )
            doc.img(rel, f"{trajectory}: 3-D target and tip paths, {group.label}")
            path, rel = ctx.figure(f"errors_{group.slug}_{trajectory}.png")
            fg.tracking_errors_figure(traj, trajectory, path, subtitle=caption, footer=footer)
            doc.img(rel, f"{trajectory}: tracking error against time, {group.label}")
            if run is None:
                doc.p(
                    f"No data for {group.label} on the {trajectory}: no run has a stored "
                    "evaluation trajectory (run `softtrack evaluate` on its runs)."
                )
            else:
                study = [
                    _study(study_rmse_3d(group.algo, group.controller, trajectory, a), 3)
                    for a in (0, 1)
                ]
                measured = [_num(rmse.get(a), 4) for a in (0, 1)]
                doc.p(
                    f"{caption}. 3-D RMSE arm 1 / arm 2: {measured[0]} / {measured[1]} m "
                    f"(study: {study[0]} / {study[1]} m)."
                )
            doc.p(ctx.provenance([group]))


def _moments_section(doc: _Doc, ctx: _Context, trajectories: Sequence[str]) -> None:
    doc.h(2, "Actuation moments (study Fig. 10)")
    for group in ctx.groups:
        moments: dict[str, pd.DataFrame | None] = {}
        subtitles: dict[str, str] = {}
        for trajectory in trajectories:
            run = representative_run(group, trajectory)
            candidates = [run] if run is not None else list(group.runs)
            df = None
            for r in candidates:
                if r.moments is not None and (r.moments["trajectory"] == trajectory).any():
                    df = r.moments[r.moments["trajectory"] == trajectory]
                    subtitles[trajectory] = f"seed {r.seed}"
                    break
            moments[trajectory] = df
        path, rel = ctx.figure(f"moments_{group.slug}.png")
        fg.moments_figure(
            moments,
            path,
            title=f"Actuation moments, {group.label}",
            subtitles=subtitles,
            footer=ctx.footer([group]),
        )
        doc.img(rel, f"Spatial-RMS moment histories, {group.label}")
        if not any(df is not None for df in moments.values()):
            doc.p(f"No data for {group.label}: no stored evaluation moments.")
    peaks = moment_peaks(ctx.groups)
    rows = []
    for group in ctx.groups:
        part = peaks[peaks["group"] == group.label] if not peaks.empty else peaks
        for trajectory in trajectories:
            for direction in DIRECTIONS:
                cells = []
                for arm in (0, 1, -1):
                    sel = (
                        part[
                            (part["trajectory"] == trajectory)
                            & (part["direction"] == direction)
                            & (part["arm"] == arm)
                        ]
                        if not part.empty
                        else part
                    )
                    peak = sel.iloc[0] if not sel.empty else None
                    cells.append("no data" if peak is None else mean_pm_std(peak["mean"], peak["std"], 1))
                study = study_peak_moment(group.algo, group.controller, trajectory, direction)
                rows.append(
                    [
                        group.label,
                        TRAJECTORY_TITLES.get(trajectory, trajectory),
                        direction,
                        *cells,
                        _study(study, 1),
                    ]
                )
    doc.h(3, "Peak element moments")
    doc.table(
        [
            "controller",
            "trajectory",
            "direction",
            "arm 1 peak (N·m)",
            "arm 2 peak (N·m)",
            "both arms peak (N·m)",
            "study, both arms (N·m)",
        ],
        rows,
    )
    doc.p(
        "Peak: the largest absolute element torque over the evaluation episode, mean ± sample "
        "std across seeds. The study reports peaks during the figure-eight only (centralized "
        f"TD3: {STUDY_PEAK_MOMENTS['normal']} N·m normal, {STUDY_PEAK_MOMENTS['binormal']} N·m "
        f"binormal); {NOT_IN_SPEC}: no study value."
    )
    doc.p(ctx.provenance())


# ---- entry points ---------------------------------------------------------------------------
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
) -> Path:
    """Write the report of ``records`` into ``out_dir``; return the path of ``index.md``.

    Reads only the runs' stored files. Missing tables give "no data" figures and table cells.

    Args:
        records: the runs (see :func:`softtrack.report.select.select_runs`).
        out_dir: the report directory (created if needed; may already hold an older report).
        command_line: the command that built the report, shown under every table.

    Raises:
        EmptySelectionError: ``records`` is empty.
        RunStoreError: ``out_dir`` exists and is not a directory.
    """
    if not records:
        raise EmptySelectionError("nothing to report: the selection contains no runs")
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise RunStoreError(f"{out_dir}: exists and is not a directory; choose another --out")
    command = command_line if isinstance(command_line, str) else shlex.join(command_line)
    runs = load_runs(records)
    groups = group_runs(runs)
    trajectories = trajectories_in(groups)
    figures_dir = out_dir / FIGURES_DIR
    figures_dir.mkdir(parents=True, exist_ok=True)
    ctx = _Context(groups, command, figures_dir)

    names = ", ".join(dict.fromkeys(g.name for g in groups))
    title = f"softtrack report: {names}"
    generated = datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z")
    doc = _Doc()
    doc.h(1, title)
    doc.p(
        f"Generated {generated} by `{command}` from the stored tables of {len(runs)} run(s); "
        "rebuild it at any time with the same command. Beside each measured number is the "
        f"study's value from the SPEC ({NOT_IN_SPEC} where the SPEC gives none)."
    )
    _runs_section(doc, ctx, runs)
    _training_section(doc, ctx)
    _final_section(doc, ctx)
    summary = metrics_summary(ctx.groups)
    _errors_section(doc, ctx, summary, trajectories)
    _actions_section(doc, ctx, summary, trajectories)
    _trajectories_section(doc, ctx, trajectories)
    _moments_section(doc, ctx, trajectories)

    index = out_dir / "index.md"
    atomic_write_text(out_dir / "index.html", doc.html(title), fsync=False)
    atomic_write_text(index, doc.markdown(), fsync=False)
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
) -> Path:
    """Select runs (:func:`select_runs`) under ``runs_dir`` and :func:`build_report` them."""
    store = RunStore(resolve_runs_dir(runs_dir))
    records = select_runs(store, selection)
    if command_line is None:
        command_line = ["softtrack", "report", *selection, "--out", str(out_dir)]
    return build_report(records, out_dir, command_line)
