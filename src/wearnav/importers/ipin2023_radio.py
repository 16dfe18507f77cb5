"""IPIN 2023 Track 3 logs, the radio part: BLE beacon readings, Wi-Fi scans, the magnetometer,
barometer pressure and the venue beacons' surveyed positions (:mod:`wearnav.importers.ipin2023` reads
the rest of a log and calls these).

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
* ``WIFI;App;Sensor;SSID;BSSID;Frequency(MHz);RSS(dBm)`` → ``wifi`` (issue 60 §1): ``t`` the app time
  of the row (one scan's rows share it), ``t_seen`` the reading's own timestamp (Android's
  ``ScanResult.timestamp``, seconds since boot: the sensor clock of ACCE, so shifted onto the app
  clock by the log's ``imu_clock_offset_s``). An SSID holding ``;`` is read whole (the last three
  fields are BSSID, frequency, RSSI). The .mat conversion's ``Wifi`` cells are (app time, BSSID,
  frequency, RSSI): no SSID (""), no own timestamp (``t_seen`` None).
* ``MAGN;App;Sensor;X;Y;Z;acc`` (µT; the header documents an empty field after X, which no row has) →
  ``magnetic``, on the app clock through the IMU's sensor-clock offset where its own offset agrees
  with it (within :data:`~wearnav.importers.ipin2023.MAX_CLOCK_DISAGREEMENT_S`), else its own.

Beacon positions: ``02 Supplementary Materials/02 - BLE Locations/BLE_Locations.csv`` (``bleID,
Lat,Lon,floor``), found from the log's folder upwards as the dataset lays it out, projected into
the recording's frame → ``meta["beacons"] = {"BLE1": [x_m, y_m, floor], ...}`` for a recording at
the venue. Without that file there is no ``meta["beacons"]`` and ``meta["beacons_note"]`` says why.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav.core import geo
from wearnav.core.timeseries import drop_duplicate_times
from wearnav.errors import FormatError
from wearnav.importers.common import check_finite, check_latlon
from wearnav.importers.radio_rows import drop_repeated_readings
from wearnav.recording import BeaconReadings, MagneticField, Pressure, WifiScans

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

log = logging.getLogger(__name__)


# ---- parsing -------------------------------------------------------------------------------


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


def _parse_wifi(rows: list[str], path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """WIFI rows → ((N, 4) app time s, sensor time s, frequency MHz, RSSI dBm; (N,) BSSIDs; (N,) SSIDs)."""
    nums, bssid, ssid = [], [], []
    for k, ln in enumerate(rows):
        f = ln.rstrip(";").split(";")
        if len(f) < 7:
            raise FormatError(f"WIFI row {k} has {len(f) - 1} fields, expected 6", path)
        try:
            nums.append((float(f[1]), float(f[2]), float(f[-2]), float(f[-1])))
        except ValueError:
            raise FormatError(f"WIFI row {k}: not a number ({f[1]!r}, {f[2]!r}, {f[-2]!r}, {f[-1]!r})", path) from None
        bssid.append(f[-3].strip().lower())
        ssid.append(";".join(f[3:-3]))
    arr = np.array(nums, dtype=np.float64).reshape(-1, 4)
    check_finite(arr, "WIFI rows", path)
    return arr, np.array(bssid, dtype=object), np.array(ssid, dtype=object)


def _mat_wifi(cells: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The .mat's ``Wifi`` cell array (N, 4): app time, BSSID, frequency, RSSI → as :func:`_parse_wifi`
    (sensor time NaN: the conversion drops it; SSIDs "")."""
    cells = np.asarray(cells, dtype=object)
    if cells.ndim != 2 or cells.shape[1] < 4:
        raise FormatError(f"variable 'Wifi' has shape {cells.shape}, expected (N, 4) cells", path)
    try:
        arr = np.array(
            [[float(np.ravel(c[0])[0]), np.nan, float(np.ravel(c[2])[0]), float(np.ravel(c[3])[0])] for c in cells],
            dtype=np.float64,
        ).reshape(-1, 4)
        bssid = [str(np.ravel(c[1])[0]).strip().lower() for c in cells]
    except (IndexError, TypeError, ValueError) as exc:
        raise FormatError(f"variable 'Wifi': not (time, BSSID, frequency, RSSI) cells ({exc})", path) from None
    check_finite(arr[:, [0, 2, 3]], "variable 'Wifi'", path)
    return arr, np.array(bssid, dtype=object), np.full(len(bssid), "", dtype=object)


# ---- building the recording ----------------------------------------------------------------


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


def _wifi_scans(w: np.ndarray, bssid: np.ndarray, ssid: np.ndarray, path: Path, meta: dict) -> WifiScans | None:
    """WIFI rows (App, Sensor, MHz, dBm) → WifiScans on the app clock (:mod:`.radio_rows`'s rules);
    the own timestamps through the IMU's clock offset (None where the rows have none)."""
    keep = drop_repeated_readings(w[:, 0], bssid, "WIFI", path, meta, None if np.isnan(w[:, 1]).any() else w[:, 1])
    w, bssid, ssid = w[keep], bssid[keep], ssid[keep]
    t_seen = None
    if np.all(np.isfinite(w[:, 1])):
        t_seen = w[:, 1] + float(meta["imu_clock_offset_s"])
    return WifiScans(w[:, 0], bssid, ssid, w[:, 2], w[:, 3], t_seen)


def _magnetic(m: np.ndarray, path: Path, meta: dict, max_disagreement_s: float) -> MagneticField:
    """MAGN rows (App, Sensor, x, y, z µT) → MagneticField on the app clock: the IMU's sensor-clock
    offset where the rows' own least delivery delay agrees with it, else their own (said in meta)."""
    keep, n_dup = drop_duplicate_times(m[:, 1], "MAGN SensorTimestamp", path)
    if n_dup:
        meta["dropped_duplicates"]["MAGN"] = n_dup
    m = m[keep]
    own = float(np.min(m[:, 0] - m[:, 1]))
    offset = float(meta["imu_clock_offset_s"])
    if abs(own - offset) > max_disagreement_s:
        meta["magnetic_clock_offset_s"] = round(own, 6)
        offset = own
    return MagneticField(m[:, 1] + offset, m[:, 2:5])


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
