"""IPIN 2023 competition, Track 3 (smartphone, off-site): GetSensorData logs.

``src`` is the dataset folder (every log under it is imported: ``*.txt`` plain/``.gz``/``.xz``,
and the organisers' ``*.mat`` conversions — MATLAB v5 via scipy, v7.3 via h5py — where no text
log of the same name exists), or one log file. Text files under the folder that are not
GetSensorData logs (``ZZ_README.txt`` ...) are skipped; a single file given explicitly must be a
log.

Log format (the ``%`` header of each log documents it): ``;``-separated rows ``TAG;AppTimestamp(s);
...``. Imported:

* ``ACCE;App;Sensor;x;y;z;acc`` (m/s², with gravity, device frame) → ``devices["phone"].acc``.
  Its samples define the stream clock.
* ``GYRO;App;Sensor;x;y;z;acc`` (rad/s) → ``gyro``, linearly interpolated onto the ACCE times
  (some phones log it at 100 Hz, ACCE at 50 Hz).
* ``AHRS;App;Sensor;PitchX;RollY;YawZ;Quat(2);Quat(3);Quat(4);acc`` → ``quat``. Quat(2..4) are
  the vector part (x, y, z) of Android's rotation-vector quaternion; Quat(1) = w is not logged and
  is rebuilt as ``sqrt(1 - x² - y² - z²)`` (w ≥ 0, as Android does). The quaternion rotates device
  vectors into the world frame east-north-up (yaw referenced to magnetic north). The logged angles
  (degrees) follow ``R = Rz(YawZ) · Rx(PitchX) · Ry(RollY)`` (intrinsic z-x'-y''; YawZ counter-
  clockwise about up, i.e. minus Android's azimuth); they are redundant with the quaternion and
  not imported (the tests check this relation on the real logs).
* ``GNSS;App;Sensor;Lat;Lon;Alt;Bearing;Accuracy(m);Speed;SatInView;SatInUse`` → ``fixes``
  (east/north metres, reported horizontal accuracy; accuracy ≤ 0 becomes NaN).
* ``POSI;App;Counter;Lat;Lon;floor;building`` (surveyed points the walker stepped on) → sparse
  ``truth`` with ``truth.floor`` = the floor ID as logged (0 = ground floor, -1, -2 below).
* ``PRES;App;Sensor;Pres(mbar);acc`` → ``pressure`` (hPa = mbar), on the app clock through its
  own sensor-clock offset (as the fixes).
* ``BLE4;App;iBeacon;MAC;RSSI(dBm);...`` (and the Eddystone variant) → ``beacons``, at the app time
  of the row, named as the venue's ``BLE_Locations.csv`` names them.
* ``WIFI`` → ``wifi`` (every reading of every scan), ``MAGN`` (µT) → ``magnetic``; LIGH, SOUN ... are ignored.

The radio part (BLE4 rows and their beacon names, WIFI, MAGN, PRES, the beacons' surveyed positions
from ``BLE_Locations.csv`` → ``meta["beacons"]``) is :mod:`wearnav.importers.ipin2023_radio`.

Clocks: everything is on the app clock (``AppTimestamp``, seconds since the log started), the one
clock all rows share and the one POSI uses. IMU samples take their ``SensorTimestamp`` (exact
sampling intervals) shifted onto the app clock by one offset per log, ``min(App - Sensor)`` over
the ACCE rows (the least-delayed delivery; GYRO and AHRS share the sensor clock, and must agree
within :data:`MAX_CLOCK_DISAGREEMENT_S`). GNSS fixes take their fix time (``SensorTimestamp``,
Unix seconds) shifted the same way with their own offset, so they are late by at most the
smallest delivery latency of the log's fixes.

Dropped on purpose, and counted in ``meta``: GetSensorData writes every fix twice (same fix time):
the repeats are dropped (``gnss_repeats_dropped``). Android also hands over stale fixes — a
cached or other-provider location delivered more than :data:`STALE_FIX_S` after its own fix time
(e.g. 19 s), or one not newer than a fix already delivered — which a live consumer would ignore:
dropped (``gnss_stale_dropped``), so fix times increase by construction. IMU or POSI rows repeating a timestamp are dropped
(``dropped_duplicates``; more than 5 % raises); ACCE samples that GYRO/AHRS cannot cover are
dropped (``dropped_uncovered``). Any timestamp going backwards after that raises.

Positions: lat/lon are projected with :func:`wearnav.core.geo.latlon_to_local` (WGS-84 east-north-up,
named in ``meta["projection"]``) around one origin per site, the same for truth and fixes of a
recording: the centre of the organisers' georeferenced floor maps for the IPIN 2023 venue
(``calib_mapa_Nuremberg.cal``), or, for a log recorded elsewhere (more than :data:`VENUE_RADIUS_M`
away), the log's first reference point (or first fix). ``meta["origin_lat"]``,
``meta["origin_lon"]`` record it.
"""

