"""Indoor Location Competition 2.0 (Microsoft / XYZ10) path traces.

Layout read: ``<site>/<floor>/path_data_files/<trace>.txt`` (plain, ``.gz`` or ``.xz``), or any
folder holding such traces, or one trace file. Each trace is tab-separated text:
``#``-header lines (``startTime``, ``SiteID``, ``SiteName``, ``FloorId``, ``FloorName``, ``Brand``,
``Model``, ``AndroidName``, sensor descriptions, ``endTime``) and data rows
``unix_ms<TAB>TYPE<TAB>values...``.

What becomes what:

* ``TYPE_ACCELEROMETER`` (m/s², with gravity, device frame) → ``devices["phone"].acc``; its
  timestamps are the stream clock.
* ``TYPE_GYROSCOPE`` (rad/s, device frame) → ``gyro``.
* ``TYPE_ROTATION_VECTOR`` (Android rotation vector: values x, y, z and, on some phones, w) →
  ``quat`` (w, x, y, z), rotating device vectors into Android's world frame (x east, y magnetic
  north, z up). When w is not logged it is rebuilt as ``sqrt(max(0, 1 - x² - y² - z²))`` exactly
  as Android's ``SensorManager.getQuaternionFromVector`` does (w ≥ 0).
* ``TYPE_WAYPOINT`` (x, y in metres) → sparse ``truth``: positions (M, 2) in the floor plan's own
  metric frame (not geo-referenced, not north-aligned); ``truth.floor`` is the floor index from
  ``FloorName`` (F1 → 0, F2 → 1, B1 → -1, the competition's convention; None when unparsable).
* ``TYPE_WIFI`` → ``wifi``, ``TYPE_BEACON`` → ``beacons`` (:func:`_wifi`, :func:`_beacons`); no magnetometer rows.
* The floor's plan, ``geojson_map.json`` beside ``floor_info.json`` (a GeoJSON FeatureCollection in
  lon/lat: the floor's outline, a (Multi)Polygon, and one polygon per shop) → ``plans``: one
  :class:`~wearnav.recording.FloorPlan` named ``<site>_<floor>`` (``meta["plan"]``), walkable
  space = the outline minus the shops, in the waypoints' metric frame. The sites label the outline
  differently (site1 ``"type": "floor"``; site2 of the same sample names the floor, ``"floor": "B1"``,
  and its shops carry ``poi_no``, ``two_class``, ``center``), so the outline is the one polygon so
  labelled, else the largest polygon where it holds the others (:func:`find_outline`); points and
  lines are labels, not space. A plan that cannot be read (not JSON, no outline) costs the plan,
  never the walks: the floor's traces are imported without one, ``meta["no_plan"]`` says why, and
  :func:`read` warns once per floor. That frame is the outline's
  lon/lat bounding box scaled to ``floor_info.json``'s width × height (checked on the shipped
  sample: 98–100 % of each floor's 699–965 waypoints lie in the walkable space, the rest within
  6.1 m of it; the scales, 96 119 m per degree of longitude and 111 319 per degree of latitude,
  are those of the WGS-84 ellipsoid at the site's 30.29° N, so the plan is not distorted).

Clock: seconds relative to the earliest imported row of the trace (in practice the first
waypoint, logged ~0.1 s before the first IMU sample); ``meta["t0_unix_ms"]`` keeps the absolute
start so times can be put back on the Unix clock.

Timestamps are handled explicitly, per row type: a sample whose timestamp repeats the previous
one is dropped (the first is kept) and counted in ``meta["dropped_duplicates"]``; more than
:data:`~wearnav.core.timeseries.MAX_DUPLICATE_SHARE` of duplicates, or any timestamp going backwards, means the file is
broken and raises. When gyroscope or rotation-vector rows are not on the accelerometer's
timestamps they are interpolated onto them (linear; normalised linear for quaternions), and
accelerometer samples they cannot cover (outside their span, or across a gap longer than
:data:`~wearnav.importers.common.MAX_INTERP_GAP_S`) are dropped and counted in ``meta["dropped_uncovered"]``. None of this
happens in the shipped sample (no duplicates, identical clocks); it exists for users' copies.

Plausibility: every trace ends with a ``#<TAB>endTime`` footer; a trace without it was cut short
and is imported as far as it goes (an unfinished last line dropped), flagged in
``meta["truncated"]`` with a one-line warning, never as complete. Timestamps must be Unix times
(2000–2100) and waypoints must lie on the floor plan of ``floor_info.json`` when it is there.
"""

