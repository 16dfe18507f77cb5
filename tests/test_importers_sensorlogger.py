"""Sensor Logger importer: round trips through the documented export layout, and bad exports.

No real export exists here: ``wearnav.importers.sensorlogger_export.write_export`` writes a Recording the way the
Sensor Logger documentation describes, and the importer must give the Recording back.
"""

from __future__ import annotations

import re
import shutil
import zipfile

import numpy as np
import pandas as pd
import pytest

from synthetic import synthetic_recording
from wearnav.core.geo import PROJECTION
from wearnav.errors import FormatError, MissingFileError, WearnavError
from wearnav.importers import import_dataset
from wearnav.importers.sensorlogger import read
from wearnav.importers.sensorlogger_export import T0_NS, time_origin, write_export, zip_export
from wearnav.recording import Recording
from wearnav.simulate import WalkConfig, simulate_recording

EXPORT = "2023-11-14_22-13-20"


def source_recording() -> Recording:
    """The recording that is exported and re-imported: a simulated walk with all three devices
    (phone moving between call, front and back pocket), 30 s. Any multi-device Recording with
    quaternions works, e.g. ``synthetic_recording()`` from tests/synthetic.py."""
    return simulate_recording(WalkConfig(mode="PVW", placement="MP", duration_s=30), seed=1)


@pytest.fixture(scope="module")
def rec() -> Recording:
    return source_recording()


def _import_one(src) -> Recording:
    recs = list(read(src))
    assert len(recs) == 1
    return recs[0]


def _quat_close(a, b, tol=1e-5):
    """Same rotation (q and -q are the same)."""
    dots = np.abs(np.sum(np.asarray(a, float) * np.asarray(b, float), axis=1))
    return np.all(np.abs(dots - 1) < tol)


def assert_round_trip(out: Recording, rec: Recording) -> None:
    t_ref = time_origin(rec)
    assert set(out.devices) == set(rec.devices)
    for dev, s in rec.devices.items():
        o = out.devices[dev]
        assert len(o) == len(s), dev
        np.testing.assert_allclose(o.t, s.t - t_ref, atol=1e-8, err_msg=dev)
        np.testing.assert_allclose(o.acc, s.acc, atol=1e-4, err_msg=dev)
        np.testing.assert_allclose(o.gyro, s.gyro, atol=1e-6, err_msg=dev)
        assert _quat_close(o.quat, s.quat), dev
    f, g = out.fixes, rec.fixes
    np.testing.assert_allclose(f.t, g.t - t_ref, atol=1e-8)
    # the importer's local frame is centred on the first fix
    np.testing.assert_allclose(f.pos - f.pos[0], g.pos - g.pos[0], atol=1e-3)
    assert out.meta["projection"] == PROJECTION
    np.testing.assert_allclose(f.accuracy, g.accuracy, rtol=1e-9)
    assert out.truth is None and out.labels.empty
    assert out.meta["source"] == "sensorlogger"
    assert out.meta["t0_unix_ns"] == T0_NS


# ---- round trips ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kw",
    [
        dict(platform="ios", standardised=False),
        dict(platform="ios", standardised=True),
        dict(platform="android", standardised=False),
        dict(platform="android", standardised=False, total_acceleration=True),
    ],
    ids=["ios", "ios-standardised", "android", "android-total"],
)
def test_round_trip_folder(rec, tmp_path, kw):
    folder = write_export(rec, tmp_path / EXPORT, **kw)
    out = _import_one(folder)
    assert out.name == EXPORT
    assert out.meta["platform"] == kw["platform"]
    assert out.meta["standardisation"] == kw["standardised"]
    assert out.meta["earbud_side"] == "left"
    assert_round_trip(out, rec)


def test_round_trip_synthetic_physics(tmp_path):
    """The hand-written physics of tests/synthetic.py (earbuds taken off and laid on their side)."""
    rec = synthetic_recording(duration=30.0, seed=3)
    for kw in (dict(platform="ios"), dict(platform="android", quat_inverted=True)):
        folder = write_export(rec, tmp_path / kw["platform"] / EXPORT, **kw)
        assert_round_trip(_import_one(folder), rec)


