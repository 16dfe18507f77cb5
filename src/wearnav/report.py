"""Reports: figures for checking a recording or a dataset, and the shipped-datasets page.

Figures are drawn on matplotlib's Agg canvas (``Figure`` objects, no pyplot state), so this works
headless and never changes the caller's backend. Files are written under a temporary name and
renamed, like every other output of wearnav.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable
import os
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import EllipseCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from wearnav.dataset import Dataset
from wearnav.errors import ValidationError, WearnavError
from wearnav.fileio import atomic_path, write_text_atomic
from wearnav.provenance import git_commit
from wearnav.metrics import errors_at_reference
from wearnav.recording import CANONICAL_DEVICES, DeviceStream, Recording

MAX_PLOT_POINTS = 4000      # per time-series line; longer series are min/max decimated
MAX_MAP_POINTS = 20000      # per trajectory line on a map
MAX_ACCURACY_CIRCLES = 150  # more circles than this hide the map; draw every k-th
ACC_COLOR, GYRO_COLOR = "tab:blue", "tab:orange"
TRUTH_COLOR, FIX_COLOR = "black", "tab:red"
# Label colours: these qualitative palettes one after the other (56 colours before any repeats);
# tab10 is left out so no label shares a colour with the signals, fixes or start marker.
LABEL_PALETTES = ("Dark2", "Set2", "tab20b", "tab20c")
FIX_MAX_GAP_S = 2.0         # a fix counts at a truth point only if one lies within this many seconds

# Shipped dataset folders (in ../shared/data) and the importer that reads each.
SHIPPED_DATASETS = {
    "ilc2_indoor_location": "ilc2",
    "ipin2023_track3": "ipin2023",
    "motionsense": "motionsense",
    "uci_hapt": "uci-hapt",
    "uji_phone_watch_har": "uji-phone-watch",
    "oxford_step_counter": "oxford-steps",
}


# ---- small helpers ------------------------------------------------------------------------

def _save(fig: Figure, out: Path, dpi: int = 110) -> Path:
    FigureCanvasAgg(fig)
    with atomic_path(out) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    return Path(out)


def _segments(t: np.ndarray, span: float) -> list[slice]:
    """Slices of ``t`` between gaps visible at plot scale (> 5 intervals and > span/1000)."""
    if t.size < 2:
        return [slice(0, t.size)]
    dt = np.diff(t)
    thr = max(5 * float(np.median(dt)), span / 1000)
    cuts = np.flatnonzero(dt > thr) + 1
    bounds = [0, *cuts.tolist(), t.size]
    return [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]


def decimate_minmax(t: np.ndarray, y: np.ndarray, max_points: int = MAX_PLOT_POINTS
                    ) -> tuple[np.ndarray, np.ndarray]:
    """At most about ``max_points`` points that draw like the full series.

    Each bin keeps its minimum and maximum (so spikes stay visible); visible gaps become NaN
    breaks instead of straight lines across them.
    """
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    span = float(t[-1] - t[0]) if t.size else 0.0
    segs = _segments(t, span)
    out_t, out_y = [], []
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

    palette = [c for name in LABEL_PALETTES for c in colormaps[name].colors]
    values = sorted(set(labels["value"]))
    return {v: palette[i % len(palette)] for i, v in enumerate(values)}


def _device_order(name: str) -> tuple[int, str]:
    """phone, watch, earbuds first (HDF5 hands devices back alphabetically), then the rest."""
    return (CANONICAL_DEVICES.index(name) if name in CANONICAL_DEVICES else len(CANONICAL_DEVICES), name)


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
    info = [f"{s.rate:.1f} Hz", f"{len(s):,} samples",
            "orientation" if s.quat is not None else "no orientation"]
    if s.gyro is not None:
        tt, yy = decimate_minmax(t, np.linalg.norm(s.gyro, axis=1))
        ax_gyro.plot(tt, yy, color=GYRO_COLOR, lw=0.6)
        ax_gyro.set_ylim(bottom=0)
    else:
        ax_gyro.text(0.5, 0.5, "no gyroscope in this stream", transform=ax_gyro.transAxes,
                     ha="center", va="center", color=GYRO_COLOR, fontsize=9, fontweight="bold")
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
            ax.broken_barh(list(zip(start[width > 0], width[width > 0])), (y + 0.1, 0.8),
                           facecolors=c, edgecolors="none")
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
        ax.text(0.5, 0.5, "no truth trajectory\nno location fixes", ha="center", va="center",
                transform=ax.transAxes, fontsize=10, color="0.3")
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
            ax.add_collection(EllipseCollection(d, d, np.zeros(circ.size), units="xy", offsets=p[circ],
                                                offset_transform=ax.transData, facecolors="none",
                                                edgecolors=FIX_COLOR, alpha=0.3, linewidths=0.6))
        ax.plot(p[:, 0], p[:, 1], ".", color=FIX_COLOR, ms=3 if len(p) < 2000 else 1.5)
        what = "" if not circ.size else (", circles: accuracy" + (f", 1 fix in {every}" if every > 1 else ""))
        handles.append(Line2D([], [], color=FIX_COLOR, marker=".", ls="none",
                              label=f"location fixes ({len(p)}){what}"))
    if truth is not None:
        p = truth.pos[:, :2]
        step = max(1, len(p) // MAX_MAP_POINTS)
        sparse = len(p) < 300 and (len(p) < 2 or np.median(np.diff(truth.t)) > 1.0)
        if sparse:
            ax.plot(p[:, 0], p[:, 1], "-o", color=TRUTH_COLOR, lw=0.8, ms=3.5, mfc="white")
            handles.append(Line2D([], [], color=TRUTH_COLOR, marker="o", mfc="white", lw=0.8,
                                  label=f"truth waypoints ({len(p)})"))
        else:
            ax.plot(p[::step, 0], p[::step, 1], "-", color=TRUTH_COLOR, lw=1.0)
            handles.append(Line2D([], [], color=TRUTH_COLOR, lw=1.0, label="truth trajectory"))
        start = p[0]
    else:
        start = fixes.pos[0, :2]
    ax.plot(*start, marker="*", color="tab:green", ms=14, mec="black", mew=0.6, ls="none", zorder=5)
    handles.append(Line2D([], [], marker="*", color="tab:green", mec="black", ms=11, ls="none",
                          label="start"))
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.grid(alpha=0.3)
    if compact:
        ax.tick_params(labelsize=7)
        if truth is None:
            ax.text(0.02, 0.98, "no truth: location fixes", transform=ax.transAxes, ha="left",
                    va="top", fontsize=7, color=FIX_COLOR)
    else:
        ax.set_xlabel("x / east [m]")
        ax.set_ylabel("y / north [m]")
    if truth is not None and truth.floor is not None and len(np.unique(truth.floor)) > 1:
        fl = truth.floor
        ax.set_title(f"floors {np.nanmin(fl):g} … {np.nanmax(fl):g} (map shows x, y only)", fontsize=8)
    if not compact:  # below the map, where it hides nothing
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.1), fontsize=8,
                  frameon=False, ncol=1)


def plot_recording(rec: Recording, out: Path) -> Path:
    """One PNG to check a recording: per-device |acc| / |gyro| over time, labels, map."""
    devices = sorted(rec.devices.items(), key=lambda kv: _device_order(kv[0]))
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
        fig.legend(handles=legend_handles, loc="outside lower center",
                   ncol=min(6, len(legend_handles)), fontsize=8, frameon=False)
    extras = [f"{rec.duration:.1f} s", ", ".join(d for d, _ in devices)]
    meta = _meta_line(rec.meta)
    fig.suptitle(f"{rec.name} — " + " · ".join(extras) + (f"\n{meta}" if meta else ""), fontsize=11)
    return _save(fig, out)


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
            sparse = len(p) < 300 and (len(p) < 2 or np.median(np.diff(rec.truth.t)) > 1.0)
            ax.plot(p[::step, 0], p[::step, 1], "-o" if sparse else "-", color=TRUTH_COLOR,
                    lw=0.9, ms=2.5, mfc="white")
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
    fig.suptitle(f"{ds.root.name}: truth trajectories ({shown} recordings; metres, start ★)",
                 fontsize=11)
    return _save(fig, out)


# ---- statistics of a dataset --------------------------------------------------------------

def _pct(x: np.ndarray, q: float) -> float:
    return float(np.percentile(x, q)) if x.size else float("nan")


def dataset_stats(ds: Dataset, progress: bool = False, fix_max_gap: float = FIX_MAX_GAP_S) -> dict:
    """Counts, rates, label tallies and fix errors of a dataset (loads every recording once).

    Per device, the intervals between consecutive samples are pooled over all recordings:
    ``rate_hz`` = 1 / median interval; ``jitter_iqr_ms`` = interquartile range (75th − 25th
    percentile) of the intervals; ``gap_share`` = share of intervals longer than twice the median.
    ``fix_error_m``: horizontal error of the location fixes at the truth points (fixes linearly
    interpolated, a truth point counted only when a fix lies within ``fix_max_gap`` s), pooled.
    """
    from tqdm import tqdm

    dev: dict[str, dict] = {}
    labels: dict[tuple[str, str], list] = {}
    fix_err: list[np.ndarray] = []
    fix_err_recs = 0
    truth_points = truth_recs = fixes_total = 0
    subjects: set[str] = set()
    duration = 0.0
    for name in tqdm(ds.names, desc=f"stats {ds.root.name}", unit="rec", disable=not progress):
        rec = ds.load(name)
        duration += rec.duration
        if str(rec.meta.get("subject", "")).strip():
            subjects.add(str(rec.meta["subject"]))
        for d, s in rec.devices.items():
            e = dev.setdefault(d, {"recordings": 0, "samples": 0, "gyro": 0, "quat": 0, "dt": []})
            e["recordings"] += 1
            e["samples"] += len(s)
            e["gyro"] += len(s) if s.gyro is not None else 0
            e["quat"] += len(s) if s.quat is not None else 0
            e["dt"].append(np.diff(s.t).astype(np.float32))
        for row in rec.labels.itertuples():
            c = labels.setdefault((row.kind, row.value), [0, 0.0])
            c[0] += 1
            c[1] += row.end - row.start
        if rec.truth is not None:
            truth_points += len(rec.truth)
            truth_recs += 1
        if rec.fixes is not None:
            fixes_total += len(rec.fixes)
        if rec.truth is not None and rec.fixes is not None:
            err = errors_at_reference(rec.fixes.t, rec.fixes.pos, rec.truth.t, rec.truth.pos, fix_max_gap)
            if err.size:
                fix_err.append(err)
                fix_err_recs += 1
    devices = {}
    for d, e in sorted(dev.items(), key=lambda kv: _device_order(kv[0])):
        dt = np.concatenate(e["dt"]).astype(np.float64) if e["dt"] else np.empty(0)
        med = _pct(dt, 50)
        devices[d] = {
            "recordings": e["recordings"],
            "samples": e["samples"],
            "rate_hz": 1.0 / med if dt.size and med > 0 else float("nan"),
            "interval_median_ms": 1e3 * med,
            "jitter_iqr_ms": 1e3 * (_pct(dt, 75) - _pct(dt, 25)),
            "gap_share": float(np.mean(dt > 2 * med)) if dt.size else float("nan"),
            "gyro_share": e["gyro"] / e["samples"],
            "orientation_share": e["quat"] / e["samples"],
        }
    errs = np.concatenate(fix_err) if fix_err else np.empty(0)
    return {
        "recordings": len(ds),
        "subjects": len(subjects),
        "duration_s": duration,
        "devices": devices,
        "labels": {k: {"intervals": v[0], "duration_s": v[1]} for k, v in sorted(labels.items())},
        "truth_points": truth_points,
        "recordings_with_truth": truth_recs,
        "fixes": fixes_total,
        "fix_error_m": None if not fix_err else {
            "points": int(errs.size), "recordings": fix_err_recs,
            "median": _pct(errs, 50), "p75": _pct(errs, 75), "max_gap_s": fix_max_gap,
        },
    }


def walk_tables(ds: Dataset, by: Iterable[str] = ("mode",)) -> dict[str, pd.DataFrame]:
    """For each manifest column in ``by``, a table per value: recordings, minutes, distance walked
    (dense truth) and the median 1-s label noise of the location fixes (EasyTrack eq. 5–6, truth
    interpolated at fix times). Each recording is loaded once, whatever ``by`` holds."""
    from wearnav.preprocess import interpolate_position
    from wearnav.simulate.fixes import label_noise

    per_rec = {}
    for name in ds.names:
        rec = ds.load(name)
        dist, noise = 0.0, np.empty(0)
        if rec.truth is not None:
            p = rec.truth.pos[:, :2]
            dist = float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
            if rec.fixes is not None:
                tp = interpolate_position(rec.truth.t, p, rec.fixes.t, max_gap=np.inf)
                inside = np.isfinite(tp[:, 0])
                noise = label_noise(rec.fixes.pos[inside], tp[inside])
        per_rec[name] = (rec.duration, dist, noise)
    tables = {}
    for col in by:
        rows = []
        for key, names in ds.manifest.groupby(col, sort=True)["name"]:
            dur, dist, noise = zip(*(per_rec[n] for n in names))
            n = np.concatenate(noise)
            rows.append({col: key or "-", "recordings": len(names), "minutes": round(sum(dur) / 60, 1),
                         "distance_km": round(sum(dist) / 1000, 2),
                         "fix_label_noise_median_cm": round(100 * float(np.median(n)), 1) if n.size else None})
        tables[col] = pd.DataFrame(rows)
    return tables


def _fmt_duration(s: float) -> str:
    if s >= 3600:
        return f"{s / 3600:.2f} h"
    if s >= 60:
        return f"{s / 60:.1f} min"
    return f"{s:.1f} s"


def stats_markdown(stats: dict) -> str:
    """Markdown tables for one dataset's :func:`dataset_stats`."""
    out = []
    truth = f"{stats['truth_points']:,} in {stats['recordings_with_truth']} recordings" \
        if stats["truth_points"] else "none"
    out += ["| recordings | subjects | total duration | truth points | location fixes |",
            "|---:|---:|---:|---:|---:|",
            f"| {stats['recordings']:,} | {stats['subjects'] or '—'} | "
            f"{_fmt_duration(stats['duration_s'])} | {truth} | {stats['fixes']:,} |", ""]
    out += ["| device | recordings | samples | median rate | median interval | jitter (IQR of intervals) "
            "| intervals > 2× median | with gyro | with orientation |",
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for d, e in stats["devices"].items():
        out.append(f"| {d} | {e['recordings']:,} | {e['samples']:,} | {e['rate_hz']:.2f} Hz | "
                   f"{e['interval_median_ms']:.2f} ms | {e['jitter_iqr_ms']:.3f} ms | "
                   f"{100 * e['gap_share']:.2f} % | {100 * e['gyro_share']:.0f} % | "
                   f"{100 * e['orientation_share']:.0f} % |")
    out.append("")
    if stats["labels"]:
        out += ["| label kind | value | intervals | total duration |", "|---|---|---:|---:|"]
        for (kind, value), c in stats["labels"].items():
            out.append(f"| {kind} | {value} | {c['intervals']:,} | {_fmt_duration(c['duration_s'])} |")
    else:
        out.append("No labels.")
    out.append("")
    fe = stats["fix_error_m"]
    if fe is not None:
        out += [f"**Location fixes at the truth points** (fixes linearly interpolated at each truth "
                f"time that has a fix within {fe['max_gap_s']:g} s; horizontal distance): "
                f"median **{fe['median']:.2f} m**, 75th percentile **{fe['p75']:.2f} m** over "
                f"{fe['points']:,} points in {fe['recordings']} recordings. This is the reference "
                f"a learned tracker must beat.", ""]
    return "\n".join(out)


def _pick_recording(ds: Dataset) -> str:
    """The recording with the most to look at: truth and fixes first, then the most truth
    points, then the longest."""
    m = ds.manifest
    tp, fx = m["truth_points"].fillna(0), m["fixes"].fillna(0)
    key = pd.DataFrame({"score": (tp > 0).astype(int) + (fx > 0).astype(int), "tp": tp,
                        "dur": m["duration"].fillna(0)})
    best = key.sort_values(["score", "tp", "dur"], ascending=False, kind="stable").index[0]
    return str(m["name"].loc[best])


def write_datasets_report(data: Path, out: Path, work: Path, progress: bool = True,
                          datasets: dict[str, str] | None = None) -> Path:
    """Import each shipped dataset (or reuse ``work/<format>``) and write a Markdown page.

    ``datasets`` maps folder names under ``data`` to importer formats (default: the shipped
    ones). Per dataset: :func:`stats_markdown` tables and a :func:`plot_recording` PNG under
    ``<out's folder>/img/``. A dataset whose folder is missing or whose import fails gets a line
    saying so; the page is written anyway, and then the failures raise one WearnavError.
    """
    from wearnav import __version__
    from wearnav.importers import import_dataset

    data, out, work = Path(data), Path(out), Path(work)
    datasets = SHIPPED_DATASETS if datasets is None else datasets
    img_dir = out.parent / "img"
    commit = git_commit()
    lines = [f"_Generated by `wearnav datasets-report --data {data} --out {out} --work {work}` "
             f"(wearnav {__version__}{', commit ' + commit if commit else ''}); do not edit by hand._",
             "", "# Shipped datasets, as imported", "",
             "Each dataset is read from its original files with `wearnav import FORMAT`. Rates: "
             "median rate = 1 / median interval between consecutive samples; **jitter = interquartile "
             "range (75th − 25th percentile) of those intervals**; both pooled over all recordings "
             "of a device. \"With orientation\" / \"with gyro\": share of samples whose stream "
             "carries a quaternion / a gyroscope.", ""]
    failures = []
    for folder, fmt in datasets.items():
        src = data / folder
        lines += [f"## {folder} (`{fmt}`)", ""]
        if not src.exists():
            lines += [f"Not found: `{src}`.", ""]
            failures.append(f"{folder}: not found")
            continue
        dest = work / fmt
        try:
            if (dest / "manifest.csv").exists():
                ds = Dataset.open(dest)
            else:
                ds = import_dataset(fmt, src, dest, progress=progress)
        except (WearnavError, ModuleNotFoundError) as exc:
            lines += [f"Import failed: `{exc}`", ""]
            failures.append(f"{folder}: {exc}")
            continue
        lines += [f"Source `{src}`, imported to `{dest}`.", ""]
        if len(ds) == 0:
            lines += ["The import produced no recordings.", ""]
            failures.append(f"{folder}: no recordings")
            continue
        lines.append(stats_markdown(dataset_stats(ds, progress=progress)))
        name = _pick_recording(ds)
        png = plot_recording(ds.load(name), img_dir / f"{fmt}.png")
        rel = os.path.relpath(png, out.parent)
        lines += [f"![{fmt}: recording {name}]({rel})", "", f"_Figure: recording `{name}`._", ""]
    write_text_atomic("\n".join(lines).rstrip() + "\n", out)
    if failures:
        raise WearnavError(f"{len(failures)} dataset(s) not reported ({'; '.join(failures)}); "
                           f"the rest is in {out}")
    return out
