"""A self-contained HTML page that plays rollouts in 3-D: the arms' nodes at each frame, drawn
in the browser on a canvas (play, pause, scrub, speed; choose the controller and the
trajectory). Everything is in the page: the frames as base64 float32 arrays and a small
renderer in plain JavaScript, so it works offline and fetches nothing.
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from softtrack.viz.camera import FRONT, Camera
from softtrack.viz.scene import ARM_COLORS

__all__ = ["VIEWER_STYLE", "Rollout", "viewer_page", "viewer_section"]


@dataclass(frozen=True)
class Rollout:
    """One controller's episode on one trajectory, at the page's frames.

    Attributes:
        controller: the name the page offers (e.g. ``td3-... (seed 0)``).
        trajectory: ``circle``, ``rectangle``, ``figure8`` or ``random k``.
        times: (F,) s.
        nodes: (F, A, 3, N) the arms' centreline nodes, m.
        target: (F, 3) the target's centre (transport: the sphere's goal), m.
        sphere: (F, 3) the held sphere's centre, or ``None``.
        errors: (F, A) each tip's distance to its point (transport: (F, 1), the sphere's), m.
        radius: the rods' radius, m; ``target_radius``, ``sphere_radius`` likewise.
        bases: (A, 3) the clamps, m.
    """

    controller: str
    trajectory: str
    times: np.ndarray
    nodes: np.ndarray
    target: np.ndarray
    sphere: np.ndarray | None
    errors: np.ndarray
    radius: float
    target_radius: float
    sphere_radius: float
    bases: np.ndarray


def _b64(values: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(values, dtype="<f4").tobytes()).decode("ascii")


def _payload(rollout: Rollout) -> dict[str, object]:
    frames, arms, _, nodes = rollout.nodes.shape
    return {
        "controller": rollout.controller,
        "trajectory": rollout.trajectory,
        "frames": int(frames),
        "arms": int(arms),
        "nodes": int(nodes),
        "times": _b64(rollout.times),
        "rods": _b64(rollout.nodes.transpose(0, 1, 3, 2)),  # (F, A, N, 3)
        "target": _b64(rollout.target),
        "sphere": None if rollout.sphere is None else _b64(rollout.sphere),
        "errors": _b64(rollout.errors),
        "error_labels": ["sphere"]
        if rollout.sphere is not None
        else [f"arm {a + 1}" for a in range(arms)],
        "radius": float(rollout.radius),
        "target_radius": float(rollout.target_radius),
        "sphere_radius": float(rollout.sphere_radius),
        "bases": np.asarray(rollout.bases, float).tolist(),
    }


def viewer_page(rollouts: Sequence[Rollout], title: str, fps: float, camera: Camera = FRONT) -> str:
    """The page (HTML text) playing ``rollouts`` at ``fps`` frames per second."""
    return (
        _PAGE.replace("__TITLE__", html.escape(title))
        .replace("__STYLE__", VIEWER_STYLE)
        .replace("__VIEWER__", viewer_section(rollouts, fps, camera))
    )


def viewer_section(rollouts: Sequence[Rollout], fps: float, camera: Camera = FRONT) -> str:
    """The viewer's controls, canvas and script, to place in a page (with
    :data:`VIEWER_STYLE` in its style sheet)."""
    basis = camera.basis()
    data = {
        "fps": float(fps),
        "camera": {"eye": list(camera.eye), "basis": basis.tolist(), "fov": float(camera.fov_deg)},
        "colors": [f"rgb{tuple(c)}" for c in ARM_COLORS],
        "rollouts": [_payload(r) for r in rollouts],
    }
    blob = json.dumps(data).replace("</", "<\\/")
    return VIEWER_HTML + VIEWER_SCRIPT.replace("__DATA__", blob)


VIEWER_STYLE = """#controls{display:flex;gap:.8em;align-items:center;flex-wrap:wrap;margin:.6em 0}
canvas{background:#eef1f6;border:1px solid #ccd;max-width:100%}
#scrub{width:24em}
"""

#: The viewer's controls and canvas (ids: controller, trajectory, play, scrub, speed, path,
#: view, status).
VIEWER_HTML = """<div id="controls">
 <label>controller <select id="controller"></select></label>
 <label>trajectory <select id="trajectory"></select></label>
 <button id="play" type="button">pause</button>
 <input id="scrub" type="range" min="0" value="0" step="1">
 <label>speed <select id="speed"><option>0.25</option><option>0.5</option>
  <option selected>1</option><option>2</option></select></label>
 <label><input id="path" type="checkbox" checked> target path</label>
</div>
<canvas id="view" width="800" height="600"></canvas>
<p id="status"></p>
"""

#: The viewer's data (``__DATA__``) and renderer; it draws into :data:`VIEWER_HTML`.
VIEWER_SCRIPT = """<script id="data" type="application/json">__DATA__</script>
<script>
"use strict";
const DATA = JSON.parse(document.getElementById("data").textContent);
const floats = (b64) => {
  if (b64 === null) return null;
  const raw = atob(b64), bytes = new Uint8Array(raw.length);
  for (let i = 0; i < raw.length; i++) bytes[i] = raw.charCodeAt(i);
  return new Float32Array(bytes.buffer);
};
const rollouts = DATA.rollouts.map((r) => Object.assign({}, r, {
  times: floats(r.times), rods: floats(r.rods), target: floats(r.target),
  sphere: floats(r.sphere), errors: floats(r.errors)}));
const canvas = document.getElementById("view"), ctx = canvas.getContext("2d");
const cam = DATA.camera, focal = 0.5 * canvas.height / Math.tan(cam.fov * Math.PI / 360);
function project(x, y, z) {
  const d = [x - cam.eye[0], y - cam.eye[1], z - cam.eye[2]], b = cam.basis;
  const lx = b[0][0]*d[0] + b[0][1]*d[1] + b[0][2]*d[2];
  const ly = b[1][0]*d[0] + b[1][1]*d[1] + b[1][2]*d[2];
  const lz = b[2][0]*d[0] + b[2][1]*d[1] + b[2][2]*d[2];
  const s = focal / Math.max(lz, 1e-6);
  return [canvas.width / 2 + lx * s, canvas.height / 2 - ly * s, lz];
}
function shade(color, k) {
  const m = color.match(/\\d+/g).map(Number);
  return `rgb(${m.map((c) => Math.round(Math.min(255, c * k))).join(",")})`;
}
const pick = {controller: document.getElementById("controller"),
  trajectory: document.getElementById("trajectory")};
const names = [...new Set(rollouts.map((r) => r.controller))];
const paths = [...new Set(rollouts.map((r) => r.trajectory))];
for (const [select, options] of [[pick.controller, names], [pick.trajectory, paths]])
  for (const name of options) select.add(new Option(name, name));
const scrub = document.getElementById("scrub"), play = document.getElementById("play");
const speed = document.getElementById("speed"), showPath = document.getElementById("path");
let frame = 0, playing = true, clock = 0;
function current() {
  return rollouts.find((r) => r.controller === pick.controller.value &&
    r.trajectory === pick.trajectory.value) || rollouts[0];
}
function floor() {
  ctx.strokeStyle = "#c3c8d2"; ctx.lineWidth = 1;
  for (let k = -4; k <= 4; k++) {
    for (const [a, b] of [[[k*0.2, 0, -0.8], [k*0.2, 0, 0.8]], [[-0.8, 0, k*0.2], [0.8, 0, k*0.2]]]) {
      const p = project(...a), q = project(...b);
      ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
    }
  }
}
function draw() {
  const r = current(), f = Math.min(frame, r.frames - 1);
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  floor();
  if (showPath.checked) {
    ctx.strokeStyle = "rgba(214,39,40,0.5)"; ctx.lineWidth = 1; ctx.beginPath();
    for (let k = 0; k < r.frames; k++) {
      const p = project(r.target[3*k], r.target[3*k+1], r.target[3*k+2]);
      if (k) ctx.lineTo(p[0], p[1]); else ctx.moveTo(p[0], p[1]);
    }
    ctx.stroke();
  }
  const items = [];
  r.bases.forEach((base) => items.push({a: [base[0], base[1] - 0.06, base[2]], b: base,
    radius: 1.5 * r.radius, color: "rgb(70,70,78)"}));
  for (let arm = 0; arm < r.arms; arm++) {
    const offset = ((f * r.arms + arm) * r.nodes) * 3;
    for (let n = 0; n + 1 < r.nodes; n++) {
      const i = offset + 3 * n;
      items.push({a: [r.rods[i], r.rods[i+1], r.rods[i+2]],
        b: [r.rods[i+3], r.rods[i+4], r.rods[i+5]], radius: r.radius,
        color: DATA.colors[arm % DATA.colors.length]});
    }
  }
  if (r.sphere) items.push({a: [r.sphere[3*f], r.sphere[3*f+1], r.sphere[3*f+2]], b: null,
    radius: r.sphere_radius, color: "rgb(90,170,90)"});
  items.push({a: [r.target[3*f], r.target[3*f+1], r.target[3*f+2]], b: null,
    radius: r.target_radius, color: "rgba(214,39,40,0.45)", flat: true});
  const drawn = items.map((it) => {
    const p = project(...it.a), q = it.b ? project(...it.b) : p;
    return Object.assign(it, {p, q, depth: (p[2] + q[2]) / 2});
  }).sort((x, y) => y.depth - x.depth);
  ctx.lineCap = "round";
  for (const it of drawn) {
    const width = 2 * focal * it.radius / Math.max(it.depth, 1e-6);
    if (it.b) {
      ctx.strokeStyle = shade(it.color, 0.75); ctx.lineWidth = width;
      ctx.beginPath(); ctx.moveTo(it.p[0], it.p[1]); ctx.lineTo(it.q[0], it.q[1]); ctx.stroke();
      ctx.strokeStyle = it.color; ctx.lineWidth = width * 0.6;
      ctx.beginPath(); ctx.moveTo(it.p[0], it.p[1]); ctx.lineTo(it.q[0], it.q[1]); ctx.stroke();
    } else {
      ctx.fillStyle = it.color; ctx.beginPath();
      ctx.arc(it.p[0], it.p[1], width / 2, 0, 2 * Math.PI); ctx.fill();
    }
  }
  const errors = r.error_labels.map((label, k) =>
    `${label}: ${r.errors[f * r.error_labels.length + k].toFixed(3)} m`).join("  ");
  ctx.fillStyle = "#141418"; ctx.font = "15px sans-serif";
  ctx.fillText(`${r.controller}`, 12, 22);
  ctx.fillText(`t = ${r.times[f].toFixed(2)} s   ${errors}`, 12, 42);
  scrub.max = r.frames - 1; scrub.value = f;
  document.getElementById("status").textContent =
    `frame ${f + 1} of ${r.frames}, ${playing ? "playing" : "paused"}`;
}
play.addEventListener("click", () => { playing = !playing; play.textContent = playing ? "pause" : "play"; draw(); });
scrub.addEventListener("input", () => { frame = Number(scrub.value); draw(); });
for (const el of [pick.controller, pick.trajectory, showPath]) el.addEventListener("change", draw);
let last = null;
function tick(now) {
  if (last !== null && playing) {
    clock += (now - last) / 1000 * Number(speed.value) * DATA.fps;
    const steps = Math.floor(clock);
    if (steps > 0) { clock -= steps; frame = (frame + steps) % current().frames; draw(); }
  }
  last = now; requestAnimationFrame(tick);
}
draw(); requestAnimationFrame(tick);
</script>"""

_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>__TITLE__</title>
<style>
body{font-family:system-ui,sans-serif;margin:1.2em;background:#f4f5f7;color:#222}
__STYLE__</style></head>
<body>
<h1 style="font-size:1.2em">__TITLE__</h1>
__VIEWER__</body></html>
"""
