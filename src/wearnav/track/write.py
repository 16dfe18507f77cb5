"""What `wearnav track` writes (the files the :mod:`wearnav.track` docstring lists): the path placed
on the fixes or taken from the map-aware filter, ``trajectory.csv``, ``fixes.csv``,
``trajectory.geojson``, ``trajectory.png``, ``trajectory.html`` and ``track.json``.

Decision: docs/decisions/0016-track-outputs-geojson.md."""

from __future__ import annotations

import dataclasses
import json
import warnings
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import fuse
from wearnav.core import geo
from wearnav.core.fileio import atomic_path, write_text_atomic
from wearnav.errors import WearnavWarning
from wearnav.fixcheck import FixCheck
from wearnav.recording import FloorPlan, Recording
from wearnav.report.trajectory_page import page_points, trajectory_html
from wearnav.track.files import TRACK_JSON

ANCHOR_TEXT = {
    "smooth": "robust smoother over every fix (wearnav.fuse): heading offset, scale (prior), heading drift, "
    "slowly varying fix bias; fixes weighted by their reported accuracy",
    "rigid": "weighted (1/σ²) least-squares rotation + translation over every kept fix of the walk",
    "first-fixes": f"weighted (1/σ²) least-squares rotation + translation over the kept fixes of the first "
    f"{fuse.ANCHOR_S:g} s",
    "none": "not placed on the fixes",
    "map": "map-aware particle filter (wearnav.fuse.particles): the odometry's moves kept inside the floor plan's "
    "walkable space, heading offset and scale per particle, every kept fix weighed in (Student-t)",
    "start": "placed by --start alone (no floor plan): the odometry turned so that its first metres run along the "
    "start heading and moved to the start position (wearnav.track.maps.place_from_start); the fixes are not used",
}
TRAJ_FORMAT = "%.4f"
COORD_DIGITS = 7  # GeoJSON and fixes.csv lat/lon decimals: 1e-7° is 1.1 cm
INDEX_LIST_MAX = 10  # track.json lists at most this many dropped fixes' indices per reason
# track.json ``path.frame``: where the path drawn lies (issue 58 §7: beside the odometry's own frame)
UNPLACED = "not placed: the odometry's own frame from (0, 0) (trajectory.csv x, y)"
PLACED = "placed: east, north (m) of the recording's local frame (trajectory.csv east, north)"


# ---- the GeoJSON and fixes.csv ------------------------------------------------------------------


def iso_utc(unix_s: float | None) -> str | None:
    """ISO 8601 UTC with milliseconds ("2023-11-14T22:13:20.123Z"); None without a Unix time."""
    if unix_s is None or not np.isfinite(unix_s):
        return None
    return datetime.fromtimestamp(float(unix_s), tz=timezone.utc).isoformat(timespec="milliseconds")[:-6] + "Z"


def _num(v: float, digits: int) -> float | None:
    return round(float(v), digits) if np.isfinite(v) else None


def geojson(
    path_ll: tuple[np.ndarray, np.ndarray],
    t: np.ndarray,
    fixes_ll: tuple[np.ndarray, np.ndarray],
    fix_t: np.ndarray,
    fix_accuracy: np.ndarray,
    fixes: FixCheck,
    props: dict,
    sigma_m: np.ndarray | None = None,
    t0_unix_s: float | None = None,
) -> dict:
    """The RFC 7946 FeatureCollection of the module docstring: the anchored path (lat, lon arrays
    at times ``t`` s, 1-σ ``sigma_m`` m where known) as one LineString with ``props`` and the
    derived properties, each fix (``fixes_ll`` lat, lon; ``fix_t`` s; ``fix_accuracy`` m; its
    status in ``fixes``) as a Point. ``t0_unix_s``: the Unix time of t = 0, where known."""

    def coords(lat, lon):
        return [[round(float(a), COORD_DIGITS), round(float(b), COORD_DIGITS)] for a, b in zip(lon, lat)]

    def when(v):
        return iso_utc(None if t0_unix_s is None else t0_unix_s + float(v))

    lat, lon = path_ll
    known = sigma_m is not None and bool(np.isfinite(sigma_m).any())
    line = {
        "kind": "path",
        **props,
        "start_time": when(t[0]),
        "end_time": when(t[-1]),
        "t_start_s": round(float(t[0]), 3),
        "t_end_s": round(float(t[-1]), 3),
        "duration_s": round(float(t[-1] - t[0]), 3),
        "median_sigma_m": _num(np.nanmedian(sigma_m), 2) if known and sigma_m is not None else None,
        "fix_status": fixes.counts(),
    }
    if known and sigma_m is not None:
        line["sigma_m"] = [_num(v, 2) for v in sigma_m]
        line["t"] = [round(float(v), 3) for v in t]
    feats = [
        {"type": "Feature", "geometry": {"type": "LineString", "coordinates": coords(lat, lon)}, "properties": line}
    ]
    for k, ((x, y), ft, a) in enumerate(zip(coords(*fixes_ll), fix_t, fix_accuracy)):
        feats.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [x, y]},
                "properties": {
                    "kind": "fix",
                    "index": k,
                    "time": when(ft),
                    "t": _num(ft, 3),
                    "accuracy_m": _num(a, 2),
                    "status": str(fixes.status[k]),
                    "reason": str(fixes.reason[k]),
                    "weight": round(float(fixes.weight[k]), 3),
                },
            }
        )
    return {"type": "FeatureCollection", "features": feats}


