"""Sensor Logger (iOS / Android app) exports → one multi-device Recording per export.

An export is a folder (or a ``.zip`` of one) holding one CSV per sensor. ``src`` may be one
export folder, one zip, or a folder of several export folders / zips. The files read are::

    Metadata.csv                          platform (ios | android), standardisation (true | false)
    Accelerometer.csv, Gravity.csv        phone, time,seconds_elapsed,z,y,x
    TotalAcceleration.csv                 phone (Android only), same columns
    Gyroscope.csv                         phone, same columns
    Orientation.csv                       phone, time,seconds_elapsed,qz,qy,qx,qw,roll,pitch,yaw
    WristMotion.csv                       Apple Watch → device "watch"
    Headphone.csv                         AirPods → device "earbuds"
    Location.csv                          phone location fixes → Recording.fixes

Columns are found by name, never by position. Everything else in an export (Magnetometer,
Barometer, Annotation, Activity, WatchLocation, ...) is ignored.

Unit and frame conversions, each with the line of the Sensor Logger documentation it rests on
(``UNITS.md`` / ``COORDINATES.md`` of tszheichoi/awesome-sensor-logger at b10f5c5, copied to
``shared/data/sensor_logger_format``; ``README.md`` and ``CROSSPLATFORM.md`` of the same repository
where noted). "The Recording convention" is specific force including gravity, m/s², device frame,
reading about +9.81 on z for a device lying screen-up on a table.

Time
  * ``t = (time - t0) * 1e-9`` s, in int64 arithmetic, with ``t0`` the earliest ``time`` of any
    file read (kept in ``meta["t0_unix_ns"]``). UNITS.md: "`time` is in nanoseconds since epoch".
    README.md: "All exported data have synchronised timestamps", so one ``t0`` serves all devices.
  * ``seconds_elapsed`` is not used (README.md: "some entries could be negative ... due to
    buffering or caching").
  * A row repeating the previous row's ``time`` is dropped (the first is kept) and counted per file
    in ``meta["dropped_duplicates"]``, as every wearnav importer does (``timeseries.drop_duplicate_times``:
    more than 5 % duplicates, or ``time`` going backwards, is an error). README.md, "Removing
    Duplicated Entries": "erroneous sensors may report the same value twice with identical
    timestamps, likely due to caching".

Sign convention of accelerations (``s = -1`` flips, ``s = +1`` keeps)
  * Android is the Recording convention. COORDINATES.md: "When you place your phone flat on a table,
    the gravity vector points in `-z` on iOS and `+z` on Android", and "there is a negative sign
    difference for all three axes between iOS and Android" for acceleration.
  * ``s = -1`` for iOS exports made with "Standardise Units & Frames" off, ``s = +1`` otherwise.
    COORDINATES.md: "Toggling **Standardise Units & Frames** ... will eliminate this difference by
    automatically converting values logged on iOS to the Android convention".
  * Both facts come from ``Metadata.csv`` (required). ``platform``: README.md, "Accessing Recording
    Metadata": "platform: Either iOS or Android". ``standardisation`` (true / false) is not in the
    documentation; it is the column name real exports carry (header ``version,device name,
    recording epoch time,recording time,recording timezone,platform,appVersion,device id,sensors,
    sampleRateMs,standardisation,platform version``). An export without it predates the toggle
    (version 1.29) and is read as off (CROSSPLATFORM.md: "This is _turned off_ by default").
  * Apple Watch and AirPods get the same ``s`` as the iPhone. COORDINATES.md: "Acceleration data from
    the Apple Watch follows the same convention as the iPhone", "The coordinate system across the
    three pictured devices is always the same and consistent", and the toggle "will convert _all
    measurements from Apple Watch and AirPods_ to Android's convention". (A Wear OS watch on an
    Android export is assumed to report the Android convention: ``s = +1``; undocumented.)
  * Rotation rates are never flipped. COORDINATES.md: "For the rotation rate readings from the
    Gyroscope sensor, iOS and Android have consistent definitions." The device axes themselves are
    the same on both platforms ("the directions of the axes are the same across platforms").

Phone accelerometer (device ``phone``)
  * ``acc = s * TotalAcceleration`` when ``TotalAcceleration.csv`` exists, else
    ``acc = s * (Accelerometer + Gravity)``, all in m/s² as written. UNITS.md: Accelerometer "`x`, `y`
    and `z` in meters per second squared"; on Android "**Accelerometer.csv**: measures acceleration
    _without_ gravity" and "**TotalAcceleration.csv**: measures acceleration _with_ gravity
    included"; "On iOS, only **Accelerometer.csv** is logged. You may create acceleration with
    gravity by combining the Accelerometer and Gravity sensor readings"; Gravity "in meters per
    second squared". Accelerometer.csv without Gravity.csv or TotalAcceleration.csv is an error:
    there is no gravity to add back.
  * ``gyro = Gyroscope`` rad/s as written. UNITS.md: Gyroscope "in radians per second (rad/s)".
  * Gravity, Gyroscope and Orientation are interpolated onto the accelerometer's timestamps
    (``timeseries.interp_onto``: linear; quaternions sign-aligned, linear, renormalised). README.md: "they
    **do not necessarily align** due to varied sampling rates". Accelerometer samples outside
    another phone file's span, or inside one of its gaps longer than ``common.MAX_INTERP_GAP_S``, are
    dropped, never filled (count in ``meta["dropped_uncovered"]``).

Apple Watch (``WristMotion.csv`` → device ``watch``)
  * ``acc = s * u * (acceleration + gravity)`` with ``u = 9.80665`` when the toggle is off, ``u = 1``
    when on. UNITS.md, WristMotion: "`gravityX`, `gravityY` and `gravityZ`, in standard gravity (g),
    when "Standardise Units & Frames" is off (default). The unit is ms-2 when ... on" and the same
    sentence for `accelerationX/Y/Z`; ``acceleration`` is the user part (the file reports gravity
    separately, as CoreMotion's device motion does). 9.80665: UNITS.md "Assumes `g` to be 9.80665ms-2".
  * ``gyro = rotationRate`` rad/s. UNITS.md: "`rotationRateX`, ... in radians per second (rad/s)".

AirPods (``Headphone.csv`` → device ``earbuds``)
  * ``acc = s * (u * acceleration + gravity)``. UNITS.md, Headphone: "`accelerationX`, ... in standard
    gravity (g), when "Standardise Units & Frames" is off (default). The unit is ms-2 when ... on"
    and "`gravityX`, `gravityY` and `gravityZ`, in meters per second squared (ms-2); Assumes `g` to
    be 9.80665ms-2, regardless of whether "Standardise Units & Frames" is turned on or not".
  * ``gyro = rotationRate`` rad/s (UNITS.md: "in radians per second (rad/s)"). ``devicelocation``
    (left / right) goes to ``meta["earbud_side"]``.

Orientation (phone ``qw,qx,qy,qz``; watch and earbuds ``quaternionW/X/Y/Z``)
  * Read as (w, x, y, z) rotating device-frame vectors into a z-up reference frame (world←device).
    COORDINATES.md: orientation is "a Tait-Bryan Z-X'-Y'' (yaw → pitch → roll) intrinsic rotation
    sequence, meaning the device is first rotated around the z axis (yaw), then the rotated x axis
    (pitch), and finally the twice-rotated y axis (roll)", with "the `x-north-z-vertical` reference
    frame". Rotating the device by those angles is R = Rz·Rx·Ry, whose columns are the device axes
    in the reference frame, i.e. world←device. The yaw reference (north, magnetic or true) is kept
    as it is; the Recording only needs a gravity-aligned frame with a fixed yaw.
  * The docs do not say outright which way the quaternion maps, so every device's quaternions are
    checked against its own data: the accelerometer rotated to the world frame must average to
    about +z (within ``TILT_TOLERANCE_DEG``), and where the gyroscope saw enough rotation, the
    rotation between successive quaternions must agree with it (``MAX_GYRO_RESIDUAL``). If the
    quaternions pass only as their inverse, the inverse is used and ``meta["quat_inverted"]``
    lists the device; if neither passes, the import fails (the usual cause: a wrong ``platform`` /
    ``standardisation`` in Metadata.csv, i.e. a flipped accelerometer sign).
  * ``yaw``, ``pitch`` and ``roll`` are not read: their signs differ between platforms
    (COORDINATES.md, "Differences Between iOS and Android" items 2 and 3).

Location (``Location.csv`` → ``Recording.fixes``)
  * ``latitude`` / ``longitude`` (UNITS.md: "in degrees") are projected to local east/north metres
    about the first fix with :func:`latlon_to_local`; the origin is kept in
    ``meta["origin_lat"]`` / ``meta["origin_lon"]``. Fixes are 2-D (altitude is not used).
  * ``accuracy = horizontalAccuracy`` m, NaN where negative or absent. UNITS.md: "`horizontalAccuracy`,
    in meters as the radius of uncertainty. ... Negative values indicate it is invalid."

Sensor Logger records no ground truth: ``truth`` is None and ``labels`` is empty.
"""

