"""Sensor Logger (iOS / Android app) exports → one multi-device Recording per export.

An export is a folder (or a ``.zip`` of one) holding one CSV per sensor. ``src`` may be one
export folder, one zip, or a folder of several export folders / zips. The files read are::

    Metadata.csv                          platform (ios | watchos | android), standardisation (true | false)
    Accelerometer.csv, Gravity.csv        phone, time,seconds_elapsed,z,y,x
    TotalAcceleration.csv                 phone (Android only), same columns
    Gyroscope.csv                         phone, same columns
    Orientation.csv                       phone, time,seconds_elapsed,qz,qy,qx,qw,roll,pitch,yaw
    WristMotion.csv                       Apple Watch → device "watch"
    Headphone.csv                         AirPods → device "earbuds"
    Location.csv                          phone location fixes → Recording.fixes (a header alone: none)
    WiFi.csv                              Wi-Fi scans (Android) → Recording.wifi (sensorlogger_radio)
    Barometer.csv                         pressure (hPa, UNITS.md) → Recording.pressure: the floor

Columns are found by name, never by position. Everything else in an export (Magnetometer,
Annotation, Activity, WatchLocation, Bluetooth, ...) is ignored.

Unit and frame conversions, each with the line of the Sensor Logger documentation it rests on
(``UNITS.md`` / ``COORDINATES.md`` of tszheichoi/awesome-sensor-logger at b10f5c5, copied to
``shared/data/sensor_logger_format``; ``README.md`` and ``CROSSPLATFORM.md`` of the same repository
where noted). "The Recording convention" is specific force including gravity, m/s², device frame,
reading about +9.81 on z for a device lying screen-up on a table.

Time
  * ``t = (time - t0) * 1e-9`` s, in int64 arithmetic, with ``t0`` the earliest ``time`` of any
    file read, stale location fixes excluded (kept in ``meta["t0_unix_ns"]``). UNITS.md: "`time` is in nanoseconds since epoch".
    README.md: "All exported data have synchronised timestamps", so one ``t0`` serves all devices.
  * ``seconds_elapsed`` is not used (README.md: "some entries could be negative ... due to
    buffering or caching").
  * A row repeating the previous row's ``time`` is dropped (the first is kept) and counted per file
    in ``meta["dropped_duplicates"]``, as every wearnav importer does (``timeseries.drop_duplicate_times``:
    more than 5 % duplicates, or ``time`` going backwards, is an error). README.md, "Removing
    Duplicated Entries": "erroneous sensors may report the same value twice with identical
    timestamps, likely due to caching".


Units, signs and devices per sensor: :mod:`wearnav.importers.sensorlogger_map` (shared with the live
receiver and the export writer); the tables → Recording step (phone clock, orientation checks,
fixes, gaps): :mod:`wearnav.importers.sensorlogger_build`.

Sensor Logger records no ground truth: ``truth`` is None and ``labels`` is empty.
"""

from __future__ import annotations

import dataclasses
import tempfile
import zipfile
from collections.abc import Iterator
from pathlib import Path, PurePosixPath

import numpy as np
import pandas as pd

from wearnav.core.timeseries import drop_duplicate_times
from wearnav.errors import ConfigError, FormatError, MissingFileError, ValidationError, WearnavError
from wearnav.importers.common import (
    check_finite,
    check_source,
    check_unix_time,
    find_file,
    read_csv,
    strip_compression,
)
from wearnav.importers.sensorlogger_build import Unusable, build_recording
from wearnav.importers.sensorlogger_map import (
    KNOWN_FILES,
    MOTION_FILES,
    PLATFORMS,
    SENSORS,
    Table,
    acceleration_convention,
)
from wearnav.importers.sensorlogger_radio import WIFI_FILE, read_wifi
from wearnav.recording import Pressure, Recording

BAROMETER_FILE = "Barometer.csv"

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


def read(src: Path, limit: int | None = None, platform: str | None = None) -> Iterator[Recording]:
    """Recordings from one export folder, one export zip, or a folder of several of either.

    ``platform`` (ios | watchos | android) stands in for Metadata.csv's, for exports that lack
    that file (see :func:`_metadata`)."""
    src, limit = check_source(src, limit, expect="a Sensor Logger export folder or .zip")
    if platform is not None and platform.strip().lower() not in PLATFORMS:
        raise ConfigError(f"platform {platform!r} is not one of {', '.join(PLATFORMS)}")
    if limit == 0:
        return
    count = 0
    for kind, path in _exports(src):
        recs = [read_export(path, platform=platform)] if kind == "dir" else _read_zip(path, platform)
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
            "WristMotion.csv / Headphone.csv in this folder, or export sub-folders or .zip files",
            src,
        )


def _read_zip(zpath: Path, platform: str | None = None) -> Iterator[Recording]:
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
            if strip_compression(Path(p.name)) in (*KNOWN_FILES, WIFI_FILE, BAROMETER_FILE):
                groups.setdefault(str(p.parent), []).append(info)
        groups = {
            d: m
            for d, m in groups.items()
            if any(
                strip_compression(Path(PurePosixPath(i.filename).name)) in ("Metadata.csv", *MOTION_FILES) for i in m
            )
        }
        if not groups:
            raise FormatError(
                "no Sensor Logger export inside (no Metadata.csv / Accelerometer.csv / "
                "WristMotion.csv / Headphone.csv)",
                zpath,
            )
        for k, (member_dir, infos) in enumerate(sorted(groups.items())):
            dest = Path(tmp) / str(k)
            dest.mkdir()
            for info in infos:
                try:
                    data = zf.read(info)
                except (zipfile.BadZipFile, EOFError, OSError, ValueError) as exc:
                    raise FormatError(f"truncated or corrupt member {info.filename!r} ({exc})", zpath) from None
                (dest / PurePosixPath(info.filename).name).write_bytes(data)
            shown = f"{zpath}!{member_dir}/" if member_dir not in (".", "") else f"{zpath}!"
            name = zpath.stem if len(groups) == 1 else f"{zpath.stem}_{PurePosixPath(member_dir).name}"
            file = shown.replace(str(zpath), zpath.name).rstrip("!/")
            yield read_export(dest, name=name, shown_as=shown, file=file, platform=platform)


