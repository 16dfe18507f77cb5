"""IPIN 2023 Track 3 importer on real logs (text and the organisers' .mat), plus one-line errors."""

from __future__ import annotations

import lzma

import h5py
import numpy as np
import pytest
import scipy.io
from scipy.spatial.transform import Rotation
from scipy.stats import spearmanr

from conftest import error_line
from wearnav.core.geo import PROJECTION, latlon_to_local
from wearnav.errors import FormatError, MissingFileError, ValidationError
from wearnav.importers import ipin2023, ipin2023_radio

LOGS = "01 Logfiles/01 IPIN2023_T3_TrainingTrials (training)"
TRA = "02 Supplementary Materials/03 - Files for Matlab Tools/Trajectories"
TXT_LOG = "IPIN2023_T3_TrainingTrial04_repetition01"
MAT_LOG = "IPIN2023_T3_TrainingTrial51_repetition01"


@pytest.fixture(scope="module")
def ipin_root(shared_data):
    return shared_data / "ipin2023_track3"


@pytest.fixture(scope="module")
def log_path(ipin_root):
    return ipin_root / LOGS / f"{TXT_LOG}.txt.xz"


@pytest.fixture(scope="module")
def log_lines(log_path):
    with lzma.open(log_path, "rt", encoding="utf-8", errors="replace") as f:
        return f.read().splitlines()


@pytest.fixture(scope="module")
def rec(log_path):
    (r,) = list(ipin2023.read(log_path))
    return r


def rows_of(lines, tag):
    return [ln.split(";") for ln in lines if ln.startswith(tag + ";")]


def read_tra(path):
    rows = [ln.split() for ln in path.read_text().splitlines() if ln[:1].isdigit()]
    return np.array([[float(v) for v in r[1:4]] for r in rows])  # lat, lon, floor


def write_log(path, lines):
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def short_log(lines, n_data=3000):
    """The header and the first ``n_data`` data rows (about 10 s) of a log."""
    head = [ln for ln in lines if ln.startswith("%")]
    data = [ln for ln in lines if ln and not ln.startswith("%")][:n_data]
    return head + data


# ---- real text log ---------------------------------------------------------------------------


def test_imu_stream(rec, log_lines):
    s = rec.devices["phone"]
    acce = rows_of(log_lines, "ACCE")
    assert rec.name == TXT_LOG
    assert len(s) == len(acce)
    assert 49.0 < s.rate < 51.0
    assert s.gyro is not None and s.quat is not None
    np.testing.assert_allclose(np.linalg.norm(s.quat, axis=1), 1.0, atol=1e-5)
    assert 9.3 < np.median(np.linalg.norm(s.acc, axis=1)) < 10.3
    np.testing.assert_allclose(s.acc[0], [float(v) for v in acce[0][3:6]], rtol=1e-6)
    # Sensor timestamps put on the app clock: never later than the app's own stamp, close to it.
    app = np.array([float(r[1]) for r in acce])
    lag = app - s.t
    assert lag.min() == pytest.approx(0.0, abs=1e-6) and np.median(lag) < 0.05
    assert rec.meta["gyro_rate_hz"] == pytest.approx(100.0, abs=1)  # resampled onto the 50 Hz ACCE


def test_quaternion_convention(rec, log_lines):
    """The docstring's claims: quat is world<-device (ENU), Euler angles are Rz(yaw)Rx(pitch)Ry(roll)."""
    s = rec.devices["phone"]
    rot = Rotation.from_quat(np.column_stack([s.quat[:, 1:], s.quat[:, :1]]))
    acc_world = rot.apply(s.acc).mean(axis=0)
    assert abs(acc_world[2] - 9.8) < 0.3 and np.hypot(*acc_world[:2]) < 0.3
    body_rate = (rot[:-1].inv() * rot[1:]).as_rotvec() / np.diff(s.t)[:, None]
    gyro = 0.5 * (s.gyro[:-1] + s.gyro[1:])
    for k in range(3):
        assert np.corrcoef(body_rate[:, k], gyro[:, k])[0, 1] > 0.9
    ahrs = np.array([[float(v) for v in r[2:6]] for r in rows_of(log_lines, "AHRS")])
    acce_sensor_t = np.array([float(r[2]) for r in rows_of(log_lines, "ACCE")])
    assert np.array_equal(ahrs[:, 0], acce_sensor_t)  # this log: AHRS on the ACCE timestamps
    pitch, roll, yaw = ahrs[:, 1], ahrs[:, 2], ahrs[:, 3]
    from_angles = Rotation.from_euler("ZXY", np.column_stack([yaw, pitch, roll]), degrees=True)
    err_deg = np.degrees((from_angles.inv() * rot).magnitude())
    assert np.percentile(err_deg, 99) < 0.5


