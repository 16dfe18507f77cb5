"""`wearnav track`: the walking path of a user's own recording, from a trained odometry model.

Steps: read the input (a Sensor Logger export folder or zip, a wearnav ``.h5`` recording, or a
dataset folder and a recording name), align the devices the model was trained on into one
horizontal frame (:mod:`wearnav.frames`, mode "common": a user's recording has no truth, so the
frame is the reference device's), predict a velocity per window (the run's window and rate),
integrate from (0, 0) at the first window centre (:func:`wearnav.trajectory.integrate_velocity`),
and write into the output folder:

``trajectory.csv``
    ``t`` (s since the recording's start; ``unix_time`` too where the recording keeps its start,
    ``meta["t0_unix_ns"]``), ``x``, ``y`` (m, in the common frame of the reference
    device), one 0/1 column per model device (present in the window whose centre is nearest), and
    where the recording has location fixes ``east``, ``north`` (m, the anchored path, below).
``trajectory.png``
    The path with its start and end, and per-device presence over time.
``trajectory.html``
    The live page's drawing (:mod:`wearnav.report.trajectory_page`), static and self-contained (opens offline
    from the file): the path (anchored where it is, 1 point per second) on a metric grid, OSM map
    tiles under it when the browser is online, the fixes used with their accuracy circles, a time
    slider, and the path coloured by the activity the shipped activity model finds as
    ``wearnav classify`` runs it (``track.json`` ``activity`` says which model, or why not).
``trajectory.geojson``
    Only when the recording has fixes and a lat/lon origin (``meta["origin_lat"/"origin_lon"]``,
    written by the importers that project lat/lon with :func:`wearnav.geo.latlon_to_local`): an
    RFC 7946 FeatureCollection (WGS-84, no ``crs`` member; coordinates ``[lon, lat]`` rounded to
    1e-7° ≈ 1 cm, converted back by :func:`wearnav.geo.local_to_latlon`): the format map tools read
    (geojson.io, QGIS, Leaflet). First feature, the anchored path as one LineString; its
    properties: ``kind`` "path"; ``recording``; ``model``; ``anchor`` (the anchoring used: smooth,
    rigid or first-fixes); ``start_time``, ``end_time`` (ISO 8601 UTC, null where the recording
    keeps no Unix time, ``meta["t0_unix_ns"]``); ``t_start_s``, ``t_end_s``, ``duration_s`` (s since
    the recording's start, as the CSV's ``t``); ``length_m`` (the anchored path's length, m);
    ``median_sigma_m`` (the median 1-σ per-axis uncertainty of its points, m; null unless smoothed);
    ``fix_status`` (how many fixes were used, down-weighted, unused, dropped); where the σ is known,
    ``sigma_m`` and ``t``, one per vertex. Then one Point per fix of the recording, properties:
    ``kind`` "fix"; ``index`` (its row in ``fixes.csv``); ``time`` (ISO 8601 UTC, or null); ``t``
    (s since the start); ``accuracy_m`` (the reported 68 % radius, null if none); ``status`` (used |
    down-weighted | unused | dropped, :mod:`wearnav.fixcheck`); ``reason`` (why dropped: no position,
    outside the walk, wide, repeat, jump; why down-weighted or unused; "" if used); ``weight`` (its
    weight in the fit relative to a fix of its accuracy: the smoother's robust weight, 1 for a
    rigid fit's fixes, 0 if not used).
``fixes.csv``
    Where the recording has fixes: one row per fix, ``index``, ``t`` (s), ``unix_time`` (where
    known), ``east``, ``north`` (m), ``lat``, ``lon`` (where the recording has a lat/lon origin),
    ``accuracy_m``, ``status``, ``reason``, ``weight`` (as in the GeoJSON).
``track.json``
    What was done: model, run (``shipped_model``: the shipped model's name where no ``--model`` was
    given or one was named, :mod:`wearnav.pretrained`), runtime (pytorch, or onnxruntime / torchscript
    for a file of `wearnav export`), devices used and present, frame reference, anchoring fit, and
    ``warnings`` (one line each; also shown on the console), e.g. a recording imported with an
    older lat/lon projection (:func:`wearnav.geo.needs_reimport`), or a reason not to trust the
    path (:func:`wearnav.track_trust.trust_warnings`, :mod:`wearnav.trust`): devices the recording lacks, a rate,
    placement or gravity direction unlike the model's training data, a model that did not beat
    standing still, a path implausible for walking.

Anchoring: the common frame has an arbitrary yaw and the path starts at (0, 0); ``anchor``
(``--anchor``) places it on the recording's location fixes by :mod:`wearnav.fuse`:
``smooth`` (default) the robust smoother over every fix (heading offset, scale, heading drift,
a slowly varying fix bias; each point's 1-σ ``sigma_m`` in the CSV and GeoJSON: the smoother's
covariance times the model's calibrated ``sigma_scale``, :func:`wearnav.fuse.sigma_scale_of`; on
IPIN 2023's held-out routes 69 % of the errors of the recipe's model trained without IPIN fell
inside 1.515 σ, where 68 % should), ``rigid`` one
rotation + translation over every fix, ``first-fixes`` the same over the first ``ANCHOR_S``
seconds' good fixes (the path then drifts freely: the map shows the odometry alone). Bad fixes
are dropped first, whichever the anchoring (:mod:`wearnav.fixcheck`: a phone's first fix is often
cached, hundreds of metres away, or 100–2000 m wide). ``track.json`` says what was used under
``anchoring``: ``fix_status`` (counts), ``fixes_dropped`` (counts by reason) and
``fixes_dropped_index`` (at most ``INDEX_LIST_MAX`` per reason), ``fixes_dropped_at_import``
(cached fixes stamped before the recording, which the Sensor Logger importer leaves out), the scale
and heading offset; the per-fix detail is in ``fixes.csv`` and the GeoJSON. A recording without
fixes keeps the path from (0, 0) and says so; fixes that all disagree fall back to first-fix
anchoring, with a warning.

Map-aware path (issue 36): where there is a floor plan (``--map auto``, the default: the plan the
recording carries, e.g. ILC2's; or a user's GeoJSON file, :func:`wearnav.plans.read_geojson_plan`)
and a start (``--start X,Y,HEADING_DEG``, or the first kept fix), the path is placed by
:func:`wearnav.fuse.placement.place` instead of the smoother (:mod:`wearnav.track_map`): a particle
filter keeping the odometry inside walkable space, weighing in every kept fix. ``track.json``
``map`` says which plans and whether they were used; ``anchoring.method`` is then "map"; the plan is
drawn under the path in ``trajectory.png`` and ``trajectory.html``. A plan without fixes or
``--start`` is not used (a warning says to give ``--start``).
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import fuse, geo, pretrained
from wearnav.errors import ConfigError, FormatError, ValidationError, WearnavWarning
from wearnav.evaluate import predict_sequence
from wearnav.fileio import atomic_path, write_text_atomic
from wearnav.fixcheck import FixCheck
from wearnav.outputs import check_out_folder, staged_output
from wearnav.preprocess import PreprocessConfig, align
from wearnav.recording import FloorPlan, Recording
from wearnav.report.trajectory_page import activity_intervals, page_points, trajectory_html
from wearnav.track_files import TRACK_FILES, TRACK_JSON
from wearnav.track_map import MAP_CHOICES, map_path
from wearnav.track_trust import trust_warnings
from wearnav.train.odometry import SPEED_SOURCES
from wearnav.train.resolve import locate_model, resolve_model
from wearnav.trajectory import integrate_velocity

ANCHOR_S = fuse.ANCHOR_S
ANCHOR_TEXT = {
    "smooth": "robust smoother over every fix (wearnav.fuse): heading offset, scale (prior), heading drift, "
    "slowly varying fix bias; fixes weighted by their reported accuracy",
    "rigid": "weighted (1/σ²) least-squares rotation + translation over every kept fix of the walk",
    "first-fixes": f"weighted (1/σ²) least-squares rotation + translation over the kept fixes of the first "
    f"{fuse.ANCHOR_S:g} s",
    "none": "not placed on the fixes",
    "map": "map-aware particle filter (wearnav.fuse.particles): the odometry's moves kept inside the floor plan's "
    "walkable space, heading offset and scale per particle, every kept fix weighed in (Student-t)",
}
TRAJ_FORMAT = "%.4f"
COORD_DIGITS = 7  # GeoJSON and fixes.csv lat/lon decimals: 1e-7° is 1.1 cm
INDEX_LIST_MAX = 10  # track.json lists at most this many dropped fixes' indices per reason


# ---- input -------------------------------------------------------------------------------------


def load_input(src: str | Path, name: str | None = None, platform: str | None = None) -> Recording:
    """The recording to track: a ``.h5`` recording, a dataset folder (``name`` picks one; the only
    one if omitted), or a Sensor Logger export (folder, zip, or folder of several with ``name``)."""
    from wearnav.dataset import MANIFEST, Dataset
    from wearnav.importers import sensorlogger

    src = Path(src)
    if not src.exists():
        raise FormatError("no such file or folder", src)
    if src.is_file() and src.suffix.lower() == ".h5":
        return Recording.load(src)
    if src.is_dir() and (src / MANIFEST).is_file():
        ds = Dataset.open(src)
        if name is None:
            if len(ds) != 1:
                raise ConfigError(
                    f"the dataset holds {len(ds)} recordings; pick one with --name (e.g. {', '.join(ds.names[:3])})",
                    src,
                )
            name = ds.names[0]
        return ds.load(name)
    # A Sensor Logger export: zips are extracted into a temporary folder that the importer removes.
    recs = list(sensorlogger.read(src, platform=platform))
    if name is not None:
        recs = [r for r in recs if r.name == name]
        if not recs:
            raise ValidationError(f"no export named {name!r} here", src)
    if len(recs) != 1:
        raise ConfigError(
            f"holds {len(recs)} Sensor Logger exports; pick one with --name ({', '.join(r.name for r in recs[:5])})",
            src,
        )
    return recs[0]


# ---- anchoring ---------------------------------------------------------------------------------


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


def fix_table(fx, fixes: FixCheck, t0_unix_s: float | None, latlon: tuple | None) -> pd.DataFrame:
    """``fixes.csv``: one row per fix of the recording (module docstring)."""
    table = pd.DataFrame({"index": np.arange(len(fx.t)), "t": np.round(fx.t, 3)})
    if t0_unix_s is not None:
        table["unix_time"] = np.round(t0_unix_s + fx.t, 3)
    table["east"], table["north"] = np.round(fx.pos[:, 0], 3), np.round(fx.pos[:, 1], 3)
    if latlon is not None:
        table["lat"], table["lon"] = np.round(latlon[0], COORD_DIGITS), np.round(latlon[1], COORD_DIGITS)
    table["accuracy_m"] = np.round(fx.accuracy, 2)
    table["status"], table["reason"], table["weight"] = fixes.status, fixes.reason, np.round(fixes.weight, 3)
    return table


# ---- one way to window and run the odometry model (track and the live receiver) ----------------


def odometry_preprocess(cfg) -> PreprocessConfig:
    """The run's preprocessing for a user's recording: its devices in one common frame (mode
    "common", :mod:`wearnav.frames`: a user's recording has no truth)."""
    return dataclasses.replace(cfg.preprocess_config(), frame_align="common")


def path_times(clock_t: np.ndarray, t_c: np.ndarray) -> np.ndarray:
    """The clock's times the path is given at: those between the first and last window centre."""
    return clock_t[(clock_t >= t_c[0]) & (clock_t <= t_c[-1])]


def odometry(model, cfg, rec: Recording, progress: bool = False):
    """The model's path of ``rec``: the aligned input (:func:`odometry_preprocess`), window centre
    times, velocities and device presence (:func:`wearnav.evaluate.predict_sequence`), and the
    path's times and positions, integrated from (0, 0) at the first centre (Suite-IN++ eq. 8,
    :func:`wearnav.trajectory.integrate_velocity`)."""
    seq = align(rec, odometry_preprocess(cfg))
    t_c, vel, present = predict_sequence(model, seq, cfg.window, cfg.stride, progress=progress)
    if t_c.size < 2:
        return seq, t_c, vel, present, np.empty(0), np.empty((0, 2))
    t = path_times(seq.t, t_c)
    return seq, t_c, vel, present, t, integrate_velocity(t_c, vel, t, np.zeros(2))


# ---- the command -------------------------------------------------------------------------------


def track(
    src: str | Path,
    model_path: str | Path | None,
    out: str | Path,
    name: str | None = None,
    platform: str | None = None,
    progress: bool = False,
    anchor: str = "smooth",
    plan: str | Path = "auto",
    start: tuple[float, float, float] | None = None,
    speed: str | None = None,
) -> dict:
    """Track one recording (see module docstring); ``anchor`` places the path on the fixes
    (:data:`wearnav.fuse.ANCHORS`); ``plan`` (``auto``, ``none`` or a GeoJSON plan file) and ``start``
    (x, y, heading of travel in degrees) make the path map-aware (:func:`wearnav.track_map.map_path`);
    ``speed``: where a learned model's speed comes from (:func:`wearnav.train.odometry.with_speed`:
    itself, or its direction with PDR's steps, 0.67 m or cadence-long; default what the model's run
    records, :func:`wearnav.pretrained.recorded_speed`); returns what ``track.json`` holds."""
    out = Path(out)
    if anchor not in fuse.ANCHORS:
        raise ConfigError(f"unknown anchoring {anchor!r}; one of {', '.join(fuse.ANCHORS)}")
    if speed is not None and speed not in SPEED_SOURCES:
        raise ConfigError(f"--speed {speed}: not one of {', '.join(SPEED_SOURCES)}")
    if str(plan) not in MAP_CHOICES and not Path(plan).is_file():
        raise ConfigError(f"--map {plan}: not auto, none or a GeoJSON plan file")
    check_out_folder(out, TRACK_FILES, TRACK_JSON, "track")  # before any work
    if model_path is not None:  # a bad --model is said before the input is read
        model_path = locate_model(model_path, "odometry")  # a run folder, checkpoint, file, shipped model, `pdr`
        model, cfg = resolve_model(model_path, "odometry", speed=speed)
    rec = load_input(src, name, platform)
    choice = "given with --model"
    if model_path is None:  # the default for the devices the recording has, and why (pretrained.default_model)
        model_path, choice = pretrained.default_model("odometry", rec.devices)
        model_path = locate_model(model_path, "odometry")
        model, cfg = resolve_model(model_path, "odometry", speed=speed)
    usable = [d for d in cfg.devices if d in rec.devices]
    if not usable:
        raise ValidationError(
            f"no IMU stream the model can use: it was trained on "
            f"{', '.join(cfg.devices)}; the recording has {', '.join(rec.devices) or 'none'}",
            src,
        )
    seq, t_c, vel, present, t, xy = odometry(model, cfg, rec, progress)
    if t_c.size < 2:
        raise ValidationError(
            f"too short to track: {seq.t[-1] - seq.t[0]:.1f} s of common data, the "
            f"model needs windows of {cfg.window / cfg.rate:g} s",
            src,
        )
    nearest = np.clip(np.searchsorted(t_c, t), 0, len(t_c) - 1)
    prev = np.clip(nearest - 1, 0, len(t_c) - 1)
    nearest = np.where(np.abs(t_c[prev] - t) < np.abs(t_c[nearest] - t), prev, nearest)
    table = pd.DataFrame({"t": t, "x": xy[:, 0], "y": xy[:, 1]})
    if "t0_unix_ns" in rec.meta:
        table.insert(1, "unix_time", rec.meta["t0_unix_ns"] * 1e-9 + t)
    for k, dev in enumerate(seq.devices):
        table[dev] = (present[nearest, k] > 0).astype(int)
    share = {dev: round(float((present[:, k] > 0).mean()), 3) for k, dev in enumerate(seq.devices)}
    frame = seq.meta.get("frame", {})
    summary: dict = {
        "recording": rec.name,
        "source": str(src),
        "model": cfg.model,
        "run": str(model_path),
        "shipped_model": pretrained.shipped_name(model_path),
        "model_choice": choice,
        "speed": speed or pretrained.recorded_speed(model_path),  # resolve_model's default
        "runtime": getattr(model, "runtime", "pytorch"),  # onnxruntime / torchscript: a `wearnav export` file
        "model_devices": list(cfg.devices),
        "devices_in_recording": list(rec.devices),
        "devices_used": usable,
        "device_share_of_windows": share,
        "rate_hz": cfg.rate,
        "window": cfg.window,
        "stride": cfg.stride,
        "frame": frame.get("frame", "none"),
        "frame_reference": frame.get("reference"),
        "duration_s": round(float(t[-1] - t[0]), 2),
        "length_m": round(float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1))), 2),
        "end_xy_m": [round(float(v), 3) for v in xy[-1]],
        "warnings": [],
    }
    if (stale := geo.needs_reimport(rec.meta, has_fixes=rec.fixes is not None)) is not None:
        summary["warnings"].append(f"{rec.name}: {stale}")
    summary["warnings"] += [
        f"{rec.name}: {w}" for w in trust_warnings(model_path, cfg, rec, seq, t_c, vel, summary["length_m"])
    ]
    placed, summary["map"], map_warnings = map_path(rec, t, xy, plan, start, progress)
    summary["warnings"] += map_warnings
    for w in summary["warnings"]:
        warnings.warn(WearnavWarning(w), stacklevel=2)
    with staged_output(out, TRACK_JSON, "track") as stage:
        _write_track(stage, out, table, t, xy, rec, cfg, seq, summary, anchor, placed)
    return summary