from __future__ import annotations

import tempfile
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from wearnav.errors import FormatError, MissingFileError, ValidationError, WearnavError
from wearnav.importers.common import (
    MAX_INTERP_GAP_S,
    check_finite,
    check_latlon,
    check_source,
    check_unix_time,
    find_file,
    latlon_to_local,
    read_csv,
    strip_compression,
)
from wearnav.recording import STANDARD_GRAVITY as G  # UNITS.md: "Assumes `g` to be 9.80665ms-2"
from wearnav.recording import DeviceStream, Fixes, Recording
from wearnav.rotations import NotUnitQuaternion, from_wxyz, normalize_wxyz, to_wxyz
from wearnav.timeseries import drop_duplicate_times, interp_onto

XYZ = ["x", "y", "z"]
MOTION_FILES = ("Accelerometer.csv", "TotalAcceleration.csv", "WristMotion.csv", "Headphone.csv")
KNOWN_FILES = ("Metadata.csv", "Gravity.csv", "Gyroscope.csv", "Orientation.csv", "Location.csv",
               *MOTION_FILES)
SOURCE = "sensorlogger"
# The world-frame mean of a device's specific force must lie this close to +z (gravity).
TILT_TOLERANCE_DEG = 20.0
# Tolerance on the mean world-vertical specific force (real phone data: 9.4–10.1 m/s²).
MAX_VERTICAL_ERROR = 1.5
# The gyroscope check on quaternions runs only after this much integrated rotation (rad).
MIN_ROTATION_FOR_CHECK = 2.0
# Largest relative mismatch between quaternion increments and gyro increments that still passes.
MAX_GYRO_RESIDUAL = 0.5