from __future__ import annotations

import functools
import io
import json
import re
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import shapely
from shapely.errors import ShapelyError
from shapely.geometry import shape
from shapely.geometry.base import BaseGeometry
from shapely.ops import unary_union

from wearnav.core.timeseries import drop_duplicate_times, interp_onto
from wearnav.errors import FormatError, MissingFileError, ValidationError, WearnavError, WearnavWarning, one_line
from wearnav.importers.common import (
    MAX_INTERP_GAP_S,
    check_finite,
    check_source,
    check_unix_time,
    find_file,
    quat_from_rotation_vector,
    read_text,
    strip_compression,
)
from wearnav.importers.radio_rows import drop_repeated_readings, ibeacon_name
from wearnav.plans import plan_from_lonlat
from wearnav.recording import (
    ANDROID_ENU_FRAME,
    BeaconReadings,
    DeviceStream,
    FloorPlan,
    Recording,
    Trajectory,
    WifiScans,
)

SOURCE = "ilc2"
LICENCE = "MIT (Copyright (c) 2017-2020 XYZ10, Inc.; Indoor Location Competition 2.0 sample data)"

ACC, GYRO, ROTVEC, WAYPOINT = ("TYPE_ACCELEROMETER", "TYPE_GYROSCOPE", "TYPE_ROTATION_VECTOR", "TYPE_WAYPOINT")
WIFI, BEACON = "TYPE_WIFI", "TYPE_BEACON"
# Fields of a radio row after the timestamp and type (upstream README): Wi-Fi SSID, BSSID, RSSI,
# frequency, last seen; iBeacon UUID, major, minor, Tx power, RSSI, distance, MAC, time again.
WIFI_FIELDS, BEACON_FIELDS = 5, 8
# Values each imported row type must carry after the timestamp and type columns.
MIN_VALUES = {ACC: 3, GYRO: 3, ROTVEC: 3, WAYPOINT: 2}
# How far outside the floor plan a waypoint may lie (survey slack at the plan's edge).
MAP_MARGIN_M, MAP_MARGIN_SHARE = 10.0, 0.1
TRACE_SUFFIXES = (".txt", ".txt.gz", ".txt.xz")
PLAN_FILE, PLAN_INFO_FILE = "geojson_map.json", "floor_info.json"
# An unlabelled outline is the largest polygon where it holds at least this share of the other
# polygons' combined area. On site1's five floors, whose outline is labelled (so the rule is checked
# against the label), the outline holds 99.95–99.99 % of its shops' area (a few shops are drawn over
# its edge) and the rule picks the labelled outline on every floor; the next-largest polygon, a
# shop, holds 12–26 % (its own area inside the outline).
OUTLINE_HOLDS_SHARE = 0.9

# ---- reading one trace ---------------------------------------------------------------------


def _split_rows(rows: list[str], n_fields: int, text: tuple[int, ...], what: str, path: Path) -> pd.DataFrame:
    """Tab-separated Wi-Fi rows → a table (column 0 the ms, 1 the type, then the fields): the columns
    ``text`` as text, the others numbers. A row with more fields than ``n_fields`` (a tab inside an
    SSID, the first text field) keeps the extra ones in that field."""
    # object, not str: pandas' string dtype costs twice the parse (10 against 6 ms for 15k rows)
    dtype = {k: (object if k in text or k == 1 else np.float64) for k in range(2 + n_fields)}
    try:
        df = pd.read_csv(
            io.StringIO("\n".join(rows)), sep="\t", header=None, dtype=dtype, quoting=3, keep_default_na=False
        )
    except ValueError as exc:  # pandas' ParserError is one: a row of another width, or not a number
        if "Expected" not in str(exc):
            raise FormatError(f"{what} rows: not a number ({one_line(str(exc))[:80]})", path) from None
    else:
        if df.shape[1] == 2 + n_fields:
            return df
    out = []
    for k, ln in enumerate(rows):
        f = ln.split("\t")
        if len(f) < 2 + n_fields:
            raise FormatError(f"{what} row {k} has {len(f) - 2} values, expected {n_fields}", path)
        extra = len(f) - 2 - n_fields
        out.append([f[0], f[1], "\t".join(f[2 : 3 + extra]), *f[3 + extra :]])
    try:
        return pd.DataFrame(out).astype(dtype)
    except ValueError as exc:
        raise FormatError(f"{what} rows: not a number ({one_line(str(exc))[:80]})", path) from None


