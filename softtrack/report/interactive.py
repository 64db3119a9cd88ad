"""The interactive report page (``softtrack report ... --html``): one self-contained HTML file.

Its first screen answers the question: per task, the study's published 3-D RMSE beside the
best controllers' interquartile mean with its 95 % bootstrap interval, per trajectory and arm
(the numbers of ``softtrack compare``). Then the 3-D rollout viewer of the featured controllers
(:mod:`softtrack.report.viewer`), the training and validation curves with their seed bands
(one checkbox per curve hides it), and the table of runs last. Everything is in the page (data as JSON, plain
JavaScript and SVG); nothing is fetched at view time.
"""

from __future__ import annotations

import html
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from softtrack.report.viewer import VIEWER_STYLE, Rollout, viewer_section

__all__ = ["AnswerTable", "CurvePanel", "interactive_page"]


@dataclass(frozen=True)
class AnswerTable:
    """One task's table on the first screen: ``header`` and ``rows`` of text cells."""

    title: str
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]


@dataclass(frozen=True)
class CurvePanel:
    """One panel of curves: ``curves`` are (label, colour, steps (P,), mean (P,), std (P,))."""

    title: str
    y_label: str
    curves: tuple[tuple[str, str, np.ndarray, np.ndarray, np.ndarray], ...]


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _finite(values: np.ndarray) -> list[float | None]:
    return [float(v) if math.isfinite(float(v)) else None for v in np.asarray(values, float)]


def interactive_page(
    title: str,
    intro: str,
    answers: Sequence[AnswerTable],
    panels: Sequence[CurvePanel],
    rollouts: Sequence[Rollout],
    runs_header: Sequence[str],
    runs_rows: Sequence[Sequence[str]],
    fps: float = 15.0,
    tune_html: str = "",
) -> str:
    """The page's HTML text (``tune_html``: the tuning studies' section, placed after the
    answers)."""
    answer_html = (
        "".join(f"<h3>{html.escape(a.title)}</h3>{_table(a.header, a.rows)}" for a in answers)
        or "<p>No evaluated controller in this selection.</p>"
    )
    curves = [
        {
            "title": p.title,
            "y": p.y_label,
            "curves": [
                {
                    "label": label,
                    "color": color,
                    "x": _finite(x),
                    "mean": _finite(m),
                    "std": _finite(s),
                }
                for label, color, x, m, s in p.curves
            ],
        }
        for p in panels
    ]
    viewer = (
        viewer_section(rollouts, fps)
        if rollouts
        else "<p>No featured controller could be replayed (no readable model).</p>"
    )
    blob = json.dumps({"panels": curves}).replace("</", "<\\/")
    return (
        _PAGE.replace("__TITLE__", html.escape(title))
        .replace("__INTRO__", html.escape(intro))
        .replace("__ANSWERS__", answer_html + tune_html)
        .replace("__VIEWER__", viewer)
        .replace("__CURVES__", blob)
        .replace("__RUNS__", _table(runs_header, runs_rows))
        .replace("__STYLE__", VIEWER_STYLE)
    )