# ---- discovery ------------------------------------------------------------------------------

def _has(folder: Path, name: str) -> bool:
    try:
        find_file(folder / name)
        return True
    except MissingFileError:
        return False


def is_export(folder: Path) -> bool:
    """Whether ``folder`` directly holds a Sensor Logger export (Metadata or a motion file)."""
    return folder.is_dir() and any(_has(folder, n) for n in ("Metadata.csv", *MOTION_FILES))


def read(src: Path, limit: int | None = None) -> Iterator[Recording]:
    """Recordings from one export folder, one export zip, or a folder of several of either."""
    src, limit = check_source(src, limit, expect="a Sensor Logger export folder or .zip")
    if limit == 0:
        return
    count = 0
    for kind, path in _exports(src):
        recs = [read_export(path)] if kind == "dir" else _read_zip(path)
        for rec in recs:
            if limit is not None and count >= limit:
                return
            yield rec
            count += 1


def _exports(src: Path) -> Iterator[tuple[str, Path]]:
    if src.is_file():
        if src.suffix.lower() != ".zip":
            raise FormatError("not a Sensor Logger export: expected an export folder or a .zip", src)
        yield "zip", src
        return
    if is_export(src):
        yield "dir", src
        return
    found = False
    for child in sorted(src.iterdir()):
        if child.is_dir() and is_export(child):
            found = True
            yield "dir", child
        elif child.is_file() and child.suffix.lower() == ".zip":
            found = True
            yield "zip", child
    if not found:
        raise FormatError(
            "no Sensor Logger export here: expected Metadata.csv and Accelerometer.csv / "
            "WristMotion.csv / Headphone.csv in this folder, or export sub-folders or .zip files", src)


