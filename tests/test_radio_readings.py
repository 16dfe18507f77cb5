"""Radio readings in the data model (issue 60 §1): Wi-Fi scans, iBeacon readings with Tx power and
distance, the magnetometer; their checks, their HDF5 round trip, and the importers (IPIN 2023's WIFI,
BLE4 and MAGN rows, ILC2's TYPE_WIFI and TYPE_BEACON rows) on small written logs and on real ones."""

from __future__ import annotations

import dataclasses
import gzip
import lzma

import h5py
import numpy as np
import pytest

from conftest import error_line, make_stream
from wearnav.errors import FormatError, ValidationError
from wearnav.importers import ilc2, ipin2023
from wearnav.recording import BeaconReadings, MagneticField, Recording, WifiScans

IPIN_LOG = "ipin2023_track3/01 Logfiles/01 IPIN2023_T3_TrainingTrials (training)/IPIN2023_T3_TrainingTrial01_repetition01.txt.xz"
IPIN_MAT = (
    "ipin2023_track3/01 Logfiles/01 IPIN2023_T3_TrainingTrials (training)/IPIN2023_T3_TrainingTrial52_repetition02.mat"
)
ILC2_TRACE = "ilc2_indoor_location/site1/F1/path_data_files/5dd9e7c4c5b77e0006b17335.txt.gz"


def wifi(**kw):
    base = dict(
        t=[1.0, 1.0, 1.0, 3.0],
        bssid=["aa:01", "aa:02", "aa:03", "aa:01"],
        ssid=["net", "net", "", "net"],
        freq_mhz=[2412, 5180, 2437, 2412],
        rssi_dbm=[-50, -70, -90, -55],
        t_seen=[0.9, 0.95, 0.5, 2.9],
    )
    return WifiScans(**(base | kw))


# ---- the tables and their checks -------------------------------------------------------------


def test_wifi_scans_hold_scans_and_readings():
    w = wifi()
    assert len(w) == 4
    np.testing.assert_array_equal(w.scan_starts, [0, 3, 4])  # two scans: at 1 s (3 readings), 3 s (1)
    assert w.bssid.dtype == object and w.ssid[2] == ""
    # one scan may hear an access point twice with different own timestamps (a cached reading)
    w2 = wifi(bssid=["aa:01", "aa:01", "aa:03", "aa:01"])
    assert len(w2) == 4


@pytest.mark.parametrize(
    "change, words",
    [
        (dict(rssi_dbm=[-50, np.nan, -90, -55]), "wifi.rssi_dbm: nan at reading 1 is not a received power"),
        (dict(rssi_dbm=[-50, 20, -90, -55]), "wifi.rssi_dbm: 20 at reading 1 is not a received power"),
        (dict(t=[1.0, 1.0, 3.0, 2.0]), "wifi.t: unsorted timestamps at sample 3"),
        (dict(t=[1.0, np.nan, 1.0, 3.0]), "wifi.t: time has non-finite values"),
        (dict(freq_mhz=[2.412, 5180, 2437, 2412]), "wifi.freq_mhz: 2.412 at reading 0 is not a Wi-Fi channel"),
        (dict(t_seen=[0.9, 0.9, 0.5, 2.9], bssid=["aa:01", "aa:01", "aa:03", "aa:01"]), "heard twice in the scan"),
        (dict(t_seen=[0.9, np.inf, 0.5, 2.9]), "wifi.t_seen: infinite value at reading 1"),
        (dict(ssid=["net", "a\x00b", "", "net"]), "contains NUL"),
        (dict(bssid=["aa:01", "aa:02"]), "wifi.bssid: shape (2,), expected (4,)"),
    ],
)
def test_wifi_scans_refuse_bad_readings_in_one_line(change, words):
    with pytest.raises(ValidationError) as e:
        wifi(**change)
    assert words in error_line(e.value)


