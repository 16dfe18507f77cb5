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
* ``BLE4;App;iBeacon;MAC;RSSI(dBm);Power;MajorID;MinorID;UUID`` (and the Eddystone variant
  ``BLE4;App;Eddystone;MAC;RSSI(dBm);...``) → ``beacons``, at the app time of the row. A beacon of
  the venue (iBeacon UUID :data:`VENUE_BEACON_UUID`) is named by the ``bleID`` of
  ``BLE_Locations.csv`` that its MinorID k maps to in :data:`VENUE_MINOR_TO_BLE_ID`: ``BLE<k>``,
  except that minors 2 and 3 are swapped (measured: see there). The venue's MAC addresses end in
  the minor (``BE:AC:20:23:00:0k``, on every BLE4 row of the text logs), which is all the .mat
  conversion keeps (its ``Ble4`` cells are time, MAC, RSSI), so there the minor comes from the
  MAC. Any other beacon is named by its MAC.
* WIFI, MAGN, LIGH, SOUN ... are ignored.

Beacon positions: ``02 Supplementary Materials/02 - BLE Locations/BLE_Locations.csv`` (``bleID,
Lat,Lon,floor``), found from the log's folder upwards as the dataset lays it out, projected into
the recording's frame → ``meta["beacons"] = {"BLE1": [x_m, y_m, floor], ...}`` for a recording at
the venue. Without that file there is no ``meta["beacons"]`` and ``meta["beacons_note"]`` says why.

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

Positions: lat/lon are projected with :func:`wearnav.geo.latlon_to_local` (WGS-84 east-north-up,
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

from wearnav import geo
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
from wearnav.recording import (
    ANDROID_ENU_FRAME,
    BeaconReadings,
    DeviceStream,
    Fixes,
    Pressure,
    Recording,
    Trajectory,
)
from wearnav.timeseries import drop_duplicate_times, interp_onto, rate

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
TXT_COLUMNS = {"ACCE": 5, "GYRO": 5, "AHRS": 8, "GNSS": 7, "POSI": 5, "PRES": 3}
# The .mat conversion's variables and their needed columns (no accuracy / counter columns).
MAT_VARS = {
    "Acce": ("ACCE", 5),
    "Gyro": ("GYRO", 5),
    "Ahrs": ("AHRS", 8),
    "Gnss": ("GNSS", 7),
    "Posi": ("POSI", 4),
    "Pres": ("PRES", 3),
}
# The venue's six iBeacons (BLE_Locations.csv's BLE1..BLE6): one UUID, major 1, minor k; their MAC
# addresses end in k (checked on every BLE4 row of the training logs).
VENUE_BEACON_UUID = "11111111-1111-BEAC-2023-111111111111"
VENUE_BEACON_MAC = re.compile(r"^BE:AC:20:23:([0-9A-F]{2}):([0-9A-F]{2})$", re.IGNORECASE)
# iBeacon minor → bleID of BLE_Locations.csv. Minors 2 and 3 are swapped against the table's
# numbering: over the 44 training walks (truth interpolated between surveyed points), minor 2's
# strongest readings (-54 dBm) lie within 4 m of the table's BLE3 (floor -2) and 20+ m from its
# BLE2, where it reads a median -89 dBm from 0-5 m; minor 3 likewise peaks at the table's BLE2
# (floor 0). With the swap every beacon's RSSI falls with distance (fitted slopes -14 to -27 dB per
# decade); without it minor 2's rises (+19 dB per decade). tests/test_importers_ipin2023.py checks it.
VENUE_MINOR_TO_BLE_ID = {1: "BLE1", 2: "BLE3", 3: "BLE2", 4: "BLE4", 5: "BLE5", 6: "BLE6"}
# Where the dataset keeps the beacons' surveyed positions, relative to its root folder.
BLE_LOCATIONS = Path("02 Supplementary Materials") / "02 - BLE Locations" / "BLE_Locations.csv"
# How many folders above a log's own folder the dataset root may be (root/01 Logfiles/<split>/log).
BLE_LOCATIONS_DEPTH = 3
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


def _venue_beacon_name(minor: int) -> str:
    """The bleID of the venue's beacon with this iBeacon minor (:data:`VENUE_MINOR_TO_BLE_ID`;
    ``BLE<minor>`` for a minor the table does not list)."""
    return VENUE_MINOR_TO_BLE_ID.get(minor, f"BLE{minor}")


def _venue_beacon_minor(mac: str) -> int | None:
    """The iBeacon minor k in a MAC address of the venue's beacons (``BE:AC:20:23:00:0k``), else None."""
    m = VENUE_BEACON_MAC.match(mac.strip())
    return int(m.group(1) + m.group(2), 16) if m else None


def _parse_ble4(rows: list[str], path: Path) -> tuple[np.ndarray, np.ndarray]:
    """BLE4 rows → ((N, 2) app time s, RSSI dBm; (N,) beacon names), see the module docstring."""
    times, rssi, names = [], [], []
    for k, ln in enumerate(rows):
        f = ln.split(";")
        if len(f) < 5:
            raise FormatError(f"BLE4 row {k} has {len(f) - 1} fields, expected at least 4", path)
        try:
            times.append(float(f[1]))
            rssi.append(float(f[4]))
        except ValueError:
            raise FormatError(f"BLE4 row {k}: not a number ({f[1]!r}, {f[4]!r})", path) from None
        if f[2] == "iBeacon" and len(f) > 8 and f[8].strip().upper() == VENUE_BEACON_UUID:
            try:
                names.append(_venue_beacon_name(int(f[7])))
            except ValueError:
                raise FormatError(f"BLE4 row {k}: MinorID {f[7]!r} is not an integer", path) from None
        else:
            names.append(f[3].strip())
    arr = np.column_stack([times, rssi]) if times else np.zeros((0, 2))
    check_finite(arr, "BLE4 rows", path)
    return arr, np.array(names, dtype=object)


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
    RSSI, with the beacon names under ``BLE4_NAME``), header info."""
    text = read_text(path)
    if not text.strip():
        raise FormatError("empty file", path)
    header: list[str] = []
    rows: dict[str, list[str]] = {tag: [] for tag in (*TXT_COLUMNS, "BLE4")}
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
    ble4 = rows.pop("BLE4")
    data = {tag: _parse_block(r, tag, path) for tag, r in rows.items() if r}
    if ble4:
        data["BLE4"], data["BLE4_NAME"] = _parse_ble4(ble4, path)
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
    """The organisers' .mat conversion (variables Acce, Gyro, Ahrs, Gnss, Posi, Pres, Ble4) → same as
    read_txt."""
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
    return data, {}


def _mat_ble4(cells: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The .mat's ``Ble4`` cell array (N, 3): app time, MAC, RSSI → as :func:`_parse_ble4`."""
    cells = np.asarray(cells, dtype=object)
    if cells.ndim != 2 or cells.shape[1] < 3:
        raise FormatError(f"variable 'Ble4' has shape {cells.shape}, expected (N, 3) cells", path)
    try:
        arr = np.array([[float(np.ravel(c[0])[0]), float(np.ravel(c[2])[0])] for c in cells], dtype=np.float64)
        macs = [str(np.ravel(c[1])[0]) for c in cells]
    except (IndexError, TypeError, ValueError) as exc:
        raise FormatError(f"variable 'Ble4': not (time, MAC, RSSI) cells ({exc})", path) from None
    check_finite(arr, "variable 'Ble4'", path)
    minors = [_venue_beacon_minor(m) for m in macs]
    return arr, np.array([m if k is None else _venue_beacon_name(k) for m, k in zip(macs, minors)], dtype=object)


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


