"""UJI smartphone + smartwatch HAR set (Matey-Sanz, Casteleyn, Granell 2023): phone and watch
recorded together, 23 subjects, 223 executions of a Timed-Up-and-Go-like sequence.

Original layout (``.gz`` / ``.xz`` copies read transparently)::

    <root>/DATA/subjects_info.csv      subject_id, age, gender, height, weight, dominant_hand, executions
    <root>/DATA/executions_info.csv    execution_id, orientation, first_turn, second_turn
    <root>/DATA/sXX/sXX_YY_sp.csv      phone:  x_acc,y_acc,z_acc,x_gyro,y_gyro,z_gyro,timestamp,label
    <root>/DATA/sXX/sXX_YY_sw.csv      watch:  same columns

``src`` may be ``<root>``, ``DATA`` or one subject folder ``sXX``. One Recording per execution,
named ``uji_sXX_YY``, with devices ``phone`` and ``watch``.

Units, checked against the data: acc in m/s² including gravity (median |acc| 9.8–10.4 in every
file, Android sign: +9.8 up at rest), gyro in rad/s (median |gyro| 0.8–2.3 while moving), so
both are taken as they are.

Clock. Both files' ``timestamp`` are UNIX milliseconds on one shared clock (first samples of
the two devices a few ms apart), so both streams keep their own times on that clock, shifted so
that t = 0 is the earlier of the two first samples (``meta["t0_unix_ms"]``). The logged values
are *delivery* times, not sampling times: rows arrive in bursts (phone: ~7 % of rows repeat the
previous millisecond, gaps up to ~150 ms followed by 0–1 ms steps), while the sensors sample at
a constant rate (fitted 102.4 Hz phone, 104.3 Hz watch in every file; residuals one-sided,
≥ −15 ms, ≤ +175 ms). Each stream's sample times are therefore rebuilt as a constant-rate clock
``t_k = a + k / rate`` (rate from a least-squares fit of timestamp on row number, ``a`` at the
lower envelope, so that no sample is timed after it was logged). No sample is dropped or
averaged. The raw timing figures are kept in ``meta["timing"]`` per device; a file whose
timestamps stray more than 0.5 s from a constant rate, or run backwards, is refused.

Labels: the per-sample ``label`` column becomes intervals. The two devices were labelled
separately and their sequences differ in a few executions (an extra short WALKING before
SITTING_DOWN on one device, transitions typically within ±20 ms), so the phone's labels are the
``activity`` rows and the watch's are kept as ``activity_watch`` rows. Labels: SEATED,
STANDING_UP, WALKING, TURNING, SITTING_DOWN.

Placement: the phone is in a trousers pocket (its long axis is vertical while walking and
horizontal while seated; ``orientation`` says which way it faces — back/front, ``_inv`` upside
down), the watch on a wrist: ``meta["placement"] = "pocket"`` (the phone's, as for the other
phone sets) and ``meta["placements"]`` per device.

Completeness: ``subjects_info.csv`` declares each subject's number of executions; a subject
folder holding a different number (an incomplete copy) gives a one-line warning and
``meta["executions_found"]`` on that subject's recordings.
"""

from __future__ import annotations

import collections
import re
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav.core.timeseries import period
from wearnav.errors import FormatError, MissingFileError, ValidationError, WearnavWarning
from wearnav.importers.common import check_finite, check_source, check_unix_time, find_file, read_csv
from wearnav.recording import DeviceStream, Recording

DATA_DIR = "DATA"
SUBJECT_RE = re.compile(r"^s(\d+)$")
FILE_RE = re.compile(r"^(s\d+)_(\d+)_(sp|sw)\.csv(\.gz|\.xz)?$")
DEVICES = {"sp": "phone", "sw": "watch"}
ACC = ["x_acc", "y_acc", "z_acc"]
GYRO = ["x_gyro", "y_gyro", "z_gyro"]
COLUMNS = ACC + GYRO + ["timestamp", "label"]
SUBJECT_COLUMNS = ["subject_id", "age", "gender", "height", "weight", "dominant_hand", "executions"]
EXECUTION_COLUMNS = ["execution_id", "orientation", "first_turn", "second_turn"]
# Largest departure of a logged timestamp from the fitted constant-rate clock that is still
# taken as delivery jitter (real files: < 0.18 s); beyond it samples were lost or the rate changed.
MAX_CLOCK_RESIDUAL_S = 0.5

META = {
    "source": "uji-phone-watch",
    "dataset": "Smartphone and smartwatch inertial measurements from heterogeneous subjects for "
    "human activity recognition (Matey-Sanz, Casteleyn, Granell), Universitat Jaume I",
    "licence": "CC BY 4.0",
    "url": "https://doi.org/10.5281/zenodo.8398688",
    "citation": "Matey-Sanz, Casteleyn, Granell, Data in Brief 51 (2023) 109809, doi:10.1016/j.dib.2023.109809",
    "placement": "pocket",
    "placements": {"phone": "pocket", "watch": "wrist"},
}