def test_beacon_readings_keep_tx_power_and_distance():
    b = BeaconReadings(
        [1.0, 1.0, 2.0], ["U:0:0:M1", "U:0:0:M2", "U:0:0:M1"], [-80, -70, -75], [-56, -56, -56], [3.0, np.nan, 2.0]
    )
    assert b.tx_power_dbm is not None and np.isnan(b.distance_m[1])
    with pytest.raises(ValidationError, match="beacons.distance_m: -1 m at reading 0 is not a distance"):
        BeaconReadings([1.0], ["x"], [-80], None, [-1.0])
    with pytest.raises(ValidationError, match=r"beacons.tx_power_dbm: shape \(2,\), expected \(1,\)"):
        BeaconReadings([1.0], ["x"], [-80], [-56, -56])


@pytest.mark.parametrize(
    "t, ut, words",
    [
        ([0.0, 0.02, 0.02], np.zeros((3, 3)), "magnetic.t: duplicated timestamps at sample 2"),
        ([0.0, 0.04, 0.02], np.zeros((3, 3)), "magnetic.t: unsorted timestamps at sample 2"),
        (
            [0.0, 0.02, 0.04],
            [[0, 0, 0], [np.nan, 0, 0], [0, 0, 0]],
            "magnetic.ut: non-finite values (first at sample 1)",
        ),
        ([0.0, 0.02, 0.04], [[0, 0, 0], [0, 0, 0], [0, 0, 9000]], "magnetic.ut: 1 of 3 samples beyond ±5000 µT"),
        ([0.0, 0.02, 0.04], np.zeros((3, 2)), "magnetic.ut: shape (3, 2), expected (3,3)"),
    ],
)
def test_magnetic_field_refuses_bad_samples(t, ut, words):
    with pytest.raises(ValidationError) as e:
        MagneticField(t, ut)
    assert words in error_line(e.value)


def radio_recording(name="radio1"):
    mag_t = np.arange(0, 2.0, 0.02)
    return Recording(
        name=name,
        devices={"phone": make_stream(200, 100.0)},
        wifi=wifi(),
        beacons=BeaconReadings([0.5, 1.5], ["U:1:2:M", "BLE1"], [-80, -60], [-59, np.nan], [4.2, np.nan]),
        magnetic=MagneticField(mag_t, np.tile([20.0, -5.0, -40.0], (mag_t.size, 1))),
    )


def test_h5_round_trip_keeps_every_radio_column(tmp_path):
    rec = radio_recording()
    back = Recording.load(rec.save(tmp_path / "r.h5"))
    w, b, m = back.wifi, back.beacons, back.magnetic
    assert w is not None and b is not None and m is not None
    for key in ("t", "freq_mhz", "rssi_dbm", "t_seen"):
        np.testing.assert_array_equal(getattr(w, key), getattr(rec.wifi, key))
    assert list(w.bssid) == list(rec.wifi.bssid) and list(w.ssid) == list(rec.wifi.ssid)
    np.testing.assert_array_equal(b.tx_power_dbm, rec.beacons.tx_power_dbm)
    np.testing.assert_array_equal(b.distance_m, rec.beacons.distance_m)
    assert list(b.beacon) == ["U:1:2:M", "BLE1"]
    np.testing.assert_array_equal(m.ut, rec.magnetic.ut)
    summary = back.summary()
    assert summary["wifi_readings"] == 4 and summary["wifi_access_points"] == 3 and summary["magnetic_readings"] == 100
    # without the optional columns
    bare = dataclasses.replace(rec, wifi=wifi(t_seen=None), beacons=BeaconReadings([0.5], ["x"], [-70]), magnetic=None)
    back = Recording.load(bare.save(tmp_path / "bare.h5"))
    assert (
        back.wifi is not None
        and back.wifi.t_seen is None
        and back.beacons.tx_power_dbm is None
        and back.magnetic is None
    )


def test_h5_with_a_corrupt_wifi_index_is_refused(tmp_path):
    path = radio_recording().save(tmp_path / "r.h5")
    with h5py.File(path, "r+") as f:
        f["wifi/bssid_index"][0] = 99
    with pytest.raises(FormatError, match="wifi/bssid_index points outside wifi/bssid_names"):
        Recording.load(path)