from __future__ import annotations

import io
import logging
import lzma
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from wearnav.core import geo
from wearnav.core.timeseries import drop_duplicate_times, interp_onto, rate
from wearnav.errors import FormatError, ValidationError, WearnavError
from wearnav.importers.common import (
    MAX_INTERP_GAP_S,
    check_finite,
    check_latlon,
    check_source,
    check_unix_time,
    find_file,
    open_text,
    quat_from_rotation_vector,
    read_text,
    strip_compression,
)
from wearnav.importers.ipin2023_radio import (
    _beacon_positions,
    _beacon_readings,
    _magnetic,
    _mat_ble4,
    _mat_wifi,
    _parse_ble4,
    _parse_wifi,
    _pressure,
    _wifi_scans,
)
from wearnav.recording import (
    ANDROID_ENU_FRAME,
    DeviceStream,
    Fixes,
    Recording,
    Trajectory,
)

SOURCE = "ipin2023"
LICENCE = (
    "CC BY 4.0 (Zenodo record; licence of the 2023 record to be confirmed) - cite "
    "Torres-Sospedra et al., IPIN 2023 Track 3 datasets, doi:10.5281/zenodo.8362205"
)

# Known venues: name -> (lat, lon) of the local frame origin.
VENUES = {
    # Centre of the floor-map images in "02 Supplementary Materials/.../calib_mapa_Nuremberg.cal".
    "IPIN 2023 Nuremberg, Museum Industriekultur": (49.46115181, 11.11114911),
}
VENUE_RADIUS_M = 2000.0
# A GNSS fix delivered this long after its own fix time is a cached / other-provider location.
STALE_FIX_S = 5.0
# ACCE, GYRO and AHRS timestamps all come from the phone's sensor clock.
MAX_CLOCK_DISAGREEMENT_S = 1.0

# Numeric columns needed after the tag (the rest is optional): text logs.
TXT_COLUMNS = {"ACCE": 5, "GYRO": 5, "AHRS": 8, "GNSS": 7, "POSI": 5, "PRES": 3, "MAGN": 5}
# The .mat conversion's variables and their needed columns (no accuracy / counter columns).
MAT_VARS = {
    "Acce": ("ACCE", 5),
    "Gyro": ("GYRO", 5),
    "Ahrs": ("AHRS", 8),
    "Gnss": ("GNSS", 7),
    "Posi": ("POSI", 4),
    "Pres": ("PRES", 3),
    "Magn": ("MAGN", 5),
}
LOG_SUFFIXES = (".txt", ".txt.gz", ".txt.xz", ".mat")
# The dataset's own documentation beside its logs (ZZ_README.txt in the organisers' folder):
# passed over without a word, where any other text file that is not a log is named.
DOC_NAME = re.compile(r"readme|licen[cs]e|changelog|citation", re.IGNORECASE)
SPLITS = {"training": "train", "testing": "validation", "validation": "validation", "scoring": "test"}

log = logging.getLogger(__name__)


# ---- parsing -------------------------------------------------------------------------------


