"""Helpers every importer shares: transparent .gz/.xz reading, column checks, geodesy."""

from __future__ import annotations

import gzip
import io
import lzma
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav.errors import FormatError, MissingFileError
from wearnav.rotations import NotUnitQuaternion, from_android_rotation_vector, normalize_wxyz

COMPRESSED_SUFFIXES = (".gz", ".xz")
EARTH_RADIUS_M = 6378137.0  # WGS-84 equatorial radius


def find_file(path: str | Path) -> Path:
    """``path`` itself, or ``path.gz`` / ``path.xz`` if only a compressed copy exists."""
    path = Path(path)
    if path.exists():
        return path
    for suf in COMPRESSED_SUFFIXES:
        cand = path.with_name(path.name + suf)
        if cand.exists():
            return cand
    raise MissingFileError("no such file (also looked for .gz/.xz)", path)


def strip_compression(path: Path) -> str:
    """File name without a trailing .gz/.xz (``a.csv.gz`` -> ``a.csv``)."""
    name = path.name
    for suf in COMPRESSED_SUFFIXES:
        if name.endswith(suf):
            return name[: -len(suf)]
    return name


def open_text(path: str | Path) -> io.TextIOBase:
    """Open a plain, .gz or .xz text file for reading (UTF-8 with or without a byte-order mark,
    undecodable bytes replaced)."""
    path = find_file(path)
    try:
        if path.suffix == ".gz":
            return io.TextIOWrapper(gzip.open(path, "rb"), encoding="utf-8-sig", errors="replace")
        if path.suffix == ".xz":
            return io.TextIOWrapper(lzma.open(path, "rb"), encoding="utf-8-sig", errors="replace")
        return open(path, encoding="utf-8-sig", errors="replace")
    except OSError as exc:
        raise FormatError(f"cannot open ({exc})", path) from None


def read_text(path: str | Path) -> str:
    """Whole text of a plain/.gz/.xz file; truncated or corrupt archives raise FormatError."""
    path = find_file(path)
    try:
        with open_text(path) as f:
            return f.read()
    except (OSError, EOFError, lzma.LZMAError) as exc:
        raise FormatError(f"truncated or corrupt file ({exc})", path) from None


def read_csv(path: str | Path, required: Iterable[str] = (), **kwargs) -> pd.DataFrame:
    """pandas.read_csv over plain/.gz/.xz with a one-line error for empty files or missing columns."""
    path = find_file(path)
    try:
        with open_text(path) as f:
            df = pd.read_csv(f, **kwargs)
    except pd.errors.EmptyDataError:
        raise FormatError("empty file", path) from None
    except (pd.errors.ParserError, ValueError, OSError, EOFError, lzma.LZMAError) as exc:
        raise FormatError(f"cannot parse as CSV ({exc})", path) from None
    require_columns(df, required, path)
    if df.empty:
        raise FormatError("no data rows", path)
    return df


def require_columns(df: pd.DataFrame, required: Iterable[str], path: str | Path) -> None:
    missing = [c for c in required if c not in df.columns]
    if missing:
        raise FormatError(f"missing columns {missing} (has {list(df.columns)})", path)


def check_finite(arr: np.ndarray, what: str, path: str | Path) -> None:
    if not np.all(np.isfinite(arr)):
        bad = int(np.argmax(~np.isfinite(np.asarray(arr, dtype=float)).reshape(len(arr), -1).all(1)))
        raise FormatError(f"{what} has NaN or infinite values (first at row {bad})", path)


def latlon_to_local(lat: np.ndarray, lon: np.ndarray, lat0: float | None = None,
                    lon0: float | None = None) -> np.ndarray:
    """Project WGS-84 lat/lon (degrees) to local east/north metres around (lat0, lon0).

    Equirectangular projection about the origin (the first point by default): within 1 km of
    the origin its error stays under about 0.1 m, far below any phone fix's accuracy.
    """
    lat = np.asarray(lat, dtype=np.float64)
    lon = np.asarray(lon, dtype=np.float64)
    lat0 = float(lat[0]) if lat0 is None else lat0
    lon0 = float(lon[0]) if lon0 is None else lon0
    east = np.deg2rad(lon - lon0) * EARTH_RADIUS_M * np.cos(np.deg2rad(lat0))
    north = np.deg2rad(lat - lat0) * EARTH_RADIUS_M
    return np.stack([east, north], axis=1)


# The importers' gap rule when they merge a phone's gyroscope / orientation onto its accelerometer
# timestamps (``timeseries.interp_onto(..., max_gap=MAX_INTERP_GAP_S)``): a fixed time, not a
# number of periods, because the streams of one phone differ in rate (50–200 Hz) and a hole
# longer than a quarter of a step is lost samples; interpolating across it would invent data.
MAX_INTERP_GAP_S = 0.25


# ---- Android sensor logs (ilc2, ipin2023) ------------------------------------------------------

def quat_from_rotation_vector(v: np.ndarray, path: str | Path, what: str) -> np.ndarray:
    """Android rotation-vector values (N, 3) x, y, z or (N, ≥4) x, y, z, w → unit (w, x, y, z)
    (:func:`wearnav.rotations.from_android_rotation_vector`), refusing rows that are not one."""
    try:
        return normalize_wxyz(from_android_rotation_vector(v))
    except NotUnitQuaternion as exc:
        raise FormatError(f"{what}: row {exc.row} is not a rotation vector (|q| = {exc.norm:.3f})",
                          path) from None