def test_a_recording_refuses_radio_readings_on_another_clock():
    with pytest.raises(ValidationError, match=r"wifi.t spans .* far outside the devices'"):
        dataclasses.replace(radio_recording(), wifi=wifi(t=[5000.0, 5000.0, 5000.0, 5002.0]))


# ---- IPIN 2023: written logs -----------------------------------------------------------------

IPIN_HEAD = ["% LogFile created by the 'GetSensorData' App for Android.", "% Model: test"]


def ipin_log(tmp_path, extra, name="IPIN2023_T3_TrainingTrial99_repetition01.txt"):
    rows = list(IPIN_HEAD)
    for k in range(300):  # 6 s of IMU at 50 Hz
        t = 0.02 * k
        rows.append(f"ACCE;{t + 0.005:.4f};{100 + t:.4f};0.1;0.2;9.8;0")
        rows.append(f"GYRO;{t + 0.005:.4f};{100 + t:.4f};0.01;0.02;0.03;0")
        rows.append(f"MAGN;{t + 0.006:.4f};{100 + t:.4f};-2.1;-34.1;-45.4;0")
    rows += extra
    path = tmp_path / name
    path.write_text("\n".join(rows) + "\n")
    return path


def test_ipin_wifi_and_magnetometer_rows_become_tables(tmp_path):
    path = ipin_log(
        tmp_path,
        [
            "WIFI;1.0000;100.9800;SSID2023_0001;20:23:00:00:00:01;2437;-60",
            "WIFI;1.0000;100.9810;odd;name;20:23:00:00:00:02;5200;-72",  # an SSID holding ';'
            "WIFI;1.0000;100.9800;SSID2023_0001;20:23:00:00:00:01;2437;-60",  # the first row again
            "WIFI;5.0000;104.9000;SSID2023_0001;20:23:00:00:00:01;2437;-66",
            "BLE4;2.0000;iBeacon;AB:CD:EF:00:00:01;-80;0;7;9;ABCDEF00-0000-0000-0000-000000000000",
        ],
    )
    (rec,) = list(ipin2023.read(path))
    w = rec.wifi
    assert w is not None and len(w) == 3 and rec.meta["dropped_duplicates"]["WIFI"] == 1
    assert list(w.ssid) == ["SSID2023_0001", "odd;name", "SSID2023_0001"]
    np.testing.assert_array_equal(w.freq_mhz, [2437, 5200, 2437])
    np.testing.assert_array_equal(w.t, [1.0, 1.0, 5.0])
    # own timestamps: the sensor clock, shifted by the IMU's offset (min App - Sensor of ACCE = -99.995)
    np.testing.assert_allclose(w.t_seen, [100.98 - 99.995, 100.981 - 99.995, 104.9 - 99.995], atol=1e-6)
    m = rec.magnetic
    assert m is not None and len(m) == 300
    np.testing.assert_allclose(m.ut[0], [-2.1, -34.1, -45.4], rtol=1e-6)
    np.testing.assert_allclose(m.t, rec.devices["phone"].t, atol=1e-9)  # same sensor clock as ACCE
    assert list(rec.beacons.beacon) == ["AB:CD:EF:00:00:01"]


@pytest.mark.parametrize(
    "row, error, words",
    [
        ("WIFI;1.0;100.9;S;20:23:00:00:00:01;2437;loud", FormatError, "WIFI row 0: not a number"),
        ("WIFI;1.0;100.9;20:23:00:00:00:01;2437", FormatError, "WIFI row 0 has 4 fields, expected 6"),
        ("WIFI;1.0;100.9;S;20:23:00:00:00:01;2437;nan", FormatError, "WIFI rows has NaN or infinite values"),
        ("WIFI;1.0;100.9;S;20:23:00:00:00:01;2437;-160", ValidationError, "wifi.rssi_dbm: -160 at reading 0"),
        ("WIFI;1.0;100.9;S;20:23:00:00:00:01;24;-60", ValidationError, "wifi.freq_mhz: 24 at reading 0"),
    ],
)
def test_ipin_bad_wifi_rows_are_one_line_errors(tmp_path, row, error, words):
    with pytest.raises(error) as e:
        list(ipin2023.read(ipin_log(tmp_path, [row])))
    assert words in error_line(e.value)