def _numbers(df: pd.DataFrame, cols: list[int], what: str, path: Path) -> np.ndarray:
    arr = df[cols].to_numpy(np.float64)
    check_finite(arr, f"{what} rows", path)
    return arr


def _wifi(rows: list[str], t0_ms: int, path: Path, meta: dict) -> WifiScans:
    """TYPE_WIFI rows (SSID, BSSID, RSSI dBm, frequency MHz, last-seen Unix ms) → WifiScans (issue 60
    §1): ``t`` the scan's time (the row's first column, shared by the scan's readings), ``t_seen``
    the last-seen time, both on the trace's clock (they do not move its zero). A phone hands cached
    results on (site 1: median 4.8 s, up to 30 s before the scan). An SSID holding a tab is read
    whole. Rows follow :mod:`wearnav.importers.radio_rows`'s rules: 3 of site 1's 2,303,930 readings
    repeat a row and are dropped; 5,086 more repeat an access point within a scan with another
    last-seen time (a cached reading beside the fresh one) and are kept. The copy in ../shared/data
    dropped the magnetometer and uncalibrated-sensor rows."""
    df = _split_rows(rows, WIFI_FIELDS, (2, 3), WIFI, path)
    num = _numbers(df, [0, 4, 5, 6], WIFI, path)  # ms, RSSI, MHz, last seen ms
    check_unix_time(num[:, 0] / 1e3, WIFI, path)
    check_unix_time(num[:, 3] / 1e3, f"{WIFI} last seen", path)
    bssid = df[3].to_numpy(object)
    keep = drop_repeated_readings(num[:, 0], bssid, WIFI, path, meta, num[:, 3])
    t, t_seen = (num[keep, 0] - t0_ms) / 1000.0, (num[keep, 3] - t0_ms) / 1000.0
    return WifiScans(t, bssid[keep], df[2].to_numpy(object)[keep], num[keep, 2], num[keep, 1], t_seen)


def _beacons(rows: list[str], t0_ms: int, path: Path, meta: dict) -> BeaconReadings:
    """TYPE_BEACON rows (iBeacon UUID, major, minor, Tx power, RSSI, distance, MAC, Unix ms again) →
    BeaconReadings on the trace's clock, named ``UUID:major:minor:MAC``
    (:func:`wearnav.importers.radio_rows.ibeacon_name`), with ``tx_power_dbm`` and ``distance_m``
    (the app's -1, "cannot tell", → NaN)."""
    fields = [ln.split("\t") for ln in rows]  # a few hundred rows a trace: plain Python beats pandas' set-up
    short = [k for k, f in enumerate(fields) if len(f) < 2 + BEACON_FIELDS]
    if short:
        raise FormatError(
            f"{BEACON} row {short[0]} has {len(fields[short[0]]) - 2} values, expected {BEACON_FIELDS}", path
        )
    try:  # ms, major, minor, Tx power, RSSI, distance
        num = np.array([[float(f[k]) for k in (0, 3, 4, 5, 6, 7)] for f in fields], dtype=np.float64)
    except ValueError as exc:
        raise FormatError(f"{BEACON} rows: not a number ({exc})", path) from None
    check_finite(num, f"{BEACON} rows", path)
    check_unix_time(num[:, 0] / 1e3, BEACON, path)
    names = np.array(
        [ibeacon_name(f[2], int(a), int(b), f[8]) for f, a, b in zip(fields, num[:, 1], num[:, 2])], dtype=object
    )
    keep = drop_repeated_readings(num[:, 0], names, BEACON, path, meta)
    distance = np.where(num[keep, 5] < 0, np.nan, num[keep, 5])  # the app's -1: cannot tell
    return BeaconReadings((num[keep, 0] - t0_ms) / 1000.0, names[keep], num[keep, 4], num[keep, 3], distance)