def test_posi_truth_matches_reference_file(rec, log_lines, ipin_root):
    posi = rows_of(log_lines, "POSI")
    assert len(rec.truth) == len(posi) == 14
    np.testing.assert_array_equal(rec.truth.t, [float(p[1]) for p in posi])
    tra = read_tra(ipin_root / TRA / f"{TXT_LOG}.tra")
    lat0, lon0 = rec.meta["origin_lat"], rec.meta["origin_lon"]
    np.testing.assert_allclose(rec.truth.pos, latlon_to_local(tra[:, 0], tra[:, 1], lat0, lon0), atol=0.01)
    np.testing.assert_array_equal(rec.truth.floor, tra[:, 2])
    assert rec.meta["floors"] == [0] and rec.meta["building"] == 100
    # The venue origin: the surveyed points lie within the museum (~100 m).
    assert np.all(np.linalg.norm(rec.truth.pos, axis=1) < 150)


def test_gnss_fixes(rec, log_lines):
    gnss = rows_of(log_lines, "GNSS")
    f, m = rec.fixes, rec.meta
    assert len(f) + m["gnss_repeats_dropped"] + m["gnss_stale_dropped"] == len(gnss)
    assert m["gnss_repeats_dropped"] >= len(gnss) // 2 - 5  # every fix is logged twice
    assert 0 < m["gnss_stale_dropped"] < 20
    assert np.all(np.diff(f.t) > 0) and 0.9 < np.median(np.diff(f.t)) < 1.1
    assert np.all(f.accuracy > 0)
    # Same origin as the truth, and the fixes near the surveyed points at the same moments.
    lat0, lon0 = m["origin_lat"], m["origin_lon"]
    g = np.array([[float(r[3]), float(r[4])] for r in gnss])
    assert np.all(
        np.min(np.linalg.norm(f.pos[:, None, :] - latlon_to_local(g[:, 0], g[:, 1], lat0, lon0)[None], axis=2), axis=1)
        < 1e-6
    )
    errs = []
    for t, p in zip(rec.truth.t, rec.truth.pos):
        k = int(np.argmin(np.abs(f.t - t)))
        if abs(f.t[k] - t) < 2.0:
            errs.append(np.linalg.norm(f.pos[k] - p))
    assert len(errs) >= 10
    assert np.max(errs) < 200 and np.median(errs) < 30


def test_meta(rec):
    m = rec.meta
    assert m["source"] == "ipin2023" and "zenodo.8362205" in m["licence"]
    assert m["device"] == "samsung SM-A520F" and m["android"] == "8.0.0"
    assert m["split"] == "train" and m["trial"] == 4 and m["repetition"] == 1
    assert m["mode"] == "walk" and m["placement"] == "handheld"
    assert m["origin"].startswith("IPIN 2023 Nuremberg")
    assert m["projection"] == PROJECTION


def test_pressure(rec, log_lines):
    pres = rows_of(log_lines, "PRES")
    p = rec.pressure
    assert len(p) == len(pres) > 500
    np.testing.assert_array_equal(p.hpa, [float(r[3]) for r in pres])
    # Sensor times on the app clock: never after the app's stamp, and within a second of it.
    delay = np.array([float(r[1]) for r in pres]) - p.t
    assert delay.min() == pytest.approx(0.0, abs=1e-6) and np.median(delay) < 1.0
    assert 900 < np.median(p.hpa) < 1050 and np.ptp(p.hpa) < 2.0  # one floor (truth.floor is all 0)


