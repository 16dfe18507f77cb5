"""Oxford Step Counter data set, ``validation`` part: phone accelerometer with step ground truth
and the carrying position, two users × six placements.

Original layout (``.gz`` / ``.xz`` copies read transparently)::

    <root>/validation/user<N>_<placement>_<unix ms>.csv
        timestamp (ns since boot), accx, accy, accz (m/s²), steps_algo, steps_groundtruth, steps_hw

no header; the last three columns are running step counts (the app's algorithm, the
ground-truth device, the phone's hardware step counter — all zero where the phone has none).
``src`` may be ``<root>``, ``validation`` or one file. One Recording per file, named
``oxford_<user>_<placement>_<unix ms>``, with one device ``phone``: accelerometer only
(``gyro=None``), acc in m/s² as logged (Android sign: +9.8 up at rest; median |acc| 9.8–10.7).

* Time: ``t`` = seconds since the first kept sample, from the logged nanosecond timestamps (the
  phone's sensor-event clock, ns since boot; ``meta["t0_boot_ns"]``); ``meta["start_unix_ms"]``
  is the file name's UNIX start time. The rate is whatever the timestamps say (≈100–108 Hz
  median in this part, with per-sample jitter; ``meta["rate_hz"]``).
* Two logging artefacts of the real files are repaired and counted in ``meta``: leading rows
  with acc exactly (0, 0, 0) — the logger's placeholder before the first sensor event — are
  dropped (``dropped_zero_rows``), and a row repeating the previous row's timestamp is dropped,
  the first kept (``dropped_duplicates``; wearnav's one policy,
  :func:`wearnav.core.timeseries.drop_duplicate_times`: more than 5 % repeats or time going backwards
  is refused). In the real files the 3 repeats (in 2 files, each followed by a ~0.2 s gap)
  repeat the whole row.
* Steps: each increment of ``steps_groundtruth`` is one ``step`` label row with zero length,
  ``start = end =`` the time of the row where the count went up, value ``"step"`` (the count
  rises by exactly one per event in the real files; a rise by k gives k rows at that time, so
  the number of ``step`` rows always equals the count's total rise). The app's own detections
  are ``step_algo`` rows in the same form, kept as a baseline, not as truth. Zero-length rows
  keep events in the one labels table every recording has, exactly timed and countable; they
  mark no samples in ``Recording.label_at`` (which is for intervals). The hardware counter
  reports in batches, so only its first/last reading goes to ``meta["hw_step_counter"]``.
* Placement: ``meta["placement"]`` and a ``placement`` label row over the whole file, with the
  file name's word (hand, frontpocket, backpocket, neckpouch, bag, armband).

The ``optimisation`` part of the upstream repository (``accelerometer.csv`` + ``stepcounter.csv``
per folder) is not read: its ``stepcounter.csv`` is a ~10 Hz two-channel on/off signal rather
than a list of step events, and no copy of it is at hand to check an interpretation against.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav.core.timeseries import drop_duplicate_times, period
from wearnav.errors import FormatError, ValidationError
from wearnav.importers.common import check_finite, check_source, read_csv
from wearnav.recording import DeviceStream, Recording

VALIDATION_DIR = "validation"
FILE_RE = re.compile(r"^(user\d+)_([A-Za-z]+)_(\d{10,})\.csv(\.gz|\.xz)?$")
MAX_STEP_COUNT = 10_000_000
FIELDS = ["timestamp_ns", "accx", "accy", "accz", "steps_algo", "steps_groundtruth", "steps_hw"]

META = {
    "source": "oxford-steps",
    "dataset": "Oxford Step Counter DataSet (Oxford-step-counter/DataSet), validation traces",
    "licence": "CC BY 4.0",
    "url": "https://github.com/Oxford-step-counter/DataSet",
    "device": "Android phone (validation README: Samsung S6), Step-Counter-Android-Implementation app",
}


def _files(src: Path) -> list[Path]:
    if src.is_file():
        if not FILE_RE.match(src.name):
            raise FormatError("not an Oxford step-counter file (expected user<N>_<placement>_<unix ms>.csv)", src)
        return [src]
    for cand in (src / VALIDATION_DIR, src):
        if cand.is_dir():
            found: dict[str, Path] = {}
            for f in cand.iterdir():
                m = FILE_RE.match(f.name)
                if m and f.is_file():
                    key = f.name[: m.start(4)] if m.group(4) else f.name
                    if key not in found or m.group(4) is None:
                        found[key] = f
            if found:
                return [found[k] for k in sorted(found)]
    raise FormatError(f"no Oxford step-counter files ({VALIDATION_DIR}/user<N>_<placement>_<unix ms>.csv) found", src)


def _events(t: np.ndarray, count: np.ndarray, what: str, path: Path) -> np.ndarray:
    """Times of the rises of a running count (a rise by k gives k events)."""
    rise = np.diff(count)
    if np.any(rise < 0):
        i = int(np.argmax(rise < 0)) + 1
        raise FormatError(f"{what} count goes down at row {i} ({count[i - 1]} → {count[i]})", path)
    idx = np.flatnonzero(rise) + 1
    return np.repeat(t[idx], rise[idx - 1])


def read_file(path: Path) -> Recording:
    """One validation trace as a Recording."""
    m = FILE_RE.match(path.name)
    if m is None:  # was an AttributeError on None
        raise FormatError("not an Oxford step-counter file (expected user<N>_<placement>_<unix ms>.csv)", path)
    user, placement, start_ms = m.groups()[:3]
    df = read_csv(path, header=None)
    if df.shape[1] != len(FIELDS):
        raise FormatError(f"expected {len(FIELDS)} columns ({', '.join(FIELDS)}), found {df.shape[1]}", path)
    df.columns = FIELDS
    ts = pd.to_numeric(df["timestamp_ns"], errors="coerce").to_numpy(np.float64)
    check_finite(ts, "timestamp", path)
    if not pd.api.types.is_integer_dtype(df["timestamp_ns"]):
        i = int(np.argmax(ts != np.round(ts))) if np.any(ts != np.round(ts)) else 0
        raise FormatError(
            f"timestamp is not whole nanoseconds in int64 range (e.g. row {i}: {df['timestamp_ns'].iloc[i]!r})", path
        )
    ts_ns = df["timestamp_ns"].astype(np.int64).to_numpy()  # exact: float64 would round ns
    acc = df[["accx", "accy", "accz"]].apply(pd.to_numeric, errors="coerce").to_numpy(np.float64)
    check_finite(acc, "acc", path)
    counts = df[FIELDS[4:]].apply(pd.to_numeric, errors="coerce").to_numpy(np.float64)
    check_finite(counts, "step counts", path)
    # Running counts of steps: whole, non-negative and far below 2**31 in any real walk.
    bad = (counts < 0) | (counts > MAX_STEP_COUNT) | (counts != np.round(counts))
    if np.any(bad):
        i = int(np.argmax(bad.any(axis=1)))
        raise FormatError(
            f"row {i}: step count {counts[i][bad[i]][0]:g} is not a whole number in 0..{MAX_STEP_COUNT}", path
        )
    counts = counts.astype(np.int64)

    # Logging artefacts: the all-zero placeholder rows written before the accelerometer's first
    # event, and repeated timestamps (wearnav's one policy: the first row of a repeat is kept).
    leading_zero = np.cumprod(np.all(acc == 0.0, axis=1)).astype(bool)
    if leading_zero.all():
        raise FormatError("no samples left after dropping all-zero placeholder rows", path)
    ts_ns, acc, counts = ts_ns[~leading_zero], acc[~leading_zero], counts[~leading_zero]
    keep, n_dup = drop_duplicate_times(ts_ns, "timestamp", path)
    ts_ns, acc, counts = ts_ns[keep], acc[keep], counts[keep]
    t = (ts_ns - ts_ns[0]) / 1e9
    steps = _events(t, counts[:, 1], "steps_groundtruth", path)
    algo = _events(t, counts[:, 0], "steps_algo", path)
    hw = counts[:, 2]
    hw_nonzero = hw[hw > 0]
    end = float(t[-1] + period(t))
    labels = [(0.0, end, "placement", placement)]
    labels += [(float(s), float(s), "step", "step") for s in steps]
    labels += [(float(s), float(s), "step_algo", "step") for s in algo]
    try:
        stream = DeviceStream(t=t, acc=acc, gyro=None)
        meta = {
            **META,
            "subject": user,
            "placement": placement,
            "start_unix_ms": int(start_ms),
            "t0_boot_ns": int(ts_ns[0]),
            "rate_hz": round(stream.rate, 3),
            "steps_groundtruth": int(steps.size),
            "steps_algo": int(algo.size),
            "hw_step_counter": ([int(hw_nonzero[0]), int(hw_nonzero[-1])] if hw_nonzero.size else None),
            "dropped_duplicates": {"timestamp": n_dup} if n_dup else {},
            "dropped_zero_rows": int(leading_zero.sum()),
            "file": path.name,
        }
        return Recording(
            name=f"oxford_{user}_{placement}_{start_ms}", devices={"phone": stream}, labels=labels, meta=meta
        )
    except ValidationError as exc:
        raise exc.with_source(path) from None


def read(src: Path, limit: int | None = None) -> Iterator[Recording]:
    """Yield Oxford step-counter recordings (at most ``limit``) from a folder or one file."""
    src, limit = check_source(src, limit, expect="an Oxford step-counter file or its folder")
    files = _files(src)
    if limit == 0:
        return
    for count, path in enumerate(files, 1):
        yield read_file(path)
        if limit is not None and count >= limit:
            return
