import h5py
import numpy as np
import pytest

from conftest import make_stream
from wearnav.errors import FormatError, MissingFileError, ValidationError
from wearnav.recording import DeviceStream, Recording


def test_roundtrip_preserves_everything(tmp_path, small_recording):
    path = small_recording.save(tmp_path / "r.h5")
    back = Recording.load(path)
    assert back.name == "walk1"
    assert set(back.devices) == {"phone", "earbuds"}
    for dev, s in small_recording.devices.items():
        b = back.devices[dev]
        np.testing.assert_array_equal(b.t, s.t)
        np.testing.assert_allclose(b.acc, s.acc)
        np.testing.assert_allclose(b.gyro, s.gyro)
        assert b.t.dtype == np.float64 and b.acc.dtype == np.float32
    assert back.devices["phone"].worn is None
    assert back.devices["earbuds"].worn.all()
    np.testing.assert_allclose(back.truth.pos, small_recording.truth.pos)
    np.testing.assert_allclose(back.fixes.accuracy, [3.0, 3.0])
    assert back.labels.to_dict("records") == small_recording.labels.to_dict("records")
    assert back.meta == small_recording.meta
    assert not list(tmp_path.glob(".*tmp"))  # atomic write leaves no temporary file


def test_accelerometer_only_stream_keeps_gyro_none(tmp_path):
    rec = Recording("acc_only", {"phone": make_stream(gyro=False, quat=False)})
    back = Recording.load(rec.save(tmp_path / "a.h5"))
    assert back.devices["phone"].gyro is None and not back.devices["phone"].has_gyro


def test_rate_and_duration():
    s = make_stream(n=101, rate=25.0)
    assert s.rate == pytest.approx(25.0)
    assert s.duration == pytest.approx(4.0)


@pytest.mark.parametrize(
    "t, msg",
    [
        ([0.0, 0.2, 0.1], "unsorted"),
        ([0.0, 0.1, 0.1], "duplicated"),
        ([0.0, np.nan, 0.2], "non-finite"),
    ],
)
def test_bad_time_rejected(t, msg):
    with pytest.raises(ValidationError, match=msg):
        DeviceStream(t=t, acc=np.tile([0, 0, 9.8], (3, 1)))


def test_shape_and_nan_rejected():
    with pytest.raises(ValidationError, match="shape"):
        DeviceStream(t=[0.0, 0.1], acc=np.zeros((2, 2)))
    acc = np.tile([0, 0, 9.8], (3, 1)).astype(float)
    acc[1, 0] = np.nan
    with pytest.raises(ValidationError, match="non-finite"):
        DeviceStream(t=[0.0, 0.1, 0.2], acc=acc)


def test_units_sanity_catches_g_and_degrees():
    n = 50
    t = np.arange(n) / 50
    with pytest.raises(ValidationError, match="looks like g"):
        DeviceStream(t=t, acc=np.tile([0, 0, 1.0], (n, 1)))
    with pytest.raises(ValidationError, match="deg/s"):
        DeviceStream(t=t, acc=np.tile([0, 0, 9.8], (n, 1)), gyro=np.full((n, 3), 60.0))


def test_load_errors_name_the_file(tmp_path):
    with pytest.raises(MissingFileError, match="nope.h5"):
        Recording.load(tmp_path / "nope.h5")
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not hdf5 at all")
    with pytest.raises(FormatError, match="junk.h5"):
        Recording.load(junk)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = 1
    with pytest.raises(FormatError, match="not a wearnav recording"):
        Recording.load(other)


def test_corrupt_values_in_file_are_reported(tmp_path, small_recording):
    path = small_recording.save(tmp_path / "r.h5")
    with h5py.File(path, "r+") as f:
        t = f["devices/phone/t"]
        t[5] = t[2]
    with pytest.raises(ValidationError, match=r"r\.h5.*phone.*unsorted"):
        Recording.load(path)


def test_label_at(small_recording):
    got = small_recording.label_at("activity", np.array([0.5, 1.5, 3.0]), default="-")
    assert list(got) == ["walk", "stand", "-"]


def test_beacons_pressure_and_plans_roundtrip(tmp_path):
    from wearnav.recording import BeaconReadings, FloorPlan, Pressure

    outer = np.array([[0, 0], [20, 0], [20, 10], [0, 10]], float)
    hole = np.array([[5, 3], [8, 3], [8, 6], [5, 6]], float)
    rec = Recording(
        "r",
        {"phone": make_stream(1000)},
        beacons=BeaconReadings([1.0, 2.0], ["BLE1", "BLE2"], [-70.0, -85.5]),
        pressure=Pressure([0.5, 1.5], [976.2, 976.3]),
        plans=[FloorPlan("site_F1", 1, [[outer, hole]])],
        meta={"beacons": {"BLE1": [1.0, 2.0, 1], "BLE2": [3.0, 4.0, 1]}},
    )
    back = Recording.load(rec.save(tmp_path / "r.h5"))
    assert back.beacons is not None and list(back.beacons.beacon) == ["BLE1", "BLE2"]
    assert np.allclose(back.beacons.rssi_dbm, [-70.0, -85.5])
    assert back.pressure is not None and np.allclose(back.pressure.hpa, [976.2, 976.3])
    assert len(back.plans) == 1 and back.plans[0].floor == 1
    assert np.allclose(back.plans[0].polygons[0][1], hole)
    assert back.summary()["plans"] == ["site_F1"]


@pytest.mark.parametrize(
    "make, msg",
    [
        (lambda: __import__("wearnav.recording").recording.Pressure([0.0], [97.6]), "kPa"),
        (lambda: __import__("wearnav.recording").recording.BeaconReadings([0.0], ["b"], [70.0]), "dBm"),
        (lambda: __import__("wearnav.recording").recording.FloorPlan("p", 0, [[np.zeros((2, 2))]]), "K>=3"),
    ],
)
def test_bad_beacons_pressure_plans_rejected(make, msg):
    with pytest.raises(ValidationError, match=msg):
        make()