def test_ipin_wifi_time_going_backwards_is_refused(tmp_path):
    rows = ["WIFI;3.0;102.9;S;20:23:00:00:00:01;2437;-60", "WIFI;1.0;100.9;S;20:23:00:00:00:02;2437;-60"]
    with pytest.raises(ValidationError, match="WIFI: timestamps go backwards at row 1"):
        list(ipin2023.read(ipin_log(tmp_path, rows)))


# ---- ILC2: written traces ----------------------------------------------------------------------

T0 = 1574559495000


def ilc2_trace(tmp_path, extra):
    rows = ["#\tSiteID:s\tSiteName:x\tFloorId:f\tFloorName:F1"]
    for k in range(300):
        t = T0 + 100 + 20 * k
        rows.append(f"{t}\tTYPE_ACCELEROMETER\t0.1\t0.2\t9.8\t3")
        rows.append(f"{t}\tTYPE_GYROSCOPE\t0.01\t0.02\t0.03\t3")
    rows.append(f"{T0 + 200}\tTYPE_WAYPOINT\t10.0\t20.0")
    rows.append(f"{T0 + 5000}\tTYPE_WAYPOINT\t14.0\t20.0")
    rows += extra
    rows.append("#\tendTime:1574559501000")
    path = tmp_path / "trace.txt"
    path.write_text("\n".join(rows) + "\n")
    return path


def test_ilc2_wifi_and_beacon_rows_become_tables(tmp_path):
    path = ilc2_trace(
        tmp_path,
        [
            f"{T0}\tTYPE_WIFI\tFMI\ta8:0c:ca:03:9d:d7\t-49\t2422\t{T0 - 1700}",  # before every other row
            f"{T0}\tTYPE_WIFI\t\ta8:0c:ca:03:9d:d7\t-72\t2422\t{T0 - 20000}",  # hidden network, cached
            f"{T0}\tTYPE_WIFI\twith\ttab\t04:33:89:79:fc:7c\t-70\t5180\t{T0 - 500}",
            f"{T0}\tTYPE_WIFI\tFMI\ta8:0c:ca:03:9d:d7\t-49\t2422\t{T0 - 1700}",  # a repeated row
            f"{T0 + 3000}\tTYPE_BEACON\t9195b3ad-a9d0-4500-85ff-9fb0f65a5201\t0\t0\t-56\t-93\t45.0\tE0:78:A3:3D:B5:D6\t{T0 + 3000}",
            f"{T0 + 3100}\tTYPE_BEACON\tFB349B5F-8000-0080-0010-00003CFE0000\t27257\t52321\t-59\t-70\t-1.0\t3c:71:bf:c2:65:cd\t{T0 + 3100}",
        ],
    )
    (rec,) = list(ilc2.read(path))
    assert rec.meta["t0_unix_ms"] == T0 + 100  # radio rows do not move the clock's zero
    w = rec.wifi
    assert w is not None and len(w) == 3 and rec.meta["dropped_duplicates"] == {"TYPE_WIFI": 1}
    np.testing.assert_allclose(w.t, [-0.1, -0.1, -0.1])
    np.testing.assert_allclose(w.t_seen, [-1.8, -20.1, -0.6])
    assert list(w.ssid) == ["FMI", "", "with\ttab"] and list(w.bssid)[2] == "04:33:89:79:fc:7c"
    b = rec.beacons
    assert b is not None and list(b.beacon) == [
        "9195B3AD-A9D0-4500-85FF-9FB0F65A5201:0:0:E0:78:A3:3D:B5:D6",
        "FB349B5F-8000-0080-0010-00003CFE0000:27257:52321:3C:71:BF:C2:65:CD",
    ]
    np.testing.assert_array_equal(b.tx_power_dbm, [-56, -59])
    assert b.distance_m[0] == 45.0 and np.isnan(b.distance_m[1])  # the app's -1: cannot tell