def _data_dir(src: Path) -> Path:
    """The folder holding the sXX subject folders, or a subject folder itself."""
    for cand in (src / DATA_DIR, src):
        if cand.is_dir() and any(d.is_dir() and SUBJECT_RE.match(d.name) for d in cand.iterdir()):
            return cand
    if SUBJECT_RE.match(src.name) and any(FILE_RE.match(f.name) for f in src.iterdir()):
        return src
    raise FormatError(f"no UJI phone/watch files ({DATA_DIR}/sXX/sXX_YY_sp.csv) found", src)


def _executions(data: Path) -> dict[str, dict[str, Path]]:
    """execution id (sXX_YY) → {"sp": file, "sw": file}; plain copies win over compressed ones."""
    folders = (
        [data]
        if SUBJECT_RE.match(data.name)
        else sorted(d for d in data.iterdir() if d.is_dir() and SUBJECT_RE.match(d.name))
    )
    out: dict[str, dict[str, Path]] = {}
    for folder in folders:
        for f in folder.iterdir():
            m = FILE_RE.match(f.name)
            if m and f.is_file():
                files = out.setdefault(f"{m.group(1)}_{m.group(2)}", {})
                if m.group(3) not in files or m.group(4) is None:
                    files[m.group(3)] = f
    if not out:
        raise FormatError("no sXX_YY_sp.csv / sXX_YY_sw.csv files found", data)
    return dict(sorted(out.items()))


def _info_table(data: Path, name: str, columns: list[str]) -> tuple[pd.DataFrame, Path]:
    folders = [data, data.parent] if SUBJECT_RE.match(data.name) else [data]
    for folder in folders:
        try:
            path = find_file(folder / name)
        except MissingFileError:
            continue
        df = read_csv(path, required=columns, dtype=str)
        key = columns[0]
        if df[key].isna().any() or df[key].duplicated().any():
            raise FormatError(f"column {key!r} has empty or repeated ids", path)
        return df.set_index(key), path
    raise MissingFileError("not found (also looked for .gz/.xz)", folders[-1] / name)


def _subject_meta(row: pd.Series, path: Path) -> dict:
    nums = pd.to_numeric(row[["age", "height", "weight", "executions"]], errors="coerce")
    if nums.isna().any():
        raise FormatError(f"non-numeric age/height/weight/executions for {row.name}", path)
    return {
        "age": int(nums["age"]),
        "gender": str(row["gender"]),
        "height_cm": float(nums["height"]),
        "weight_kg": float(nums["weight"]),
        "dominant_hand": str(row["dominant_hand"]),
        "executions": int(nums["executions"]),
    }


def regular_clock(ts_ms: np.ndarray, path: Path) -> tuple[np.ndarray, dict]:
    """Constant-rate sample times (ms, same clock) for logged delivery times ``ts_ms``.

    Returns the rebuilt times and the raw timing figures for ``meta``.
    """
    n = ts_ms.size
    if n < 2:
        raise FormatError(f"only {n} sample(s)", path)
    dt = np.diff(ts_ms)
    if np.any(dt < 0):
        i = int(np.argmax(dt < 0)) + 1
        raise FormatError(f"timestamps go backwards at row {i} ({ts_ms[i - 1]:.0f} → {ts_ms[i]:.0f} ms)", path)
    if ts_ms[-1] == ts_ms[0]:
        raise FormatError("all timestamps are equal", path)
    k = np.arange(n, dtype=np.float64)
    slope, icpt = np.polyfit(k, ts_ms - ts_ms[0], 1)
    resid = (ts_ms - ts_ms[0]) - (icpt + slope * k)
    if slope <= 0 or resid.max() - resid.min() > MAX_CLOCK_RESIDUAL_S * 1e3:
        raise FormatError(
            f"timestamps stray {(resid.max() - resid.min()) / 1e3:.2f} s from a constant sampling "
            f"rate (limit {MAX_CLOCK_RESIDUAL_S} s): samples lost or rate changed",
            path,
        )
    fitted = ts_ms[0] + icpt + resid.min() + slope * k
    timing = {
        "fitted_rate_hz": round(1e3 / slope, 3),
        "raw_rate_hz": round((n - 1) / (ts_ms[-1] - ts_ms[0]) * 1e3, 3),
        "raw_median_dt_ms": float(np.median(dt)),
        "raw_repeated_timestamps": int(np.sum(dt == 0)),
        "raw_max_gap_ms": float(dt.max()),
        "max_logging_delay_ms": round(float(resid.max() - resid.min()), 1),
    }
    return fitted, timing


def _label_rows(labels: np.ndarray, t: np.ndarray, kind: str) -> list[tuple]:
    """Runs of equal per-sample labels → (start, end, kind, value); an interval ends where the
    next begins, the last one sample period after the last sample."""
    change = np.flatnonzero(labels[1:] != labels[:-1]) + 1
    starts = np.r_[0, change]
    ends_t = np.r_[t[change], t[-1] + period(t)]
    return [(float(t[s]), float(e), kind, str(labels[s])) for s, e in zip(starts, ends_t)]


