"""Helpers every importer shares: transparent .gz/.xz reading, column checks (lat/lon → metres is
:mod:`wearnav.core.geo`)."""

from __future__ import annotations

import gzip
import io
import lzma
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav.core.fileio import require_regular_file
from wearnav.core.rotations import NotUnitQuaternion, from_android_rotation_vector, normalize_wxyz
from wearnav.errors import ConfigError, FormatError, MissingFileError

COMPRESSED_SUFFIXES = (".gz", ".xz")


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
    path = require_regular_file(find_file(path))
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


def read_csv(path: str | Path, required: Iterable[str] = (), empty_ok: bool = False, **kwargs) -> pd.DataFrame:
    """pandas.read_csv over plain/.gz/.xz with a one-line error for empty files or missing columns;
    ``empty_ok``: a header without rows is an empty table (an optional sensor that recorded nothing),
    not an error."""
    path = find_file(path)
    try:
        with open_text(path) as f:
            df = pd.read_csv(f, **kwargs)
    except pd.errors.EmptyDataError:
        raise FormatError("empty file", path) from None
    except (pd.errors.ParserError, ValueError, OSError, EOFError, lzma.LZMAError) as exc:
        raise FormatError(f"cannot parse as CSV ({exc})", path) from None
    require_columns(df, required, path)
    if df.empty and not empty_ok:
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


# ---- the start of every importer's read() ------------------------------------------------------


def check_limit(limit) -> int | None:
    """``limit`` (at most this many recordings) if it is None or a non-negative integer."""
    if limit is None:
        return None
    if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 0:
        raise ConfigError(f"limit must be a non-negative integer or None, got {limit!r}")
    return int(limit)


def check_source(
    src: str | Path, limit=None, *, expect: str, file: bool = True, folder: bool = True
) -> tuple[Path, int | None]:
    """The checks every importer's ``read()`` starts with; returns ``(src, limit)``.

    ``src`` must exist (a file may also be found as ``.gz`` / ``.xz``) and be a folder or a
    regular file as the format allows (named pipes and devices are refused, never opened);
    ``expect`` says what the format wants, for the error message. ``limit`` must be None or a
    non-negative integer.
    """
    limit = check_limit(limit)
    src = Path(src)
    if not src.exists():
        try:
            src = find_file(src) if file else src
        except MissingFileError:
            pass
        if not src.exists():
            raise MissingFileError("no such file or folder", src)
    if src.is_dir():
        if not folder:
            raise FormatError(f"expected {expect}, got a folder", src)
    else:
        require_regular_file(src)
        if not file:
            raise FormatError(f"expected {expect}, got a file", src)
    return src, limit


def check_latlon(lat: np.ndarray, lon: np.ndarray, what: str, path: str | Path) -> None:
    """Refuse latitudes outside ±90° and longitudes outside ±180° (a wrong column, a sentinel, a
    corrupt value), naming the first bad row."""
    lat, lon = np.asarray(lat, dtype=np.float64), np.asarray(lon, dtype=np.float64)
    bad = ~((np.abs(lat) <= 90) & (np.abs(lon) <= 180))
    if np.any(bad):
        i = int(np.argmax(bad))
        raise FormatError(
            f"{what}: latitude/longitude ({lat[i]:g}, {lon[i]:g}) out of range (first at row {i} of that type)", path
        )


# Unix times of real recordings: after 2000-01-01 and before 2100-01-01. A timestamp outside
# (a corrupt value, or another clock or unit) would shift or discard every other sample.
UNIX_TIME_RANGE_S = (946684800.0, 4102444800.0)


def check_unix_time(t_s: np.ndarray, what: str, path: str | Path) -> None:
    """Refuse Unix timestamps (given in seconds) outside :data:`UNIX_TIME_RANGE_S`."""
    t_s = np.asarray(t_s, dtype=np.float64)
    lo, hi = UNIX_TIME_RANGE_S
    bad = ~((t_s >= lo) & (t_s <= hi))
    if np.any(bad):
        i = int(np.argmax(bad))
        raise FormatError(
            f"{what}: timestamp {t_s[i]:.6g} s at row {i} of that type is not a Unix time "
            "between 2000 and 2100 (corrupt value or wrong unit?)",
            path,
        )


# The importers' gap rule when they merge a phone's gyroscope / orientation onto its accelerometer
# timestamps (``timeseries.interp_onto(..., max_gap=MAX_INTERP_GAP_S)``): a fixed time, not a
# number of periods, because the streams of one phone differ in rate (50–200 Hz) and a hole
# longer than a quarter of a step is lost samples; interpolating across it would invent data.
MAX_INTERP_GAP_S = 0.25


# ---- Android sensor logs (ilc2, ipin2023) ------------------------------------------------------


def quat_from_rotation_vector(v: np.ndarray, path: str | Path, what: str) -> np.ndarray:
    """Android rotation-vector values (N, 3) x, y, z or (N, ≥4) x, y, z, w → unit (w, x, y, z)
    (:func:`wearnav.core.rotations.from_android_rotation_vector`), refusing rows that are not one."""
    try:
        return normalize_wxyz(from_android_rotation_vector(v))
    except NotUnitQuaternion as exc:
        raise FormatError(f"{what}: row {exc.row} is not a rotation vector (|q| = {exc.norm:.3f})", path) from None