def test_beacon_readings_are_named_as_the_location_table(rec, log_lines):
    ble = rows_of(log_lines, "BLE4")
    b = rec.beacons
    assert len(b) == len(ble) > 100
    np.testing.assert_array_equal(b.t, [float(r[1]) for r in ble])
    np.testing.assert_array_equal(b.rssi_dbm, [float(r[4]) for r in ble])
    swap = {"2": "BLE3", "3": "BLE2"}
    assert list(b.beacon) == [swap.get(r[7], f"BLE{r[7]}") for r in ble]
    # The .mat keeps only the MAC: its last two bytes are the minor on every row.
    assert [ipin2023_radio._venue_beacon_minor(r[3]) for r in ble] == [int(r[7]) for r in ble]
    assert set(b.beacon) <= set(rec.meta["beacons"])


def test_each_beacon_fades_with_distance_from_its_own_surveyed_position(ipin_root):
    """The evidence for VENUE_MINOR_TO_BLE_ID (minors 2 and 3 swapped against the table): over the
    first repetition of every trial, with the walker's position interpolated between consecutive
    surveyed points on one floor, each beacon's RSSI falls with the distance from its own surveyed
    position (Spearman ρ < -0.5) more clearly than from any other beacon's position (readings on
    that position's floor)."""
    pairs: dict[tuple[str, str], list[tuple[np.ndarray, np.ndarray]]] = {}
    beacons: dict = {}
    for path in sorted((ipin_root / LOGS).glob("*repetition01.*")):
        (r,) = list(ipin2023.read(path))
        beacons, tr, b = r.meta["beacons"], r.truth, r.beacons
        i = np.clip(np.searchsorted(tr.t, b.t) - 1, 0, len(tr) - 2)
        on_span = (b.t > tr.t[0]) & (b.t < tr.t[-1]) & (tr.floor[i] == tr.floor[i + 1])
        pos = np.column_stack([np.interp(b.t, tr.t, tr.pos[:, k]) for k in range(2)])
        for bid in beacons:
            for at in beacons:
                m = on_span & (b.beacon == bid) & (tr.floor[i] == beacons[at][2])
                pairs.setdefault((bid, at), []).append(
                    (np.linalg.norm(pos[m] - beacons[at][:2], axis=1), b.rssi_dbm[m])
                )
    for bid in beacons:
        rho = {}
        for at in beacons:
            d, rssi = (np.concatenate(x) for x in zip(*pairs[bid, at]))
            rho[at] = spearmanr(d, rssi)[0] if len(d) > 20 else np.nan
        assert rho[bid] < -0.5 and rho[bid] == np.nanmin(list(rho.values())), (bid, rho)


def test_beacon_positions(rec, ipin_root):
    table = ipin_root / "02 Supplementary Materials/02 - BLE Locations/BLE_Locations.csv"
    rows = [ln.split(",") for ln in table.read_text().splitlines()[1:]]
    lat0, lon0 = rec.meta["origin_lat"], rec.meta["origin_lon"]
    xy = latlon_to_local([float(r[1]) for r in rows], [float(r[2]) for r in rows], lat0, lon0)
    beacons = rec.meta["beacons"]
    assert list(beacons) == [f"BLE{k}" for k in range(1, 7)]
    np.testing.assert_allclose([v[:2] for v in beacons.values()], xy, atol=1e-3)
    assert [v[2] for v in beacons.values()] == [0, 0, -2, -2, -2, -2]
    assert np.all(np.linalg.norm(xy, axis=1) < 60)  # inside the museum, about the venue origin


def test_no_beacon_table_no_positions(tmp_path, log_path):
    (tmp_path / log_path.name).write_bytes(log_path.read_bytes())
    (r,) = list(ipin2023.read(tmp_path / log_path.name))
    assert "beacons" not in r.meta and "BLE_Locations.csv not found" in r.meta["beacons_note"]
    assert len(r.beacons) > 100  # the readings are still there


# ---- the organisers' .mat and our own .mat round trips ----------------------------------------


