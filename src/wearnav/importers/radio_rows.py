"""The bad-row rules every importer applies to radio readings (Wi-Fi scans, iBeacon readings), as
:func:`wearnav.core.timeseries.drop_duplicate_times` is for the sensor streams (issue 60 §1).

A scan's readings share one time, so a repeated *time* is normal; a repeated *reading* (the same
access point or beacon twice at one time, with the same own timestamp where the rows carry one) is
a row written twice: the first is kept, the rest
dropped and counted in ``meta["dropped_duplicates"][<tag>]``, and more than
:data:`~wearnav.core.timeseries.MAX_DUPLICATE_SHARE` of them means the file is broken (raises). Time
going backwards raises. NaN or infinite numbers are the caller's :func:`check_finite`; a received
power or frequency out of range is refused by the table itself
(:class:`~wearnav.recording.WifiScans`, :class:`~wearnav.recording.BeaconReadings`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from wearnav.core.timeseries import MAX_DUPLICATE_SHARE
from wearnav.errors import ValidationError
from wearnav.recording.radio import repeated_readings


def drop_repeated_readings(
    t: np.ndarray, source: np.ndarray, what: str, path: Path | None, meta: dict, t_seen: np.ndarray | None = None
) -> np.ndarray:
    """Indices of the readings to keep: times must not go backwards; a reading repeating the time,
    source and own timestamp (``t_seen``, where the rows have one) of an earlier one is dropped
    (counted in ``meta["dropped_duplicates"][what]``)."""
    t = np.asarray(t, np.float64)
    dt = np.diff(t)
    if np.any(dt < 0):
        i = int(np.argmax(dt < 0)) + 1
        raise ValidationError(
            f"{what}: timestamps go backwards at row {i} of that type ({t[i - 1]!r} then {t[i]!r})", path
        )
    repeat = np.zeros(t.size, bool)
    repeat[repeated_readings(t, source, t_seen)] = True
    n_dup = int(repeat.sum())
    if n_dup > max(1.0, MAX_DUPLICATE_SHARE * t.size):
        raise ValidationError(f"{what}: {n_dup} of {t.size} readings are repeated rows (file broken?)", path)
    if n_dup:
        meta.setdefault("dropped_duplicates", {})[what] = n_dup
    return np.flatnonzero(~repeat)


def ibeacon_name(uuid: str, major: str | int, minor: str | int, mac: str) -> str:
    """An iBeacon without a surveyed position named by what identifies it: ``UUID:major:minor:MAC``.

    UUID, major and minor alone do not tell beacons apart everywhere: in ILC2's site 1, 337 of the
    698 beacons heard share UUID 9195B3AD-... with major 0 and minor 0 and differ only in their MAC."""
    return f"{uuid.strip().upper()}:{int(major)}:{int(minor)}:{mac.strip().upper()}"
