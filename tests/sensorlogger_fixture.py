"""Write a Recording as a Sensor Logger export (the inverse of wearnav.importers.sensorlogger).

Written independently from the importer, from the documentation in
``shared/data/sensor_logger_format`` (UNITS.md, COORDINATES.md): nanosecond ``time``, columns in
the app's order (``z,y,x``), user acceleration and gravity split, g units on the Apple wearables
when "Standardise Units & Frames" is off, iOS's flipped acceleration sign, lat/lon from local metres
(WGS-84 east-north-up about ``ORIGIN``, by pymap3d).
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pymap3d
from scipy.spatial.transform import Rotation

from wearnav.recording import STANDARD_GRAVITY
from wearnav.recording import Recording

G = STANDARD_GRAVITY
T0_NS = 1_700_000_000_123_456_789
ORIGIN = (49.4480, 11.0955)  # lat, lon of the local frame's origin


def time_origin(rec: Recording) -> float:
    """The recording time written as ``T0_NS`` (the earliest sample of any stream or fix)."""
    starts = [s.t[0] for s in rec.devices.values()]
    if rec.fixes is not None:
        starts.append(rec.fixes.t[0])
    return float(min(starts))


def _time_cols(t: np.ndarray, t_ref: float) -> dict:
    ns = T0_NS + np.round((np.asarray(t) - t_ref) * 1e9).astype(np.int64)
    return {"time": ns, "seconds_elapsed": (ns - T0_NS) / 1e9}


def _split(s, quat_inverted: bool = False):
    """User acceleration and gravity (m/s², Android sign), quaternions as written."""
    if s.quat is None:
        raise ValueError("the fixture needs quaternions to split gravity from user acceleration")
    r = Rotation.from_quat(np.asarray(s.quat, float)[:, [1, 2, 3, 0]])
    grav = r.inv().apply([0.0, 0.0, G])
    user = np.asarray(s.acc, float) - grav
    q = (r.inv() if quat_inverted else r).as_quat()[:, [3, 0, 1, 2]]
    return user, grav, q, r


def _euler(r: Rotation) -> np.ndarray:
    return r.as_euler("ZXY")  # yaw, pitch, roll (COORDINATES.md: Z-X'-Y'')


def write_export(rec: Recording, folder: str | Path, platform: str = "ios",
                 standardised: bool = False, total_acceleration: bool = False,
                 quat_inverted: bool = False, metadata: bool = True, layout_version: int = 3,
                 watch_extras: bool = False) -> Path:
    """Write ``rec`` (devices phone / watch / earbuds, fixes) into ``folder`` as Sensor Logger would.

    ``total_acceleration`` writes Android's TotalAcceleration.csv too. ``quat_inverted`` writes
    device←world quaternions (to test the importer's convention check). ``platform="watchos"``
    is what an export recorded on an Apple Watch alone says (iPhone sign convention);
    ``watch_extras`` adds the watch-only files such exports carry (uncalibrated accelerometer,
    heart rate, compass), which the importer must ignore.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    t_ref = time_origin(rec)
    apple = platform in ("ios", "watchos") and not standardised
    sign = -1.0 if apple else 1.0
    unit = G if not standardised else 1.0
    sensors = []

    if "phone" in rec.devices:
        s = rec.devices["phone"]
        user, grav, q, r = _split(s, quat_inverted)
        tc = _time_cols(s.t, t_ref)

        def xyz(v):
            return pd.DataFrame({**tc, "z": v[:, 2], "y": v[:, 1], "x": v[:, 0]})

        xyz(sign * user).to_csv(folder / "Accelerometer.csv", index=False)
        xyz(sign * grav).to_csv(folder / "Gravity.csv", index=False)
        if total_acceleration:
            xyz(sign * np.asarray(s.acc, float)).to_csv(folder / "TotalAcceleration.csv", index=False)
        if s.gyro is not None:
            xyz(np.asarray(s.gyro, float)).to_csv(folder / "Gyroscope.csv", index=False)
        e = _euler(r)
        pd.DataFrame({**tc, "qz": q[:, 3], "qy": q[:, 2], "qx": q[:, 1], "qw": q[:, 0],
                      "roll": e[:, 2], "pitch": e[:, 1], "yaw": e[:, 0]}).to_csv(
            folder / "Orientation.csv", index=False)
        sensors += ["Accelerometer", "Gravity", "Gyroscope", "Orientation"]

    for dev, fname in (("watch", "WristMotion.csv"), ("earbuds", "Headphone.csv")):
        if dev not in rec.devices:
            continue
        s = rec.devices[dev]
        user, grav, q, r = _split(s, quat_inverted)
        gyro = np.zeros((len(s.t), 3)) if s.gyro is None else np.asarray(s.gyro, float)
        e = _euler(r)
        # Headphone gravity is m/s² whatever the toggle (UNITS.md); WristMotion's follows it.
        grav_unit = unit if dev == "watch" else 1.0
        cols = {**_time_cols(s.t, t_ref)}
        for k, a in enumerate("XYZ"):
            cols[f"rotationRate{a}"] = gyro[:, k]
        for k, a in enumerate("XYZ"):
            cols[f"gravity{a}"] = sign * grav[:, k] / grav_unit
        for k, a in enumerate("XYZ"):
            cols[f"acceleration{a}"] = sign * user[:, k] / unit
        for k, a in enumerate("WXYZ"):
            cols[f"quaternion{a}"] = q[:, k]
        cols.update(pitch=e[:, 1], roll=e[:, 2], yaw=e[:, 0])
        if dev == "earbuds":
            cols["devicelocation"] = "left"
        pd.DataFrame(cols).to_csv(folder / fname, index=False)
        sensors.append("Wrist Motion" if dev == "watch" else "Headphone")

    if rec.fixes is not None:
        f = rec.fixes
        lat0, lon0 = ORIGIN
        lat, lon, _ = pymap3d.enu2geodetic(f.pos[:, 0], f.pos[:, 1], 0.0, lat0, lon0, 0.0)
        acc = np.where(np.isfinite(f.accuracy), f.accuracy, -1.0)
        pd.DataFrame({**_time_cols(f.t, t_ref), "bearingAccuracy": 0.0, "speedAccuracy": 0.0,
                      "verticalAccuracy": 3.0, "horizontalAccuracy": acc, "speed": 1.2,
                      "bearing": 0.0, "altitude": 300.0, "longitude": lon, "latitude": lat}).to_csv(
            folder / "Location.csv", index=False)
        sensors.append("Location")

    if watch_extras and "watch" in rec.devices:
        s = rec.devices["watch"]
        tc = _time_cols(s.t, t_ref)
        pd.DataFrame({**tc, "z": -s.acc[:, 2] / G, "y": -s.acc[:, 1] / G, "x": -s.acc[:, 0] / G}).to_csv(
            folder / "WatchAccelerometerUncalibrated.csv", index=False)
        tc1 = _time_cols(s.t[::500], t_ref)
        pd.DataFrame({**tc1, "bpm": 92.0}).to_csv(folder / "HeartRate.csv", index=False)
        pd.DataFrame({**tc1, "magneticHeading": 10.0, "trueHeading": 12.0, "headingAccuracy": 5.0}).to_csv(
            folder / "WatchCompass.csv", index=False)
        sensors += ["Watch Accelerometer Uncalibrated", "Heart Rate", "Watch Compass"]

    if metadata:
        pd.DataFrame([{
            "version": layout_version, "device name": "test phone", "recording epoch time": T0_NS // 1_000_000,
            "recording time": "2023-11-14_22-13-20", "recording timezone": "Europe/Berlin",
            "platform": platform, "appVersion": "1.40", "device id": "abc",
            "sensors": "|".join(sensors), "sampleRateMs": "10",
            "standardisation": "true" if standardised else "false", "platform version": "17.0",
        }]).to_csv(folder / "Metadata.csv", index=False)
    return folder


def zip_export(folder: str | Path, zpath: str | Path, subfolder: str | None = None) -> Path:
    """Zip an export folder (files at the archive root, or under ``subfolder``)."""
    folder, zpath = Path(folder), Path(zpath)
    with zipfile.ZipFile(zpath, "w", zipfile.ZIP_DEFLATED) as zf:
        for p in sorted(folder.iterdir()):
            zf.write(p, f"{subfolder}/{p.name}" if subfolder else p.name)
    return zpath


# ---- exports as they really are (issue 8): damage an export the way real ones differ -----------

def edit_csv(path: str | Path, fn) -> None:
    path = Path(path)
    fn(pd.read_csv(path)).to_csv(path, index=False)


def glitch_quaternion(path: str | Path, row: int, angle: float = 1.0) -> None:
    """One quaternion turned by ``angle`` rad about the device's x axis, its neighbours untouched
    (a start-up glitch). Works on Orientation.csv (qw..) and WristMotion / Headphone (quaternionW..)."""
    def fn(df):
        cols = ["qw", "qx", "qy", "qz"] if "qw" in df else [f"quaternion{a}" for a in "WXYZ"]
        q = df.loc[row, cols].to_numpy(float)
        r = Rotation.from_quat(q[[1, 2, 3, 0]]) * Rotation.from_rotvec([angle, 0.0, 0.0])
        df.loc[row, cols] = r.as_quat()[[3, 0, 1, 2]]
        return df
    edit_csv(path, fn)


def prepend_stale_fix(path: str | Path, seconds_before: float = 90.0, km_away: float = 5.0,
                      accuracy: float = 3000.0) -> None:
    """A cached fix from before the recording as the first row of Location.csv: negative
    ``seconds_elapsed``, ``km_away`` north, ``accuracy`` metres."""
    def fn(df):
        row = df.iloc[[0]].copy()
        row["time"] = int(df["time"].iloc[0]) - int(seconds_before * 1e9)
        row["seconds_elapsed"] = float(df["seconds_elapsed"].iloc[0]) - seconds_before
        row["latitude"] = pymap3d.enu2geodetic(0.0, km_away * 1e3, 0.0, df["latitude"].iloc[0],
                                               df["longitude"].iloc[0], 0.0)[0]
        row["horizontalAccuracy"] = accuracy
        return pd.concat([row, df], ignore_index=True)
    edit_csv(path, fn)


def cut_gap(path: str | Path, start_s: float, length_s: float) -> None:
    """Remove the rows of ``length_s`` seconds starting ``start_s`` after the file's first row."""
    def fn(df):
        t = (df["time"] - df["time"].iloc[0]) / 1e9
        return df[(t < start_s) | (t >= start_s + length_s)]
    edit_csv(path, fn)


def resample_rows(path: str | Path, rate_hz: float) -> None:
    """Keep the rows nearest to a ``rate_hz`` clock (a slower stream of the same phone)."""
    def fn(df):
        t = (df["time"].to_numpy() - df["time"].iloc[0]) / 1e9
        want = np.arange(0.0, t[-1], 1.0 / rate_hz)
        return df.iloc[np.unique(np.clip(np.searchsorted(t, want), 0, len(df) - 1))]
    edit_csv(path, fn)