def _write_track(
    stage: Path,
    out: Path,
    table: pd.DataFrame,
    t: np.ndarray,
    xy: np.ndarray,
    rec: Recording,
    cfg,
    seq,
    summary: dict,
    anchor: str = "smooth",
    placed: fuse.FuseResult | None = None,
) -> None:
    """Place the path on the fixes by ``anchor`` (:mod:`wearnav.fuse`), or take the map-aware path
    ``placed`` (:func:`wearnav.track_map.place_on_map`), and write the files into ``stage`` (moved to
    ``out`` afterwards)."""
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
    elif res is not None:  # the map-aware path (wearnav.track_map.place_on_map)
        summary["anchoring"] = {
            "requested": f"--map ({anchor} is not used with a plan)",
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
        res = fuse.fuse(t, xy, fx.t, fx.pos[:, :2], fx.accuracy, anchor, fcfg)
        assert res.fixes is not None  # every anchoring reports on each fix it was given
        summary["anchoring"] = {
            "requested": anchor,
            "method": res.method,
            "description": ANCHOR_TEXT[res.method],
            "odometry_calibration": cal or "none in the run: the smoother's defaults",
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
                fix_table(fx, res.fixes, t0_unix, fix_ll).to_csv(tmp, index=False)
        if res.method != "none":
            anchored = res.xy
            table["east"], table["north"] = anchored[:, 0], anchored[:, 1]
            # the length reported is the length of the path drawn (issue 34): the placed one, which
            # the smoother may stretch; the odometry's own length is kept beside it
            summary["odometry_length_m"] = summary["length_m"]
            summary["length_m"] = round(float(np.sum(np.linalg.norm(np.diff(anchored, axis=0), axis=1))), 2)
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
                    {"recording": rec.name, "model": cfg.model, "anchor": res.method, "length_m": summary["length_m"]},
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
        page_html(t, xy, rec, cfg, summary, res if anchored is not None else None, kept), stage / "trajectory.html"
    )
    summary["files"] = ["trajectory.csv", "trajectory.png", "trajectory.html", TRACK_JSON] + [
        f for f in ("trajectory.geojson", "fixes.csv") if (stage / f).is_file()
    ]
    write_text_atomic(json.dumps(summary, indent=2, default=str), stage / TRACK_JSON)


def page_html(
    t: np.ndarray, xy: np.ndarray, rec: Recording, cfg, summary: dict, res=None, kept: np.ndarray | None = None
) -> str:
    """``trajectory.html`` (:mod:`wearnav.report.trajectory_page`): the live page's drawing of the path (anchored
    by ``res`` where given, with the ``kept`` fixes; else the odometry's own frame, without fixes),
    self-contained, with a time slider, coloured by the activity ``classify`` finds
    (``summary["activity"]`` says which model, or why not)."""
    rows, note = activity_intervals(rec)
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
        else f"placed on the location fixes ({summary['anchoring']['method']})"
        if res is not None
        else "the odometry's own frame from (0, 0): not placed on the fixes"
    )
    return trajectory_html(
        state,
        f"{rec.name}: wearnav track",
        f"{summary['length_m']:.0f} m in {summary['duration_s']:.0f} s; model {cfg.model}",
        note,
        f"{summary['length_m']:.0f} m, {where}; {len(state['path'])} points (1 per s)",
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
        f"{summary['recording']}: {summary['length_m']:.0f} m in {summary['duration_s']:.0f} s; "
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


__all__ = [
    "track",
    "load_input",
    "odometry",
    "odometry_preprocess",
    "path_times",
    "ANCHOR_S",
]