@pytest.mark.parametrize(
    "rows, error, words",
    [
        ([f"{T0}\tTYPE_WIFI\tS\taa\t-49\t2422"], FormatError, "TYPE_WIFI row 0 has 4 values, expected 5"),
        ([f"{T0}\tTYPE_WIFI\tS\taa\tloud\t2422\t{T0}"], FormatError, "TYPE_WIFI rows: not a number"),
        ([f"{T0}\tTYPE_WIFI\tS\taa\t-49\t2422\t17"], FormatError, "TYPE_WIFI last seen: timestamp 0.017 s"),
        (
            [f"{T0 + 9}\tTYPE_WIFI\tS\taa\t-49\t2422\t{T0}", f"{T0}\tTYPE_WIFI\tS\tbb\t-49\t2422\t{T0}"],
            ValidationError,
            "TYPE_WIFI: timestamps go backwards at row 1",
        ),
        ([f"{T0}\tTYPE_BEACON\tU\t0\t0\t-56\t-93\t45.0"], FormatError, "TYPE_BEACON row 0 has 6 values, expected 8"),
        ([f"{T0}\tTYPE_BEACON\tU\t0\t0\t-56\t7\t45.0\tM\t{T0}"], ValidationError, "beacons.rssi_dbm: 7 at reading 0"),
    ],
)
def test_ilc2_bad_radio_rows_are_one_line_errors(tmp_path, rows, error, words):
    with pytest.raises(error) as e:
        list(ilc2.read(ilc2_trace(tmp_path, rows)))
    assert words in error_line(e.value)


# ---- real data ---------------------------------------------------------------------------------


def test_real_ipin_log_keeps_every_wifi_and_magnetometer_row(shared_data):
    path = shared_data / IPIN_LOG
    with lzma.open(path, "rt", encoding="utf-8", errors="replace") as f:
        lines = f.read().splitlines()
    (rec,) = list(ipin2023.read(path))
    wifi_rows = [ln.split(";") for ln in lines if ln.startswith("WIFI;")]
    magn_rows = [ln for ln in lines if ln.startswith("MAGN;")]
    assert len(rec.wifi) == len(wifi_rows) == 982  # no repeated row in this log
    assert rec.wifi.bssid[0] == wifi_rows[0][4] and rec.wifi.rssi_dbm[0] == float(wifi_rows[0][6])
    assert len(np.unique(rec.wifi.t)) == len({r[1] for r in wifi_rows})  # one scan per app time
    # the readings are fresh: heard at most a third of a second before their scan was delivered
    age = rec.wifi.t - rec.wifi.t_seen
    assert 0 < age.min() and age.max() < 0.4
    assert len(rec.magnetic) == len(magn_rows) - rec.meta["dropped_duplicates"].get("MAGN", 0)
    assert 20 < np.median(np.linalg.norm(rec.magnetic.ut, axis=1)) < 80  # the Earth's field, µT


def test_real_ipin_mat_conversion_has_wifi_without_own_timestamps(shared_data):
    (rec,) = list(ipin2023.read(shared_data / IPIN_MAT))
    assert rec.wifi is not None and len(rec.wifi) == 844 and rec.wifi.t_seen is None
    assert set(rec.wifi.ssid) == {""}
    assert rec.magnetic is not None and len(rec.magnetic) > 13000


def test_real_ilc2_trace_keeps_every_radio_row(shared_data):
    path = shared_data / ILC2_TRACE
    with gzip.open(path, "rt", encoding="utf-8") as f:
        rows = [ln.split("\t") for ln in f.read().splitlines() if not ln.startswith("#")]
    (rec,) = list(ilc2.read(path))
    n_wifi = sum(r[1] == "TYPE_WIFI" for r in rows)
    n_beacon = sum(r[1] == "TYPE_BEACON" for r in rows)
    assert len(rec.wifi) + rec.meta["dropped_duplicates"].get("TYPE_WIFI", 0) == n_wifi == 10929
    # this trace lists 614 hidden networks twice in a scan, with other last-seen times: all kept
    assert len(rec.wifi) == n_wifi
    assert len(rec.beacons) == n_beacon > 0
    assert np.all(rec.wifi.t - rec.wifi.t_seen >= 0)  # last seen before the scan was delivered
