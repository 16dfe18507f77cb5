"""The statistics behind ``wearnav info`` and the datasets page: counts, sampling rates and
jitter, label tallies, fix errors at the truth, and per-group walking tables."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import pandas as pd

from wearnav.core.geo import needs_reimport
from wearnav.core.progress import progress as report_progress
from wearnav.core.timeseries import sampling
from wearnav.dataset import Dataset
from wearnav.metrics import FIX_MAX_GAP_S, errors_at_reference, label_noise
from wearnav.recording import device_order


def _pct(x: np.ndarray, q: float) -> float:
    return float(np.percentile(x, q)) if x.size else float("nan")


def dataset_stats(ds: Dataset, progress: bool = False, fix_max_gap: float = FIX_MAX_GAP_S) -> dict:
    """Counts, rates, label tallies and fix errors of a dataset (loads every recording once).

    Per device, the intervals between consecutive samples are pooled over all recordings:
    ``rate_hz`` = 1 / median interval; ``jitter_iqr_ms`` = interquartile range (75th − 25th
    percentile) of the intervals; ``gap_share`` = share of intervals longer than twice the median.
    ``fix_error_m``: horizontal error of the location fixes at the truth points (fixes linearly
    interpolated, a truth point counted only when a fix lies within ``fix_max_gap`` s), pooled.
    ``needs_reimport``: one line naming the recordings whose positions came from an older lat/lon
    projection (:func:`wearnav.core.geo.needs_reimport`), or None.
    """
    dev: dict[str, dict] = {}
    labels: dict[tuple[str, str], list] = {}
    fix_err: list[np.ndarray] = []
    fix_err_recs = 0
    truth_points = truth_recs = fixes_total = 0
    subjects: set[str] = set()
    stale: dict[str, str] = {}
    duration = 0.0
    for name in report_progress(ds.names, desc=f"stats {ds.root.name}", unit="rec", enabled=progress):
        rec = ds.load(name)
        duration += rec.duration
        if (why := needs_reimport(rec.meta, has_fixes=rec.fixes is not None)) is not None:
            stale[name] = why
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
    for d, e in sorted(dev.items(), key=lambda kv: device_order(kv[0])):
        smp = sampling(np.concatenate(e["dt"]) if e["dt"] else np.empty(0))
        devices[d] = {
            "recordings": e["recordings"],
            "samples": e["samples"],
            "rate_hz": smp.rate_hz,
            "interval_median_ms": 1e3 * smp.interval_median_s,
            "jitter_iqr_ms": 1e3 * smp.jitter_iqr_s,
            "gap_share": smp.gap_share,
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
        "fix_error_m": None
        if not fix_err
        else {
            "points": int(errs.size),
            "recordings": fix_err_recs,
            "median": _pct(errs, 50),
            "p75": _pct(errs, 75),
            "max_gap_s": fix_max_gap,
        },
        "needs_reimport": None
        if not stale
        else (
            f"{len(stale)} of {len(ds)} recordings ({', '.join(list(stale)[:3])}{', ...' if len(stale) > 3 else ''})"
            f": {next(iter(stale.values()))}"
        ),
    }


def walk_tables(ds: Dataset, by: Iterable[str] = ("mode",)) -> dict[str, pd.DataFrame]:
    """For each manifest column in ``by``, a table per value: recordings, minutes, distance walked
    (dense truth) and the median 1-s label noise of the location fixes (EasyTrack eq. 5–6, truth
    interpolated at fix times, :func:`wearnav.metrics.label_noise`). Each recording is loaded
    once, whatever ``by`` holds."""
    per_rec = {}
    for name in ds.names:
        rec = ds.load(name)
        dist, noise = 0.0, np.empty(0)
        if rec.truth is not None:
            p = rec.truth.pos[:, :2]
            dist = float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
            if rec.fixes is not None:
                noise = label_noise(rec.fixes.t, rec.fixes.pos, rec.truth.t, p)
        per_rec[name] = (rec.duration, dist, noise)
    tables = {}
    for col in by:
        rows = []
        for key, names in ds.manifest.groupby(col, sort=True)["name"]:
            durs, dists, noises = zip(*(per_rec[n] for n in names))
            n = np.concatenate(noises)
            rows.append(
                {
                    col: key or "-",
                    "recordings": len(names),
                    "minutes": round(sum(durs) / 60, 1),
                    "distance_km": round(sum(dists) / 1000, 2),
                    "fix_label_noise_median_cm": round(100 * float(np.median(n)), 1) if n.size else None,
                }
            )
        tables[col] = pd.DataFrame(rows)
    return tables


def _fmt_duration(s: float) -> str:
    if s >= 3600:
        return f"{s / 3600:.2f} h"
    if s >= 60:
        return f"{s / 60:.1f} min"
    return f"{s:.1f} s"


def _markdown(df: pd.DataFrame, align: str) -> str:
    """``df`` (cells already formatted as text) as a Markdown table; ``align``: one letter per
    column, l(eft) or r(ight)."""
    colalign = [{"l": "left", "r": "right"}[a] for a in align]
    return df.to_markdown(index=False, disable_numparse=True, colalign=colalign)


def stats_markdown(stats: dict) -> str:
    """Markdown tables for one dataset's :func:`dataset_stats`."""
    out = []
    truth = (
        f"{stats['truth_points']:,} in {stats['recordings_with_truth']} recordings" if stats["truth_points"] else "none"
    )
    overview = pd.DataFrame(
        [
            {
                "recordings": f"{stats['recordings']:,}",
                "subjects": str(stats["subjects"] or "—"),
                "total duration": _fmt_duration(stats["duration_s"]),
                "truth points": truth,
                "location fixes": f"{stats['fixes']:,}",
            }
        ]
    )
    out += [_markdown(overview, "rrrrr"), ""]
    devices = pd.DataFrame(
        [
            {
                "device": d,
                "recordings": f"{e['recordings']:,}",
                "samples": f"{e['samples']:,}",
                "median rate": f"{e['rate_hz']:.2f} Hz",
                "median interval": f"{e['interval_median_ms']:.2f} ms",
                "jitter (IQR of intervals)": f"{e['jitter_iqr_ms']:.3f} ms",
                "intervals > 2× median": f"{100 * e['gap_share']:.2f} %",
                "with gyro": f"{100 * e['gyro_share']:.0f} %",
                "with orientation": f"{100 * e['orientation_share']:.0f} %",
            }
            for d, e in stats["devices"].items()
        ],
        columns=[
            "device",
            "recordings",
            "samples",
            "median rate",
            "median interval",
            "jitter (IQR of intervals)",
            "intervals > 2× median",
            "with gyro",
            "with orientation",
        ],
    )
    out += [_markdown(devices, "lrrrrrrrr"), ""]
    if stats["labels"]:
        labels = pd.DataFrame(
            [
                {
                    "label kind": kind,
                    "value": value,
                    "intervals": f"{c['intervals']:,}",
                    "total duration": _fmt_duration(c["duration_s"]),
                }
                for (kind, value), c in stats["labels"].items()
            ]
        )
        out.append(_markdown(labels, "llrr"))
    else:
        out.append("No labels.")
    out.append("")
    fe = stats["fix_error_m"]
    if fe is not None:
        out += [
            f"**Location fixes at the truth points** (fixes linearly interpolated at each truth "
            f"time that has a fix within {fe['max_gap_s']:g} s; horizontal distance): "
            f"median **{fe['median']:.2f} m**, 75th percentile **{fe['p75']:.2f} m** over "
            f"{fe['points']:,} points in {fe['recordings']} recordings. This is the reference "
            f"a learned tracker must beat.",
            "",
        ]
    return "\n".join(out)