def _read_device(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    df = read_csv(path, required=COLUMNS)
    vals = df[ACC + GYRO + ["timestamp"]].apply(pd.to_numeric, errors="coerce").to_numpy(np.float64)
    check_finite(vals, "acc/gyro/timestamp", path)
    check_unix_time(vals[:, 6] / 1e3, "timestamp", path)
    labels = df["label"]
    if labels.isna().any():
        raise FormatError(f"empty label at row {int(np.argmax(labels.isna().to_numpy()))}", path)
    return vals[:, 6], vals[:, 0:3], vals[:, 3:6], labels.astype(str).str.strip().to_numpy()


def read_execution(eid: str, files: dict[str, Path], subject: dict, execution: dict) -> Recording:
    """One execution (phone + watch files) as a Recording."""
    raw = {}
    for code in ("sp", "sw"):
        if code not in files:
            folder = next(iter(files.values())).parent
            raise MissingFileError(
                f"the {DEVICES[code]} file of execution {eid} is missing (also looked for .gz/.xz)",
                folder / f"{eid}_{code}.csv",
            )
        ts, acc, gyro, labels = _read_device(files[code])
        t_ms, timing = regular_clock(ts, files[code])
        raw[code] = (t_ms, acc, gyro, labels, timing)
    t0 = min(raw[c][0][0] for c in raw)
    devices, label_rows, timing = {}, [], {}
    for code, (t_ms, acc, gyro, labels, tim) in raw.items():
        dev = DEVICES[code]
        t = (t_ms - t0) / 1e3
        try:
            devices[dev] = DeviceStream(t=t, acc=acc, gyro=gyro)
        except ValidationError as exc:
            raise exc.with_source(files[code]) from None
        label_rows += _label_rows(labels, t, "activity" if dev == "phone" else f"activity_{dev}")
        timing[dev] = tim
    meta = {
        **META,
        "subject": eid.split("_")[0],
        **subject,
        "execution": eid,
        **execution,
        "t0_unix_ms": float(t0),
        "timing": timing,
        "files": [files["sp"].name, files["sw"].name],
    }
    try:
        return Recording(name=f"uji_{eid}", devices=devices, labels=label_rows, meta=meta)
    except ValidationError as exc:
        raise exc.with_source(files["sp"]) from None


def _count_mismatch(executions: dict, subjects: pd.DataFrame) -> dict[str, tuple[int, int]]:
    """Subjects whose execution files number differently from subjects_info.csv's declared
    ``executions`` (the one declared length of this format): sid → (declared, found)."""
    found = collections.Counter(eid.split("_")[0] for eid in executions)
    out = {}
    for sid, n in found.items():
        if sid in subjects.index:
            declared = pd.to_numeric(subjects.loc[sid, "executions"], errors="coerce")
            if np.isfinite(declared) and int(declared) != n:
                out[sid] = (int(declared), n)
    return out


def read(src: Path, limit: int | None = None) -> Iterator[Recording]:
    """Yield UJI executions (at most ``limit``) from the dataset root, ``DATA`` or a subject folder."""
    src, limit = check_source(src, limit, expect="the UJI dataset folder (or DATA, or a subject folder)", file=False)
    data = _data_dir(src)
    executions = _executions(data)
    if limit == 0:
        return
    subjects, subjects_path = _info_table(data, "subjects_info.csv", SUBJECT_COLUMNS)
    exec_info, exec_path = _info_table(data, "executions_info.csv", EXECUTION_COLUMNS)
    mismatch = _count_mismatch(executions, subjects)
    if mismatch:
        shown = ", ".join(f"{sid} {declared} declared, {found} found" for sid, (declared, found) in mismatch.items())
        warnings.warn(
            WearnavWarning(
                f"{subjects_path}: executions column disagrees with the files ({shown}): files missing "
                "(an incomplete copy?); those subjects' recordings are flagged in meta['executions_found']"
            ),
            stacklevel=2,
        )
    for count, (eid, files) in enumerate(executions.items(), 1):
        sid = eid.split("_")[0]
        if sid not in subjects.index:
            raise FormatError(f"subject {sid} (of {eid}) is not listed", subjects_path)
        if eid not in exec_info.index:
            raise FormatError(f"execution {eid} is not listed", exec_path)
        execution = exec_info.loc[eid]
        rec = read_execution(
            eid,
            files,
            _subject_meta(subjects.loc[sid], subjects_path),
            {
                "phone_orientation": str(execution["orientation"]),
                "first_turn": str(execution["first_turn"]),
                "second_turn": str(execution["second_turn"]),
            },
        )
        if sid in mismatch:
            rec.meta["executions_found"] = mismatch[sid][1]
        yield rec
        if limit is not None and count >= limit:
            return