def test_real_mat_conversion(ipin_root):
    (r,) = list(ipin2023.read(ipin_root / LOGS / f"{MAT_LOG}.mat"))
    s = r.devices["phone"]
    assert r.name == MAT_LOG and r.meta["file_format"] == "mat"
    assert 49.0 < s.rate < 51.0 and s.gyro is not None and s.quat is not None
    assert 9.3 < np.median(np.linalg.norm(s.acc, axis=1)) < 10.3
    tra = read_tra(ipin_root / TRA / f"{MAT_LOG}.tra")
    lat0, lon0 = r.meta["origin_lat"], r.meta["origin_lon"]
    np.testing.assert_allclose(r.truth.pos, latlon_to_local(tra[:, 0], tra[:, 1], lat0, lon0), atol=0.01)
    np.testing.assert_array_equal(r.truth.floor, tra[:, 2])
    assert r.meta["floors"] == [-2, -1, 0]
    assert len(r.fixes) > 100 and np.all(np.diff(r.fixes.t) > 0)
    mat = scipy.io.loadmat(ipin_root / LOGS / f"{MAT_LOG}.mat")
    np.testing.assert_array_equal(r.pressure.hpa, mat["Pres"][:, 2])
    assert len(r.beacons) == len(mat["Ble4"]) and set(r.beacons.beacon) <= set(r.meta["beacons"])
    np.testing.assert_array_equal(r.beacons.rssi_dbm, [float(np.ravel(c[2])[0]) for c in mat["Ble4"]])


def mat_arrays(log_path):
    data, _ = ipin2023.read_txt(log_path)
    return {
        "Acce": data["ACCE"],
        "Gyro": data["GYRO"],
        "Ahrs": data["AHRS"],
        "Gnss": data["GNSS"],
        "Posi": data["POSI"][:, :4],
    }


def write_mat_v73(path, arrays):
    """What MATLAB's save -v7.3 writes: HDF5 behind a 512-byte MAT header, arrays transposed."""
    with h5py.File(path, "w", userblock_size=512) as f:
        for k, v in arrays.items():
            f.create_dataset(k, data=np.asarray(v).T)
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, HDF5 schema 1.00 .".ljust(116, b" ")
    with open(path, "r+b") as f:
        f.write((header + b"\0" * 8 + b"\x00\x02IM").ljust(512, b"\0"))


@pytest.mark.parametrize("version", ["v5", "v7.3"])
def test_mat_matches_text_log(tmp_path, log_path, rec, version):
    path = tmp_path / f"{TXT_LOG}.mat"
    if version == "v5":
        scipy.io.savemat(path, mat_arrays(log_path))
    else:
        write_mat_v73(path, mat_arrays(log_path))
    (r,) = list(ipin2023.read(path))
    a, b = r.devices["phone"], rec.devices["phone"]
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.acc, b.acc)
    np.testing.assert_allclose(a.quat, b.quat, atol=1e-6)
    np.testing.assert_array_equal(r.truth.pos, rec.truth.pos)
    np.testing.assert_array_equal(r.fixes.t, rec.fixes.t)


# ---- folders -----------------------------------------------------------------------------------


def test_folder_import_skips_docs_and_honours_limit(ipin_root):
    logs = ipin2023.find_logs(ipin_root)
    assert len(logs) == 44 and not any("README" in p.name for p in logs)
    assert sum(p.suffix == ".mat" for p in logs) == 2
    recs = list(ipin2023.read(ipin_root / LOGS, limit=2))
    assert len(recs) == 2 and recs[0].name != recs[1].name


def test_text_log_wins_over_mat_of_same_name(tmp_path, log_path):
    (tmp_path / log_path.name).write_bytes(log_path.read_bytes())
    scipy.io.savemat(tmp_path / f"{TXT_LOG}.mat", {"Acce": np.zeros((3, 5))})
    (tmp_path / "README.txt").write_text("Contents: logs\n")
    assert ipin2023.find_logs(tmp_path) == [tmp_path / log_path.name]


def test_the_datasets_own_readme_is_skipped_without_a_word(tmp_path, caplog):
    """ZZ_README.txt (the organisers' readme) and a LICENSE pass silently; a stray text file that is
    not a log is still named."""
    (tmp_path / "trial01.txt").write_text("% GetSensorData log\nACCE;0.01;0.01;0.1;0.2;9.8;3\n")
    (tmp_path / "ZZ_README.txt").write_text("Contents of the IPIN 2023 Track 3 folder\n")
    (tmp_path / "LICENSE.txt").write_text("CC BY 4.0\n")
    (tmp_path / "notes.txt").write_text("my notes\n")
    with caplog.at_level("INFO", logger="wearnav.importers.ipin2023"):
        logs = ipin2023.find_logs(tmp_path)
    assert logs == [tmp_path / "trial01.txt"]
    skipped = [r.getMessage() for r in caplog.records if r.getMessage().startswith("skipping")]
    assert skipped == [f"skipping {tmp_path / 'notes.txt'}: not a GetSensorData log"]


