"""A tuning study in the report (``softtrack report --study NAME``): its trials in parallel
coordinates (one axis per tuned parameter and one for the score; a line per trial, coloured by
its score, pruned trials grey and hideable), the parameters' importance, and the best trials.

The report knows nothing of Optuna: :func:`softtrack.tune.view.study_view` reads a study into
the plain :class:`TuneView` drawn here (the Markdown section as a table, the interactive page
as SVG drawn by plain JavaScript, nothing fetched).
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass

from softtrack.report.document import Doc

__all__ = ["TuneAxis", "TuneTrial", "TuneView", "tune_html_section", "tune_section"]

#: Best complete trials listed in the Markdown section.
BEST_SHOWN = 5


@dataclass(frozen=True)
class TuneAxis:
    """One tuned parameter: its spec path, ``kind`` (``float``, ``int``, ``categorical``),
    whether its range is searched on a log scale, its range (``low``, ``high``; ``None`` for a
    categorical) and its choices as text (categorical only)."""

    path: str
    kind: str
    log: bool
    low: float | None
    high: float | None
    choices: tuple[str, ...] = ()


@dataclass(frozen=True)
class TuneTrial:
    """One trial: its number, state (``COMPLETE``, ``PRUNED``, ``FAIL``, ``RUNNING``,
    ``WAITING``), score (m; a pruned trial's last reported one; ``None`` if none), the env
    step of that score, its values (number, or the choice's text for a categorical) and its
    run id."""

    number: int
    state: str
    score: float | None
    step: int | None
    values: dict[str, float | str]
    run_id: str | None


@dataclass(frozen=True)
class TuneView:
    """A study as the report draws it.

    Attributes:
        name: the study.
        objective: what its score is (e.g. ``best validation score (mean 3-D RMSE, m)``).
        axes: the tuned parameters.
        trials: every trial, by number.
        importance: (path, share) per parameter, largest first (shares sum to 1); empty when it
            could not be computed (``importance_note`` says why).
        importance_method: how it was computed (Optuna's evaluator).
        importance_note: why there is none, or an empty string.
    """

    name: str
    objective: str
    axes: tuple[TuneAxis, ...]
    trials: tuple[TuneTrial, ...]
    importance: tuple[tuple[str, float], ...]
    importance_method: str
    importance_note: str = ""

    def count(self, state: str) -> int:
        return sum(t.state == state for t in self.trials)

    def best(self) -> list[TuneTrial]:
        """The complete trials with a finite score, best first."""
        done = [t for t in self.trials if t.state == "COMPLETE" and t.score is not None]
        return sorted(done, key=lambda t: (t.score, t.number))

    def summary(self) -> str:
        best = self.best()
        text = (
            f"{len(self.trials)} trials: {self.count('COMPLETE')} complete, "
            f"{self.count('PRUNED')} pruned, {self.count('FAIL')} failed"
        )
        if best:
            text += f"; best trial {best[0].number}: {best[0].score:.4g} m"
        return text


def _value_text(value: float | str | None) -> str:
    if value is None:
        return "—"
    if isinstance(value, str):
        return value
    return f"{value:.4g}"


def _leaf(path: str, paths: Sequence[str]) -> str:
    leaf = path.rsplit(".", 1)[-1]
    return leaf if sum(p.rsplit(".", 1)[-1] == leaf for p in paths) == 1 else path


def tune_section(doc: Doc, views: Sequence[TuneView]) -> None:
    """Per study: its summary, the parameters' importance and its best trials (Markdown)."""
    for view in views:
        doc.h(2, f"Tuning study {view.name}")
        doc.p(
            f"{view.summary()}. The score is the {view.objective}; lower is better. The "
            "interactive page (`--html`) draws every trial in parallel coordinates."
        )
        if view.importance:
            doc.p(f"Parameter importance ({view.importance_method}):")
            doc.table(
                ("parameter", "importance"),
                [(path, f"{share:.2f}") for path, share in view.importance],
            )
        else:
            doc.p(f"Parameter importance: {view.importance_note}")
        best = view.best()[:BEST_SHOWN]
        if best:
            paths = [a.path for a in view.axes]
            doc.table(
                ("trial", "score (m)", *(_leaf(p, paths) for p in paths), "run"),
                [
                    (
                        str(t.number),
                        f"{t.score:.4f}" if t.score is not None else "—",
                        *(_value_text(t.values.get(p)) for p in paths),
                        t.run_id or "—",
                    )
                    for t in best
                ],
            )


def _position(axis: TuneAxis, value: float | str | None) -> float | None:
    """``value`` on its axis, 0 (bottom) … 1 (top); ``None`` where it has none."""
    if value is None:
        return None
    if axis.kind == "categorical":
        if str(value) not in axis.choices:
            return None
        index = axis.choices.index(str(value))
        return 0.5 if len(axis.choices) == 1 else index / (len(axis.choices) - 1)
    if isinstance(value, str) or axis.low is None or axis.high is None:
        return None
    low, high, v = float(axis.low), float(axis.high), float(value)
    if axis.log and low > 0 and v > 0:
        low, high, v = math.log(low), math.log(high), math.log(v)
    return 0.5 if high == low else min(1.0, max(0.0, (v - low) / (high - low)))


def _ticks(axis: TuneAxis) -> list[tuple[float, str]]:
    if axis.kind == "categorical":
        return [(_position(axis, c) or 0.0, c) for c in axis.choices]
    return [(0.0, _value_text(axis.low)), (1.0, _value_text(axis.high))]


def _payload(view: TuneView) -> dict[str, object]:
    scores = [t.score for t in view.trials if t.score is not None and math.isfinite(t.score)]
    low, high = (min(scores), max(scores)) if scores else (0.0, 1.0)
    paths = [a.path for a in view.axes]
    axes = [{"label": _leaf(a.path, paths), "ticks": _ticks(a)} for a in view.axes]
    axes.append(
        {
            "label": "score (m)",
            "ticks": [(0.0, _value_text(high)), (1.0, _value_text(low))],
        }
    )
    complete = [t.score for t in view.best() if t.score is not None]
    c_low, c_high = (min(complete), max(complete)) if complete else (low, high)
    trials = []
    for t in view.trials:
        if t.state not in ("COMPLETE", "PRUNED") or t.score is None:
            continue
        score = 0.5 if high == low else (t.score - low) / (high - low)
        # the colour spans the complete trials' scores (pruned lines are grey)
        shade = 0.5 if c_high == c_low else (t.score - c_low) / (c_high - c_low)
        points = [_position(a, t.values.get(a.path)) for a in view.axes]
        trials.append(
            {
                "number": t.number,
                "pruned": t.state == "PRUNED",
                # the best score at the top of its axis
                "points": [*points, 1.0 - score],
                "shade": min(1.0, max(0.0, shade)),
                "text": f"trial {t.number} ({t.state.lower()}"
                + (f" at step {t.step:,}" if t.state == "PRUNED" and t.step else "")
                + f"): {t.score:.4g} m; "
                + ", ".join(f"{_leaf(p, paths)} {_value_text(t.values.get(p))}" for p in paths)
                + (f"; run {t.run_id}" if t.run_id else ""),
            }
        )
    return {
        "name": view.name,
        "axes": axes,
        "trials": trials,
        "importance": [[_leaf(p, paths), share] for p, share in view.importance],
    }


def tune_html_section(views: Sequence[TuneView]) -> str:
    """The interactive page's section: per study a summary, the parameters' importance as
    bars and the trials in parallel coordinates (SVG drawn by the page's script)."""
    if not views:
        return ""
    parts = []
    for k, view in enumerate(views):
        importance = (
            f"<p>Parameter importance ({html.escape(view.importance_method)}):</p>"
            f'<div class="importance" id="importance-{k}"></div>'
            if view.importance
            else f"<p>Parameter importance: {html.escape(view.importance_note)}</p>"
        )
        parts.append(
            f"<h3>{html.escape(view.name)}</h3><p>{html.escape(view.summary())}. Score: the "
            f"{html.escape(view.objective)}; the best score is at the top of its axis. Hover "
            f"a line for its trial.</p>{importance}"
            f'<label><input type="checkbox" id="pruned-{k}" checked> pruned trials (grey, '
            f"at their last score)</label>"
            f'<div class="parallel" id="parallel-{k}"></div>'
            f'<p class="trial-caption" id="caption-{k}">&nbsp;</p>'
        )
    blob = json.dumps([_payload(v) for v in views]).replace("</", "<\\/")
    return (
        '<h2 id="tune">Tuning studies</h2>'
        + "".join(parts)
        + f'<script id="tune-data" type="application/json">{blob}</script>'
        + f"<script>{_SCRIPT}</script>"
    )


_SCRIPT = """
"use strict";
(() => {
  const STUDIES = JSON.parse(document.getElementById("tune-data").textContent);
  const NS = "http://www.w3.org/2000/svg";
  const node = (name, attrs, parent) => {
    const el = document.createElementNS(NS, name);
    for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
    if (parent) parent.appendChild(el);
    return el;
  };
  // score 0 (best) … 1 (worst): dark blue → teal → yellow
  const shade = (s) => {
    const stops = [[33, 49, 140], [32, 160, 135], [240, 210, 40]];
    const u = Math.min(1, Math.max(0, s)) * 2, i = Math.min(1, Math.floor(u)), f = u - i;
    const c = stops[i].map((v, j) => Math.round(v + (stops[i + 1][j] - v) * f));
    return `rgb(${c.join(",")})`;
  };
  STUDIES.forEach((study, k) => {
    const bars = document.getElementById(`importance-${k}`);
    if (bars) {
      for (const [label, share] of study.importance) {
        const row = document.createElement("div"); row.className = "bar-row";
        const width = Math.round(share * 300);
        row.innerHTML = `<span class="bar-label"></span><span class="bar" style="width:${width}px"></span>`;
        row.append(` ${share.toFixed(2)}`);
        row.firstChild.textContent = label;
        bars.appendChild(row);
      }
    }
    const n = study.axes.length, W = Math.max(480, 120 * n), H = 320, M = {l: 50, r: 50, t: 24, b: 40};
    const svg = node("svg", {width: W, height: H, id: `parallel-svg-${k}`}, document.getElementById(`parallel-${k}`));
    const ax = (i) => M.l + i * (W - M.l - M.r) / Math.max(1, n - 1);
    const ay = (p) => H - M.b - p * (H - M.t - M.b);
    const caption = document.getElementById(`caption-${k}`);
    const lines = node("g", {}, svg);
    const order = study.trials.slice().sort((a, b) => (b.pruned - a.pruned) || (b.shade - a.shade));
    for (const trial of order) {
      const pts = trial.points.map((p, i) => p === null ? null : `${ax(i)},${ay(p)}`).filter((v) => v);
      const line = node("polyline", {points: pts.join(" "), fill: "none",
        stroke: trial.pruned ? "#aaa" : shade(trial.shade), "stroke-width": trial.pruned ? 1.2 : 2,
        "stroke-dasharray": trial.pruned ? "4 3" : "", class: trial.pruned ? "pruned" : "complete",
        "data-trial": trial.number}, lines);
      const title = node("title", {}, line); title.textContent = trial.text;
      line.addEventListener("mouseenter", () => {
        line.setAttribute("stroke-width", 4); caption.textContent = trial.text;
      });
      line.addEventListener("mouseleave", () => { line.setAttribute("stroke-width", trial.pruned ? 1.2 : 2); });
    }
    study.axes.forEach((axis, i) => {
      node("line", {x1: ax(i), y1: ay(0), x2: ax(i), y2: ay(1), stroke: "#555"}, svg);
      const label = node("text", {x: ax(i), y: H - 12, "text-anchor": "middle", "font-size": 11,
        "font-weight": "bold"}, svg);
      label.textContent = axis.label;
      for (const [p, text] of axis.ticks) {
        const t = node("text", {x: ax(i) + 4, y: ay(p) + 4, "font-size": 10, fill: "#333"}, svg);
        t.textContent = text;
      }
    });
    const toggle = document.getElementById(`pruned-${k}`);
    toggle.addEventListener("change", () => {
      for (const line of svg.querySelectorAll("polyline.pruned")) line.style.display = toggle.checked ? "" : "none";
    });
  });
})();
"""
