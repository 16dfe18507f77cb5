"""Importers of the activity / step sets: MotionSense, UCI HAPT, UJI phone+watch, Oxford steps.

Real-data tests read a few recordings of ../shared/data and check them against the raw files
parsed independently here; error tests write small broken copies of real files to tmp_path.
"""

from __future__ import annotations

import gzip
import lzma
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from wearnav.errors import FormatError, MissingFileError, ValidationError, WearnavError
from wearnav.importers import get_importer, motionsense, oxford_steps, uci_hapt, uji_phone_watch

ROOT = Path(__file__).resolve().parents[1]


def raw_lines(path: Path) -> list[str]:
    opener = lzma.open if path.suffix == ".xz" else open
    with opener(path, "rt") as f:
        return f.read().splitlines()


def write_lines(path: Path, lines: list[str]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")
    return path


def med_norm(a: np.ndarray) -> float:
    return float(np.median(np.linalg.norm(a, axis=1)))


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (N,3) by unit quaternions q (N,4) w,x,y,z."""
    w, u = q[:, :1], q[:, 1:]
    return v + 2 * np.cross(u, np.cross(u, v) + w * v)


def assert_error(exc_type, fn, *must_contain):
    with pytest.raises(exc_type) as info:
        fn()
    msg = str(info.value)
    assert "\n" not in msg
    for part in must_contain:
        assert str(part) in msg, msg
    return msg


# ---- MotionSense ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def ms_root(shared_data) -> Path:
    return shared_data / "motionsense"


def test_motionsense_real_slice(ms_root):
    recs = list(motionsense.read(ms_root, limit=2))
    assert [r.name for r in recs] == ["motionsense_dws_1_sub01", "motionsense_dws_1_sub02"]
    subjects = pd.read_csv(ms_root / "data_subjects_info.csv", encoding="utf-8-sig").set_index("code")
    for i, rec in enumerate(recs, 1):
        raw = raw_lines(ms_root / "A_DeviceMotion_data" / "dws_1" / f"sub_{i}.csv.xz")
        s = rec.devices["phone"]
        assert len(s) == len(raw) - 1
        assert s.rate == pytest.approx(50.0)
        assert 9.0 < med_norm(s.acc) < 11.0
        assert s.gyro is not None and s.quat is not None
        assert rec.labels.values.tolist() == [[0.0, len(s) / 50.0, "activity", "downstairs"]]
        assert rec.meta["placement"] == "front_pocket"
        assert rec.meta["weight_kg"] == subjects.loc[i, "weight"]
        assert rec.meta["height_cm"] == subjects.loc[i, "height"]
        assert rec.meta["age"] == subjects.loc[i, "age"]
        assert rec.meta["gender"] == ("M" if subjects.loc[i, "gender"] == 1 else "F")
        assert rec.meta["licence"] and rec.meta["source"]
        # gyro is rotationRate unchanged; acc is -(gravity + userAcceleration) in m/s².
        first = np.array(raw[1].split(",")[1:], dtype=float)
        np.testing.assert_allclose(s.gyro[0], first[6:9], rtol=1e-6)
        np.testing.assert_allclose(s.acc[0], -(first[3:6] + first[9:12]) * 9.80665, rtol=1e-6)


def test_motionsense_frames_on_a_sitting_trial(ms_root):
    # A trial folder as src; sitting: specific force rotated to the world frame must be +g up.
    rec = next(motionsense.read(ms_root / "A_DeviceMotion_data" / "sit_5", limit=1))
    s = rec.devices["phone"]
    acc_world = rotate(s.quat.astype(float), s.acc.astype(float))
    np.testing.assert_allclose(acc_world.mean(axis=0), [0, 0, 9.81], atol=0.15)
    assert rec.meta["activity"] == "sitting"


def test_motionsense_quaternion_is_rz_rx_ry_of_the_attitude(ms_root):
    # Core Motion: R = Rz(yaw)·Rx(pitch)·Ry(roll), built here from elementary matrices.
    path = ms_root / "A_DeviceMotion_data" / "wlk_7" / "sub_3.csv.xz"
    raw = pd.read_csv(path)[::37]
    s = next(motionsense.read(path)).devices["phone"]
    q = s.quat[raw.index].astype(float)

    def rx(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    def ry(a):
        return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    def rz(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    for k, (roll, pitch, yaw) in enumerate(raw[["attitude.roll", "attitude.pitch", "attitude.yaw"]].to_numpy()):
        R = rz(yaw) @ rx(pitch) @ ry(roll)
        for axis in np.eye(3):  # columns of R = device axes in the world frame
            np.testing.assert_allclose(rotate(q[k : k + 1], axis[None]), (R @ axis)[None], atol=1e-6)


def test_motionsense_vigorous_jogging_trial_is_kept(ms_root):
    # jog_9/sub_4: median |acc| 14.9 m/s² (a thigh pocket swings hard while jogging) is real data.
    path = ms_root / "A_DeviceMotion_data" / "jog_9" / "sub_4.csv.xz"
    rec = next(motionsense.read(path))
    assert rec.name == "motionsense_jog_9_sub04"
    assert med_norm(rec.devices["phone"].acc) > 14.0


@pytest.fixture
def ms_copy(ms_root, tmp_path) -> Path:
    """A plain-text MotionSense layout with one 60-row file."""
    lines = raw_lines(ms_root / "A_DeviceMotion_data" / "dws_1" / "sub_1.csv.xz")[:61]
    write_lines(tmp_path / "ms" / "A_DeviceMotion_data" / "dws_1" / "sub_1.csv", lines)
    shutil.copy(ms_root / "data_subjects_info.csv", tmp_path / "ms" / "data_subjects_info.csv")
    return tmp_path / "ms"


def test_motionsense_plain_copy_reads(ms_copy):
    (rec,) = motionsense.read(ms_copy)
    assert len(rec.devices["phone"]) == 60


def test_motionsense_errors(ms_copy, tmp_path):
    f = ms_copy / "A_DeviceMotion_data" / "dws_1" / "sub_1.csv"
    lines = f.read_text().splitlines()
    read = lambda: list(motionsense.read(ms_copy))

    (tmp_path / "empty_dir").mkdir()
    assert_error(
        FormatError, lambda: list(motionsense.read(tmp_path / "empty_dir")), "empty_dir", "no MotionSense trial folders"
    )
    assert_error(MissingFileError, lambda: list(motionsense.read(tmp_path / "nope")), "nope")

    write_lines(f, [lines[0].replace("userAcceleration.z", "userAccel.z")] + lines[1:])
    assert_error(FormatError, read, "sub_1.csv", "userAcceleration.z")

    write_lines(f, lines[:1])
    assert_error(FormatError, read, "sub_1.csv", "no data rows")
    f.write_text("")
    assert_error(FormatError, read, "sub_1.csv", "empty")

    bad = lines[:]
    bad[5] = bad[5].replace(bad[5].split(",")[4], "nan", 1)
    write_lines(f, bad)
    assert_error(FormatError, read, "sub_1.csv", "NaN")

    write_lines(f, lines[:10] + [lines[11], lines[10]] + lines[12:])
    assert_error(FormatError, read, "sub_1.csv", "row index")

    # A copy already converted to m/s² (gravity no longer a unit vector) is refused.
    ms2 = [
        ",".join(c[:4] + [str(float(v) * 9.80665) for v in c[4:7]] + c[7:]) for c in (x.split(",") for x in lines[1:])
    ]
    write_lines(f, lines[:1] + ms2)
    assert_error(FormatError, read, "sub_1.csv", "median |gravity|")

    # A truncated .xz copy instead of the plain file.
    data = lzma.compress("\n".join(lines).encode())
    f.unlink()
    f.with_name("sub_1.csv.xz").write_bytes(data[: len(data) // 2])
    assert_error(FormatError, read, "sub_1.csv.xz")

    write_lines(f, lines)
    (ms_copy / "data_subjects_info.csv").unlink()
    assert_error(MissingFileError, read, "data_subjects_info.csv")


# ---- UCI HAPT ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def hapt_root(shared_data) -> Path:
    return shared_data / "uci_hapt"


def hapt_names(root: Path) -> dict[int, str]:
    lines = (root / "activity_labels.txt").read_text().splitlines()
    return {int(a): b for a, b in (line.split() for line in lines if line.strip())}


def test_uci_hapt_real_slice(hapt_root):
    recs = list(uci_hapt.read(hapt_root, limit=2))
    assert [r.name for r in recs] == ["uci_hapt_exp01_user01", "uci_hapt_exp02_user01"]
    names = hapt_names(hapt_root)
    assert len(names) == 12
    table = np.array([line.split() for line in raw_lines(hapt_root / "RawData" / "labels.txt.xz")], dtype=int)
    for exp, rec in enumerate(recs, 1):
        s = rec.devices["phone"]
        acc_raw = raw_lines(hapt_root / "RawData" / f"acc_exp{exp:02d}_user01.txt.xz")
        gyro_raw = raw_lines(hapt_root / "RawData" / f"gyro_exp{exp:02d}_user01.txt.xz")
        assert len(s) == len(acc_raw) == len(gyro_raw)
        for k in (0, len(s) - 1):  # g → m/s² with standard gravity; gyro as is
            np.testing.assert_allclose(s.acc[k], np.array(acc_raw[k].split(), float) * 9.80665, rtol=1e-6)
            np.testing.assert_allclose(s.gyro[k], np.array(gyro_raw[k].split(), float), rtol=1e-6)
        assert s.rate == pytest.approx(50.0)
        assert 9.3 < med_norm(s.acc) < 10.5
        assert med_norm(s.gyro) < 2.0
        rows = table[table[:, 0] == exp]
        lab = rec.labels.sort_values("start")
        assert (lab["kind"] == "activity").all()
        assert len(lab) == len(rows) > 10
        assert lab["value"].tolist() == [names[a] for a in rows[:, 2]]
        np.testing.assert_allclose(lab["start"], (rows[:, 3] - 1) / 50)
        np.testing.assert_allclose(lab["end"], rows[:, 4] / 50)
        assert rec.meta["placement"] == "waist" and rec.meta["subject"] == "user01"
        assert rec.meta.get("split", "") == ""  # the subject lists are not in this copy
    # Transitions are kept, not only the 6 basic activities.
    values = set(recs[0].labels["value"])
    assert "STAND_TO_SIT" in values and "WALKING" in values


@pytest.fixture
def hapt_copy(hapt_root, tmp_path) -> Path:
    """A plain HAPT layout with one 400-sample experiment and labels inside it."""
    root = tmp_path / "hapt"
    raw = root / "RawData"
    for kind in ("acc", "gyro"):
        write_lines(
            raw / f"{kind}_exp01_user01.txt", raw_lines(hapt_root / "RawData" / f"{kind}_exp01_user01.txt.xz")[:400]
        )
    write_lines(raw / "labels.txt", ["1 1 5 250 300", "1 1 7 301 400"])
    shutil.copy(hapt_root / "activity_labels.txt", root / "activity_labels.txt")
    return root


def test_uci_hapt_copy_reads_and_split(hapt_copy):
    (rec,) = uci_hapt.read(hapt_copy / "RawData")  # the RawData folder itself
    assert rec.labels["value"].tolist() == ["STANDING", "STAND_TO_SIT"]
    assert rec.labels["end"].iloc[-1] == pytest.approx(len(rec.devices["phone"]) / 50)
    write_lines(hapt_copy / "Train" / "subject_id_train.txt", ["3", "1"])
    write_lines(hapt_copy / "Test" / "subject_id_test.txt", ["2"])
    (rec,) = uci_hapt.read(hapt_copy)
    assert rec.meta["split"] == "train"


def test_uci_hapt_errors(hapt_copy, tmp_path):
    raw = hapt_copy / "RawData"
    acc, gyro, labels = raw / "acc_exp01_user01.txt", raw / "gyro_exp01_user01.txt", raw / "labels.txt"
    acc_lines, gyro_lines = acc.read_text().splitlines(), gyro.read_text().splitlines()
    read = lambda: list(uci_hapt.read(hapt_copy))

    (tmp_path / "other").mkdir()
    assert_error(FormatError, lambda: list(uci_hapt.read(tmp_path / "other")), "other", "no UCI HAPT")

    write_lines(gyro, gyro_lines[:350])
    assert_error(FormatError, read, "gyro_exp01_user01.txt", "350 rows")
    write_lines(gyro, gyro_lines)

    write_lines(acc, [" ".join(x.split()[:2]) for x in acc_lines])
    assert_error(FormatError, read, "acc_exp01_user01.txt", "3 columns")
    write_lines(acc, acc_lines[:399] + [acc_lines[399].rsplit(" ", 1)[0]])  # last row cut short
    assert_error(FormatError, read, "acc_exp01_user01.txt", "NaN")
    write_lines(acc, acc_lines)

    write_lines(labels, ["1 1 5 250 300", "1 1 7 301 401"])
    assert_error(FormatError, read, "labels.txt", "beyond")
    write_lines(labels, ["1 1 5 250 200"])
    assert_error(FormatError, read, "labels.txt", "bad interval")
    write_lines(labels, ["1 1 13 250 300"])
    assert_error(FormatError, read, "activity_labels.txt", "13")
    write_lines(labels, ["1 1 5 250 300"])

    gyro.unlink()
    assert_error(MissingFileError, read, "gyro_exp01_user01.txt")


# ---- UJI phone + watch ------------------------------------------------------------------------


@pytest.fixture(scope="module")
def uji_root(shared_data) -> Path:
    return shared_data / "uji_phone_watch_har"


UJI_LABELS = {"SEATED", "STANDING_UP", "WALKING", "TURNING", "SITTING_DOWN"}


def label_runs(values) -> list[str]:
    values = list(values)
    return [v for i, v in enumerate(values) if i == 0 or v != values[i - 1]]


def test_uji_real_slice(uji_root):
    recs = list(uji_phone_watch.read(uji_root, limit=2))
    assert [r.name for r in recs] == ["uji_s01_01", "uji_s01_02"]
    for rec in recs:
        eid = rec.meta["execution"]
        assert set(rec.devices) == {"phone", "watch"}
        t0 = rec.meta["t0_unix_ms"]
        for dev, code, rate in (("phone", "sp", 102.4), ("watch", "sw", 104.3)):
            raw = pd.read_csv(uji_root / "DATA" / "s01" / f"{eid}_{code}.csv.xz")
            s = rec.devices[dev]
            assert len(s) == len(raw)
            assert s.gyro is not None and s.quat is None
            assert s.rate == pytest.approx(rate, abs=0.5)
            assert np.std(np.diff(s.t)) < 1e-6  # rebuilt constant-rate clock
            assert 9.3 < med_norm(s.acc) < 10.6 and med_norm(s.gyro) < 5
            np.testing.assert_allclose(s.acc, raw[["x_acc", "y_acc", "z_acc"]], rtol=1e-6, atol=1e-6)
            # On the shared UNIX clock: never after the logged time, never more than 0.2 s before.
            lag = raw["timestamp"].to_numpy() - (s.t * 1e3 + t0)
            assert lag.min() > -1e-3 and lag.max() < 200
            kind = "activity" if dev == "phone" else "activity_watch"
            lab = rec.labels[rec.labels["kind"] == kind].sort_values("start")
            assert lab["value"].tolist() == label_runs(raw["label"])
            assert set(lab["value"]) <= UJI_LABELS
            assert (rec.label_at(kind, s.t) == raw["label"].to_numpy()).all()
        assert abs(rec.devices["phone"].t[0] - rec.devices["watch"].t[0]) < 0.1
        assert rec.meta["phone_orientation"] == "back_inv" and rec.meta["age"] == 54
        assert rec.meta["licence"] == "CC BY 4.0"


@pytest.fixture
def uji_copy(uji_root, tmp_path) -> Path:
    """DATA/s01 with s01_01 (phone plain, watch .gz, 300 rows each) and the info tables."""
    data = tmp_path / "uji" / "DATA"
    for code in ("sp", "sw"):
        lines = raw_lines(uji_root / "DATA" / "s01" / f"s01_01_{code}.csv.xz")[:301]
        p = write_lines(data / "s01" / f"s01_01_{code}.csv", lines)
        if code == "sw":
            with open(p, "rb") as src, gzip.open(p.with_name(p.name + ".gz"), "wb") as dst:
                dst.write(src.read())
            p.unlink()
    shutil.copy(uji_root / "DATA" / "executions_info.csv", data / "executions_info.csv")
    # The copy holds one execution of s01: say so, as the table declares how many there are.
    subjects = (uji_root / "DATA" / "subjects_info.csv").read_text().splitlines()
    write_lines(
        data / "subjects_info.csv",
        [",".join(ln.split(",")[:-1] + ["1"]) if ln.startswith("s01,") else ln for ln in subjects],
    )
    return tmp_path / "uji"


def test_uji_copy_reads_from_subject_folder(uji_copy):
    (rec,) = uji_phone_watch.read(uji_copy / "DATA" / "s01")
    assert len(rec.devices["phone"]) == len(rec.devices["watch"]) == 300


def test_uji_errors(uji_copy, tmp_path):
    f = uji_copy / "DATA" / "s01" / "s01_01_sp.csv"
    lines = f.read_text().splitlines()
    read = lambda: list(uji_phone_watch.read(uji_copy))

    (tmp_path / "x").mkdir()
    assert_error(FormatError, lambda: list(uji_phone_watch.read(tmp_path / "x")), "no UJI")

    write_lines(f, [lines[0].replace("timestamp", "time")] + lines[1:])
    assert_error(FormatError, read, "s01_01_sp.csv", "timestamp")

    def with_ts(i, new):
        cells = lines[i].split(",")
        cells[6] = str(new)
        return lines[:i] + [",".join(cells)] + lines[i + 1 :]

    write_lines(f, with_ts(100, int(lines[99].split(",")[6]) - 5))
    assert_error(FormatError, read, "s01_01_sp.csv", "backwards")
    shifted = lines[:1] + [
        ",".join(c[:6] + [str(int(c[6]) + (2000 if i > 150 else 0))] + c[7:])
        for i, c in enumerate((x.split(",") for x in lines[1:]), 1)
    ]
    write_lines(f, shifted)
    assert_error(FormatError, read, "s01_01_sp.csv", "constant sampling rate")

    bad = lines[:]
    bad[7] = bad[7].replace(bad[7].split(",")[3], "", 1)
    write_lines(f, bad)
    assert_error(FormatError, read, "s01_01_sp.csv", "NaN")
    write_lines(f, lines[:1])
    assert_error(FormatError, read, "s01_01_sp.csv", "no data rows")

    f.unlink()
    assert_error(MissingFileError, read, "s01_01_sp.csv", "phone")


# ---- Oxford step counter ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def ox_dir(shared_data) -> Path:
    return shared_data / "oxford_step_counter" / "validation"


def test_oxford_real_files(ox_dir):
    for name, dup, zero in (("user1_hand_1506421989895", 0, 1), ("user1_armband_1506423438471", 1, 0)):
        path = ox_dir / f"{name}.csv.xz"
        raw = pd.read_csv(path, header=None)
        (rec,) = oxford_steps.read(path)
        s = rec.devices["phone"]
        assert rec.name == f"oxford_{name}"
        assert s.gyro is None and s.quat is None
        assert len(s) == len(raw) - dup - zero
        assert rec.meta["dropped_duplicates"] == ({"timestamp": dup} if dup else {})
        assert rec.meta["dropped_zero_rows"] == zero
        assert 95 < s.rate < 110 and rec.meta["rate_hz"] == pytest.approx(s.rate, abs=1e-3)
        assert 9.5 < med_norm(s.acc) < 10.8
        gt, algo = raw[5].to_numpy(), raw[4].to_numpy()
        steps = rec.labels[rec.labels["kind"] == "step"]
        assert len(steps) == gt[-1] - gt[0] == rec.meta["steps_groundtruth"] > 300
        assert (steps["start"] == steps["end"]).all()
        # Each step is timed at the (kept) row where the raw count rose.
        ts = raw[0].to_numpy()
        t_rise = (ts[np.flatnonzero(np.diff(gt)) + 1] - rec.meta["t0_boot_ns"]) / 1e9
        np.testing.assert_allclose(np.sort(steps["start"].to_numpy()), t_rise, atol=1e-9)
        assert (rec.labels["kind"] == "step_algo").sum() == algo[-1] - algo[0]
        placement = name.split("_")[1]
        assert rec.meta["placement"] == placement
        assert rec.labels[rec.labels["kind"] == "placement"]["value"].tolist() == [placement]
        assert rec.meta["hw_step_counter"] is None  # user1's phone logged no hardware count


def test_oxford_folder_limit(ox_dir):
    recs = list(oxford_steps.read(ox_dir.parent, limit=3))
    assert len(recs) == 3 == len({r.name for r in recs})
    assert {r.meta["subject"] for r in recs} == {"user1"}


def test_oxford_errors(ox_dir, tmp_path):
    lines = raw_lines(ox_dir / "user2_hand_1506421987098.csv.xz")[:300]
    f = tmp_path / "validation" / "user2_hand_1506421987098.csv"
    read = lambda: list(oxford_steps.read(tmp_path))
    write_lines(f, lines)
    (rec,) = read()
    assert len(rec.devices["phone"]) == 300

    (tmp_path / "nothing").mkdir()
    write_lines(tmp_path / "nothing" / "README.md", ["no data"])
    assert_error(FormatError, lambda: list(oxford_steps.read(tmp_path / "nothing")), "nothing", "no Oxford")

    def set_cell(i, col, value):
        cells = lines[i].split(",")
        cells[col] = value
        return lines[:i] + [",".join(cells)] + lines[i + 1 :]

    write_lines(f, set_cell(50, 0, lines[49].split(",")[0]))  # same time, other values
    (rec,) = read()  # the one duplicate policy: the first row is kept, the repeat counted
    assert len(rec.devices["phone"]) == 299 and rec.meta["dropped_duplicates"] == {"timestamp": 1}
    np.testing.assert_allclose(rec.devices["phone"].acc[49], [float(x) for x in lines[49].split(",")[1:4]], rtol=1e-6)
    write_lines(f, set_cell(50, 0, str(int(lines[49].split(",")[0]) - 1000)))
    assert_error(ValidationError, read, f.name, "backwards")
    write_lines(f, set_cell(50, 2, "nan"))
    assert_error(FormatError, read, f.name, "NaN")
    write_lines(f, [",".join(x.split(",")[:6]) for x in lines])
    assert_error(FormatError, read, f.name, "7 columns")
    f.write_text("")
    assert_error(FormatError, read, f.name, "empty")
    # The raw .xz cut in half.
    data = lzma.compress("\n".join(lines).encode())
    f.unlink()
    f.with_name(f.name + ".xz").write_bytes(data[: len(data) // 2])
    assert_error(FormatError, read, f.name + ".xz")


def test_oxford_step_count_going_down_is_refused(ox_dir, tmp_path):
    lines = raw_lines(ox_dir / "user2_hand_1506421987098.csv.xz")[:3000]
    counts = [int(x.split(",")[5]) for x in lines]
    i = next(k for k in range(1, len(counts)) if counts[k] > counts[k - 1])
    cells = lines[i + 1].split(",")
    cells[5] = str(counts[i] - 1)
    f = write_lines(tmp_path / "user2_hand_1506421987098.csv", lines[: i + 1] + [",".join(cells)] + lines[i + 2 :])
    assert_error(FormatError, lambda: list(oxford_steps.read(f)), f.name, "goes down")


# ---- all four: registry, validation errors name the file, command line -----------------------


@pytest.mark.parametrize("fmt", ["motionsense", "uci-hapt", "uji-phone-watch", "oxford-steps"])
def test_registry_and_limit_zero(fmt, shared_data):
    module = get_importer(fmt)
    folder = {
        "motionsense": "motionsense",
        "uci-hapt": "uci_hapt",
        "uji-phone-watch": "uji_phone_watch_har",
        "oxford-steps": "oxford_step_counter",
    }[fmt]
    assert list(module.read(shared_data / folder, limit=0)) == []


def test_units_error_names_the_file(ox_dir, tmp_path):
    # acc logged in g instead of m/s²: the Recording's unit check fires, attributed to the file.
    lines = raw_lines(ox_dir / "user2_hand_1506421987098.csv.xz")[:300]
    scaled = [
        ",".join([c[0]] + [f"{float(v) / 9.81:.6f}" for v in c[1:4]] + c[4:]) for c in (x.split(",") for x in lines)
    ]
    f = write_lines(tmp_path / "user2_hand_1506421987098.csv", scaled)
    msg = assert_error(ValidationError, lambda: list(oxford_steps.read(f)), f.name, "median |acc|")
    assert "9.80665" in msg


def test_cli_import_and_one_line_error(ox_dir, tmp_path):
    exe = Path(sys.executable).with_name("wearnav")
    ok = subprocess.run(
        [str(exe), "import", "oxford-steps", str(ox_dir), "--out", str(tmp_path / "ds"), "--limit", "1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert ok.returncode == 0, ok.stderr
    assert '"recordings": 1' in ok.stdout
    (tmp_path / "empty").mkdir()
    bad = subprocess.run(
        [str(exe), "import", "uci-hapt", str(tmp_path / "empty"), "--out", str(tmp_path / "ds2")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bad.returncode == 2
    # Besides tqdm's progress bar (import_dataset's), exactly one line: the error.
    err = [x for x in bad.stderr.strip().splitlines() if not x.startswith("import uci-hapt:")]
    assert len(err) == 1 and err[0].startswith("error:") and "empty" in err[0]
    assert issubclass(FormatError, WearnavError)