_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>__TITLE__</title>
<style>
body{font-family:system-ui,sans-serif;margin:1.2em 2em;background:#f7f8fa;color:#222;max-width:1200px}
table{border-collapse:collapse;margin:.4em 0 1.2em;font-size:.9em}
th,td{border:1px solid #ccd;padding:.25em .6em;text-align:left}
th{background:#e8ebf2}
.panel{display:inline-block;vertical-align:top;margin:0 1.5em 1.5em 0}
.legend label{display:block;font-size:.85em}
svg{background:#fff;border:1px solid #ccd}
.bar-row{font-size:.85em;margin:2px 0}.bar-label{display:inline-block;width:12em}
.bar{display:inline-block;height:.8em;background:#3b6fb6;vertical-align:middle}
__STYLE__</style></head>
<body>
<h1 style="font-size:1.35em">__TITLE__</h1>
<p>__INTRO__</p>
<h2 id="answers">Best controllers per task beside the study</h2>
__ANSWERS__
<h2 id="viewer">The featured controllers in 3-D</h2>
__VIEWER__
<h2 id="training">Training and validation curves (mean ± 1 std across seeds; a checkbox hides a curve)</h2>
<div id="curves"></div>
<script id="curve-data" type="application/json">__CURVES__</script>
<script>
"use strict";
(() => {
  const DATA = JSON.parse(document.getElementById("curve-data").textContent);
  const NS = "http://www.w3.org/2000/svg", W = 520, H = 300, M = {l: 60, r: 10, t: 10, b: 36};
  const node = (name, attrs, parent) => {
    const el = document.createElementNS(NS, name);
    for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
    if (parent) parent.appendChild(el);
    return el;
  };
  DATA.panels.forEach((panel, p) => {
    const box = document.createElement("div"); box.className = "panel";
    box.innerHTML = `<b>${panel.title}</b><br>`;
    const svg = node("svg", {width: W, height: H, id: `curves-${p}`}, box);
    const xs = panel.curves.flatMap((c) => c.x.filter((v) => v !== null));
    const ys = panel.curves.flatMap((c) => c.mean.map((m, i) => m === null ? null :
      [m - (c.std[i] || 0), m + (c.std[i] || 0)]).filter((v) => v !== null).flat());
    if (!xs.length || !ys.length) { box.append("no data"); document.getElementById("curves").appendChild(box); return; }
    const x0 = 0, x1 = Math.max(...xs), y0 = Math.min(...ys), y1 = Math.max(...ys);
    const sx = (x) => M.l + (x - x0) / ((x1 - x0) || 1) * (W - M.l - M.r);
    const sy = (y) => H - M.b - (y - y0) / ((y1 - y0) || 1) * (H - M.t - M.b);
    node("line", {x1: M.l, y1: H - M.b, x2: W - M.r, y2: H - M.b, stroke: "#888"}, svg);
    node("line", {x1: M.l, y1: M.t, x2: M.l, y2: H - M.b, stroke: "#888"}, svg);
    for (const [value, y] of [[y0, sy(y0)], [y1, sy(y1)]]) {
      const t = node("text", {x: M.l - 4, y: y + 4, "text-anchor": "end", "font-size": 10}, svg);
      t.textContent = value.toPrecision(3);
    }
    const xt = node("text", {x: W - M.r, y: H - 8, "text-anchor": "end", "font-size": 10}, svg);
    xt.textContent = `${x1.toExponential(1)} env steps`;
    const yt = node("text", {x: M.l + 6, y: M.t + 10, "font-size": 10}, svg);
    yt.textContent = panel.y;
    const legend = document.createElement("div"); legend.className = "legend";
    panel.curves.forEach((c, k) => {
      const group = node("g", {id: `curve-${p}-${k}`}, svg);
      const pts = c.x.map((x, i) => [x, c.mean[i], c.std[i]]).filter((v) => v[0] !== null && v[1] !== null);
      const upper = pts.map(([x, m, s]) => `${sx(x)},${sy(m + (s || 0))}`);
      const lower = pts.slice().reverse().map(([x, m, s]) => `${sx(x)},${sy(m - (s || 0))}`);
      node("polygon", {points: upper.concat(lower).join(" "), fill: c.color,
        "fill-opacity": 0.18, stroke: "none"}, group);
      node("polyline", {points: pts.map(([x, m]) => `${sx(x)},${sy(m)}`).join(" "), fill: "none",
        stroke: c.color, "stroke-width": 1.6}, group);
      const label = document.createElement("label");
      const box2 = document.createElement("input"); box2.type = "checkbox"; box2.checked = true;
      box2.id = `toggle-${p}-${k}`;
      box2.addEventListener("change", () => { group.style.display = box2.checked ? "" : "none"; });
      label.appendChild(box2);
      label.append(` ${c.label}`); label.style.color = c.color;
      legend.appendChild(label);
    });
    box.appendChild(legend);
    document.getElementById("curves").appendChild(box);
  });
})();
</script>
<h2 id="runs">Runs</h2>
__RUNS__
</body></html>
"""