def _parse_block(rows: list[str], tag: str, path: Path) -> np.ndarray:
    need = TXT_COLUMNS[tag]
    try:
        df = pd.read_csv(io.StringIO("\n".join(rows)), sep=";", header=None)
    except pd.errors.ParserError as exc:
        raise FormatError(f"{tag} rows: inconsistent number of fields ({exc})", path) from None
    if df.shape[1] < 1 + need:
        raise FormatError(f"{tag} rows have {df.shape[1] - 1} fields, expected at least {need}", path)
    try:
        arr = df.iloc[:, 1 : 1 + need].to_numpy(dtype=np.float64)
    except (ValueError, TypeError) as exc:
        raise FormatError(f"{tag} rows: not a number ({exc})", path) from None
    check_finite(arr, f"{tag} rows", path)
    if tag == "POSI":  # App, Counter, Lat, Lon, floor[, building] -> App, Lat, Lon, floor, building
        building = (
            pd.to_numeric(df.iloc[:, 6], errors="coerce").to_numpy(np.float64)
            if df.shape[1] > 6
            else np.full(len(df), np.nan)
        )
        arr = np.column_stack([arr[:, 0], arr[:, 2], arr[:, 3], arr[:, 4], building])
    return arr


def _header_info(lines: list[str]) -> dict[str, str]:
    info = {}
    for ln in lines:
        m = re.match(r"%\s*([A-Za-z][A-Za-z ]*?)\s*:\s*(.+?)\s*$", ln)
        if m and m.group(1) in (
            "Manufacturer",
            "Model",
            "API Android version",
            "Android version Release",
            "Date of creation",
            "Version",
        ):
            info[m.group(1)] = m.group(2).strip()
        m = re.match(r"%\s*Version\s+(\S.*?)\s*$", ln)
        if m:
            info["Version"] = m.group(1)
    return info


def read_txt(path: Path) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """A GetSensorData text log → {tag: numeric rows} for the imported tags (BLE4: app time and
    RSSI, with the beacon names under ``BLE4_NAME``; WIFI: app time, sensor time, MHz, dBm, with
    ``WIFI_BSSID`` and ``WIFI_SSID``), header info."""
    text = read_text(path)
    if not text.strip():
        raise FormatError("empty file", path)
    header: list[str] = []
    rows: dict[str, list[str]] = {tag: [] for tag in (*TXT_COLUMNS, "BLE4", "WIFI")}
    first_other = None
    for ln in text.splitlines():
        if not ln:
            continue
        if ln[0] == "%":
            header.append(ln)
            continue
        bucket = rows.get(ln[:4]) if ln[4:5] == ";" else None
        if bucket is not None:
            bucket.append(ln)
        elif first_other is None and not ln.isspace():
            first_other = ln
    if not rows["ACCE"]:
        seen = first_other or (header[0] if header else "")
        raise FormatError(f"not a GetSensorData log: no ACCE rows (first line: {seen[:60]!r})", path)
    ble4, wifi = rows.pop("BLE4"), rows.pop("WIFI")
    data = {tag: _parse_block(r, tag, path) for tag, r in rows.items() if r}
    if ble4:
        data["BLE4"], data["BLE4_NAME"] = _parse_ble4(ble4, path)
    if wifi:
        data["WIFI"], data["WIFI_BSSID"], data["WIFI_SSID"] = _parse_wifi(wifi, path)
    return data, _header_info(header)


def _load_mat(path: Path) -> dict[str, np.ndarray]:
    import scipy.io

    try:
        return {k: v for k, v in scipy.io.loadmat(str(path)).items() if not k.startswith("__")}
    except NotImplementedError:  # MATLAB v7.3 = HDF5; MATLAB stores arrays transposed
        import h5py

        try:
            with h5py.File(path, "r") as f:
                return {k: np.asarray(f[k][()]).T for k in f if isinstance(f[k], h5py.Dataset)}
        except OSError as exc:
            raise FormatError(f"cannot read MATLAB v7.3 file ({exc})", path) from None
    except (ValueError, TypeError, OSError) as exc:
        raise FormatError(f"cannot read as a MATLAB file ({exc})", path) from None


