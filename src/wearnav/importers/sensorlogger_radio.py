"""Sensor Logger's Wi-Fi scans (``WiFi.csv``, Android) → :class:`~wearnav.recording.WifiScans`: what a
radio map (issue 60, :mod:`wearnav.fuse.radiomap`) reads from a user's own recording.

UNITS.md (``shared/data/sensor_logger_format``), "WiFi": ``ssid`` the network's name, ``bssid`` the
MAC address, ``frequency`` the network frequency, ``level`` the signal strength in dBm,
``capabilities`` the advertised security; like every Sensor Logger file, ``time`` in nanoseconds
since the epoch. Read here:

* ``t = (time - t0) * 1e-9`` s on the recording's clock (``meta["t0_unix_ns"]``, the motion files'
  start; a scan before it has a negative time). The readings of one scan share their ``time``
  (a :class:`~wearnav.recording.WifiScans` scan is the readings sharing one time). UNITS.md does not
  say how the app stamps a scan's results; a file whose every row has its own time reads as scans of
  one access point each, which a radio map cannot place (``min_common_aps``) and ``track`` says so.
* ``frequency`` is read as MHz (Android's ``ScanResult.frequency``; the table refuses a value that is
  not a Wi-Fi channel in MHz), ``level`` as dBm (refused outside -130..0), ``bssid`` in lower case.
* No reading's own timestamp is written (``t_seen`` None): no reading is left out as stale.
* Rows follow :mod:`wearnav.importers.radio_rows` (a repeated reading dropped and counted in
  ``meta["dropped_duplicates"]["WiFi.csv"]``, time going backwards refused); a missing column, a
  non-number or a truncated last row is a one-line error naming the file, as for every other file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from wearnav.errors import FormatError, MissingFileError, ValidationError
from wearnav.importers.common import check_finite, check_unix_time, find_file, read_csv
from wearnav.importers.radio_rows import drop_repeated_readings
from wearnav.recording import WifiScans

WIFI_FILE = "WiFi.csv"
WIFI_COLS = ("time", "bssid", "frequency", "level")  # required; ssid and capabilities where present


def read_wifi(folder: Path, t0_ns: int, meta: dict) -> WifiScans | None:
    """The export's Wi-Fi scans on the recording's clock (module docstring); None without ``WiFi.csv``."""
    try:
        path = find_file(Path(folder) / WIFI_FILE)
    except MissingFileError:
        return None
    df = read_csv(path, required=WIFI_COLS, empty_ok=True, dtype={"bssid": str, "ssid": str}, keep_default_na=False)
    if df.empty:  # the Wi-Fi sensor on, no scan delivered (Wi-Fi off, or throttled)
        return None
    num = df[["time", "level", "frequency"]].apply(pd.to_numeric, errors="coerce").to_numpy(np.float64)
    bad = ~np.isfinite(num).all(axis=1)
    if bad.any() and np.flatnonzero(bad)[0] == len(df) - 1:
        raise FormatError(f"last row (line {len(df) + 1}) is incomplete: truncated file?", path)
    check_finite(num, "columns ['time', 'level', 'frequency']", path)
    t_ns = (
        df["time"].to_numpy(np.int64)
        if pd.api.types.is_integer_dtype(df["time"])
        else np.round(num[:, 0]).astype(np.int64)
    )
    check_unix_time(t_ns / 1e9, "time", path)
    bssid = df["bssid"].astype(str).str.strip().str.lower().to_numpy(object)
    if np.any(bssid == ""):
        raise FormatError(
            f"row {int(np.argmax(bssid == ''))}: an empty bssid (every reading names its access point)", path
        )
    ssid = df["ssid"].astype(str).to_numpy(object) if "ssid" in df.columns else np.full(len(df), "", object)
    t = (t_ns - int(t0_ns)).astype(np.float64) * 1e-9
    keep = drop_repeated_readings(t, bssid, WIFI_FILE, path, meta)
    try:
        return WifiScans(t[keep], bssid[keep], ssid[keep], num[keep, 2], num[keep, 1])
    except ValidationError as exc:  # a reading out of range: named with the file it came from
        raise FormatError(str(exc), path) from None


__all__ = ["WIFI_FILE", "read_wifi"]