def test_stale_fix_is_dropped(tmp_path, log_lines):
    lines = short_log(log_lines)
    gnss = [k for k, ln in enumerate(lines) if ln.startswith("GNSS;")]
    base = ipin2023.read_log(write_log(tmp_path / "a.txt", lines))
    k = gnss[-1]
    f = lines[k].split(";")
    f[1] = f"{float(f[1]) + 0.01:.4f}"
    f[2] = f"{float(f[2]) - 30:.4f}"  # a location from 30 s ago, handed over now
    lines.insert(k + 1, ";".join(f))
    r = ipin2023.read_log(write_log(tmp_path / "b.txt", lines))
    assert r.meta["gnss_stale_dropped"] == base.meta["gnss_stale_dropped"] + 1
    np.testing.assert_array_equal(r.fixes.t, base.fixes.t)
    assert base.truth is None  # the first 10 s hold no reference point


# ---- one-line errors ---------------------------------------------------------------------------


def test_missing_path(tmp_path):
    with pytest.raises(MissingFileError) as e:
        list(ipin2023.read(tmp_path / "nope.txt"))
    assert "nope.txt" in error_line(e.value)


def test_wrong_folder(tmp_path):
    (tmp_path / "README.txt").write_text("nothing to see\n")
    with pytest.raises(FormatError, match="no GetSensorData logs") as e:
        list(ipin2023.read(tmp_path))
    error_line(e.value)


def test_empty_file_alone_and_in_a_folder(tmp_path):
    (tmp_path / "log.txt").write_text("")
    for src in (tmp_path / "log.txt", tmp_path):
        with pytest.raises(FormatError, match="empty file") as e:
            list(ipin2023.read(src))
        assert "log.txt" in error_line(e.value)


def test_truncated_xz(tmp_path, log_path):
    data = log_path.read_bytes()
    bad = tmp_path / "cut.txt.xz"
    bad.write_bytes(data[: len(data) // 3])
    with pytest.raises(FormatError, match="truncated or corrupt") as e:
        list(ipin2023.read(bad))
    assert "cut.txt.xz" in error_line(e.value)


def test_nan_in_acce(tmp_path, log_lines):
    lines = short_log(log_lines)
    k = [i for i, ln in enumerate(lines) if ln.startswith("ACCE;")][50]
    f = lines[k].split(";")
    f[4] = "nan"
    lines[k] = ";".join(f)
    with pytest.raises(FormatError, match="ACCE rows has NaN") as e:
        list(ipin2023.read(write_log(tmp_path / "nan.txt", lines)))
    assert "nan.txt" in error_line(e.value)


def test_acce_time_going_backwards(tmp_path, log_lines):
    lines = short_log(log_lines)
    idx = [i for i, ln in enumerate(lines) if ln.startswith("ACCE;")]
    lines[idx[20]], lines[idx[21]] = lines[idx[21]], lines[idx[20]]
    with pytest.raises(ValidationError, match="ACCE SensorTimestamp: timestamps go backwards") as e:
        list(ipin2023.read(write_log(tmp_path / "back.txt", lines)))
    assert "back.txt" in error_line(e.value)


def test_wrong_format_text(tmp_path, shared_data):
    trace = sorted((shared_data / "ilc2_indoor_location").rglob("*.txt.gz"))[0]
    bad = tmp_path / "trace.txt.gz"
    bad.write_bytes(trace.read_bytes())
    with pytest.raises(FormatError, match="not a GetSensorData log") as e:
        list(ipin2023.read(bad))
    assert "trace.txt.gz" in error_line(e.value)


def test_wrong_format_mat(tmp_path):
    scipy.io.savemat(tmp_path / "other.mat", {"x": np.zeros(3)})
    with pytest.raises(FormatError, match="no 'Acce' variable"):
        list(ipin2023.read(tmp_path / "other.mat"))
    (tmp_path / "junk.mat").write_bytes(b"\x01\x02 definitely not matlab" * 20)
    with pytest.raises(FormatError) as e:
        list(ipin2023.read(tmp_path / "junk.mat"))
    assert "junk.mat" in error_line(e.value)