def read_mat(path: Path) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """The organisers' .mat conversion (variables Acce, Gyro, Ahrs, Gnss, Posi, Pres, Magn, Ble4, Wifi)
    → same as read_txt."""
    mat = _load_mat(path)
    if "Acce" not in mat:
        raise FormatError(f"not an IPIN .mat log: no 'Acce' variable (has {sorted(mat)[:8]})", path)
    data = {}
    for var, (tag, need) in MAT_VARS.items():
        if var not in mat:
            continue
        try:
            arr = np.asarray(mat[var], dtype=np.float64)
        except (TypeError, ValueError):
            raise FormatError(f"variable {var!r} is not numeric", path) from None
        if arr.size == 0:
            continue
        if arr.ndim != 2 or arr.shape[1] < need:
            raise FormatError(f"variable {var!r} has shape {arr.shape}, expected (N, >={need})", path)
        arr = arr[:, :need]
        check_finite(arr, f"variable {var!r}", path)
        if tag == "POSI":  # App, Lat, Lon, floor (no counter / building in the .mat)
            arr = np.column_stack([arr, np.full(len(arr), np.nan)])
        data[tag] = arr
    if "ACCE" not in data:
        raise FormatError("variable 'Acce' is empty", path)
    if "Ble4" in mat and np.size(mat["Ble4"]):
        data["BLE4"], data["BLE4_NAME"] = _mat_ble4(mat["Ble4"], path)
    if "Wifi" in mat and np.size(mat["Wifi"]):
        data["WIFI"], data["WIFI_BSSID"], data["WIFI_SSID"] = _mat_wifi(mat["Wifi"], path)
    return data, {}


# ---- building the recording ----------------------------------------------------------------


def _imu(data: dict[str, np.ndarray], path: Path, meta: dict) -> DeviceStream:
    dropped: dict[str, int] = {}
    streams = {}
    for tag in ("ACCE", "GYRO", "AHRS"):
        if tag not in data:
            continue
        a = data[tag]
        keep, n_dup = drop_duplicate_times(a[:, 1], f"{tag} SensorTimestamp", path)
        if n_dup:
            dropped[tag] = n_dup
        streams[tag] = a[keep]
    acc = streams["ACCE"]
    offset = float(np.min(acc[:, 0] - acc[:, 1]))
    for tag in ("GYRO", "AHRS"):
        if tag in streams:
            own = float(np.min(streams[tag][:, 0] - streams[tag][:, 1]))
            if abs(own - offset) > MAX_CLOCK_DISAGREEMENT_S:
                raise ValidationError(f"{tag} sensor clock differs from ACCE's by {own - offset:.3f} s", path)
    t = acc[:, 1] + offset
    keep = np.ones(t.shape, bool)
    gyro = quat = None
    if "GYRO" in streams:
        g = streams["GYRO"]
        meta["gyro_rate_hz"] = round(rate(g[:, 1]), 2)
        gyro, ok = interp_onto(t, g[:, 1] + offset, g[:, 2:5], max_gap=MAX_INTERP_GAP_S)
        keep &= ok
    if "AHRS" in streams:
        h = streams["AHRS"]
        q = quat_from_rotation_vector(h[:, 5:8], path, "AHRS quaternion")
        quat, ok = interp_onto(t, h[:, 1] + offset, q, max_gap=MAX_INTERP_GAP_S, quaternion=True)
        keep &= ok
    n_uncovered = int((~keep).sum())
    if n_uncovered == t.size:
        raise ValidationError("GYRO / AHRS do not overlap ACCE", path)
    if n_uncovered:
        t, acc = t[keep], acc[keep]
        gyro = None if gyro is None else gyro[keep]
        quat = None if quat is None else quat[keep]
    if t.size < 2:
        raise FormatError(f"only {t.size} ACCE sample(s)", path)
    meta.update(
        {
            "imu_clock_offset_s": round(offset, 6),
            "imu_latency_median_s": round(float(np.median(acc[:, 0] - acc[:, 1]) - offset), 6),
            "dropped_duplicates": dropped,
            "dropped_uncovered": n_uncovered,
        }
    )
    return DeviceStream(t=t, acc=acc[:, 2:5], gyro=gyro, quat=quat)


