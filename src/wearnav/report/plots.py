"""Figures for checking a recording or a dataset: signals over time, labels, maps.

Figures are drawn on matplotlib's Agg canvas (``Figure`` objects, no pyplot state), so this works
headless and never changes the caller's backend. Files are written under a temporary name and
renamed, like every other output of wearnav.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import EllipseCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from numpy.typing import ArrayLike

from wearnav.core.fileio import atomic_path
from wearnav.core.timeseries import period
from wearnav.dataset import Dataset
from wearnav.errors import ValidationError
from wearnav.metrics import ecdf
from wearnav.recording import DeviceStream, Recording, device_order

MAX_PLOT_POINTS = 4000  # per time-series line; longer series are min/max decimated
MAX_MAP_POINTS = 20000  # per trajectory line on a map
MAX_CDF_POINTS = 2000  # steps per empirical CDF line
MAX_ACCURACY_CIRCLES = 150  # more circles than this hide the map; draw every k-th
ACC_COLOR, GYRO_COLOR = "tab:blue", "tab:orange"
TRUTH_COLOR, FIX_COLOR = "black", "tab:red"
# Label colours: these qualitative palettes one after the other (56 colours before any repeats);
# tab10 is left out so no label shares a colour with the signals, fixes or start marker.
LABEL_PALETTES = ("Dark2", "Set2", "tab20b", "tab20c")


# ---- small helpers ------------------------------------------------------------------------


def save(fig: Figure, out: Path, dpi: int = 110) -> Path:
    FigureCanvasAgg(fig)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    return Path(out)


def plot_ecdf(ax, values, max_points: int = MAX_CDF_POINTS, **kw) -> None:
    """Draw the empirical CDF of ``values`` (:func:`wearnav.metrics.ecdf`) on ``ax`` as a step
    function rising from 0 at the smallest value to 1 at the largest; ``kw`` go to
    ``Axes.step`` (label, colour...). A sample with more distinct values than ``max_points`` is
    drawn through every k-th step (and the last), which looks the same at figure scale."""
    x, p = ecdf(values)
    if x.size > max_points:
        keep = np.unique(np.r_[np.arange(0, x.size, -(-x.size // max_points)), x.size - 1])
        x, p = x[keep], p[keep]
    ax.step(np.r_[x[0], x], np.r_[0.0, p], where="post", **kw)


def _segments(t: np.ndarray, span: float) -> list[slice]:
    """Slices of ``t`` between gaps visible at plot scale (> 5 intervals and > span/1000)."""
    if t.size < 2:
        return [slice(0, t.size)]
    dt = np.diff(t)
    thr = max(5 * period(t), span / 1000)
    cuts = np.flatnonzero(dt > thr) + 1
    bounds = [0, *cuts.tolist(), t.size]
    return [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]


def decimate_minmax(t: np.ndarray, y: np.ndarray, max_points: int = MAX_PLOT_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """At most about ``max_points`` points that draw like the full series.

    Each bin keeps its minimum and maximum (so spikes stay visible); visible gaps become NaN
    breaks instead of straight lines across them.
    """
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    span = float(t[-1] - t[0]) if t.size else 0.0
    segs = _segments(t, span)
    out_t: list[ArrayLike] = []
    out_y: list[ArrayLike] = []
    for k, sl in enumerate(segs):
        ts, ys = t[sl], y[sl]
        budget = max(4, int(max_points * ts.size / max(t.size, 1)))
        if ts.size > budget:
            edges = np.linspace(0, ts.size, budget // 2 + 1).astype(int)
            edges = np.unique(edges[:-1])
            lo = np.minimum.reduceat(ys, edges)
            hi = np.maximum.reduceat(ys, edges)
            tb = ts[edges]
            ts = np.repeat(tb, 2)
            ys = np.column_stack([lo, hi]).ravel()
        out_t.append(ts)
        out_y.append(ys)
        if k < len(segs) - 1:
            out_t.append([np.nan])
            out_y.append([np.nan])
    return np.concatenate(out_t), np.concatenate(out_y)


def _runs(mask: np.ndarray, t: np.ndarray) -> list[tuple[float, float]]:
    """(start, end) times of the runs where ``mask`` is True."""
    m = np.asarray(mask, dtype=np.int8)
    d = np.diff(np.concatenate([[0], m, [0]]))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    return [(float(t[a]), float(t[b])) for a, b in zip(starts, ends)]


def _label_colors(labels) -> dict[str, tuple]:
    """A distinct colour per label value (the same value in two kinds, e.g. phone and watch
    annotations of one activity, shares it), drawn in order from one long qualitative palette."""
    from matplotlib import colormaps

    # the LABEL_PALETTES are ListedColormaps (their colours a list); a Colormap in general has none
    palette = [c for name in LABEL_PALETTES for c in colormaps[name].colors]  # type: ignore[attr-defined]
    values = sorted(set(labels["value"]))
    return {v: palette[i % len(palette)] for i, v in enumerate(values)}


def _meta_line(meta: dict, keys=("source", "subject", "mode", "placement", "scene")) -> str:
    parts = [f"{k} {meta[k]}" for k in keys if str(meta.get(k, "")).strip()]
    return " · ".join(parts)


# ---- one recording ------------------------------------------------------------------------


def _device_panel(ax_acc, ax_gyro, dev: str, s: DeviceStream, t0: float) -> list:
    """|acc| above |gyro|, not-worn spans shaded in both; returns the legend handles used."""
    t = s.t - t0
    handles = []
    tt, yy = decimate_minmax(t, np.linalg.norm(s.acc, axis=1))
    ax_acc.plot(tt, yy, color=ACC_COLOR, lw=0.6)
    ax_acc.set_ylabel("|acc|\nm/s²", color=ACC_COLOR, fontsize=8)
    info = [f"{s.rate:.1f} Hz", f"{len(s):,} samples", "orientation" if s.quat is not None else "no orientation"]
    if s.gyro is not None:
        tt, yy = decimate_minmax(t, np.linalg.norm(s.gyro, axis=1))
        ax_gyro.plot(tt, yy, color=GYRO_COLOR, lw=0.6)
        ax_gyro.set_ylim(bottom=0)
    else:
        ax_gyro.text(
            0.5,
            0.5,
            "no gyroscope in this stream",
            transform=ax_gyro.transAxes,
            ha="center",
            va="center",
            color=GYRO_COLOR,
            fontsize=9,
            fontweight="bold",
        )
        ax_gyro.set_yticks([])
    ax_gyro.set_ylabel("|gyro|\nrad/s", color=GYRO_COLOR, fontsize=8)
    if s.worn is not None and not s.worn.all():
        for ax in (ax_acc, ax_gyro):
            for a, b in _runs(~s.worn, t):
                ax.axvspan(a, b, facecolor="0.6", alpha=0.35, hatch="//", edgecolor="0.4", lw=0)
        handles.append(Patch(facecolor="0.6", alpha=0.35, hatch="//", edgecolor="0.4", label="not worn"))
        info.append(f"worn {100 * s.worn.mean():.0f} %")
    ax_acc.set_title(f"{dev}: " + " · ".join(info), loc="left", fontsize=9, pad=2)
    for ax in (ax_acc, ax_gyro):
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=8)
    return handles


def _label_lanes(ax, labels, colors, t0: float) -> list:
    """One lane per label kind, intervals as coloured bars, point events as ticks."""
    kinds = sorted(set(labels["kind"]))
    for k, kind in enumerate(kinds):
        rows = labels[labels["kind"] == kind]
        y = len(kinds) - 1 - k
        for value, g in rows.groupby("value", sort=True):
            c = colors[value]
            start = g["start"].to_numpy() - t0
            width = (g["end"] - g["start"]).to_numpy()
            ax.broken_barh(
                list(zip(start[width > 0], width[width > 0])), (y + 0.1, 0.8), facecolors=c, edgecolors="none"
            )
            if np.any(width == 0):  # point events (e.g. steps): ticks
                ax.vlines(start[width == 0], y + 0.1, y + 0.9, colors=[c], lw=0.8)
    ax.set_yticks(np.arange(len(kinds)) + 0.5, labels=list(reversed(kinds)))
    ax.set_ylim(0, len(kinds))
    ax.tick_params(axis="y", length=0)
    ax.grid(axis="x", alpha=0.3)
    handles = []
    for value, c in colors.items():
        in_kinds = sorted(set(labels.loc[labels["value"] == value, "kind"]))
        handles.append(Patch(facecolor=c, label=f"{', '.join(in_kinds)}: {value}"))
    return handles


def _map_panel(ax, rec: Recording, compact: bool = False) -> None:
    truth, fixes = rec.truth, rec.fixes
    if truth is None and fixes is None:
        ax.text(
            0.5,
            0.5,
            "no truth trajectory\nno location fixes",
            ha="center",
            va="center",
            transform=ax.transAxes,
            fontsize=10,
            color="0.3",
        )
        ax.set_xticks([])
        ax.set_yticks([])
        return
    handles = []
    if fixes is not None:
        p = fixes.pos[:, :2]
        ok = np.isfinite(fixes.accuracy) & (fixes.accuracy > 0)
        every = max(1, int(np.ceil(ok.sum() / MAX_ACCURACY_CIRCLES)))
        circ = np.flatnonzero(ok)[::every]
        if circ.size:
            d = 2 * fixes.accuracy[circ]  # diameters: the circle's radius is the accuracy
            ax.add_collection(
                EllipseCollection(
                    d,
                    d,
                    np.zeros(circ.size),
                    units="xy",
                    offsets=p[circ],
                    offset_transform=ax.transData,
                    facecolors="none",
                    edgecolors=FIX_COLOR,
                    alpha=0.3,
                    linewidths=0.6,
                )
            )
        ax.plot(p[:, 0], p[:, 1], ".", color=FIX_COLOR, ms=3 if len(p) < 2000 else 1.5)
        what = "" if not circ.size else (", circles: accuracy" + (f", 1 fix in {every}" if every > 1 else ""))
        handles.append(Line2D([], [], color=FIX_COLOR, marker=".", ls="none", label=f"location fixes ({len(p)}){what}"))
    if truth is not None:
        p = truth.pos[:, :2]
        step = max(1, len(p) // MAX_MAP_POINTS)
        sparse = len(p) < 300 and (len(p) < 2 or period(truth.t) > 1.0)
        if sparse:
            ax.plot(p[:, 0], p[:, 1], "-o", color=TRUTH_COLOR, lw=0.8, ms=3.5, mfc="white")
            handles.append(
                Line2D([], [], color=TRUTH_COLOR, marker="o", mfc="white", lw=0.8, label=f"truth waypoints ({len(p)})")
            )
        else:
            ax.plot(p[::step, 0], p[::step, 1], "-", color=TRUTH_COLOR, lw=1.0)
            handles.append(Line2D([], [], color=TRUTH_COLOR, lw=1.0, label="truth trajectory"))
        start = p[0]
    else:
        assert fixes is not None  # neither: returned above
        start = fixes.pos[0, :2]
    ax.plot(*start, marker="*", color="tab:green", ms=14, mec="black", mew=0.6, ls="none", zorder=5)
    handles.append(Line2D([], [], marker="*", color="tab:green", mec="black", ms=11, ls="none", label="start"))
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.grid(alpha=0.3)
    if compact:
        ax.tick_params(labelsize=7)
        if truth is None:
            ax.text(
                0.02,
                0.98,
                "no truth: location fixes",
                transform=ax.transAxes,
                ha="left",
                va="top",
                fontsize=7,
                color=FIX_COLOR,
            )
    else:
        ax.set_xlabel("x / east [m]")
        ax.set_ylabel("y / north [m]")
    if truth is not None and truth.floor is not None and len(np.unique(truth.floor)) > 1:
        fl = truth.floor
        ax.set_title(f"floors {np.nanmin(fl):g} … {np.nanmax(fl):g} (map shows x, y only)", fontsize=8)
    if not compact:  # below the map, where it hides nothing
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.1), fontsize=8, frameon=False, ncol=1)


def plot_recording(rec: Recording, out: Path) -> Path:
    """One PNG to check a recording: per-device |acc| / |gyro| over time, labels, map."""
    devices = sorted(rec.devices.items(), key=lambda kv: device_order(kv[0]))
    t0 = rec.t_start
    has_labels = not rec.labels.empty
    kinds = sorted(set(rec.labels["kind"])) if has_labels else []
    lane_h = 0.35 * len(kinds) + 0.3 if has_labels else 0
    heights = ([lane_h] if has_labels else []) + [1.3, 1.0] * len(devices)
    fig = Figure(figsize=(16, max(5.0, 1.6 + sum(heights))), layout="constrained")
    gs = fig.add_gridspec(len(heights), 2, width_ratios=[2.3, 1], height_ratios=heights)
    axes = []
    legend_handles: list = []
    first = None
    if has_labels:
        ax = fig.add_subplot(gs[0, 0])
        legend_handles += _label_lanes(ax, rec.labels, _label_colors(rec.labels), t0)
        ax.set_title("labels", loc="left", fontsize=9)
        axes.append(ax)
        first = ax
    for i, (dev, s) in enumerate(devices):
        row = 2 * i + int(has_labels)
        ax_acc = fig.add_subplot(gs[row, 0], sharex=first)
        first = first or ax_acc
        ax_gyro = fig.add_subplot(gs[row + 1, 0], sharex=first)
        for h in _device_panel(ax_acc, ax_gyro, dev, s, t0):
            if h.get_label() not in [x.get_label() for x in legend_handles]:
                legend_handles.append(h)
        axes += [ax_acc, ax_gyro]
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    axes[-1].set_xlabel("time since start [s]" + (f" (t0 = {t0:.3f} s)" if abs(t0) > 1e-9 else ""))
    axes[0].set_xlim(0, max(rec.duration, 1e-3))
    _map_panel(fig.add_subplot(gs[:, 1]), rec)
    if legend_handles:
        fig.legend(
            handles=legend_handles,
            loc="outside lower center",
            ncol=min(6, len(legend_handles)),
            fontsize=8,
            frameon=False,
        )
    extras = [f"{rec.duration:.1f} s", ", ".join(d for d, _ in devices)]
    meta = _meta_line(rec.meta)
    fig.suptitle(f"{rec.name} — " + " · ".join(extras) + (f"\n{meta}" if meta else ""), fontsize=11)
    return save(fig, out)


# ---- a dataset ----------------------------------------------------------------------------


def plot_trajectories(ds: Dataset, out: Path, max_recordings: int = 12) -> Path:
    """A grid of small maps of truth trajectories: up to ``max_recordings``, taken in turn from
    each walking mode so that every mode is shown."""
    if len(ds) == 0:
        raise ValidationError("dataset is empty, nothing to plot", ds.root)
    by_mode = ds.manifest.groupby("mode", sort=True)["name"].apply(list)
    names = [n for row in itertools.zip_longest(*by_mode) for n in row if n is not None][:max_recordings]
    ncols = min(4, len(names))
    nrows = -(-len(names) // ncols)
    fig = Figure(figsize=(3.6 * ncols, 3.5 * nrows + 0.6), layout="constrained")
    for k, name in enumerate(names):
        ax = fig.add_subplot(nrows, ncols, k + 1)
        rec = ds.load(name)
        if rec.truth is None:
            _map_panel(ax, rec, compact=True)
        else:
            p = rec.truth.pos[:, :2]
            step = max(1, len(p) // MAX_MAP_POINTS)
            sparse = len(p) < 300 and (len(p) < 2 or period(rec.truth.t) > 1.0)
            ax.plot(p[::step, 0], p[::step, 1], "-o" if sparse else "-", color=TRUTH_COLOR, lw=0.9, ms=2.5, mfc="white")
            ax.plot(*p[0], marker="*", color="tab:green", ms=11, mec="black", mew=0.5)
            ax.set_aspect("equal", adjustable="datalim")
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=7)
        m = rec.meta
        sub = " · ".join(str(m.get(k)) for k in ("mode", "placement") if str(m.get(k, "")).strip())
        if str(m.get("subject", "")).strip():
            sub += (" · " if sub else "") + f"subject {m['subject']}"
        ax.set_title(f"{name}\n{sub}" if sub else name, fontsize=8)
    shown = f"{len(names)} of {len(ds)}" if len(names) < len(ds) else f"all {len(ds)}"
    fig.suptitle(f"{ds.root.name}: truth trajectories ({shown} recordings; metres, start ★)", fontsize=11)
    return save(fig, out)