def _pressure(p: np.ndarray, path: Path, meta: dict) -> Pressure:
    """PRES rows (App, Sensor, hPa) → Pressure on the app clock: sensor times shifted by the rows'
    least delivery delay, as the fixes."""
    keep, n_dup = drop_duplicate_times(p[:, 1], "PRES SensorTimestamp", path)
    if n_dup:
        meta["dropped_duplicates"]["PRES"] = n_dup
    p = p[keep]
    offset = float(np.min(p[:, 0] - p[:, 1]))
    meta["pressure_clock_offset_s"] = round(offset, 6)
    return Pressure(p[:, 1] + offset, p[:, 2])


def _beacon_readings(b: np.ndarray, names: np.ndarray, path: Path, meta: dict) -> BeaconReadings:
    """BLE4 rows (App time, RSSI) and names → BeaconReadings; a row repeating the time of the one
    before is dropped (counted in ``meta["dropped_duplicates"]``)."""
    keep, n_dup = drop_duplicate_times(b[:, 0], "BLE4", path)
    if n_dup:
        meta["dropped_duplicates"]["BLE4"] = n_dup
    return BeaconReadings(b[keep, 0], names[keep], b[keep, 1])


def find_ble_locations(log_path: Path) -> Path | None:
    """The dataset's ``BLE_Locations.csv`` for a log: :data:`BLE_LOCATIONS` under the log's folder or
    one of the :data:`BLE_LOCATIONS_DEPTH` folders above it (the dataset root), or the file name
    alone beside the log; None if there is none."""
    for folder in [log_path.parent, *list(log_path.parent.parents)[:BLE_LOCATIONS_DEPTH]]:
        for cand in (folder / BLE_LOCATIONS, folder / BLE_LOCATIONS.name):
            if cand.is_file():
                return cand
    return None


def read_ble_locations(path: Path, lat0: float, lon0: float) -> dict[str, list[float]]:
    """``BLE_Locations.csv`` (``bleID,Lat,Lon,floor``) → {bleID: [x_m, y_m, floor]} about lat0/lon0."""
    try:
        df = pd.read_csv(path, dtype={"bleID": str})
        lat, lon = df["Lat"].to_numpy(np.float64), df["Lon"].to_numpy(np.float64)
        floors = df["floor"].to_numpy(np.float64)
    except (KeyError, ValueError, pd.errors.ParserError) as exc:
        raise FormatError(f"not a beacon table bleID,Lat,Lon,floor ({exc})", path) from None
    check_latlon(lat, lon, "BLE_Locations", path)
    check_finite(floors, "BLE_Locations floor", path)
    xy = geo.latlon_to_local(lat, lon, lat0, lon0)
    return {
        str(name).strip(): [round(float(x), 3), round(float(y), 3), int(f)]
        for name, (x, y), f in zip(df["bleID"], xy, floors)
    }


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
    return Recording(
        name=name,
        devices={"phone": stream},
        truth=truth,
        fixes=fixes,
        meta=meta,
        beacons=beacons,
        pressure=pressure,
    )


def _beacon_positions(path: Path, lat0: float, lon0: float, meta: dict) -> None:
    """``meta["beacons"]`` (and the file it came from) from the dataset's BLE_Locations.csv, or a
    ``meta["beacons_note"]`` saying it was not found."""
    table = find_ble_locations(path)
    if table is None:
        meta["beacons_note"] = f"{BLE_LOCATIONS.name} not found beside the logs: beacon positions unknown"
        log.debug("%s: %s not found beside the log: no beacon positions", path.name, BLE_LOCATIONS.name)
        return
    meta["beacons"] = read_ble_locations(table, lat0, lon0)
    meta["beacons_file"] = BLE_LOCATIONS.name


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
