"""The checks every part of a :class:`~wearnav.recording.Recording` runs on construction: names and
text that HDF5 and a file name can hold, arrays of the right dtype, shape and range, increasing
times, positions on Earth. :mod:`wearnav.recording` and :mod:`wearnav.recording.radio` share them;
each raises :class:`~wearnav.errors.ValidationError` naming the field."""

from __future__ import annotations

import numpy as np

from wearnav.errors import ValidationError

# Positions are metres in a local frame about the recording's own origin: nothing on Earth is
# farther than half its circumference (~2e7 m), so a larger coordinate is a corrupt value.
POS_ABS_MAX = 2.0e7
# Longest recording / device name: it becomes a file name (``<name>.h5``, 255 bytes on most
# file systems) and an HDF5 link name.
MAX_NAME_BYTES = 200


def check_text(text, what: str) -> int:
    """Refuse text that HDF5 and CSV cannot store and give back: not a string, holding NUL, not
    UTF-8-encodable (lone surrogates). Returns its UTF-8 size in bytes."""
    if not isinstance(text, str):
        raise ValidationError(f"{what} {text!r} is not a string")
    if "\x00" in text:
        raise ValidationError(f"{what} {text!r} contains NUL")
    try:
        return len(text.encode("utf-8"))
    except UnicodeEncodeError:
        raise ValidationError(f"{what} {text!r} cannot be encoded as UTF-8") from None


def check_name(name, what: str) -> None:
    """Refuse a recording / device name that cannot round-trip through HDF5 and a file name:
    what :func:`check_text` refuses, empty, '.', '..', containing '/', too long."""
    size = check_text(name, what)
    if name in ("", ".", "..") or "/" in name:
        raise ValidationError(f"{what} {name!r} is empty, '.', '..' or contains '/'")
    if size > MAX_NAME_BYTES:
        raise ValidationError(f"{what} is {size} bytes long (at most {MAX_NAME_BYTES})")


def _as_array(x, dtype, name: str) -> np.ndarray:
    try:
        return np.ascontiguousarray(np.asarray(x, dtype=dtype))
    except (TypeError, ValueError) as exc:
        raise ValidationError(f"{name}: cannot be read as {np.dtype(dtype).name} ({exc})") from None


def _as_flags(x, name: str) -> np.ndarray:
    """Booleans, or numbers that are all 0 or 1, as a bool array (anything else is refused: NumPy
    would read 0.5, 2 or the text "no" as True)."""
    a = np.asarray(x)
    if a.dtype != bool:
        if a.dtype.kind not in "iuf" or not np.all((a == 0) | (a == 1)):
            raise ValidationError(
                f"{name}: not booleans (True/False or 0/1), got dtype {a.dtype.name}"
                + (
                    f" with value {a.flat[int(np.argmax(~((a == 0) | (a == 1))))].item()!r}"
                    if a.dtype.kind in "iuf" and a.size
                    else ""
                )
            )
    return np.ascontiguousarray(a, dtype=bool)


def _check_time(t: np.ndarray, name: str, repeats: bool = False) -> None:
    """1-D, finite, increasing times; ``repeats``: equal times allowed (readings of several sources
    at one instant, e.g. beacons), going backwards never."""
    if t.ndim != 1:
        raise ValidationError(f"{name}: time must be 1-D, got shape {t.shape}")
    if t.size == 0:
        raise ValidationError(f"{name}: is empty")
    if not np.all(np.isfinite(t)):
        raise ValidationError(f"{name}: time has non-finite values")
    dt = np.diff(t)
    if np.any(dt < 0) or (not repeats and np.any(dt == 0)):
        i = int(np.argmax(dt < 0)) if repeats else int(np.argmax(dt <= 0))
        what = "duplicated" if dt[i] == 0 else "unsorted"
        raise ValidationError(f"{name}: {what} timestamps at sample {i + 1} (t={t[i + 1]:.6f})")


def _check_range(a: np.ndarray | None, limit: float, unit: str, name: str) -> None:
    if a is None or a.size == 0:
        return
    over = np.abs(a) > limit
    if np.any(over):
        i = int(np.argmax(over.any(axis=1)))
        n_bad = int(over.any(axis=1).sum())
        raise ValidationError(
            f"{name}: {n_bad} of {len(a)} samples beyond ±{limit:.4g} {unit} per axis (first at "
            f"sample {i}: {float(a[i][over[i]][0]):.4g}), the full-scale range of a consumer IMU: "
            "corrupt values or wrong unit?"
        )


def _check_position(pos: np.ndarray, name: str) -> None:
    if pos.size and np.any(np.abs(pos) > POS_ABS_MAX):
        i = int(np.argmax(np.any(np.abs(pos) > POS_ABS_MAX, axis=1)))
        raise ValidationError(
            f"{name}: coordinate {float(np.max(np.abs(pos[i]))):.4g} m at point {i} "
            f"is farther than anything on Earth ({POS_ABS_MAX:.0e} m)"
        )


def _check_rows(a: np.ndarray | None, n: int, width: tuple[int, ...] | int, name: str) -> None:
    if a is None:
        return
    widths = (width,) if isinstance(width, int) else width
    if a.ndim != 2 or a.shape[0] != n or a.shape[1] not in widths:
        want = " or ".join(f"({n},{w})" for w in widths)
        raise ValidationError(f"{name}: shape {a.shape}, expected {want}")
    if not np.all(np.isfinite(a)):
        bad = int(np.argmax(~np.all(np.isfinite(a), axis=1)))
        raise ValidationError(f"{name}: non-finite values (first at sample {bad})")