def _read_zip(zpath: Path) -> Iterator[Recording]:
    """Extract the known CSVs of each export inside ``zpath`` and read them.

    Only base names are written (no member path is trusted), and errors name the zip member.
    """
    try:
        zf = zipfile.ZipFile(zpath)
    except (zipfile.BadZipFile, OSError) as exc:
        raise FormatError(f"not a readable zip archive ({exc})", zpath) from None
    with zf, tempfile.TemporaryDirectory(prefix="wearnav-sl-") as tmp:
        groups: dict[str, list[zipfile.ZipInfo]] = {}
        for info in zf.infolist():
            p = PurePosixPath(info.filename)
            if info.is_dir() or "__MACOSX" in p.parts or p.name.startswith("._"):
                continue
            if strip_compression(Path(p.name)) in KNOWN_FILES:
                groups.setdefault(str(p.parent), []).append(info)
        groups = {d: m for d, m in groups.items()
                  if any(strip_compression(Path(PurePosixPath(i.filename).name)) in
                         ("Metadata.csv", *MOTION_FILES) for i in m)}
        if not groups:
            raise FormatError("no Sensor Logger export inside (no Metadata.csv / Accelerometer.csv / "
                              "WristMotion.csv / Headphone.csv)", zpath)
        for k, (member_dir, infos) in enumerate(sorted(groups.items())):
            dest = Path(tmp) / str(k)
            dest.mkdir()
            for info in infos:
                try:
                    data = zf.read(info)
                except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
                    raise FormatError(f"truncated or corrupt member {info.filename!r} ({exc})",
                                      zpath) from None
                (dest / PurePosixPath(info.filename).name).write_bytes(data)
            shown = f"{zpath}!{member_dir}/" if member_dir not in (".", "") else f"{zpath}!"
            name = zpath.stem if len(groups) == 1 else f"{zpath.stem}_{PurePosixPath(member_dir).name}"
            file = shown.replace(str(zpath), zpath.name).rstrip("!/")
            yield read_export(dest, name=name, shown_as=shown, file=file)


# ---- one export -----------------------------------------------------------------------------

@dataclass
class _Table:
    path: Path
    t_ns: np.ndarray          # int64 ns since epoch, strictly increasing
    df: pd.DataFrame
    duplicates: int

    def values(self, cols: list[str]) -> np.ndarray:
        return self.df[cols].to_numpy(np.float64)


def _load(folder: Path, fname: str, cols: list[str], optional_cols: tuple[str, ...] = ()) -> _Table | None:
    """Read one CSV (None if absent): required columns numeric and finite, time increasing."""
    try:
        path = find_file(folder / fname)
    except MissingFileError:
        return None
    df = read_csv(path, required=["time", *cols])
    for c in ["time", *cols, *[c for c in optional_cols if c in df.columns]]:
        if not pd.api.types.is_numeric_dtype(df[c]):
            df[c] = pd.to_numeric(df[c], errors="coerce")
    vals = df[["time", *cols]].to_numpy(np.float64)
    bad = ~np.isfinite(vals).all(axis=1)
    if bad.any() and np.flatnonzero(bad)[0] == len(df) - 1:
        raise FormatError(f"last row (line {len(df) + 1}) is incomplete: truncated file?", path)
    check_finite(vals, f"columns {['time', *cols]}", path)
    if pd.api.types.is_integer_dtype(df["time"]):
        t_ns = df["time"].to_numpy(np.int64)
    else:  # written as float: keep what precision there is
        t_ns = np.round(df["time"].to_numpy(np.float64)).astype(np.int64)
    check_unix_time(t_ns / 1e9, "time", path)
    keep, n_dup = drop_duplicate_times(t_ns, "time", path)
    if n_dup:
        df, t_ns = df.iloc[keep].reset_index(drop=True), t_ns[keep]
    return _Table(path, t_ns, df, n_dup)


