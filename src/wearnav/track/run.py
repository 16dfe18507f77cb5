"""`wearnav track`: the walking path of a user's own recording, from a trained odometry model
(placing it and writing the files below: :mod:`wearnav.track.write`).

Steps: read the input (a Sensor Logger export folder or zip, a wearnav ``.h5`` recording, or a
dataset folder and a recording name), align the devices the model was trained on into one
horizontal frame (:mod:`wearnav.preprocess.frames`, mode "common": a user's recording has no truth, so the
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
    written by the importers that project lat/lon with :func:`wearnav.core.geo.latlon_to_local`): an
    RFC 7946 FeatureCollection (WGS-84, no ``crs`` member; coordinates ``[lon, lat]`` rounded to
    1e-7° ≈ 1 cm, converted back by :func:`wearnav.core.geo.local_to_latlon`): the format map tools read
    (geojson.io, QGIS, Leaflet). First feature, the anchored path as one LineString; its
    properties: ``kind`` "path"; ``recording``; ``model``; ``anchor`` (the anchoring used: smooth,
    rigid, first-fixes, map or start); ``start_time``, ``end_time`` (ISO 8601 UTC, null where the recording
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
    What was done: model, run (``shipped_model``: the shipped model's name where no ``--model`` was given or
    one was named), runtime (pytorch, or onnxruntime / torchscript for a `wearnav export` file), devices
    present and used (a one-device model's, e.g. PDR's: the first present per window); ``odometry``, the
    integrated path in its own frame (``frame`` in words, :func:`wearnav.pretrained.frame_words`; ``frame_align``,
    ``frame_reference``, ``length_m``, ``end_xy_m``: the CSV's last x, y); ``path``, the path drawn (``frame``:
    placed on east, north or not; ``length_m``); the anchoring fit; ``warnings`` (one line each, also on the
    console): an older lat/lon projection (:func:`wearnav.core.geo.needs_reimport`), a reason not to trust the path
    (:func:`wearnav.track.trust.trust_warnings`, :mod:`wearnav.trust`).

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
:func:`wearnav.fuse.placement.place` instead of the smoother (:mod:`wearnav.track.maps`): a particle
filter keeping the odometry inside walkable space, weighing in every kept fix. ``track.json``
``map`` says which plans and whether they were used; ``anchoring.method`` is then "map"; the plan is
drawn under the path in ``trajectory.png`` and ``trajectory.html``. A plan without fixes or
``--start`` is not used (a warning says to give ``--start``). Without a plan, ``--start`` places the
path alone (issue 56 §4, :func:`wearnav.track.maps.place_from_start`): the odometry turned so that its
first metres run along the start heading and moved to the start position, ``anchoring.method``
"start"; the user's start is honoured over the recording's fixes, which are then checked and marked
unused (``fixes.csv``).

A file of `wearnav export` gives the path of the model it came from: its header carries the
defaults ``track`` takes from a run (:func:`wearnav.pretrained.track_defaults`: the speed source,
the smoother's calibration).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav import fuse, pretrained
from wearnav.core import geo
from wearnav.errors import ConfigError, FormatError, ValidationError, WearnavWarning
from wearnav.evaluate import odometry as odometry  # re-exported with the two below: wearnav.track, the live tracker
from wearnav.evaluate import odometry_preprocess as odometry_preprocess
from wearnav.evaluate import path_times as path_times
from wearnav.fuse import radiomap as radiomap_mod
from wearnav.fuse.radiofixes import with_radio_fixes
from wearnav.fuse.radiofloor import floor_over_time
from wearnav.models import registry
from wearnav.outputs import check_out_folder, staged_output
from wearnav.recording import Recording
from wearnav.report.trajectory_page import activity_intervals
from wearnav.track.files import TRACK_FILES, TRACK_JSON
from wearnav.track.maps import MAP_CHOICES, map_path
from wearnav.track.trust import trust_warnings
from wearnav.track.write import UNPLACED, write_track
from wearnav.train.odometry import SPEED_SOURCES
from wearnav.train.resolve import locate_model, resolve_model

ANCHOR_S = fuse.ANCHOR_S


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


# ---- what was used, said once (issue 58 §7) --------------------------------------------------------


def devices_used(cfg, devices: tuple[str, ...], present: np.ndarray) -> list[str]:
    """The devices the model actually read (of ``devices``, the aligned input's, in the model's
    order): a one-device model (layout "single", e.g. PDR) the first present one of each window
    (:func:`wearnav.models.base.first_present`), the others every device present in any window;
    ``present`` (windows × devices)."""
    on = present > 0
    if registry.get(cfg.model).layout == "single":
        firsts = {int(np.argmax(row)) for row in on if row.any()}
        return [d for k, d in enumerate(devices) if k in firsts]
    return [d for k, d in enumerate(devices) if on[:, k].any()]


def model_line(summary: dict) -> str:
    """The line `wearnav track` prints of the model it ran: its name (and shipped name), the devices
    it read, where its speed came from, and its frames (:func:`wearnav.pretrained.frame_words`), all
    from ``summary`` (what ``track.json`` holds)."""
    shipped = f" (shipped model {summary['shipped_model']})" if summary.get("shipped_model") else ""
    used = summary["devices_used"]
    on = f"the {used[0]}" if len(used) == 1 else ", ".join(used)
    unused = [
        d for d in summary["model_devices"] if d not in used and registry.get(summary["model"]).layout != "single"
    ]
    lacking = f" (of {', '.join(summary['model_devices'])}: {', '.join(unused)} absent)" if unused else ""
    speed = "" if summary["speed"] == "model" else f"; speed: {summary['speed']}"
    return f"model: {summary['model']}{shipped} on {on}{lacking}{speed}; frame: {summary['odometry']['frame']}"


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
    fix_lag_s: float | None = None,
    radiomap: str | Path | None = None,
) -> dict:
    """Track one recording (see module docstring); ``anchor`` places the path on the fixes
    (:data:`wearnav.fuse.ANCHORS`); ``plan`` (``auto``, ``none`` or a GeoJSON plan file) and ``start``
    (x, y, heading of travel in degrees) make the path map-aware (:func:`wearnav.track.maps.map_path`; the start
    alone places it where no plan is used);
    ``speed``: where a learned model's speed comes from (:func:`wearnav.train.odometry.with_speed`:
    itself, or its direction with PDR's steps, 0.67 m or cadence-long; default what the model's run
    records, :func:`wearnav.pretrained.recorded_speed`, or a file of `wearnav export` carries); ``fix_lag_s``: how many seconds the fixes lag
    the walker (:func:`wearnav.track.write.write_track`); ``radiomap``: a radio map folder of
    `wearnav radiomap build` whose positions of the recording's Wi-Fi scans join its fixes
    (:func:`wearnav.fuse.radiofixes.with_radio_fixes`, issue 60 §3; ``track.json`` ``radiomap``); returns
    what ``track.json`` holds."""
    out = Path(out)
    if anchor not in fuse.ANCHORS:
        raise ConfigError(f"unknown anchoring {anchor!r}; one of {', '.join(fuse.ANCHORS)}")
    if speed is not None and speed not in SPEED_SOURCES:
        raise ConfigError(f"--speed {speed}: not one of {', '.join(SPEED_SOURCES)}")
    if str(plan) not in MAP_CHOICES and not Path(plan).is_file():
        raise ConfigError(f"--map {plan}: not auto, none or a GeoJSON plan file")
    if fix_lag_s is not None and not 0.0 <= fix_lag_s <= fuse.MAX_FIX_LAG_S:
        raise ConfigError(f"--fix-lag {fix_lag_s:g}: expected seconds from 0 to {fuse.MAX_FIX_LAG_S:g}")
    check_out_folder(out, TRACK_FILES, TRACK_JSON, "track")  # before any work
    rmap = radiomap_mod.RadioMap.load(radiomap) if radiomap is not None else None  # a bad map before any work
    if model_path is not None:  # a bad --model is said before the input is read
        model_path = locate_model(model_path, "odometry")  # a run folder, checkpoint, file, shipped model, `pdr`
        model, cfg = resolve_model(model_path, "odometry", speed=speed)
    rec = load_input(src, name, platform)
    radio_fix: np.ndarray | None = None
    radio_info: dict | None = None
    radio_warnings: list[str] = []
    if rmap is not None:  # the radio map's positions of the scans join the fixes (issue 60 §3)
        rec, radio_fix, radio_info, radio_warnings = with_radio_fixes(rec, rmap)
    choice = "given with --model"
    # without --model: the default for the devices and fixes the recording has, and why (pretrained.default_model)
    if model_path is None:
        smoothed = anchor == "smooth" and rec.fixes is not None and len(rec.fixes.t) > 0
        model_path, choice = pretrained.default_model("odometry", rec.devices, has_fixes=smoothed)
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
    if radio_fix is not None and radio_fix.any() and rec.fixes is not None and rec.fixes.floor is not None:
        assert rmap is not None and radio_info is not None
        table["floor"], floor_info = floor_over_time(
            rec.pressure, rmap.floor_levels, rec.fixes.t[radio_fix], rec.fixes.floor[radio_fix], t
        )
        radio_info |= floor_info
    share = {dev: round(float((present[:, k] > 0).mean()), 3) for k, dev in enumerate(seq.devices)}
    used = devices_used(cfg, seq.devices, present)
    frame = seq.meta.get("frame", {})
    odometry_m = round(float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1))), 2)
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
        "devices_used": used,
        "device_share_of_windows": share,
        "rate_hz": cfg.rate,
        "window": cfg.window,
        "stride": cfg.stride,
        "duration_s": round(float(t[-1] - t[0]), 2),
        # the integrated odometry (trajectory.csv x, y): its own frame, from (0, 0)
        "odometry": {
            "frame": pretrained.frame_words(cfg.heading_frame, used, frame.get("reference")),
            "frame_align": frame.get("frame", "none"),
            "frame_reference": frame.get("reference"),
            "length_m": odometry_m,
            "end_xy_m": [round(float(v), 3) for v in xy[-1]],
        },
        # the path drawn (trajectory.csv east, north where placed): track_write.write_track places it
        "path": {"frame": UNPLACED, "length_m": odometry_m},
        "warnings": [],
    }
    if radio_info is not None:
        summary["radiomap"] = {"map": str(radiomap), **radio_info}
        summary["warnings"] += radio_warnings
    if (stale := geo.needs_reimport(rec.meta, has_fixes=rec.fixes is not None)) is not None:
        summary["warnings"].append(f"{rec.name}: {stale}")
    # the activity model runs once: the distance check and the page's colours both read it
    activity = activity_intervals(rec)
    found = trust_warnings(model_path, cfg, rec, seq, t_c, vel, odometry_m, activity[0])
    summary["warnings"] += [f"{rec.name}: {w}" for w in found]
    placed, summary["map"], map_warnings = map_path(rec, t, xy, plan, start, progress, fix_lag_s or 0.0)
    summary["warnings"] += map_warnings
    for w in summary["warnings"]:
        warnings.warn(WearnavWarning(w), stacklevel=2)
    with staged_output(out, TRACK_JSON, "track") as stage:
        write_track(stage, out, table, t, xy, rec, cfg, seq, summary, activity, anchor, placed, fix_lag_s, radio_fix)
    return summary
