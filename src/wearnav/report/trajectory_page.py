"""``trajectory.html``: the live page's drawing as one static, self-contained file (``wearnav track``).

The drawing lives here, below both of its users: ``wearnav track`` writes the static file and
``wearnav live`` serves the same ``static/draw.js`` and ``static/style.css`` beside its own page
(:mod:`wearnav.live.app`), and takes :func:`page_points` for its path.

The file holds the live page's stylesheet and drawing code (``static/style.css``, ``static/draw.js``)
inline, and the path as data in the live state's form (:meth:`wearnav.live.tracker.LiveTracker.state`:
``origin``, ``path`` [t, east, north, σ] at ``POINT_S``, ``fixes`` [t, east, north, accuracy]), so it
opens from the file with no network (map tiles only when online). A time slider draws the path up
to a moment; the path is coloured by the activity that ``classify`` finds (the shipped activity
model, :func:`wearnav.train.labelling.window_classes`), where the recording has the phone it needs.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np

from wearnav import pretrained
from wearnav.errors import ConfigError, ValidationError
from wearnav.train.labelling import intervals, window_classes
from wearnav.train.resolve import resolve_model

STATIC = Path(__file__).parent / "static"
TRAJECTORY_HTML = "trajectory.html"
POINT_S = 1.0  # the path drawn: one point per this many seconds (live and static), and the last

_SCRIPT = """
"use strict";
(() => {
  const data = JSON.parse(document.getElementById("wearnav-data").textContent);
  window.wearnavState = data;
  const canvas = document.getElementById("map"), slider = document.getElementById("slider");
  const colors = data.path.map(p => WearnavDraw.activityColor(labelAt(p[0])));
  function labelAt(t) {
    for (const a of data.activity || []) if (t >= a.start_s && t <= a.end_s) return a.label;
    return null;
  }
  slider.max = Math.max(0, data.path.length - 1);
  slider.value = slider.max;
  function render() {
    const upto = Number(slider.value);
    WearnavDraw.draw(canvas, data, {colors, upto, redraw: render});
    const p = data.path[upto];
    document.getElementById("points").textContent = data.path.length ? upto + 1 : 0;
    document.getElementById("time").textContent = p ? p[0].toFixed(1) : "–";
    document.getElementById("activity").textContent = (p && labelAt(p[0])) || "–";
    window.wearnavState.upto = upto;
  }
  const legend = document.getElementById("legend");
  for (const label of [...new Set((data.activity || []).map(a => a.label))]) {
    const span = document.createElement("span"), i = document.createElement("i");
    i.style.background = WearnavDraw.activityColor(label);
    span.append(i, label);
    legend.appendChild(span);
  }
  slider.addEventListener("input", render);
  window.addEventListener("resize", render);
  render();
})();
"""

_PAGE = """<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>{css}</style>
</head>
<body>
<header><h1>{title}</h1><span class="muted">{subtitle}</span></header>
<main>
  <canvas id="map" aria-label="the walking path on a metric grid"></canvas>
  <aside>
    <h2>Time</h2><input id="slider" type="range" min="0" max="0" step="1" value="0" aria-label="time">
    <div>at <span id="time">–</span> s: <span id="activity">–</span> (<span id="points">0</span> points drawn)</div>
    <h2>Activity</h2><div class="legend" id="legend"></div><div class="small">{activity_note}</div>
    <h2>Path</h2><div class="small">{path_note}</div>
    <h2>Warnings</h2><ul id="warnings">{warnings}</ul>
    <p class="small">The grid is metres east/north of the local origin; map tiles © OpenStreetMap contributors
      when online.</p>
  </aside>
</main>
<script id="wearnav-data" type="application/json">{data}</script>
<script>{draw}</script>
<script>{script}</script>
</body>
</html>
"""


def activity_intervals(rec, model: str | Path | None = None) -> tuple[list[dict] | None, str]:
    """The recording's activity intervals as ``classify`` finds them (start_s, end_s, label,
    windows, mean_confidence), or None and why not (no shipped activity model, no phone)."""
    try:
        path = pretrained.model_path(model, "classify")
        clf, cfg, classes = resolve_model(path, "classify")
    except ConfigError as exc:
        return None, f"not coloured by activity: {exc}"
    missing = [d for d in cfg.devices if d not in rec.devices]
    if missing:
        return None, f"not coloured by activity: the activity model needs {', '.join(missing)}"
    try:
        _, t, cls, conf = window_classes(clf, cfg, rec)
    except ValidationError as exc:
        return None, f"not coloured by activity: {exc}"
    if len(cls) == 0:
        return None, "not coloured by activity: shorter than one window of the activity model"
    rows = intervals(t[:, 0], t[:, 1], cls, conf, classes)
    return rows, f"coloured by {cfg.model} ({pretrained.shipped_name(path) or path}), as `wearnav classify` labels it"


def page_points(t: np.ndarray, xy: np.ndarray, sigma: np.ndarray | None, rate: float) -> list[list]:
    """The path as the live state holds it: one point per ``POINT_S`` of clock samples and the last."""
    step = max(1, int(round(POINT_S * rate)))
    idx = np.arange(0, len(t), step)
    if len(t) and idx[-1] != len(t) - 1:
        idx = np.append(idx, len(t) - 1)
    sig = np.full(len(t), np.nan) if sigma is None else np.asarray(sigma, float)
    return [
        [
            round(float(t[i]), 3),
            round(float(xy[i, 0]), 3),
            round(float(xy[i, 1]), 3),
            round(float(sig[i]), 2) if np.isfinite(sig[i]) else None,
        ]
        for i in idx
    ]


def trajectory_html(state: dict, title: str, subtitle: str = "", activity_note: str = "", path_note: str = "") -> str:
    """The self-contained page for ``state`` (the live state's keys, ``activity`` as intervals)."""
    data = json.dumps(state, allow_nan=False).replace("</", "<\\/")  # never ends the script element
    warnings = "".join(f"<li>{html.escape(w)}</li>" for w in state.get("warnings", []))
    return _PAGE.format(
        title=html.escape(title),
        subtitle=html.escape(subtitle),
        css=(STATIC / "style.css").read_text(),
        activity_note=html.escape(activity_note),
        path_note=html.escape(path_note),
        warnings=warnings,
        data=data,
        draw=(STATIC / "draw.js").read_text(),
        script=_SCRIPT,
    )


__all__ = ["POINT_S", "TRAJECTORY_HTML", "activity_intervals", "page_points", "trajectory_html"]
