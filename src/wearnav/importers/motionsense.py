"""MotionSense (Malekzadeh et al., QMUL): iPhone 6s in the trousers' front pocket, 6 activities.

Reads the ``A_DeviceMotion_data`` part of the dataset in its original layout::

    <root>/data_subjects_info.csv                  code, weight, height, age, gender (0 F, 1 M)
    <root>/A_DeviceMotion_data/<act>_<trial>/sub_<n>.csv    (.gz / .xz read transparently)

``src`` may be ``<root>``, the ``A_DeviceMotion_data`` folder (also the doubly nested
``A_DeviceMotion_data/A_DeviceMotion_data`` of the Kaggle archive) or one ``<act>_<trial>`` folder;
``data_subjects_info.csv`` is looked up there and in the folders above. One Recording per
(trial, subject), named ``motionsense_<act>_<trial>_sub<nn>``, with one device ``phone``.

Each CSV row is one Core Motion ``CMDeviceMotion`` sample at 50 Hz; the files carry no timestamps,
only a row index, so ``t = index / 50`` (the index must run 0, 1, 2, ... or the file is refused).

Conventions (checked against the data, see below):

* ``acc`` = **−(gravity + userAcceleration) × 9.80665**, i.e. specific force in m/s². Core Motion
  reports acceleration in g with the opposite sign of a specific-force accelerometer: ``gravity``
  points *down* in the device frame (a phone lying face up gives gravity ≈ (0, 0, −1)), and
  ``userAcceleration`` has the raw accelerometer's sign (raw = gravity + userAcceleration). The
  negation makes a resting phone read +9.81 m/s² "up", as Android and the rest of wearnav do.
  Evidence: with this sign the world-vertical specific force of walking trials stays ≥ 0
  (0.5th percentile +0.07 g) and jogging shows free-fall phases (|acc| → 0.1 g) and heel-strike
  peaks of 4–6 g; the opposite sign of ``userAcceleration`` gives a body pulled down harder than
  gravity (0.5th percentile −0.4 g while walking).
* ``gyro`` = ``rotationRate`` (rad/s, device frame; Core Motion's right-handed axes: x right,
  y up along the screen, z out of the screen — the same axes as Android).
* ``quat`` (w, x, y, z), world←device, from ``attitude.roll/pitch/yaw`` (rad) with Core Motion's
  Euler order: R = Rz(yaw) · Rx(pitch) · Ry(roll) (roll about device y, pitch about x, yaw about
  z). The world frame is Core Motion's reference frame: z up, x arbitrary but fixed within a
  trial (``xArbitraryZVertical``), the "game rotation vector" convention wearnav uses. Checked:
  rotating each file's ``gravity`` vector by this quaternion gives (0, 0, −1) to within 2e-3 g.

Units check: every file's ``gravity`` must have median norm 1 ± 0.05 (g), a direct check of the
units on top of :class:`DeviceStream`'s generic one. (16 of the 48 jogging trials have median
|acc| of 14.1–18.4 m/s²: a thigh pocket swings hard; their time-mean acc vector is
10.6–12.3 m/s².)

Labels: one ``activity`` row covering the whole trial (downstairs, upstairs, walking, jogging,
sitting, standing); the activity, trial and subject attributes are also in ``meta``.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd

from wearnav.core.rotations import from_euler, to_wxyz
from wearnav.errors import FormatError, MissingFileError, ValidationError
from wearnav.importers.common import check_finite, check_source, find_file, read_csv, require_columns
from wearnav.recording import STANDARD_GRAVITY as G  # Core Motion's unit of acceleration
from wearnav.recording import DeviceStream, Recording

RATE_HZ = 50.0
ACTIVITIES = {
    "dws": "downstairs",
    "ups": "upstairs",
    "wlk": "walking",
    "jog": "jogging",
    "sit": "sitting",
    "std": "standing",
}
ATTITUDE = ["attitude.roll", "attitude.pitch", "attitude.yaw"]
GRAVITY = ["gravity.x", "gravity.y", "gravity.z"]
ROTATION_RATE = ["rotationRate.x", "rotationRate.y", "rotationRate.z"]
USER_ACC = ["userAcceleration.x", "userAcceleration.y", "userAcceleration.z"]
COLUMNS = ATTITUDE + GRAVITY + ROTATION_RATE + USER_ACC
SUBJECT_COLUMNS = ["code", "weight", "height", "age", "gender"]
SUBJECTS_FILE = "data_subjects_info.csv"
DATA_DIR = "A_DeviceMotion_data"

TRIAL_RE = re.compile(r"^(dws|ups|wlk|jog|sit|std)_(\d+)$")
FILE_RE = re.compile(r"^sub_(\d+)\.csv(\.gz|\.xz)?$")

META = {
    "source": "motionsense",
    "dataset": "MotionSense (Malekzadeh, Clegg, Cavallaro, Haddadi), A_DeviceMotion_data",
    "licence": "MIT (official repository, (c) 2018 Mohammad Malekzadeh); no separate data "
    "licence stated (the Kaggle mirror lists ODbL)",
    "url": "https://github.com/mmalekzadeh/motion-sense",
    "citation": "Malekzadeh et al., Mobile Sensor Data Anonymization, IoTDI 2019",
    "device": "iPhone 6s (Core Motion CMDeviceMotion via SensingKit/Crowdsense)",
    "placement": "front_pocket",
    "rate_hz": RATE_HZ,
}


def _trial_dirs(src: Path) -> list[Path]:
    """The ``<act>_<trial>`` folders under ``src`` (or ``src`` itself if it is one)."""
    if TRIAL_RE.match(src.name):
        return [src]
    for base in (src, src / DATA_DIR, src / DATA_DIR / DATA_DIR):
        if base.is_dir():
            dirs = [d for d in base.iterdir() if d.is_dir() and TRIAL_RE.match(d.name)]
            if dirs:

                def key(d: Path):
                    act, trial = TRIAL_RE.match(d.name).groups()  # type: ignore[union-attr]  # dirs were filtered by it
                    return (int(trial), act)

                return sorted(dirs, key=key)
    raise FormatError(f"no MotionSense trial folders (dws_1, wlk_7, ... under {DATA_DIR}/) found", src)


def _subject_files(trial_dir: Path) -> list[tuple[int, Path]]:
    """(subject number, file) pairs of a trial folder; a plain copy wins over a compressed one."""
    found: dict[int, Path] = {}
    for f in trial_dir.iterdir():
        m = FILE_RE.match(f.name)
        if m and f.is_file():
            n = int(m.group(1))
            if n not in found or m.group(2) is None:
                found[n] = f
    return sorted(found.items())


def _find_subjects_file(src: Path, trial_dir: Path) -> Path:
    """``data_subjects_info.csv`` in ``src`` or up to three folders above the trial folder."""
    folders = [src, *trial_dir.parents[:3]]
    for folder in dict.fromkeys(folders):
        try:
            return find_file(folder / SUBJECTS_FILE)
        except MissingFileError:
            continue
    raise MissingFileError(f"{SUBJECTS_FILE} not found next to the data", src / SUBJECTS_FILE)


def read_subjects(path: Path) -> dict[int, dict]:
    """Subject attributes from ``data_subjects_info.csv`` keyed by subject code."""
    df = read_csv(path)
    df.columns = [str(c).strip() for c in df.columns]
    require_columns(df, SUBJECT_COLUMNS, path)
    vals = df[SUBJECT_COLUMNS].apply(pd.to_numeric, errors="coerce").to_numpy(float)
    check_finite(vals, "subject table", path)
    dup = df["code"][df["code"].duplicated()]
    if len(dup):
        raise FormatError(f"subject code {dup.iloc[0]} is listed more than once", path)
    out = {}
    for code, weight, height, age, gender in vals:
        if gender not in (0, 1):
            raise FormatError(f"gender must be 0 (F) or 1 (M), got {gender:g} for subject {code:g}", path)
        out[int(code)] = {
            "weight_kg": float(weight),
            "height_cm": float(height),
            "age": int(age),
            "gender": "M" if gender == 1 else "F",
        }
    return out


def read_file(path: Path, act: str, trial: int, subject: int, subject_info: dict | None) -> Recording:
    """One ``sub_<n>.csv`` of one trial folder as a Recording."""
    df = read_csv(path, required=COLUMNS)
    index_col = df.columns[0]
    if index_col in COLUMNS:
        raise FormatError("first column must be the row index (the files carry no timestamps)", path)
    vals = df[COLUMNS].apply(pd.to_numeric, errors="coerce").to_numpy(np.float64)
    check_finite(vals, "sensor columns", path)
    index = pd.to_numeric(df[index_col], errors="coerce").to_numpy(np.float64)
    check_finite(index, "row index", path)
    bad = np.flatnonzero(index != np.arange(len(index)))
    if bad.size:
        i = int(bad[0])
        raise FormatError(
            f"row index is not 0, 1, 2, ... (row {i} has index {index[i]:g}); time is built from "
            f"it at {RATE_HZ:g} Hz, so rows must be complete and in order",
            path,
        )
    att, grav, rot, user = (vals[:, k : k + 3] for k in (0, 3, 6, 9))
    n = len(df)
    # Core Motion's Euler angles lie in [-π, π] (pitch in [-π/2, π/2]); anything else is not an
    # attitude, though its quaternion would still look like one.
    if np.any(np.abs(att) > np.pi + 1e-3):
        i = int(np.argmax(np.any(np.abs(att) > np.pi + 1e-3, axis=1)))
        raise FormatError(f"row {i}: attitude angle {float(np.max(np.abs(att[i]))):.4g} rad is outside [-π, π]", path)
    # Core Motion's gravity is a unit vector in g: a direct check of the units.
    gnorm = float(np.median(np.linalg.norm(grav, axis=1)))
    if not 0.95 <= gnorm <= 1.05:
        raise FormatError(f"median |gravity| is {gnorm:.3g}, expected 1 (Core Motion gives g)", path)
    acc = -(grav + user) * G
    try:
        stream = DeviceStream(
            t=np.arange(n) / RATE_HZ,
            acc=acc,
            gyro=rot,
            # Core Motion's z-x'-y'' attitude: yaw, pitch, roll = att[:, 2], att[:, 1], att[:, 0].
            quat=to_wxyz(from_euler("ZXY", att[:, ::-1])),
        )
        activity = ACTIVITIES[act]
        name = f"motionsense_{act}_{trial}_sub{subject:02d}"
        meta = {
            **META,
            "subject": f"sub{subject:02d}",
            **(subject_info or {}),
            "activity": activity,
            "activity_code": act,
            "trial": trial,
            "file": f"{act}_{trial}/{path.name}",
        }
        return Recording(
            name=name,
            devices={"phone": stream},
            labels=[(0.0, n / RATE_HZ, "activity", activity)],
            meta=meta,
        )
    except ValidationError as exc:
        raise exc.with_source(path) from None


def read(src: Path, limit: int | None = None) -> Iterator[Recording]:
    """Yield MotionSense recordings (at most ``limit``) from a folder in the original layout."""
    src, limit = check_source(src, limit, expect="a MotionSense folder or sub_<n>.csv file")
    if src.is_file():
        # One sub_<n>.csv: its folder names the activity and trial.
        m, t = FILE_RE.match(src.name), TRIAL_RE.match(src.parent.name)
        if not (m and t):
            raise FormatError("not a MotionSense file (expected <act>_<trial>/sub_<n>.csv)", src)
        jobs = [(src.parent, [(int(m.group(1)), src)])]
    else:
        jobs = [(d, _subject_files(d)) for d in _trial_dirs(src)]
        if not any(files for _, files in jobs):
            raise FormatError("no sub_<n>.csv files in the MotionSense trial folders", src)
    if limit == 0:
        return
    base = src if src.is_dir() else src.parent
    subjects = read_subjects(_find_subjects_file(base, jobs[0][0]))
    count = 0
    for trial_dir, files in jobs:
        act, trial = TRIAL_RE.match(trial_dir.name).groups()  # type: ignore[union-attr]  # jobs' folders matched it
        for n, path in files:
            if n not in subjects:
                raise FormatError(f"subject {n} is not in {SUBJECTS_FILE}", path)
            yield read_file(path, act, int(trial), n, subjects[n])
            count += 1
            if limit is not None and count >= limit:
                return