def fix_table(
    fx, fixes: FixCheck, t0_unix_s: float | None, latlon: tuple | None, radio: np.ndarray | None = None
) -> pd.DataFrame:
    """``fixes.csv``: one row per fix of the recording (module docstring); with ``--radiomap`` (``radio``:
    which fixes are the radio map's positions) a ``source`` column, phone or radio map, and ``floor``."""
    table = pd.DataFrame({"index": np.arange(len(fx.t)), "t": np.round(fx.t, 3)})
    if t0_unix_s is not None:
        table["unix_time"] = np.round(t0_unix_s + fx.t, 3)
    table["east"], table["north"] = np.round(fx.pos[:, 0], 3), np.round(fx.pos[:, 1], 3)
    if latlon is not None:
        table["lat"], table["lon"] = np.round(latlon[0], COORD_DIGITS), np.round(latlon[1], COORD_DIGITS)
    table["accuracy_m"] = np.round(fx.accuracy, 2)
    table["status"], table["reason"], table["weight"] = fixes.status, fixes.reason, np.round(fixes.weight, 3)
    if radio is not None and radio.size == len(fx.t):
        table["source"] = np.where(radio, "radio map", "phone")
        table["floor"] = fx.floor if fx.floor is not None else np.nan
    return table


# ---- placing the path and writing the files ----------------------------------------------------