# ---- one export -----------------------------------------------------------------------------


def _load(
    folder: Path, fname: str, cols: list[str], optional_cols: tuple[str, ...] = (), empty_ok: bool = False
) -> Table | None:
    """Read one CSV (None if absent, or where ``empty_ok`` a header without rows: a side sensor that
    recorded nothing, as Location.csv indoors): required columns numeric and finite, time increasing."""
    try:
        path = find_file(folder / fname)
    except MissingFileError:
        return None
    df = read_csv(path, required=["time", *cols], empty_ok=empty_ok)
    if df.empty:
        return None
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
    return Table(path, t_ns, df, n_dup)


def _metadata(folder: Path, given: str | None = None) -> tuple[str, bool, dict]:
    """Platform, standardisation flag and descriptive fields. ``given`` (the ``--platform``
    option) replaces Metadata.csv's platform; without Metadata.csv it is required, and
    standardisation is then read as off (the app's default, CROSSPLATFORM.md)."""
    given = given.strip().lower() if given else None
    try:
        path = find_file(folder / "Metadata.csv")
    except MissingFileError:
        if given is None:
            raise FormatError(
                "Metadata.csv is missing from this export: its 'platform' (iOS, watchOS or Android) "
                "decides the acceleration sign; copy Metadata.csv from the original export, or say "
                "which phone recorded it (wearnav import sensorlogger --platform ios|watchos|android)",
                folder,
            ) from None
        return given, False, {"platform_from": "--platform (no Metadata.csv; standardisation read as off)"}
    df = read_csv(path, required=["platform"], dtype=str, keep_default_na=False)
    row = df.iloc[0]
    platform = given or row["platform"].strip().lower()
    if platform not in PLATFORMS:
        raise FormatError(
            f"platform {row['platform']!r} is none of iOS, watchOS, Android (--platform overrides it)", path
        )
    flag = str(row.get("standardisation", "")).strip().lower()
    if flag not in ("", "true", "false"):
        raise FormatError(f"standardisation {flag!r} is neither true nor false", path)
    info = {
        k: str(row[c])
        for k, c in (
            ("device_name", "device name"),
            ("app_version", "appVersion"),
            ("platform_version", "platform version"),
            ("recording_time", "recording time"),
            ("layout_version", "version"),
        )
        if c in df.columns
    }
    if given:
        info["platform_from"] = f"--platform (Metadata.csv says {row['platform']!r})"
    return platform, flag == "true", info


def read_export(
    folder: str | Path,
    name: str | None = None,
    shown_as: str | None = None,
    file: str | None = None,
    platform: str | None = None,
) -> Recording:
    """Read one export folder.

    ``shown_as`` replaces the folder in error messages and ``file`` names it in
    ``meta["file"]`` (both for exports extracted from a zip)."""
    folder = Path(folder)
    try:
        return _read_export(folder, name or folder.name, file or folder.name, platform)
    except WearnavError as exc:
        if shown_as and exc.source and exc.source.startswith(str(folder)):
            exc.source = shown_as + exc.source[len(str(folder)) :].lstrip("/\\")
            exc.args = (str(exc),)
        raise


def export_tables(folder: Path, platform: str | None = None) -> tuple[str, bool, dict, dict[str, Table]]:
    """Platform, standardisation, Metadata.csv's descriptive fields and every sensor's table (by
    file name) of one export folder: what :func:`read_export` builds a Recording from, and what
    ``wearnav replay`` sends."""
    platform, standardised, info = _metadata(folder, platform)
    tables = {}
    for fname, sensor in SENSORS.items():
        # the location fixes may be absent (indoors, no fix at all): their file's header alone reads as none
        table = _load(folder, fname, list(sensor.cols), optional_cols=sensor.optional, empty_ok=sensor.device is None)
        if table is not None:
            tables[fname] = table
    return platform, standardised, info, tables


def _read_export(folder: Path, name: str, file: str, given_platform: str | None = None) -> Recording:
    platform, standardised, info, tables = export_tables(folder, given_platform)
    rec = build_recording(tables, platform, standardised, folder, name, file, info)
    t0 = int(rec.meta["t0_unix_ns"])
    wifi, pressure = read_wifi(folder, t0, rec.meta), _pressure(folder, t0, rec.meta)
    if wifi is None and pressure is None:
        return rec
    return dataclasses.replace(rec, wifi=wifi, pressure=pressure)


def _pressure(folder: Path, t0_ns: int, meta: dict) -> Pressure | None:
    """``Barometer.csv`` on the recording's clock (its rows as every sensor file's: a repeated time
    dropped and counted in ``meta["dropped_duplicates"]``, time going backwards refused); a pressure
    that is not one is refused naming the file. None without the file."""
    table = _load(folder, BAROMETER_FILE, ["pressure"], empty_ok=True)
    if table is None:
        return None
    if table.duplicates:
        meta.setdefault("dropped_duplicates", {})[BAROMETER_FILE] = table.duplicates
    try:
        return Pressure((table.t_ns - t0_ns).astype(np.float64) * 1e-9, table.column("pressure"))
    except ValidationError as exc:
        raise FormatError(str(exc), table.path) from None


__all__ = ["PLATFORMS", "Unusable", "acceleration_convention", "export_tables", "is_export", "read", "read_export"]