def _metadata(folder: Path) -> tuple[str, bool, dict]:
    try:
        path = find_file(folder / "Metadata.csv")
    except MissingFileError:
        raise FormatError("Metadata.csv is missing; its 'platform' decides the acceleration sign "
                          "(iOS and Android differ, COORDINATES.md)", folder) from None
    df = read_csv(path, required=["platform"], dtype=str, keep_default_na=False)
    row = df.iloc[0]
    platform = row["platform"].strip().lower()
    if platform not in ("ios", "android"):
        raise FormatError(f"platform {row['platform']!r} is neither iOS nor Android", path)
    flag = str(row.get("standardisation", "")).strip().lower()
    if flag not in ("", "true", "false"):
        raise FormatError(f"standardisation {flag!r} is neither true nor false", path)
    info = {k: str(row[c]) for k, c in (("device_name", "device name"), ("app_version", "appVersion"),
                                        ("platform_version", "platform version"),
                                        ("recording_time", "recording time")) if c in df.columns}
    return platform, flag == "true", info


def read_export(folder: str | Path, name: str | None = None, shown_as: str | None = None,
                file: str | None = None) -> Recording:
    """Read one export folder.

    ``shown_as`` replaces the folder in error messages and ``file`` names it in
    ``meta["file"]`` (both for exports extracted from a zip)."""
    folder = Path(folder)
    try:
        return _read_export(folder, name or folder.name, file or folder.name)
    except WearnavError as exc:
        if shown_as and exc.source and exc.source.startswith(str(folder)):
            exc.source = shown_as + exc.source[len(str(folder)):].lstrip("/\\")
            exc.args = (str(exc),)
        raise


