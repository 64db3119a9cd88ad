"""The report's document model and the pieces every section shares.

:class:`Doc` collects headings, paragraphs, tables and images and renders them to Markdown and
to a standalone HTML page; the ``*_text`` helpers format table cells; :class:`Context` gives
the sections the run groups, the provenance footer of every figure and the paths of the
figures they write; :func:`provenance_section` states each controller's provenance once.
"""

from __future__ import annotations

import html
import math
import re
import shlex
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, TypeAlias

from softtrack.report.data import Group, RunData
from softtrack.report.plan import FigurePlan
from softtrack.report.reference import STUDY_BUDGET_TEXT

__all__ = [
    "FIGURES_DIR",
    "NOT_IN_STUDY",
    "Context",
    "Doc",
    "commit_text",
    "group_provenance",
    "num_text",
    "provenance_section",
    "seeds_text",
    "study_text",
]

#: The report's figure directory, relative to the report directory.
FIGURES_DIR = "figures"
#: The cell shown where the study gives no value.
NOT_IN_STUDY = "—"
#: A figure footer names the experiments, specs and commits of at most this many experiments
#: (more are counted, and listed in the report's *Behind these numbers*).
FOOTER_LISTS_UP_TO = 4


# ---- a minimal document model rendered to Markdown and HTML ---------------------------------
Block: TypeAlias = (
    tuple[Literal["h"], int, str]
    | tuple[Literal["p"], str]
    | tuple[Literal["table"], list[str], list[list[str]]]
    | tuple[Literal["img"], str, str]
)


@dataclass
class Doc:
    """Blocks: ("h", level, text), ("p", text), ("table", header, rows), ("img", src, alt)."""

    blocks: list[Block] = field(default_factory=list)

    def h(self, level: int, text: str) -> None:
        """A heading of ``level`` (1 = the title)."""
        self.blocks.append(("h", level, text))

    def p(self, text: str) -> None:
        """A paragraph (inline Markdown: code, bold, italics)."""
        self.blocks.append(("p", text))

    def table(self, header: Sequence[str], rows: Iterable[Sequence[str]]) -> None:
        """A table of text cells under ``header``."""
        self.blocks.append(("table", list(header), [list(r) for r in rows]))

    def img(self, src: str, alt: str) -> None:
        """An image by path relative to the report, with its alternative text."""
        self.blocks.append(("img", src, alt))

    def markdown(self) -> str:
        """The document as Markdown."""
        out: list[str] = []
        for block in self.blocks:
            if block[0] == "h":
                out.append(f"{'#' * int(block[1])} {block[2]}")
            elif block[0] == "p":
                out.append(str(block[1]))
            elif block[0] == "table":
                header, rows = block[1], block[2]

                def cell(s: object) -> str:
                    return str(s).replace("|", "\\|").replace("\n", " ")

                out.append(
                    "\n".join(
                        [
                            "| " + " | ".join(cell(h) for h in header) + " |",
                            "|" + "---|" * len(header),
                        ]
                        + ["| " + " | ".join(cell(c) for c in r) + " |" for r in rows]
                    )
                )
            elif block[0] == "img":
                out.append(f"![{block[2]}]({block[1]})")
        return "\n\n".join(out) + "\n"

    def html(self, title: str) -> str:
        """The document as a standalone HTML page titled ``title``."""

        def inline(text: object) -> str:
            escaped = html.escape(str(text))
            escaped = re.sub(r"`([^`]+)`", r"<code>\1</code>", escaped)
            escaped = re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", escaped)
            return re.sub(r"\*([^*]+)\*", r"<em>\1</em>", escaped)

        body: list[str] = []
        for block in self.blocks:
            if block[0] == "h":
                body.append(f"<h{block[1]}>{inline(block[2])}</h{block[1]}>")
            elif block[0] == "p":
                body.append(f"<p>{inline(block[1])}</p>")
            elif block[0] == "table":
                head = "".join(f"<th>{inline(h)}</th>" for h in block[1])
                rows = "".join(
                    "<tr>" + "".join(f"<td>{inline(c)}</td>" for c in r) + "</tr>" for r in block[2]
                )
                body.append(f"<table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>")
            elif block[0] == "img":
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
def num_text(value: float | None, digits: int) -> str:
    """A measured value with ``digits`` decimals, or "no data" (``None`` or not finite)."""
    if value is None or not math.isfinite(value):
        return "no data"
    return f"{value:.{digits}f}"


def study_text(value: float | None, digits: int) -> str:
    """A study value with ``digits`` decimals, or :data:`NOT_IN_STUDY` (``None``)."""
    return NOT_IN_STUDY if value is None else f"{value:.{digits}f}"


def seeds_text(seeds: Iterable[int]) -> str:
    """The distinct seeds, sorted and comma-separated, or "none"."""
    return ", ".join(str(s) for s in sorted(set(seeds))) or "none"