def test_ios_sign_and_units_are_really_converted(rec, tmp_path):
    """The written files are not the Recording's numbers: iOS flips sign, the watch is in g."""
    folder = write_export(rec, tmp_path / EXPORT, platform="ios", standardised=False)
    wrist = pd.read_csv(folder / "WristMotion.csv")
    grav_g = wrist[["gravityX", "gravityY", "gravityZ"]].to_numpy()
    assert np.median(np.linalg.norm(grav_g, axis=1)) == pytest.approx(1.0, abs=1e-3)
    phone_grav = pd.read_csv(folder / "Gravity.csv")[["x", "y", "z"]].to_numpy()
    rot_acc = rec.devices["phone"].acc
    # gravity points against the mean specific force on iOS
    assert np.dot(phone_grav.mean(0), rot_acc.mean(0)) < 0
    out = _import_one(folder)
    np.testing.assert_allclose(out.devices["watch"].acc, rec.devices["watch"].acc, atol=1e-4)


def test_round_trip_zip(rec, tmp_path):
    folder = write_export(rec, tmp_path / "x" / EXPORT, platform="ios")
    root_zip = zip_export(folder, tmp_path / f"{EXPORT}.zip")
    out = _import_one(root_zip)
    assert out.name == EXPORT
    assert_round_trip(out, rec)
    assert out.meta["file"] == f"{EXPORT}.zip"
    nested = zip_export(folder, tmp_path / "nested.zip", subfolder=EXPORT)
    out = _import_one(nested)
    assert_round_trip(out, rec)
    assert out.name == "nested" and out.meta["file"] == f"nested.zip!{EXPORT}"


def test_folder_of_exports_and_registry(rec, tmp_path):
    top = tmp_path / "exports"
    write_export(rec, top / "a", platform="ios")
    write_export(rec, top / "b", platform="android")
    zip_export(write_export(rec, tmp_path / "c", platform="ios", standardised=True), top / "c.zip")
    (top / "notes.txt").write_text("not an export")
    assert [r.name for r in read(top)] == ["a", "b", "c"]
    assert [r.name for r in read(top, limit=2)] == ["a", "b"]
    ds = import_dataset("sensorlogger", top, tmp_path / "ds", progress=False)
    assert ds.names == ["a", "b", "c"]
    assert ds.manifest.loc[0, "devices"] == "phone;watch;earbuds"
    assert_round_trip(ds.load("c"), rec)


def test_inverted_quaternions_are_detected(rec, tmp_path):
    folder = write_export(rec, tmp_path / EXPORT, quat_inverted=True)
    q_written = pd.read_csv(folder / "Orientation.csv")[["qw", "qx", "qy", "qz"]].to_numpy()
    assert not _quat_close(q_written, rec.devices["phone"].quat, tol=1e-2)
    out = _import_one(folder)
    assert_round_trip(out, rec)
    assert out.meta["quat_inverted"] == ["phone", "watch", "earbuds"]


def test_phone_files_interpolated_onto_accelerometer_clock(rec, tmp_path):
    """Gravity, Gyroscope and Orientation at half the accelerometer's rate (as on Android)."""
    folder = write_export(rec, tmp_path / EXPORT, platform="android")
    for name in ("Gravity.csv", "Gyroscope.csv", "Orientation.csv"):
        df = pd.read_csv(folder / name)
        df.iloc[::2].to_csv(folder / name, index=False)
    out = _import_one(folder)
    src, o = rec.devices["phone"], out.devices["phone"]
    n = len(o)
    # accelerometer samples after the last kept gyro sample cannot be interpolated
    assert n == (len(src) - 1) // 2 * 2 + 1
    np.testing.assert_allclose(o.acc[::2], src.acc[:n:2], atol=1e-4)  # exact where samples coincide
    np.testing.assert_allclose(o.gyro[::2], src.gyro[:n:2], atol=1e-6)
    # in between: interpolated, so close to the source but not equal to it
    err_gyro = np.abs(o.gyro[1::2] - src.gyro[1:n:2]).max()
    assert 1e-4 < err_gyro < 0.05
    ang = 2 * np.degrees(np.arccos(np.clip(np.abs(np.sum(o.quat * src.quat[:n], 1)), 0, 1)))
    assert ang.max() < 0.5
    assert np.abs(o.acc - src.acc[:n]).max() < 0.05