def _parse_header(lines: list[str]) -> dict[str, str]:
    info: dict[str, str] = {}
    sensors = []
    for ln in lines:
        fields = [f for f in ln.lstrip("#").strip().split("\t") if ":" in f]
        pairs = dict(f.split(":", 1) for f in fields)
        if "type" in pairs and "name" in pairs:
            sensors.append(f"{pairs['name']} ({pairs.get('vendor', '?')})")
        else:
            info.update({k.strip(): v.strip() for k, v in pairs.items()})
    if sensors:
        info["sensors"] = "; ".join(sensors)
    return info


def _parse_rows(rows: list[str], what: str, path: Path) -> np.ndarray:
    """Tab-separated rows ``ms<TAB>TYPE<TAB>v1...`` → float array (N, 1 + values)."""
    n_values = MIN_VALUES[what]
    try:
        df = pd.read_csv(io.StringIO("\n".join(rows)), sep="\t", header=None)
    except pd.errors.ParserError as exc:
        raise FormatError(f"{what} rows: inconsistent number of fields ({exc})", path) from None
    if df.shape[1] < 2 + n_values:
        raise FormatError(f"{what} rows have {df.shape[1] - 2} values, expected at least {n_values}", path)
    try:
        arr = df.drop(columns=1).to_numpy(dtype=np.float64)
    except (ValueError, TypeError) as exc:
        raise FormatError(f"{what} rows: not a number ({exc})", path) from None
    # Only the columns we use must be finite; a rotation vector's optional w and the accuracy
    # column may be absent on some rows.
    check_finite(arr[:, : 1 + n_values], f"{what} rows", path)
    return arr


def _floor_index(name: str) -> int | None:
    """Floor name → index, competition convention: F1/1F/L1/G → 0, F2 → 1, B1 → -1."""
    name = name.strip().upper()
    if name in ("G", "GF"):
        return 0
    m = re.fullmatch(r"([FLB])(\d+)|(\d+)([FB])", name)
    if not m:
        return None
    letter, num = (m.group(1), m.group(2)) if m.group(1) else (m.group(4), m.group(3))
    n = int(num)
    return -n if letter == "B" else n - 1


def _map_size(trace: Path) -> list[float] | None:
    """Floor-plan width/height (m) from ``../floor_info.json`` beside ``path_data_files``."""
    if trace.parent.name != "path_data_files":
        return None
    info = trace.parent.parent / "floor_info.json"
    try:
        info = find_file(info)
    except MissingFileError:
        return None
    try:
        m = json.loads(read_text(info))["map_info"]
        return [float(m["width"]), float(m["height"])]
    except (ValueError, KeyError, TypeError) as exc:
        raise FormatError(f"unreadable floor info ({exc.__class__.__name__}: {exc})", info) from None


def find_outline(parts: list[tuple[dict, BaseGeometry]], floor_name: str, floor: int | None) -> tuple[int | None, str]:
    """Which of a floor's polygons (``(properties, geometry)`` in file order) is its outline: the one
    labelled ``"type": "floor"`` (site1), else the one whose ``floor`` property names this floor
    (``floor_name``, the floor's folder, or its index ``floor``; site2), else the largest polygon where
    it holds :data:`OUTLINE_HOLDS_SHARE` of the others' area. Returns its index and "", or None and why
    there is none."""
    if not parts:
        return None, "no polygons (neither the floor's outline nor its shops)"

    def names_floor(value: Any) -> bool:
        text = str(value).strip().upper()
        return text == floor_name.upper() or (floor is not None and _floor_index(text) == floor)

    for labelled in (
        [k for k, (props, _) in enumerate(parts) if props.get("type") == "floor"],
        [k for k, (props, _) in enumerate(parts) if props.get("floor") is not None and names_floor(props["floor"])],
    ):
        if len(labelled) == 1:
            return labelled[0], ""
    geoms = [shapely.make_valid(g) for _, g in parts]
    big = int(np.argmax([g.area for g in geoms]))
    others = unary_union([g for k, g in enumerate(geoms) if k != big])
    share = 1.0 if others.area == 0 else others.intersection(geoms[big]).area / others.area
    if geoms[big].area > 0 and share >= OUTLINE_HOLDS_SHARE:
        return big, ""
    return None, (
        f"no floor outline: no polygon is labelled as one ('type': 'floor' or 'floor': '{floor_name}') and the "
        f"largest holds {share:.0%} of the others' area (an outline holds them all)"
    )