def _gnss(g: np.ndarray, path: Path, meta: dict):
    """(fix times on the app clock, lat, lon, accuracy), repeats and stale fixes dropped; None if
    no fix is left."""
    check_unix_time(g[:, 1], "GNSS SensorTimestamp", path)
    _, first = np.unique(g[:, 1], return_index=True)
    repeat = np.ones(len(g), bool)
    repeat[first] = False
    g_unique = g[~repeat]
    delay = g_unique[:, 0] - g_unique[:, 1]
    offset = float(np.min(delay))
    late = delay - offset > STALE_FIX_S
    # A fix not newer than one already delivered (another provider's, handed over late).
    newest_before = np.maximum.accumulate(np.concatenate([[-np.inf], g_unique[:-1, 1]]))
    older = g_unique[:, 1] <= newest_before
    stale = late | older
    g_kept = g_unique[~stale]
    meta.update(
        {
            "gnss_clock_offset_s": round(offset, 4),
            "t0_unix_s": round(-offset, 3),  # Unix time of app-clock zero (from the fixes)
            "gnss_repeats_dropped": int(repeat.sum()),
            "gnss_stale_dropped": int(stale.sum()),
        }
    )
    if not len(g_kept):
        return None
    t = g_kept[:, 1] + offset
    lat, lon = g_kept[:, 2], g_kept[:, 3]
    check_latlon(lat, lon, "GNSS", path)
    acc = g_kept[:, 6].copy()
    acc[acc <= 0] = np.nan
    return t, lat, lon, acc


def _origin(lat: float, lon: float) -> tuple[float, float, str]:
    for name, (lat0, lon0) in VENUES.items():
        if np.linalg.norm(geo.latlon_to_local([lat], [lon], lat0, lon0)) <= VENUE_RADIUS_M:
            return lat0, lon0, name
    return lat, lon, "first reference point or fix of the recording"


def _split(path: Path) -> str:
    for word in re.findall(r"[A-Za-z]+", path.name) + re.findall(r"\((\w+)\)", path.parent.name):
        for key, split in SPLITS.items():
            if word.lower().startswith(key):
                return split
    return ""


def read_log(path: str | Path) -> Recording:
    """One GetSensorData log (.txt plain/.gz/.xz, or the organisers' .mat) → Recording."""
    path = find_file(path)
    try:
        return _read_log(path)
    except WearnavError as exc:
        raise exc.with_source(path) from None


def _read_log(path: Path) -> Recording:
    is_mat = path.name.endswith(".mat")
    data, info = read_mat(path) if is_mat else read_txt(path)
    name = strip_compression(path)
    for suf in (".txt", ".mat"):
        name = name[: -len(suf)] if name.endswith(suf) else name
    m = re.search(r"Trial(\d+)(?:_repetition(\d+))?", name)
    meta: dict = {
        "source": SOURCE,
        "licence": LICENCE,
        "mode": "walk",
        "placement": "handheld",
        "scene": "indoor",
        "split": _split(path),
        "trial": int(m.group(1)) if m else None,
        "repetition": int(m.group(2)) if m and m.group(2) else None,
        "device": " ".join(x for x in (info.get("Manufacturer", ""), info.get("Model", "")) if x),
        "android": info.get("Android version Release", ""),
        "app_version": info.get("Version", ""),
        "log_created": info.get("Date of creation", ""),
        "file_format": "mat" if is_mat else "txt",
        "file": path.name,
        "clock": "GetSensorData app clock (s since the log started)",
        "quat_frame": ANDROID_ENU_FRAME,
    }
    stream = _imu(data, path, meta)

    fix_t: np.ndarray | None = None
    fix_lat: Any = None  # these three are set together with fix_t
    fix_lon: Any = None
    fix_acc: Any = None
    if "GNSS" in data:
        gnss = _gnss(data["GNSS"], path, meta)
        if gnss is not None:
            fix_t, fix_lat, fix_lon, fix_acc = gnss
    posi = None
    if "POSI" in data:
        p = data["POSI"]
        check_latlon(p[:, 1], p[:, 2], "POSI", path)
        keep, n_dup = drop_duplicate_times(p[:, 0], "POSI", path)
        if n_dup:
            meta["dropped_duplicates"]["POSI"] = n_dup
        posi = p[keep]

    truth = fixes = None
    if posi is not None or fix_t is not None:
        ref = (posi[0, 1], posi[0, 2]) if posi is not None else (fix_lat[0], fix_lon[0])
        lat0, lon0, origin = _origin(*ref)
        meta.update(
            {
                "origin_lat": lat0,
                "origin_lon": lon0,
                "origin": origin,
                "projection": geo.PROJECTION,
                "position_frame": "local east, north (m) around origin_lat/origin_lon",
            }
        )
        if posi is not None:
            truth = Trajectory(posi[:, 0], geo.latlon_to_local(posi[:, 1], posi[:, 2], lat0, lon0), floor=posi[:, 3])
            buildings = sorted({int(b) for b in posi[:, 4] if np.isfinite(b)})
            meta["building"] = buildings[0] if len(buildings) == 1 else (buildings or None)
            meta["floors"] = sorted({int(f) for f in posi[:, 3]})
        if fix_t is not None:
            fixes = Fixes(fix_t, geo.latlon_to_local(fix_lat, fix_lon, lat0, lon0), fix_acc)
        if origin in VENUES:
            _beacon_positions(path, lat0, lon0, meta)
    pressure = _pressure(data["PRES"], path, meta) if "PRES" in data else None
    beacons = _beacon_readings(data["BLE4"], data["BLE4_NAME"], path, meta) if "BLE4" in data else None
    wifi = _wifi_scans(data["WIFI"], data["WIFI_BSSID"], data["WIFI_SSID"], path, meta) if "WIFI" in data else None
    magnetic = _magnetic(data["MAGN"], path, meta, MAX_CLOCK_DISAGREEMENT_S) if "MAGN" in data else None
    return Recording(
        name=name,
        devices={"phone": stream},
        truth=truth,
        fixes=fixes,
        meta=meta,
        beacons=beacons,
        pressure=pressure,
        wifi=wifi,
        magnetic=magnetic,
    )