def write_track(
    stage: Path,
    out: Path,
    table: pd.DataFrame,
    t: np.ndarray,
    xy: np.ndarray,
    rec: Recording,
    cfg,
    seq,
    summary: dict,
    activity: tuple[list[dict] | None, str],
    anchor: str = "smooth",
    placed: fuse.FuseResult | None = None,
    fix_lag_s: float | None = None,
    radio: np.ndarray | None = None,
) -> None:
    """Place the path on the fixes by ``anchor`` (:mod:`wearnav.fuse`), or take the map-aware path
    or the start's ``placed`` (:func:`wearnav.track.maps.map_path`), and write the files into ``stage`` (moved to
    ``out`` afterwards). ``fix_lag_s``: how far the fixes lag the walker (the smoother's
    ``fix_lag_s``), None: the run's calibration's (0 for the shipped models). ``radio``: which fixes
    are the radio map's (``fixes.csv``'s ``source``)."""
    anchored, res = None, placed
    fx = rec.fixes
    has_fixes = fx is not None and len(fx) > 0
    if res is None and not has_fixes:
        summary["anchoring"] = {
            "method": "none",
            "requested": anchor,
            "note": "the recording has no location fixes: the path starts at (0, 0) in the odometry's own frame",
        }
        summary["warnings"].append(f"{rec.name}: no location fixes: the path is not placed on a map")
        warnings.warn(WearnavWarning(summary["warnings"][-1]), stacklevel=2)
    elif res is not None:  # the map-aware path, or the start's (wearnav.track.maps.map_path)
        summary["anchoring"] = {
            "requested": f"--map ({anchor} is not used with a plan)"
            if res.method == "map"
            else f"--start ({anchor} is not used with a start pose and no plan)",
            "method": res.method,
            "description": ANCHOR_TEXT[res.method],
            **{k: _rounded(v) for k, v in res.info.items() if k != "method"},
        }
    else:
        assert fx is not None
        fcfg, cal = fuse.config_for(
            summary["run"] if Path(summary["run"]).exists() else None,
            rec.meta,
            seq.meta.get("frame", {}).get("reference"),
        )
        if fix_lag_s is not None:
            fcfg = dataclasses.replace(fcfg, fix_lag_s=fix_lag_s)
        res = fuse.fuse(t, xy, fx.t, fx.pos[:, :2], fx.accuracy, anchor, fcfg)
        assert res.fixes is not None  # every anchoring reports on each fix it was given
        summary["anchoring"] = {
            "requested": anchor,
            "method": res.method,
            "description": ANCHOR_TEXT[res.method],
            "odometry_calibration": cal or "none in the run: the smoother's defaults",
            "fix_lag_s": fcfg.fix_lag_s,
            **{k: _rounded(v) for k, v in res.info.items() if k not in ("x", "smoother")},
            "fixes_dropped_index": {r: i[:INDEX_LIST_MAX] for r, i in res.info["fixes_dropped_index"].items()},
            "fixes_dropped_at_import": int(rec.meta.get("dropped_stale_fixes", 0)),
            "per_fix": "fixes.csv" + (" and trajectory.geojson" if res.method != "none" else ""),
        }
    if res is not None:
        summary["warnings"] += [f"{rec.name}: {w}" for w in res.warnings]
        for w in res.warnings:
            warnings.warn(WearnavWarning(f"{rec.name}: {w}"), stacklevel=2)
        lat0, lon0 = rec.meta.get("origin_lat"), rec.meta.get("origin_lon")
        origin = (float(lat0), float(lon0)) if lat0 is not None and lon0 is not None else None
        fix_ll = geo.local_to_latlon(fx.pos[:, :2], *origin) if origin is not None and fx is not None else None
        t0_unix = rec.meta["t0_unix_ns"] * 1e-9 if "t0_unix_ns" in rec.meta else None
        if has_fixes and res.fixes is not None:
            assert fx is not None
            with atomic_path(stage / "fixes.csv") as tmp:
                fix_table(fx, res.fixes, t0_unix, fix_ll, radio).to_csv(tmp, index=False)
        if res.method != "none":
            anchored = res.xy
            table["east"], table["north"] = anchored[:, 0], anchored[:, 1]
            # the path drawn is the placed one (issue 34), which the smoother may stretch; the
            # odometry's own length stays under summary["odometry"]
            summary["path"] = {
                "frame": PLACED,
                "length_m": round(float(np.sum(np.linalg.norm(np.diff(anchored, axis=0), axis=1))), 2),
            }
            if np.isfinite(res.sigma_m).any():
                table["sigma_m"] = res.sigma_m
            if origin is not None and has_fixes and fix_ll is not None and res.fixes is not None:
                assert fx is not None
                gj = geojson(
                    geo.local_to_latlon(anchored, *origin),
                    t,
                    fix_ll,
                    fx.t,
                    fx.accuracy,
                    res.fixes,
                    {
                        "recording": rec.name,
                        "model": cfg.model,
                        "anchor": res.method,
                        "length_m": summary["path"]["length_m"],
                    },
                    sigma_m=res.sigma_m,
                    t0_unix_s=t0_unix,
                )
                write_text_atomic(json.dumps(gj, allow_nan=False), stage / "trajectory.geojson")
                summary["geojson"] = str(out / "trajectory.geojson")
            else:
                summary["geojson"] = "not written: the recording has no location fixes with a lat/lon origin"
    with atomic_path(stage / "trajectory.csv") as tmp:
        table.to_csv(tmp, index=False, float_format=TRAJ_FORMAT)
    kept = res.fixes.kept if res is not None and fx is not None and len(fx) and res.fixes is not None else None
    drawn_plans = rec.plans if summary.get("map", {}).get("used") else None
    plot_track(table, seq.devices, anchored, fx, summary, stage / "trajectory.png", kept, drawn_plans)
    write_text_atomic(
        page_html(t, xy, rec, cfg, summary, activity, res if anchored is not None else None, kept),
        stage / "trajectory.html",
    )
    summary["files"] = ["trajectory.csv", "trajectory.png", "trajectory.html", TRACK_JSON] + [
        f for f in ("trajectory.geojson", "fixes.csv") if (stage / f).is_file()
    ]
    write_text_atomic(json.dumps(summary, indent=2, default=str), stage / TRACK_JSON)


