"""UCI HAPT (Reyes-Ortiz et al.): a waist-worn Samsung Galaxy S II, 30 subjects, 61 experiments.

Reads the raw inertial part of "Smartphone-Based Recognition of Human Activities and Postural
Transitions" v2.1 in its original layout::

    <root>/activity_labels.txt                 "<id> <NAME>", 1 WALKING .. 12 LIE_TO_STAND
    <root>/RawData/acc_expXX_userYY.txt        x y z, g (gravity included), 50 Hz
    <root>/RawData/gyro_expXX_userYY.txt       x y z, rad/s, same rows as the acc file
    <root>/RawData/labels.txt                  exp user activity_id start_sample end_sample
    <root>/{Train,Test}/subject_id_*.txt       optional: the dataset's subject split

(each file may be .gz / .xz). ``src`` may be ``<root>`` or ``RawData``. One Recording per
experiment, named ``uci_hapt_expXX_userYY``, with one device ``phone`` (placement ``waist``).

* ``t = (k − 1) / 50`` s for the k-th row (1-based, as the labels count samples): the files carry
  no timestamps and the README gives a constant 50 Hz.
* ``acc`` = file × 9.80665 (the README: accelerations in g, gravity included, same sign as an
  Android accelerometer — a resting phone reads about +1 g up). ``gyro`` as in the file, rad/s.
* Labels: every labels.txt row of the experiment becomes an ``activity`` row named from
  activity_labels.txt, all 12 kept (6 basic activities and 6 postural transitions). Sample
  indices are read as 1-based and inclusive (consecutive rows meet: ``… 1232`` then ``1233 …``),
  so a row ``s e`` covers ``[(s − 1)/50, e/50)``. Samples outside every row are unlabelled, as
  in the dataset.
* ``split`` is ``train``/``test`` from ``Train/subject_id_train.txt`` and
  ``Test/subject_id_test.txt`` when those files are present, else empty (no guessing).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav.errors import FormatError, MissingFileError, ValidationError
from wearnav.importers.common import (
    check_finite,
    check_source,
    find_file,
    read_csv,
    read_text,
    strip_compression,
)
from wearnav.recording import STANDARD_GRAVITY as G  # the files' unit of acceleration
from wearnav.recording import DeviceStream, Recording

RATE_HZ = 50.0
RAW_DIR = "RawData"
ACC_RE = re.compile(r"^acc_exp(\d+)_user(\d+)\.txt(\.gz|\.xz)?$")
LABEL_FIELDS = ["exp", "user", "activity", "start", "end"]

META = {
    "source": "uci-hapt",
    "dataset": "UCI HAPT: Smartphone-Based Recognition of Human Activities and Postural "
    "Transitions v2.1 (Reyes-Ortiz, Oneto, Samà, Parra, Anguita), RawData",
    "licence": "CC BY 4.0 (UCI Machine Learning Repository)",
    "url": "https://archive.ics.uci.edu/dataset/341",
    "citation": "Reyes-Ortiz et al., Transition-Aware Human Activity Recognition Using "
    "Smartphones, Neurocomputing 171 (2016)",
    "device": "Samsung Galaxy S II",
    "placement": "waist",
    "rate_hz": RATE_HZ,
}


def _raw_dir(src: Path) -> Path:
    for cand in (src / RAW_DIR, src):
        if cand.is_dir() and any(ACC_RE.match(f.name) for f in cand.iterdir()):
            return cand
    raise FormatError(f"no UCI HAPT raw files ({RAW_DIR}/acc_expXX_userYY.txt) found", src)


def _find(folders: list[Path], name: str) -> Path:
    for folder in folders:
        try:
            return find_file(folder / name)
        except MissingFileError:
            continue
    raise MissingFileError("not found (also looked for .gz/.xz)", folders[0] / name)


def read_activity_names(path: Path) -> dict[int, str]:
    """``activity_labels.txt``: activity id → name."""
    names = {}
    for lineno, line in enumerate(read_text(path).splitlines(), 1):
        if not line.strip():
            continue
        parts = line.split()
        if len(parts) != 2 or not parts[0].isdigit():
            raise FormatError(f"line {lineno}: expected '<id> <NAME>', got {line.strip()!r}", path)
        if int(parts[0]) in names:
            raise FormatError(f"line {lineno}: activity id {parts[0]} is listed more than once", path)
        names[int(parts[0])] = parts[1]
    if not names:
        raise FormatError("empty file", path)
    return names


def read_label_table(path: Path) -> pd.DataFrame:
    """``labels.txt`` as a DataFrame with columns exp, user, activity, start, end (integers)."""
    df = read_csv(path, sep=r"\s+", header=None)
    if df.shape[1] != len(LABEL_FIELDS):
        raise FormatError(f"expected {len(LABEL_FIELDS)} columns ({' '.join(LABEL_FIELDS)}), found {df.shape[1]}", path)
    vals = df.apply(pd.to_numeric, errors="coerce").to_numpy(np.float64)
    check_finite(vals, "label table", path)
    if np.any(vals != np.round(vals)) or np.any(np.abs(vals) >= 2**31):
        raise FormatError("label table has non-integer or out-of-range values", path)
    out = pd.DataFrame(vals.astype(np.int64), columns=LABEL_FIELDS)
    bad = np.flatnonzero((out["start"] < 1) | (out["end"] < out["start"]))
    if bad.size:
        r = out.iloc[int(bad[0])]
        raise FormatError(f"row {int(bad[0]) + 1}: bad interval {r['start']}..{r['end']}", path)
    # Rows of one experiment cover disjoint sample ranges (inclusive); a repeated or
    # overlapping row would label samples twice.
    order = out.sort_values(["exp", "start"], kind="stable")
    same_exp = order["exp"].to_numpy()[1:] == order["exp"].to_numpy()[:-1]
    clash = np.flatnonzero(same_exp & (order["start"].to_numpy()[1:] <= order["end"].to_numpy()[:-1]))
    if clash.size:
        a, b = order.index[clash[0]], order.index[clash[0] + 1]
        what = "repeats" if (out.loc[a] == out.loc[b]).all() else "overlaps"
        raise FormatError(
            f"row {max(a, b) + 1} {what} row {min(a, b) + 1} (experiment "
            f"{out.loc[a, 'exp']}, samples {out.loc[b, 'start']}..{out.loc[b, 'end']})",
            path,
        )
    return out


def read_split(root: Path) -> dict[int, str]:
    """Subject → "train"/"test" from the dataset's own subject lists, if they are present."""
    split: dict[int, str] = {}
    for folder, name in (("Train", "train"), ("Test", "test")):
        try:
            path = find_file(root / folder / f"subject_id_{name}.txt")
        except MissingFileError:
            return {}
        for tok in read_text(path).split():
            if not tok.isdigit():
                raise FormatError(f"expected subject numbers, got {tok!r}", path)
            split[int(tok)] = name
    return split