def _read_export(folder: Path, name: str, file: str) -> Recording:
    platform, standardised, info = _metadata(folder)
    s = -1.0 if (platform == "ios" and not standardised) else 1.0
    u = 1.0 if standardised else G
    units = (f"acceleration read as {'m/s²' if standardised else 'g'} because Metadata.csv says "
             f"standardisation is {'on' if standardised else 'off'}")

    t_acc = _load(folder, "TotalAcceleration.csv", XYZ)
    acc_lin = _load(folder, "Accelerometer.csv", XYZ) if t_acc is None else None
    grav = _load(folder, "Gravity.csv", XYZ) if t_acc is None else None
    gyro = _load(folder, "Gyroscope.csv", XYZ)
    ori = _load(folder, "Orientation.csv", ["qw", "qx", "qy", "qz"])
    wrist = _load(folder, "WristMotion.csv", [*_xyz("rotationRate"), *_xyz("gravity"),
                                              *_xyz("acceleration"), *_quat_cols()])
    head = _load(folder, "Headphone.csv", [*_xyz("rotationRate"), *_xyz("gravity"),
                                           *_xyz("acceleration"), *_quat_cols()])
    loc = _load(folder, "Location.csv", ["latitude", "longitude"], optional_cols=("horizontalAccuracy",))
    if acc_lin is not None and grav is None:
        raise FormatError("holds acceleration without gravity (UNITS.md) and neither Gravity.csv nor "
                          "TotalAcceleration.csv is there to add it back", acc_lin.path)
    tables = [x for x in (t_acc, acc_lin, grav, gyro, ori, wrist, head, loc) if x is not None]
    if not any(x is not None for x in (t_acc, acc_lin, wrist, head)):
        raise FormatError("no motion file (Accelerometer.csv, TotalAcceleration.csv, WristMotion.csv "
                          "or Headphone.csv)", folder)
    t0 = min(int(x.t_ns[0]) for x in tables)

    def sec(t_ns: np.ndarray) -> np.ndarray:
        return (t_ns - t0).astype(np.float64) * 1e-9

    inverted: list[str] = []
    uncovered: dict[str, int] = {}
    devices: dict[str, DeviceStream] = {}

    base = t_acc if t_acc is not None else acc_lin
    if base is not None:
        t = sec(base.t_ns)
        acc = base.values(XYZ)
        keep = np.ones(len(t), bool)
        w = q = None
        if grav is not None:
            g, ok = interp_onto(t, sec(grav.t_ns), grav.values(XYZ), max_gap=MAX_INTERP_GAP_S)
            acc, keep = acc + g, keep & ok
        if gyro is not None:
            w, ok = interp_onto(t, sec(gyro.t_ns), gyro.values(XYZ), max_gap=MAX_INTERP_GAP_S)
            keep &= ok
        if ori is not None:
            q, ok = interp_onto(t, sec(ori.t_ns), _unit_quats(ori.values(["qw", "qx", "qy", "qz"]), ori.path),
                                max_gap=MAX_INTERP_GAP_S, quaternion=True)
            keep &= ok
        if keep.sum() < 2:
            others = ", ".join(x.path.name for x in (grav, gyro, ori) if x is not None)
            raise FormatError(f"{base.path.name} does not overlap in time with {others}", folder)
        if not keep.all():
            uncovered["phone"] = int((~keep).sum())
            t, acc = t[keep], acc[keep]
            w = None if w is None else w[keep]
            q = None if q is None else q[keep]
        devices["phone"] = _stream("phone", t, s * acc, w, q, base.path, ori.path if ori else None,
                                   "phone acceleration is m/s² in every export (UNITS.md)", inverted)

    if wrist is not None:
        acc = s * u * (wrist.values(_xyz("acceleration")) + wrist.values(_xyz("gravity")))
        devices["watch"] = _stream("watch", sec(wrist.t_ns), acc, wrist.values(_xyz("rotationRate")),
                                   _unit_quats(wrist.values(_quat_cols()), wrist.path), wrist.path,
                                   wrist.path, units, inverted)
    if head is not None:
        acc = s * (u * head.values(_xyz("acceleration")) + head.values(_xyz("gravity")))
        devices["earbuds"] = _stream("earbuds", sec(head.t_ns), acc, head.values(_xyz("rotationRate")),
                                     _unit_quats(head.values(_quat_cols()), head.path), head.path,
                                     head.path, units, inverted)

    meta = {
        "source": SOURCE,
        "dataset": "Sensor Logger export",
        "subject": "", "mode": "", "placement": "",
        "platform": platform,
        "standardisation": standardised,
        **info,
        "t0_unix_ns": t0,
        "quat_frame": "Sensor Logger orientation, world z up; phone yaw 0 with x north (iOS true, "
                      "Android magnetic north); watch / earbuds yaw reference not documented",
        "quat_inverted": inverted,
        "dropped_duplicates": {x.path.name: x.duplicates for x in tables if x.duplicates},
        "dropped_uncovered": uncovered,
        "file": file,
    }
    if head is not None and "devicelocation" in head.df.columns:
        sides = head.df["devicelocation"].dropna().astype(str)
        if len(sides):
            meta["earbud_side"] = str(sides.mode().iloc[0])
    fixes = None
    if loc is not None:
        fixes, origin = _fixes(loc, sec(loc.t_ns))
        meta.update(origin)
    return Recording(name=name, devices=devices, fixes=fixes, meta=meta)


def _xyz(prefix: str) -> list[str]:
    return [f"{prefix}{a}" for a in "XYZ"]


def _quat_cols() -> list[str]:
    return [f"quaternion{a}" for a in "WXYZ"]


def _unit_quats(q: np.ndarray, path: Path) -> np.ndarray:
    try:
        return normalize_wxyz(q)
    except NotUnitQuaternion as exc:
        raise FormatError(f"quaternion at line {exc.row + 2} has norm {exc.norm:.3g}, not a unit "
                          "quaternion", path) from None


def _stream(dev: str, t, acc, gyro, quat, path: Path, qpath: Path | None, units: str,
            inverted: list[str]) -> DeviceStream:
    try:
        stream = DeviceStream(t=t, acc=acc, gyro=gyro, quat=None)
    except ValidationError as exc:
        raise FormatError(f"device {dev!r}: {exc.reason}; {units}", path) from None
    if quat is not None:
        quat, convention = _check_orientation(quat, acc, gyro, t, qpath)
        if convention != "world<-device":
            inverted.append(dev)
        stream.quat = quat
        stream.validate()
    return stream


