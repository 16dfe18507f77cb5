"""Write a Recording as a Sensor Logger export: the inverse of :mod:`wearnav.importers.sensorlogger`.

Files, columns and unit conventions come from the importer (``DEVICE_FILES``, ``GRAVITY_IN_G``,
:func:`~wearnav.importers.sensorlogger_map.acceleration_convention`, ``xyz_cols``), which cites the
app's documentation (``shared/data/sensor_logger_format``: UNITS.md, COORDINATES.md,
CROSSPLATFORM.md): nanosecond ``time``, columns in the app's order (``z,y,x``), user acceleration
and gravity split, g units on the Apple wearables when "Standardise Units & Frames" is off, iOS's
flipped acceleration sign, lat/lon from local metres by :func:`wearnav.core.geo.local_to_latlon` (about
the recording's own origin, else ``ORIGIN``).

:func:`simulated_export` writes one simulated walk (phone, watch, earbuds and GPS fixes) this way,
marked as simulated in ``Metadata.csv`` (``device name``): what ``wearnav simulate --format
sensorlogger`` writes, to try ``wearnav import sensorlogger`` and ``wearnav track`` on.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from wearnav.core import geo
from wearnav.core.fileio import write_text_atomic
from wearnav.core.rotations import from_wxyz, to_wxyz
from wearnav.importers.sensorlogger_map import (
    DEVICE_FILES,
    GRAVITY_IN_G,
    ORIENTATION_COLS,
    acceleration_convention,
    quat_cols,
    xyz_cols,
)
from wearnav.outputs import staged_output
from wearnav.recording import STANDARD_GRAVITY as G
from wearnav.recording import Recording
from wearnav.simulate import WalkConfig, simulate_recording

T0_NS = 1_700_000_000_123_456_789  # the export's first sample, ns since the Unix epoch (2023-11-14)
ORIGIN = (49.4480, 11.0955)  # lat, lon (degrees) of the local frame's origin
SIMULATED_DEVICE_NAME = "wearnav simulator (simulated, not a real recording)"
SIMULATED_MARKER = "wearnav_simulated.json"  # beside the app's files: what wearnav wrote, and that it is simulated
SIMULATED_WALK_S = 180.0  # long enough for a path to anchor (track's ANCHOR_S = 60 s of fixes)


def time_origin(rec: Recording) -> float:
    """The recording time (s) written as ``T0_NS``: the earliest sample of any stream or fix."""
    starts = [s.t[0] for s in rec.devices.values()]
    if rec.fixes is not None:
        starts.append(rec.fixes.t[0])
    return float(min(starts))


def _time_cols(t: np.ndarray, t_ref: float) -> dict:
    ns = T0_NS + np.round((np.asarray(t) - t_ref) * 1e9).astype(np.int64)
    return {"time": ns, "seconds_elapsed": (ns - T0_NS) / 1e9}


def _split(s, quat_inverted: bool = False):
    """User acceleration and gravity (m/s², Android sign), quaternions (w, x, y, z) as written."""
    if s.quat is None:
        raise ValueError("an export needs quaternions to split gravity from user acceleration")
    r = from_wxyz(np.asarray(s.quat, float))
    grav = r.inv().apply([0.0, 0.0, G])
    user = np.asarray(s.acc, float) - grav
    q = to_wxyz(r.inv() if quat_inverted else r)
    return user, grav, q, r


def _euler(r: Rotation) -> np.ndarray:
    return r.as_euler("ZXY")  # yaw, pitch, roll (COORDINATES.md: Z-X'-Y'')


def write_export(
    rec: Recording,
    folder: str | Path,
    platform: str = "ios",
    standardised: bool = False,
    total_acceleration: bool = False,
    quat_inverted: bool = False,
    metadata: bool = True,
    layout_version: int = 3,
    watch_extras: bool = False,
    device_name: str = "test phone",
) -> Path:
    """Write ``rec`` (devices phone / watch / earbuds, fixes, Wi-Fi scans, barometer) into ``folder`` as Sensor
    Logger would; fixes at their place on Earth where ``rec`` has a lat/lon origin, else about ``ORIGIN``.

    ``total_acceleration`` writes Android's TotalAcceleration.csv too. ``quat_inverted`` writes
    device←world quaternions (to test the importer's convention check). ``platform="watchos"``
    is what an export recorded on an Apple Watch alone says (iPhone sign convention);
    ``watch_extras`` adds the watch-only files such exports carry (uncalibrated accelerometer,
    heart rate, compass), which the importer must ignore. ``device_name`` goes to Metadata.csv.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    t_ref = time_origin(rec)
    sign, unit = acceleration_convention(platform, standardised)
    sensors = []

    if "phone" in rec.devices:
        s = rec.devices["phone"]
        user, grav, q, r = _split(s, quat_inverted)
        tc = _time_cols(s.t, t_ref)

        def xyz(v):
            return pd.DataFrame({**tc, "z": v[:, 2], "y": v[:, 1], "x": v[:, 0]})

        # the phone's files are m/s² whatever the toggle (UNITS.md): only the sign applies
        xyz(sign * user).to_csv(folder / "Accelerometer.csv", index=False)
        xyz(sign * grav).to_csv(folder / "Gravity.csv", index=False)
        if total_acceleration:
            xyz(sign * np.asarray(s.acc, float)).to_csv(folder / "TotalAcceleration.csv", index=False)
        if s.gyro is not None:
            xyz(np.asarray(s.gyro, float)).to_csv(folder / "Gyroscope.csv", index=False)
        e = _euler(r)
        quat = dict(zip(ORIENTATION_COLS, q.T))
        pd.DataFrame(
            {
                **tc,
                **{c: quat[c] for c in reversed(ORIENTATION_COLS)},
                "roll": e[:, 2],
                "pitch": e[:, 1],
                "yaw": e[:, 0],
            }
        ).to_csv(folder / "Orientation.csv", index=False)
        sensors += ["Accelerometer", "Gravity", "Gyroscope", "Orientation"]

    for dev, fname in DEVICE_FILES.items():
        if dev not in rec.devices:
            continue
        s = rec.devices[dev]
        user, grav, q, r = _split(s, quat_inverted)
        gyro = np.zeros((len(s.t), 3)) if s.gyro is None else np.asarray(s.gyro, float)
        e = _euler(r)
        grav_unit = unit if GRAVITY_IN_G[dev] else 1.0
        cols = {**_time_cols(s.t, t_ref)}
        cols.update(zip(xyz_cols("rotationRate"), gyro.T))
        cols.update(zip(xyz_cols("gravity"), (sign * grav / grav_unit).T))
        cols.update(zip(xyz_cols("acceleration"), (sign * user / unit).T))
        cols.update(zip(quat_cols(), q.T))
        cols.update(pitch=e[:, 1], roll=e[:, 2], yaw=e[:, 0])
        if dev == "earbuds":
            cols["devicelocation"] = "left"
        pd.DataFrame(cols).to_csv(folder / fname, index=False)
        sensors.append("Wrist Motion" if dev == "watch" else "Headphone")

    # lat/lon about the recording's own origin where it has one (an imported walk written where it was)
    lat0, lon0 = rec.meta.get("origin_lat"), rec.meta.get("origin_lon")
    origin = (float(lat0), float(lon0)) if lat0 is not None and lon0 is not None else ORIGIN
    if rec.fixes is not None:
        f = rec.fixes
        lat, lon = geo.local_to_latlon(f.pos[:, :2], *origin)
        acc = np.where(np.isfinite(f.accuracy), f.accuracy, -1.0)
        pd.DataFrame(
            {
                **_time_cols(f.t, t_ref),
                "bearingAccuracy": 0.0,
                "speedAccuracy": 0.0,
                "verticalAccuracy": 3.0,
                "horizontalAccuracy": acc,
                "speed": 1.2,
                "bearing": 0.0,
                "altitude": 300.0,
                "longitude": lon,
                "latitude": lat,
            }
        ).to_csv(folder / "Location.csv", index=False)
        sensors.append("Location")

    if rec.wifi is not None:  # Android's WiFi.csv (UNITS.md "WiFi"; wearnav.importers.sensorlogger_radio)
        w = rec.wifi
        pd.DataFrame(
            {
                **_time_cols(w.t, t_ref),
                "ssid": w.ssid,
                "bssid": w.bssid,
                "frequency": np.round(w.freq_mhz).astype(np.int64),
                "level": w.rssi_dbm,
                "capabilities": "[WPA2-PSK-CCMP][ESS]",
            }
        ).to_csv(folder / "WiFi.csv", index=False)
        sensors.append("WiFi")

    if rec.pressure is not None:  # UNITS.md "Barometer": hPa; relativeAltitude m since the start
        p = rec.pressure
        pd.DataFrame(
            {
                **_time_cols(p.t, t_ref),
                # the standard atmosphere's height for a pressure change near sea level: 8.43 m per hPa
                "relativeAltitude": 8.43 * (p.hpa[0] - p.hpa),
                "pressure": p.hpa,
            }
        ).to_csv(folder / "Barometer.csv", index=False)
        sensors.append("Barometer")

    if watch_extras and "watch" in rec.devices:
        s = rec.devices["watch"]
        tc = _time_cols(s.t, t_ref)
        pd.DataFrame({**tc, "z": -s.acc[:, 2] / G, "y": -s.acc[:, 1] / G, "x": -s.acc[:, 0] / G}).to_csv(
            folder / "WatchAccelerometerUncalibrated.csv", index=False
        )
        tc1 = _time_cols(s.t[::500], t_ref)
        pd.DataFrame({**tc1, "bpm": 92.0}).to_csv(folder / "HeartRate.csv", index=False)
        pd.DataFrame({**tc1, "magneticHeading": 10.0, "trueHeading": 12.0, "headingAccuracy": 5.0}).to_csv(
            folder / "WatchCompass.csv", index=False
        )
        sensors += ["Watch Accelerometer Uncalibrated", "Heart Rate", "Watch Compass"]

    if metadata:
        pd.DataFrame(
            [
                {
                    "version": layout_version,
                    "device name": device_name,
                    "recording epoch time": T0_NS // 1_000_000,
                    "recording time": "2023-11-14_22-13-20",
                    "recording timezone": "Europe/Berlin",
                    "platform": platform,
                    "appVersion": "1.40",
                    "device id": "abc",
                    "sensors": "|".join(sensors),
                    "sampleRateMs": "10",
                    "standardisation": "true" if standardised else "false",
                    "platform version": "17.0",
                }
            ]
        ).to_csv(folder / "Metadata.csv", index=False)
    return folder


def zip_export(folder: str | Path, zpath: str | Path, subfolder: str | None = None) -> Path:
    """Zip an export folder (files at the archive root, or under ``subfolder``)."""
    folder, zpath = Path(folder), Path(zpath)
    with zipfile.ZipFile(zpath, "w", zipfile.ZIP_DEFLATED) as zf:
        for p in sorted(folder.iterdir()):
            zf.write(p, f"{subfolder}/{p.name}" if subfolder else p.name)
    return zpath


def simulated_export(
    folder: str | Path, seed: int = 0, duration_s: float = SIMULATED_WALK_S, platform: str = "ios"
) -> dict:
    """One simulated walk (phone in the hand, watch, earbuds, GPS fixes; :mod:`wearnav.simulate`)
    written as an iPhone's Sensor Logger export into ``folder``, marked simulated: Metadata.csv's
    ``device name`` and ``SIMULATED_MARKER`` (what was written, returned too). A folder holding files
    of the same names that this did not write is refused (:mod:`wearnav.outputs`)."""
    rec = simulate_recording(WalkConfig(mode="PVW", placement="MP", duration_s=duration_s), seed=seed)
    with staged_output(folder, SIMULATED_MARKER, "simulate") as stage:  # all files or none
        write_export(rec, stage, platform=platform, device_name=SIMULATED_DEVICE_NAME)
        files = sorted(p.name for p in stage.iterdir())
        record = {
            "simulated": True,
            "generator": "wearnav simulate --format sensorlogger",
            "seed": seed,
            "duration_s": duration_s,
            "platform": platform,
            "devices": sorted(rec.devices),
            "fixes": 0 if rec.fixes is None else len(rec.fixes),
            "origin_lat_lon": list(ORIGIN),
            "export": str(folder),
            "files": files + [SIMULATED_MARKER],
        }
        write_text_atomic(json.dumps(record, indent=2), stage / SIMULATED_MARKER)
    return record


__all__ = [
    "ORIGIN",
    "SIMULATED_DEVICE_NAME",
    "SIMULATED_MARKER",
    "T0_NS",
    "simulated_export",
    "time_origin",
    "write_export",
    "zip_export",
]