def _read_xyz(path: Path) -> np.ndarray:
    df = read_csv(path, sep=r"\s+", header=None)
    if df.shape[1] != 3:
        raise FormatError(f"expected 3 columns (x y z), found {df.shape[1]}", path)
    vals = df.apply(pd.to_numeric, errors="coerce").to_numpy(np.float64)
    check_finite(vals, "x/y/z", path)
    return vals


def read_experiment(
    acc_path: Path,
    gyro_path: Path,
    labels: pd.DataFrame,
    labels_path: Path,
    names: dict[int, str],
    names_path: Path,
    split: str = "",
) -> Recording:
    """One experiment (acc + gyro files and its rows of labels.txt) as a Recording."""
    m = ACC_RE.match(acc_path.name)
    assert m is not None  # read() lists only the files it matches
    exp, user = int(m.group(1)), int(m.group(2))
    acc = _read_xyz(acc_path)
    gyro = _read_xyz(gyro_path)
    n = len(acc)
    if len(gyro) != n:
        raise FormatError(f"{len(gyro)} rows but {acc_path.name} has {n}", gyro_path)
    rows = labels[labels["exp"] == exp]
    if (rows["user"] != user).any():
        raise FormatError(
            f"experiment {exp} is labelled with user {int(rows['user'].iloc[0])}, the file name says user {user}",
            labels_path,
        )
    if (rows["end"] > n).any():
        e = int(rows["end"].max())
        raise FormatError(
            f"experiment {exp}: label ends at sample {e}, beyond the {n} samples "
            f"of {acc_path.name} (truncated data file?)",
            labels_path,
        )
    unknown = sorted(set(rows["activity"]) - set(names))
    if unknown:
        raise FormatError(f"activity ids {unknown} (used in labels.txt) are not listed", names_path)
    label_rows = [
        ((s - 1) / RATE_HZ, e / RATE_HZ, "activity", names[a])
        for a, s, e in rows[["activity", "start", "end"]].itertuples(index=False)
    ]
    try:
        stream = DeviceStream(t=np.arange(n) / RATE_HZ, acc=acc * G, gyro=gyro)
        meta = {
            **META,
            "subject": f"user{user:02d}",
            "experiment": exp,
            "files": [acc_path.name, gyro_path.name],
            **({"split": split} if split else {}),
        }
        return Recording(
            name=f"uci_hapt_exp{exp:02d}_user{user:02d}", devices={"phone": stream}, labels=label_rows, meta=meta
        )
    except ValidationError as exc:
        raise exc.with_source(acc_path) from None


def read(src: Path, limit: int | None = None) -> Iterator[Recording]:
    """Yield UCI HAPT experiments (at most ``limit``) from the dataset folder or its RawData."""
    src, limit = check_source(src, limit, expect="the UCI HAPT folder (or its RawData folder)", file=False)
    raw = _raw_dir(src)
    root = raw.parent if raw.name == RAW_DIR else raw
    accs: dict[tuple[int, int], Path] = {}
    for f in raw.iterdir():
        m = ACC_RE.match(f.name)
        if m and ((key := (int(m.group(1)), int(m.group(2)))) not in accs or m.group(3) is None):
            accs[key] = f
    if limit == 0:
        return
    labels_path = _find([raw, root], "labels.txt")
    names_path = _find([root, raw], "activity_labels.txt")
    labels = read_label_table(labels_path)
    names = read_activity_names(names_path)
    split = read_split(root)
    for count, ((_exp, user), acc_path) in enumerate(sorted(accs.items()), 1):
        gyro_path = find_file(raw / ("gyro_" + strip_compression(acc_path)[len("acc_") :]))
        yield read_experiment(acc_path, gyro_path, labels, labels_path, names, names_path, split.get(user, ""))
        if limit is not None and count >= limit:
            return