@functools.lru_cache(maxsize=16)
def floor_plan(floor_dir: Path, name: str, floor: int | None) -> tuple[FloorPlan | None, str]:
    """The walkable space of the floor in ``floor_dir`` (``geojson_map.json`` and ``floor_info.json``;
    see the module docstring) and "", or None and "" where either file is missing, or None and why the
    plan cannot be read (a short line naming the file; the traces are imported without it)."""
    try:
        gj, info = find_file(floor_dir / PLAN_FILE), find_file(floor_dir / PLAN_INFO_FILE)
    except MissingFileError:
        return None, ""
    try:
        doc = json.loads(read_text(gj))
    except ValueError as exc:  # json's JSONDecodeError; UnicodeDecodeError
        return None, f"{PLAN_FILE}: not JSON ({one_line(str(exc))[:80]})"
    except WearnavError as exc:  # a corrupt .gz / .xz copy
        return None, f"{PLAN_FILE}: {exc.reason}"
    try:
        size = json.loads(read_text(info))["map_info"]
        width, height = float(size["width"]), float(size["height"])
        feats = doc["features"] if isinstance(doc, dict) else None
        if not isinstance(feats, list):
            return None, f"{PLAN_FILE}: not a GeoJSON FeatureCollection"
        # Points and lines are labels on the plan, not space.
        parts = [
            (f.get("properties") or {}, shape(f["geometry"]))
            for f in feats
            if isinstance(f, dict)
            and isinstance(f.get("geometry"), dict)
            and f["geometry"].get("type") in ("Polygon", "MultiPolygon")
        ]
        k, why = find_outline(parts, floor_dir.name, floor)
        if k is None:
            return None, f"{PLAN_FILE}: {why}"
        outline = [parts[k][1]]
        shops = [g for i, (_, g) in enumerate(parts) if i != k]
        lon0, lat0, lon1, lat1 = outline[0].bounds
        if not (lon1 > lon0 and lat1 > lat0 and width > 0 and height > 0):
            return None, f"{PLAN_FILE}: the outline or {PLAN_INFO_FILE}'s size has no extent"
        sx, sy = width / (lon1 - lon0), height / (lat1 - lat0)
        plan = plan_from_lonlat(
            name, floor, outline, shops, lambda lon, lat: np.stack([(lon - lon0) * sx, (lat - lat0) * sy], axis=1)
        )
    except (ValueError, KeyError, TypeError, AttributeError, IndexError, ShapelyError, WearnavError) as exc:
        return None, f"{PLAN_FILE}: unreadable floor plan ({exc.__class__.__name__}: {one_line(str(exc))[:80]})"
    return plan, ""


def read_trace(path: str | Path, root: Path | None = None) -> Recording:
    """One ILC2 trace file (plain/.gz/.xz) → Recording named after the trace id.

    ``root`` (the folder the import started from) only shortens ``meta["file"]``.
    """
    path = find_file(path)
    try:
        return _read_trace(path, root)
    except WearnavError as exc:
        raise exc.with_source(path) from None