def page_html(
    t: np.ndarray,
    xy: np.ndarray,
    rec: Recording,
    cfg,
    summary: dict,
    activity: tuple[list[dict] | None, str],
    res=None,
    kept: np.ndarray | None = None,
) -> str:
    """``trajectory.html`` (:mod:`wearnav.report.trajectory_page`): the live page's drawing of the path (anchored
    by ``res`` where given, with the ``kept`` fixes; else the odometry's own frame, without fixes),
    self-contained, with a time slider, coloured by the ``activity`` intervals ``classify`` finds
    (:func:`wearnav.report.trajectory_page.activity_intervals`; ``summary["activity"]`` says which
    model, or why not)."""
    rows, note = activity
    summary["activity"] = note
    origin, fixes = None, []
    fx = rec.fixes
    if res is not None and fx is not None and len(fx):
        k = np.ones(len(fx.t), dtype=np.bool_) if kept is None else kept
        fixes = [
            [round(float(a), 3), round(float(e), 3), round(float(n), 3), _num(acc, 2)]
            for a, (e, n), acc in zip(fx.t[k], fx.pos[k, :2], fx.accuracy[k])
        ]
        if rec.meta.get("origin_lat") is not None and rec.meta.get("origin_lon") is not None:
            origin = [float(rec.meta["origin_lat"]), float(rec.meta["origin_lon"])]
    drawn = (
        [[[np.round(r, 2).tolist() for r in poly] for poly in p.polygons] for p in rec.plans]
        if summary.get("map", {}).get("used")
        else []
    )
    state = {
        "origin": origin,
        "path": page_points(t, res.xy if res is not None else xy, res.sigma_m if res is not None else None, cfg.rate),
        "anchor": res.method if res is not None else "none",
        "fixes": fixes,
        "activity": rows,
        "plan": drawn,
        "warnings": summary["warnings"],
        "t_s": round(float(t[-1]), 3),
    }
    where = (
        "the map-aware path on the floor plan"
        if res is not None and res.method == "map"
        else "placed from --start"
        if res is not None and res.method == "start"
        else f"placed on the location fixes ({summary['anchoring']['method']})"
        if res is not None
        else "the odometry's own frame from (0, 0): not placed on the fixes"
    )
    return trajectory_html(
        state,
        f"{rec.name}: wearnav track",
        f"{summary['path']['length_m']:.0f} m in {summary['duration_s']:.0f} s; model {cfg.model}",
        note,
        f"{summary['path']['length_m']:.0f} m, {where}; {len(state['path'])} points (1 per s)",
    )


def _rounded(v):
    if isinstance(v, float):
        return round(v, 4)
    if isinstance(v, list):
        return [_rounded(x) for x in v]
    if isinstance(v, dict):
        return {k: _rounded(x) for k, x in v.items()}
    return v


def plot_track(
    table: pd.DataFrame,
    devices: tuple[str, ...],
    anchored,
    fixes,
    summary: dict,
    out: Path,
    kept: np.ndarray | None = None,
    floor_plans: list[FloorPlan] | None = None,
) -> Path:
    """The path (anchored on the fixes where there are some) with start and end, and per-device
    presence over time; of the fixes only the ``kept`` ones (all if None) are drawn, so that a
    cached fix far away does not shrink the map; the ``floor_plans`` the path was placed on under it."""
    from matplotlib.figure import Figure

    from wearnav.report.plots import save

    fig = Figure(figsize=(7.5, 8.5), layout="constrained")
    ax, ax_dev = fig.subplots(2, 1, height_ratios=[5, 1])
    xy = anchored if anchored is not None else table[["x", "y"]].to_numpy()
    for k, plan in enumerate(floor_plans or []):
        for poly in plan.polygons:
            for j, ring in enumerate(poly):
                ax.fill(
                    *ring.T,
                    color="0.88" if j == 0 else "white",
                    lw=0.3,
                    ec="0.6",
                    zorder=0,
                    label="walkable (floor plan)" if k == 0 and j == 0 and poly is plan.polygons[0] else None,
                )
    if anchored is not None and fixes is not None and len(fixes):
        shown = np.ones(len(fixes.t), bool) if kept is None else kept
        ax.scatter(
            fixes.pos[shown, 0],
            fixes.pos[shown, 1],
            s=8,
            c="tab:red",
            alpha=0.6,
            label="location fixes" + (f" ({int(np.sum(~shown))} dropped, not drawn)" if (~shown).any() else ""),
        )
    ax.plot(xy[:, 0], xy[:, 1], color="tab:blue", lw=1.2, label=f"path ({summary['model']})")
    ax.plot(*xy[0], "o", color="tab:green", ms=8, label="start")
    ax.plot(*xy[-1], "s", color="black", ms=7, label="end")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east (m)" if anchored is not None else "x (m, common frame)")
    ax.set_ylabel("north (m)" if anchored is not None else "y (m, common frame)")
    ax.set_title(
        f"{summary['recording']}: {summary['path']['length_m']:.0f} m in {summary['duration_s']:.0f} s; "
        f"devices used: {', '.join(summary['devices_used'])}",
        fontsize=9,
    )
    ax.legend(fontsize=8, loc="best")
    ax.grid(alpha=0.3)
    t = table["t"].to_numpy()
    for k, dev in enumerate(devices):
        on = table[dev].to_numpy().astype(float)
        ax_dev.fill_between(t, k + 0.1, k + 0.1 + 0.8 * on, step="mid", color=f"C{k}", alpha=0.7)
    ax_dev.set_yticks(np.arange(len(devices)) + 0.5, devices)
    ax_dev.set_ylim(0, len(devices))
    ax_dev.set_xlabel("time (s)")
    ax_dev.set_title("device present per window", fontsize=9)
    return save(fig, out)