def _check_orientation(q_wxyz: np.ndarray, acc: np.ndarray, gyro: np.ndarray | None,
                       t: np.ndarray, path: Path) -> tuple[np.ndarray, str]:
    """Pick the quaternion direction the data agrees with (see module docstring), or fail.

    A direction passes when the world-frame mean of the specific force lies within
    TILT_TOLERANCE_DEG of +z and, where the gyro saw enough rotation, the quaternions' rotation
    increments match the gyro's (relative residual <= MAX_GYRO_RESIDUAL). When both directions
    pass (a device that stays nearly upright), the one with the smaller gyro residual wins,
    the documented world←device reading on a tie.
    """
    rot = from_wxyz(q_wxyz)
    found = []
    for label, r in (("world<-device", rot), ("device<-world (inverted on import)", rot.inv())):
        mean_world = r.apply(acc).mean(axis=0)
        tilt = float(np.degrees(np.arccos(np.clip(mean_world[2] / np.linalg.norm(mean_world), -1, 1))))
        res = _gyro_residual(r, gyro, t)
        ok = tilt <= TILT_TOLERANCE_DEG and (res is None or res <= MAX_GYRO_RESIDUAL)
        found.append((ok, res if res is not None else 0.0, label, r, tilt, res))
    passing = [f for f in found if f[0]]
    if passing:
        _, _, label, r, _, _ = min(passing, key=lambda f: f[1])  # stable: world<-device on a tie
        # Over a walk the mean vertical specific force is g; gravity counted twice (an
        # acceleration column that already holds it) or not at all shows up here even when the
        # median |acc| looks plausible.
        vertical = float(r.apply(acc)[:, 2].mean())
        if abs(vertical - G) > MAX_VERTICAL_ERROR:
            raise FormatError(
                f"mean vertical specific force in the world frame is {vertical:.1f} m/s², expected "
                f"{G:.1f} (gravity counted twice or missing?)", path)
        return to_wxyz(r), label
    (_, _, _, _, tilt_a, res_a), (_, _, _, _, tilt_b, res_b) = found
    gyro_note = "" if res_a is None else f", gyro residual {res_a:.2f} ({res_b:.2f} inverse)"
    raise FormatError(
        f"orientation does not fit the accelerometer: gravity rotated to the world frame is "
        f"{tilt_a:.0f}° from up ({tilt_b:.0f}° with the inverse rotation){gyro_note}; is "
        f"Metadata.csv's platform / standardisation right?", path)


def _gyro_residual(rot: Rotation, gyro: np.ndarray | None, t: np.ndarray) -> float | None:
    """Σ|Δθ_quat − Δθ_gyro|² / Σ|Δθ_gyro|² over successive samples (body-frame increments).

    Near 0 when the quaternions are world←device and agree with the gyro; None when there is
    no gyro or too little rotation to tell.
    """
    if gyro is None or len(t) < 3:
        return None
    dt = np.diff(t)
    step = dt <= 2 * np.median(dt)  # across a gap the two increments need not match
    inc = (rot[:-1][step].inv() * rot[1:][step]).as_rotvec()
    w = 0.5 * (gyro[:-1] + gyro[1:])[step] * dt[step, None]
    if np.linalg.norm(w, axis=1).sum() < MIN_ROTATION_FOR_CHECK:
        return None
    return float(np.sum((inc - w) ** 2) / np.sum(w * w))


def _fixes(loc: _Table, t: np.ndarray) -> tuple[Fixes, dict]:
    lat, lon = loc.df["latitude"].to_numpy(np.float64), loc.df["longitude"].to_numpy(np.float64)
    check_latlon(lat, lon, "Location", loc.path)
    if "horizontalAccuracy" in loc.df.columns:
        accuracy = loc.df["horizontalAccuracy"].to_numpy(np.float64)
        accuracy = np.where(accuracy >= 0, accuracy, np.nan)  # negative = invalid (UNITS.md)
    else:
        accuracy = np.full(len(t), np.nan)
    pos = latlon_to_local(lat, lon)
    try:
        fixes = Fixes(t=t, pos=pos, accuracy=accuracy)
    except ValidationError as exc:
        raise FormatError(exc.reason, loc.path) from None
    return fixes, {"origin_lat": float(lat[0]), "origin_lon": float(lon[0])}


__all__ = ["read", "read_export", "is_export"]