def test_gap_in_gyroscope_drops_samples_instead_of_inventing_them(rec, tmp_path):
    folder = write_export(rec, tmp_path / EXPORT, platform="android")
    gyro = pd.read_csv(folder / "Gyroscope.csv")
    t = (gyro["time"] - T0_NS) / 1e9
    gyro[(t < 10.0) | (t >= 12.0)].to_csv(folder / "Gyroscope.csv", index=False)
    out = _import_one(folder)
    tp = out.devices["phone"].t
    assert not np.any((tp > 10.0) & (tp < 11.99))
    assert out.meta["dropped_uncovered"]["phone"] == pytest.approx(200, abs=2)
    assert len(out.devices["watch"]) == len(rec.devices["watch"])


def test_duplicate_rows_are_dropped(rec, tmp_path):
    folder = write_export(rec, tmp_path / EXPORT)
    df = pd.read_csv(folder / "WristMotion.csv")
    pd.concat([df.iloc[:50], df.iloc[49:50], df.iloc[50:]]).to_csv(folder / "WristMotion.csv", index=False)
    out = _import_one(folder)
    assert_round_trip(out, rec)
    assert out.meta["dropped_duplicates"] == {"WristMotion.csv": 1}
    assert out.meta["dropped_uncovered"] == {} and out.meta["quat_inverted"] == []


# ---- bad exports --------------------------------------------------------------------------


def _edit_csv(path, fn):
    df = pd.read_csv(path)
    fn(df).to_csv(path, index=False)


def _nan(df):
    df.loc[100, "y"] = np.nan
    return df


def _backwards(df):
    df.loc[100, "time"] = df.loc[98, "time"]
    return df


def _broken_clock(df):
    df.loc[1::2, "time"] = df.loc[::2, "time"].to_numpy()[: len(df.loc[1::2])]
    return df


def _truncate(path):
    text = path.read_text()
    path.write_text(text[: len(text) - 25])


def _drop_metadata_platform(path):
    _edit_csv(path, lambda df: df.drop(columns=["platform"]))