def training_commits(run: RunData) -> list[tuple[str, bool]]:
    """The distinct (commit, uncommitted changes) a run was created and trained with, oldest
    first: run.json's git_commit, then each training session's (a resumed run may have more)."""
    info = run.record.info
    found = [(info.git_commit, info.git_dirty)]
    found += [(s.get("git_commit"), s.get("git_dirty")) for s in info.sessions]
    commits: list[tuple[str, bool]] = []
    for commit, dirty in found:
        if commit and (commit, bool(dirty)) not in commits:
            commits.append((commit, bool(dirty)))
    return commits


def commit_text(run: RunData) -> str:
    """A run's git commits (12 digits, noting uncommitted changes; several when its training
    sessions ran different code), or "unknown"."""
    commits = training_commits(run)
    if not commits:
        return "unknown"
    return ", then ".join(c[:12] + (" (+ uncommitted changes)" if d else "") for c, d in commits)


def group_provenance(group: Group) -> str:
    """One group's experiment, spec hashes, seeds, budgets, commits and training commands."""
    budgets = ", ".join(group.budgets)
    reached = ", ".join(f"{r.last_step:,}" for r in group.runs)
    commits = "; ".join(sorted({commit_text(r) for r in group.runs}))
    hashes = ", ".join(sorted({r.record.info.spec_hash[:12] for r in group.runs}))
    commands = sorted(
        {shlex.join(r.record.info.command) for r in group.runs if r.record.info.command}
    )
    planner = group.controller == "mpc"
    text = (
        f"**{group.label}**: experiment `{group.name}`, spec `{hashes}`, seeds "
        f"{seeds_text(group.seeds)}, "
        + (budgets if planner else f"budget {budgets} (reached {reached})")
        + f", commit `{commits}`"
    )
    if commands:
        text += ("; created by " if planner else "; trained by ") + ", ".join(
            f"`{c}`" for c in commands
        )
    bases = sorted(
        {
            str(base.get("name"))
            for r in group.runs
            if isinstance(base := r.record.info.notes.get("derived_from"), dict)
        }
    )
    if bases:
        text += (
            f"; derived from the runs of `{'`, `'.join(bases)}` (the same training, the "
            "spec changed after it: run.json `notes.derived_from`)"
        )
    return text


class Context:
    """What every section needs: the groups, the report command, the figure list, whether
    to draw the per-run figures of every controller (``all_figures``) or of a chosen few, and
    the controllers and colours of the comparison figures (``plan``)."""

    def __init__(
        self,
        groups: list[Group],
        command: str,
        figures_dir: Path,
        all_figures: bool = False,
        plan: FigurePlan | None = None,
    ) -> None:
        self.groups = groups
        self.plan = plan if plan is not None else FigurePlan()
        self.command = command
        self.figures_dir = figures_dir
        self.all_figures = all_figures
        self.written: list[str] = []

    def footer(self, groups: Sequence[Group] | None = None) -> str:
        """The one-line provenance printed under a figure of ``groups`` (default: all)."""
        groups = self.groups if groups is None else groups
        names = sorted({g.name for g in groups})
        seeds = seeds_text(s for g in groups for s in g.seeds)
        budgets = ", ".join(sorted({b for g in groups for b in g.budgets}))
        hashes = sorted({r.record.info.spec_hash[:8] for g in groups for r in g.runs})
        commits = sorted({c[:8] for g in groups for r in g.runs for c, _ in training_commits(r)})
        if len(names) > FOOTER_LISTS_UP_TO:  # counted; listed under *Behind these numbers*
            return (
                f"{len(names)} experiments, {len(hashes)} specs, {len(commits)} commits "
                f"(listed in the report under Behind these numbers) · seeds {seeds} · "
                f"budget {budgets}"
            )
        return (
            f"experiment {', '.join(names)} · spec {', '.join(hashes)} · seeds {seeds} · "
            f"budget {budgets} · commit {', '.join(commits) or 'unknown'}"
        )

    def figure(self, name: str) -> tuple[Path, str]:
        """(path to write, path relative to the report) of figure ``name``."""
        self.written.append(f"{FIGURES_DIR}/{name}")
        return self.figures_dir / name, f"{FIGURES_DIR}/{name}"


def provenance_section(doc: Doc, ctx: Context) -> None:
    """*Behind these numbers*, once for the whole report: the command, then one paragraph per
    controller (experiment, spec, seeds, budget, commits, training commands), then the
    study's protocol. Every table and figure below draws on these runs only."""
    doc.h(2, "Behind these numbers")
    doc.p(
        f"Every table and figure below is computed from the stored tables of these runs by "
        f"`{ctx.command}`; each figure repeats its runs' experiment, spec, seeds, budget and "
        "commit in its footer."
    )
    for group in ctx.groups:
        doc.p(group_provenance(group) + ".")
    doc.p(f"Study: {STUDY_BUDGET_TEXT}.")