def _read_trace(path: Path, root: Path | None) -> Recording:
    text = read_text(path)
    if not text.strip():
        raise FormatError("empty file", path)
    lines = text.splitlines()
    # Every trace ends with a "#<TAB>endTime:<ms>" footer (all 580 shipped ones do): without it
    # the file was cut short, and a cut last line could still parse as a shorter number.
    truncated = not any(ln.startswith("#") and "endTime:" in ln for ln in lines[-3:])
    if truncated and not text.endswith("\n"):
        lines = lines[:-1]
    header: list[str] = []
    rows: dict[str, list[str]] = {ACC: [], GYRO: [], ROTVEC: [], WAYPOINT: []}
    radio: dict[str, list[str]] = {WIFI: [], BEACON: []}  # kept apart: they do not set the clock's zero
    first_data = None
    for ln in lines:
        if not ln or ln.isspace():
            continue
        if ln[0] == "#":
            header.append(ln)
            continue
        i = ln.find("\t")
        j = ln.find("\t", i + 1)
        kind = ln[i + 1 : j] if j > 0 else ln[i + 1 :]
        bucket = rows.get(kind)
        if bucket is None:
            bucket = radio.get(kind)
        if bucket is not None:
            bucket.append(ln)
        elif first_data is None:
            first_data = ln
    if not rows[ACC]:
        seen = first_data or (header[0] if header else "")
        raise FormatError(f"not an ILC2 trace: no {ACC} rows (first line: {seen[:60]!r})", path)

    data = {k: _parse_rows(v, k, path) for k, v in rows.items() if v}
    for k, a in data.items():
        check_unix_time(a[:, 0] / 1e3, k, path)
    meta_dropped: dict[str, int] = {}
    for k in list(data):
        keep, n_dup = drop_duplicate_times(data[k][:, 0], k, path)
        if n_dup:
            meta_dropped[k] = n_dup
            data[k] = data[k][keep]
    t0_ms = min(int(a[0, 0]) for a in data.values())

    def secs(a: np.ndarray) -> np.ndarray:
        return (a[:, 0] - t0_ms) / 1000.0

    acc = data[ACC]
    t = secs(acc)
    keep = np.ones(t.shape, bool)
    gyro = quat = None
    if GYRO in data:
        gyro, ok = interp_onto(t, secs(data[GYRO]), data[GYRO][:, 1:4], max_gap=MAX_INTERP_GAP_S)
        keep &= ok
    if ROTVEC in data:
        rv = data[ROTVEC]
        # Column 4 is Android's optional w only when a row has two columns after z
        # (x, y, z, w, accuracy); with one it is the accuracy.
        has_w = rv.shape[1] >= 6 and bool(np.all(np.isfinite(rv[:, 4])))
        q = quat_from_rotation_vector(rv[:, 1:5] if has_w else rv[:, 1:4], path, ROTVEC)
        quat, ok = interp_onto(t, secs(rv), q, max_gap=MAX_INTERP_GAP_S, quaternion=True)
        keep &= ok
    n_uncovered = int((~keep).sum())
    if n_uncovered:
        if n_uncovered == t.size:
            raise ValidationError("gyroscope / rotation vector do not overlap the accelerometer", path)
        t, acc = t[keep], acc[keep]
        gyro = None if gyro is None else gyro[keep]
        quat = None if quat is None else quat[keep]
    if t.size < 2:
        raise FormatError(f"only {t.size} {ACC} sample(s)", path)

    info = _parse_header(header)
    # <site>/<floor>/path_data_files/<trace>: folder names stand in for missing header fields.
    parts = path.resolve().parts
    in_layout = len(parts) >= 4 and parts[-2] == "path_data_files"
    floor_name = info.get("FloorName", parts[-3] if in_layout else "")
    floor = _floor_index(floor_name) if floor_name else None
    truth = None
    size = _map_size(path)
    if WAYPOINT in data:
        wp = data[WAYPOINT]
        if size is not None:  # waypoints were surveyed on this floor plan (all 580 shipped lie on it)
            margin = max(MAP_MARGIN_M, MAP_MARGIN_SHARE * max(size))
            off = (
                (wp[:, 1] < -margin)
                | (wp[:, 1] > size[0] + margin)
                | (wp[:, 2] < -margin)
                | (wp[:, 2] > size[1] + margin)
            )
            if np.any(off):
                i = int(np.argmax(off))
                raise ValidationError(
                    f"{WAYPOINT} ({wp[i, 1]:g}, {wp[i, 2]:g}) m lies outside the "
                    f"{size[0]:.0f} × {size[1]:.0f} m floor plan of floor_info.json",
                    path,
                )
        truth = Trajectory(secs(wp), wp[:, 1:3], floor=None if floor is None else np.full(len(wp), float(floor)))

    stream = DeviceStream(t=t, acc=acc[:, 1:4], gyro=gyro, quat=quat)
    name = strip_compression(path)
    name = name[: -len(".txt")] if name.endswith(".txt") else name
    meta: dict[str, Any] = {
        "source": SOURCE,
        "licence": LICENCE,
        "mode": "walk",
        "placement": "handheld",
        "scene": "indoor",
        "trace": name,
        "site_id": info.get("SiteID", ""),
        "site_name": info.get("SiteName", ""),
        "site": parts[-4] if in_layout else "",
        "floor_id": info.get("FloorId", ""),
        "floor_name": floor_name,
        "floor_index": floor,
        "device": " ".join(x for x in (info.get("Brand", ""), info.get("Model", "")) if x),
        "android": info.get("AndroidName", ""),
        "app_version": info.get("VersionName", ""),
        "sensors": info.get("sensors", ""),
        "t0_unix_ms": t0_ms,
        "start_time_unix_ms": int(info["startTime"]) if info.get("startTime", "").isdigit() else None,
        "end_time_unix_ms": int(info["endTime"]) if info.get("endTime", "").isdigit() else None,
        "truth_frame": "ILC2 floor-plan frame, metres (not geo-referenced)",
        "quat_frame": ANDROID_ENU_FRAME,
        "dropped_duplicates": meta_dropped,
        "dropped_uncovered": n_uncovered,
        "file": str(path.relative_to(root)) if root is not None and path.is_relative_to(root) else path.name,
    }
    radio_meta: dict[str, Any] = {}  # the radio rows' dropped repeats, into meta["dropped_duplicates"]
    wifi = _wifi(radio[WIFI], t0_ms, path, radio_meta) if radio[WIFI] else None
    beacons = _beacons(radio[BEACON], t0_ms, path, radio_meta) if radio[BEACON] else None
    meta_dropped.update(radio_meta.get("dropped_duplicates", {}))
    plans = []
    if size is not None:
        meta["map_size_m"] = size
        plan, no_plan = floor_plan(
            path.parent.parent.resolve(), f"{meta['site'] or 'site'}_{floor_name or 'floor'}", floor
        )
        if plan is not None:
            plans.append(plan)
            meta["plan"] = plan.name
            meta["building"] = meta["site"] or meta["site_id"]
        elif no_plan:
            meta["no_plan"] = no_plan
    if truncated:
        meta["truncated"] = "no endTime footer: the trace was cut short (an unfinished last line is dropped)"
        warnings.warn(
            WearnavWarning(f"{path}: {meta['truncated']}; imported as far as it goes, flagged in meta['truncated']"),
            stacklevel=2,
        )
    return Recording(
        name=name, devices={"phone": stream}, truth=truth, meta=meta, plans=plans, wifi=wifi, beacons=beacons
    )