# ---- finding logs --------------------------------------------------------------------------


def _looks_like_log(path: Path) -> bool:
    """Cheap sniff of a file found in a folder: is it a GetSensorData log (or broken trying)?"""
    if path.name.endswith(".mat"):
        try:
            import scipy.io

            return any(v[0] == "Acce" for v in scipy.io.whosmat(str(path)))
        except NotImplementedError:
            import h5py

            try:
                with h5py.File(path, "r") as f:
                    return "Acce" in f
            except OSError:
                return True  # let the full read report what is wrong
        except (ValueError, TypeError, OSError):
            return True
    try:
        with open_text(path) as f:
            head = f.read(8192)
    except (OSError, EOFError, lzma.LZMAError, FormatError):
        return True
    if not head.strip():
        return True  # an empty log is a broken log: let read_log say so
    return "GetSensorData" in head or re.search(r"^(ACCE|GYRO|AHRS|GNSS|POSI);", head, re.M) is not None


def find_logs(src: Path) -> list[Path]:
    """Log files under ``src``, sorted; the text log wins over a .mat of the same name. The dataset's
    documentation (:data:`DOC_NAME`) is passed over quietly; another file that is not a log is
    named in an info line ("skipping ...")."""
    by_stem: dict[Path, Path] = {}
    for p in sorted(src.rglob("*")):
        if not (p.is_file() and p.name.endswith(LOG_SUFFIXES)):
            continue
        stem = strip_compression(p)
        stem = (
            stem[: -len(".txt")] if stem.endswith(".txt") else stem[: -len(".mat")] if stem.endswith(".mat") else stem
        )
        key = p.with_name(stem)
        prev = by_stem.get(key)
        if prev is None or (prev.name.endswith(".mat") and not p.name.endswith(".mat")):
            by_stem[key] = p
    logs = []
    for p in sorted(by_stem.values()):
        if DOC_NAME.search(p.name):
            continue
        if _looks_like_log(p):
            logs.append(p)
        else:
            log.info("skipping %s: not a GetSensorData log", p)
    return logs


def read(src: Path, limit: int | None = None) -> Iterator[Recording]:
    """IPIN 2023 Track 3 logs from the dataset folder (all logs under it) or from one log file."""
    src, limit = check_source(src, limit, expect="a GetSensorData log or a folder of them")
    if src.is_file():
        if limit != 0:
            yield read_log(src)
        return
    files = find_logs(src)
    if not files:
        raise FormatError("no GetSensorData logs found (*.txt[.gz|.xz] or *.mat)", src)
    for path in files[:limit]:
        yield read_log(path)