CASES = {
    "renamed-column": (
        "Accelerometer.csv",
        lambda p: _edit_csv(p, lambda d: d.rename(columns={"x": "X"})),
        ["Accelerometer.csv", "missing columns", "'x'"],
    ),
    "renamed-watch-column": (
        "WristMotion.csv",
        lambda p: _edit_csv(p, lambda d: d.rename(columns={"gravityX": "gravX"})),
        ["WristMotion.csv", "missing columns", "gravityX"],
    ),
    "empty-file": ("Gyroscope.csv", lambda p: p.write_text(""), ["Gyroscope.csv", "empty file"]),
    "header-only": (
        "Gravity.csv",
        lambda p: p.write_text("time,seconds_elapsed,z,y,x\n"),
        ["Gravity.csv", "no data rows"],
    ),
    "truncated": ("Accelerometer.csv", _truncate, ["Accelerometer.csv", "truncated"]),
    "nan": ("Gyroscope.csv", lambda p: _edit_csv(p, _nan), ["Gyroscope.csv", "NaN"]),
    "time-backwards": (
        "Orientation.csv",
        lambda p: _edit_csv(p, _backwards),
        ["Orientation.csv", "time", "backwards at row 100"],
    ),
    "broken-clock": (
        "Accelerometer.csv",
        lambda p: _edit_csv(p, _broken_clock),
        ["Accelerometer.csv", "timestamps are duplicated"],
    ),
    "no-metadata": ("Metadata.csv", lambda p: p.unlink(), ["Metadata.csv is missing", EXPORT]),
    "metadata-without-platform": (
        "Metadata.csv",
        _drop_metadata_platform,
        ["Metadata.csv", "missing columns", "platform"],
    ),
    "bad-location": (
        "Location.csv",
        lambda p: _edit_csv(p, lambda d: d.assign(latitude=d["latitude"] + 100)),
        ["Location.csv", "out of range"],
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_export_raises_one_line_error_naming_the_file(rec, tmp_path, case):
    fname, damage, expected = CASES[case]
    folder = write_export(rec, tmp_path / EXPORT, platform="ios")
    damage(folder / fname)
    with pytest.raises(WearnavError) as err:
        list(read(folder))
    msg = str(err.value)
    assert "\n" not in msg
    for part in expected:
        assert part in msg, (part, msg)


def test_wrong_platform_is_caught_by_the_orientation_check(rec, tmp_path):
    """iOS data (flipped sign) declared as Android: gravity ends up pointing down."""
    folder = write_export(rec, tmp_path / EXPORT, platform="ios")
    _edit_csv(folder / "Metadata.csv", lambda d: d.assign(platform="android"))
    with pytest.raises(FormatError, match=r"Orientation\.csv: orientation does not fit .* 180° from up"):
        list(read(folder))


def test_wrong_standardisation_is_caught(rec, tmp_path):
    """Standardised (m/s², Android sign) data declared as not standardised."""
    folder = write_export(rec, tmp_path / "ios" / EXPORT, platform="ios", standardised=True)
    _edit_csv(folder / "Metadata.csv", lambda d: d.assign(standardisation="false"))
    # on iOS that flips the phone's sign: gravity points down
    with pytest.raises(FormatError, match=r"Orientation\.csv: orientation does not fit .* 180° from up"):
        list(read(folder))
    # on Android only the watch's units change: read as g, |acc| is 9.8 times too large
    folder = write_export(rec, tmp_path / "android" / EXPORT, platform="android", standardised=True)
    _edit_csv(folder / "Metadata.csv", lambda d: d.assign(standardisation="false"))
    msg = r"WristMotion\.csv: device 'watch': acc: median \|acc\| is .*read as g"
    with pytest.raises(FormatError, match=msg) as err:
        list(read(folder))
    assert float(re.search(r"median \|acc\| is ([\d.]+),", str(err.value)).group(1)) > 50


def test_wrong_folder_and_files(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(FormatError, match="no Sensor Logger export here"):
        list(read(tmp_path / "empty"))
    (tmp_path / "data.csv").write_text("a,b\n1,2\n")
    with pytest.raises(FormatError, match=r"data\.csv: not a Sensor Logger export"):
        list(read(tmp_path / "data.csv"))
    with pytest.raises(MissingFileError):
        list(read(tmp_path / "nowhere"))
    only_location = tmp_path / "loc"
    only_location.mkdir()
    (only_location / "Metadata.csv").write_text("platform\nios\n")
    with pytest.raises(FormatError, match="no motion file"):
        list(read(only_location))


def test_zip_errors_name_the_archive(rec, tmp_path):
    folder = write_export(rec, tmp_path / "x" / EXPORT)
    _edit_csv(folder / "Gyroscope.csv", _nan)
    z = zip_export(folder, tmp_path / "rec.zip", subfolder=EXPORT)
    with pytest.raises(FormatError, match=rf"rec\.zip!{EXPORT}/Gyroscope\.csv: .*NaN"):
        list(read(z))

    good = zip_export(write_export(rec, tmp_path / "y" / EXPORT), tmp_path / "good.zip")
    data = good.read_bytes()
    cut = tmp_path / "cut.zip"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(FormatError, match=r"cut\.zip: "):
        list(read(cut))

    empty = tmp_path / "other.zip"
    with zipfile.ZipFile(empty, "w") as zf:
        zf.writestr("readme.txt", "hello")
    with pytest.raises(FormatError, match=r"other\.zip: no Sensor Logger export inside"):
        list(read(empty))


def test_gzipped_csvs_are_read(rec, tmp_path):
    import gzip

    folder = write_export(rec, tmp_path / EXPORT)
    for p in list(folder.glob("*.csv")):
        with open(p, "rb") as f, gzip.open(p.with_name(p.name + ".gz"), "wb") as g:
            shutil.copyfileobj(f, g)
        p.unlink()
    assert_round_trip(_import_one(folder), rec)


def test_negative_accuracy_means_unknown(rec, tmp_path):
    folder = write_export(rec, tmp_path / EXPORT)
    _edit_csv(
        folder / "Location.csv",
        lambda d: d.assign(horizontalAccuracy=d["horizontalAccuracy"].where(d.index % 3 != 0, -1.0)),
    )
    acc = _import_one(folder).fixes.accuracy
    assert np.all(np.isnan(acc[::3]))
    np.testing.assert_allclose(acc[1::3], rec.fixes.accuracy[1::3])


def test_partial_exports(rec, tmp_path):
    """A watch-only export; a phone without Orientation.csv or Location.csv."""
    folder = write_export(rec, tmp_path / "watch" / EXPORT)
    for name in (
        "Accelerometer.csv",
        "Gravity.csv",
        "Gyroscope.csv",
        "Orientation.csv",
        "Headphone.csv",
        "Location.csv",
    ):
        (folder / name).unlink()
    out = _import_one(folder)
    assert list(out.devices) == ["watch"] and out.fixes is None
    np.testing.assert_allclose(out.devices["watch"].acc, rec.devices["watch"].acc, atol=1e-4)

    folder = write_export(rec, tmp_path / "phone" / EXPORT, platform="android")
    for name in ("Orientation.csv", "WristMotion.csv", "Headphone.csv", "Location.csv"):
        (folder / name).unlink()
    phone = _import_one(folder).devices["phone"]
    assert phone.quat is None
    np.testing.assert_allclose(phone.acc, rec.devices["phone"].acc, atol=1e-4)
    np.testing.assert_allclose(phone.gyro, rec.devices["phone"].gyro, atol=1e-6)


def test_gravity_counted_twice_is_caught(rec, tmp_path):
    """Headphone acceleration that already holds gravity: |acc| ≈ 19.6 passes the generic units
    band, the world-frame vertical mean does not."""
    folder = write_export(rec, tmp_path / "android" / EXPORT, platform="android", standardised=True)
    _edit_csv(
        folder / "Headphone.csv",
        lambda d: d.assign(**{f"acceleration{a}": d[f"acceleration{a}"] + d[f"gravity{a}"] for a in "XYZ"}),
    )
    with pytest.raises(FormatError, match=r"Headphone\.csv: mean vertical specific force .* 19\.\d m/s²"):
        list(read(folder))


def test_the_orientation_check_says_whether_the_data_told_the_directions_apart(tmp_path):
    """A phone turning while tilted tells world←device from its inverse (one passes, the other
    fails: clear); one lying still and level passes both ways (too little rotation: the documented
    direction, not clear). The live receiver rechecks only the latter before its decision (issue 61)."""
    from pathlib import Path

    from scipy.spatial.transform import Rotation

    from wearnav.core.rotations import to_wxyz
    from wearnav.importers import sensorlogger_build as slb

    t = np.arange(0.0, 10.0, 0.01)
    turning = Rotation.from_euler("z", t[:, None]) * Rotation.from_euler("x", 60, degrees=True)
    for rot, gyro, clear in (
        (turning, np.tile(Rotation.from_euler("x", 60, degrees=True).inv().apply([0, 0, 1.0]), (len(t), 1)), True),
        (Rotation.from_euler("z", np.full((len(t), 1), 0.7)), np.zeros((len(t), 3)), False),
    ):
        acc = rot.inv().apply([0.0, 0.0, 9.81])
        q, label, told = slb._check_orientation(to_wxyz(rot), acc, gyro, t, Path("Orientation.csv"))
        assert label == "world<-device" and told is clear
        np.testing.assert_allclose(np.abs(np.sum(q * to_wxyz(rot), axis=1)), 1.0, atol=1e-9)