# ---- finding traces ------------------------------------------------------------------------


def find_traces(src: Path) -> list[Path]:
    """Trace files under ``src``, sorted; prefer those in ``path_data_files`` folders.

    A trace present both plain and compressed is taken once (the plain copy).
    """
    found: dict[Path, Path] = {}
    for p in sorted(src.rglob("*")):
        if p.is_file() and p.name.endswith(TRACE_SUFFIXES):
            key = p.with_name(strip_compression(p))
            if key not in found or p == key:
                found[key] = p
    files = sorted(found.values())
    in_pdf = [p for p in files if p.parent.name == "path_data_files"]
    return in_pdf or files


def read(src: Path, limit: int | None = None) -> Iterator[Recording]:
    """ILC2 traces from a dataset folder (any level of site/floor/path_data_files) or one file."""
    src, limit = check_source(src, limit, expect="an ILC2 trace or a folder of them")
    warned: set[Path] = set()
    if src.is_file():
        if limit != 0:
            yield _warn_no_plan(read_trace(src), src, warned)
        return
    files = find_traces(src)
    if not files:
        raise FormatError("no ILC2 traces found (expected <site>/<floor>/path_data_files/*.txt[.gz])", src)
    for path in files[:limit]:
        yield _warn_no_plan(read_trace(path, root=src), path, warned)


def _warn_no_plan(rec: Recording, path: Path, warned: set[Path]) -> Recording:
    """``rec`` as it is, after one warning line for the first trace of a floor whose plan could not be
    read (``meta["no_plan"]``); ``warned`` holds the floors already said."""
    floor_dir = path.parent.parent
    if rec.meta.get("no_plan") and floor_dir not in warned:
        warned.add(floor_dir)
        warnings.warn(
            WearnavWarning(f"{floor_dir}: {rec.meta['no_plan']}; its traces are imported without a floor plan"),
            stacklevel=3,
        )
    return rec
