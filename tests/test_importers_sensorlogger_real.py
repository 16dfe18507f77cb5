"""Sensor Logger exports as they really are (issue 8, section 2).

Each case was met in public exports made by other people; none is copied here. The fixtures are
built from a simulated walk by ``wearnav.importers.sensorlogger_export.write_export`` (plus one damage helper per
case), and every test failed on the importer before these cases were handled.
"""

from __future__ import annotations

import sys
import warnings

import numpy as np
import pandas as pd
import pytest

from sensorlogger_fixture import cut_gap, edit_csv, glitch_quaternion, prepend_stale_fix, resample_rows
from test_importers_sensorlogger import EXPORT, _import_one, assert_round_trip, source_recording
from wearnav import cli
from wearnav.dataset import Dataset
from wearnav.errors import FormatError, WearnavWarning
from wearnav.importers.sensorlogger import read
from wearnav.importers.sensorlogger_export import T0_NS, write_export
from wearnav.preprocess import PreprocessConfig, align
from wearnav.recording import Recording


@pytest.fixture(scope="module")
def rec() -> Recording:
    return source_recording()


def _quiet(src, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = _import_one(src) if not kw else list(read(src, **kw))[0]
    return out, [w for w in caught if issubclass(w.category, WearnavWarning)]


def test_one_glitched_quaternion_does_not_fail_the_direction_check(rec, tmp_path):
    """A ~1 rad jump in one sample of Orientation.csv and of Headphone.csv (as in a real Android
    phone's and AirPods' files): the import succeeds, in both quaternion conventions."""
    for inverted in (False, True):
        folder = write_export(rec, tmp_path / str(inverted) / EXPORT, platform="android", quat_inverted=inverted)
        glitch_quaternion(folder / "Orientation.csv", row=3)
        glitch_quaternion(folder / "Headphone.csv", row=3)
        out, _ = _quiet(folder)
        assert set(out.devices) == {"phone", "watch", "earbuds"}
        assert out.meta["quat_inverted"] == (["phone", "watch", "earbuds"] if inverted else [])


def test_gyro_disagreement_does_not_blame_platform_when_gravity_agrees(rec, tmp_path):
    folder = write_export(rec, tmp_path / EXPORT, platform="ios")
    edit_csv(folder / "Gyroscope.csv", lambda d: d.assign(x=-d["x"], y=-d["y"], z=-d["z"]))
    with pytest.raises(FormatError) as err:
        _import_one(folder)
    msg = str(err.value)
    assert "Orientation.csv" in msg and "gyroscope" in msg and "gravity agrees" in msg
    assert "platform" not in msg and "standardisation" not in msg


def test_watch_only_export(rec, tmp_path):
    """Recorded on the Apple Watch alone: platform watchos, layout version 4, extra watch files."""
    watch = Recording(name="w", devices={"watch": rec.devices["watch"]})
    folder = write_export(watch, tmp_path / EXPORT, platform="watchos", layout_version=4, watch_extras=True)
    assert (folder / "HeartRate.csv").is_file() and (folder / "WatchCompass.csv").is_file()
    out, caught = _quiet(folder)
    assert not caught
    assert set(out.devices) == {"watch"}
    assert out.meta["platform"] == "watchos" and out.meta["layout_version"] == "4"
    np.testing.assert_allclose(out.devices["watch"].acc, rec.devices["watch"].acc, atol=1e-4)
    assert out.devices["watch"].t[0] == 0.0


def test_unusable_phone_stream_leaves_the_other_devices(rec, tmp_path):
    """Accelerometer.csv without gravity and no Gravity/TotalAcceleration: the watch and earbuds
    are imported, with one warning line naming the file and the reason."""
    folder = write_export(rec, tmp_path / EXPORT, platform="ios")
    (folder / "Gravity.csv").unlink()
    out, caught = _quiet(folder)
    assert set(out.devices) == {"watch", "earbuds"}
    assert len(caught) == 1
    msg = str(caught[0].message)
    assert "\n" not in msg and "Accelerometer.csv" in msg and "without gravity" in msg
    assert "without gravity" in out.meta["left_out"]["phone"]
    np.testing.assert_allclose(out.devices["watch"].acc, rec.devices["watch"].acc, atol=1e-4)
    # with nothing else usable it is still an error
    phone = Recording(name="p", devices={"phone": rec.devices["phone"]})
    folder = write_export(phone, tmp_path / "phone" / EXPORT, platform="ios")
    (folder / "Gravity.csv").unlink()
    with pytest.raises(FormatError, match=r"Accelerometer\.csv: holds acceleration without gravity"):
        _import_one(folder)


def test_stale_cached_first_fix_does_not_shift_t0(rec, tmp_path):
    folder = write_export(rec, tmp_path / EXPORT, platform="ios")
    prepend_stale_fix(folder / "Location.csv", seconds_before=90.0, km_away=5.0, accuracy=3000.0)
    assert pd.read_csv(folder / "Location.csv")["seconds_elapsed"].iloc[0] < 0
    out, _ = _quiet(folder)
    assert out.meta["t0_unix_ns"] == T0_NS
    assert out.meta["dropped_stale_fixes"] == 1
    assert len(out.fixes) == len(rec.fixes)
    # the local origin is the first real fix, not the stale one 5 km away
    first_lat = pd.read_csv(folder / "Location.csv")["latitude"].iloc[1]  # row 0 is the stale one
    assert out.meta["origin_lat"] == pytest.approx(first_lat, abs=1e-9)
    assert_round_trip(out, rec)


def test_android_phone_rate_follows_the_best_stream(rec, tmp_path):
    """TotalAcceleration.csv at ~59 Hz beside 100 Hz Accelerometer/Gravity/Gyroscope/Orientation."""
    folder = write_export(rec, tmp_path / EXPORT, platform="android", total_acceleration=True)
    resample_rows(folder / "TotalAcceleration.csv", 59.0)
    out, _ = _quiet(folder)
    clock = out.meta["phone_clock"]
    assert clock["file"] == "Accelerometer.csv"
    assert clock["rate_hz"] == pytest.approx(rec.devices["phone"].rate, rel=0.02)
    # rows kept from a 100 Hz file: spacings of 10 and 20 ms, median-based rate 50-60 Hz
    assert 45.0 < clock["rates_hz"]["TotalAcceleration.csv"] < 62.0
    assert out.devices["phone"].rate == pytest.approx(rec.devices["phone"].rate, rel=0.02)
    assert_round_trip(out, rec)
    # equal rates: TotalAcceleration.csv as written (no interpolation needed)
    folder = write_export(rec, tmp_path / "eq" / EXPORT, platform="android", total_acceleration=True)
    assert _quiet(folder)[0].meta["phone_clock"]["file"] == "TotalAcceleration.csv"


def test_gap_in_wrist_motion_is_reported_and_masked(rec, tmp_path):
    folder = write_export(rec, tmp_path / EXPORT, platform="ios")
    cut_gap(folder / "WristMotion.csv", start_s=8.0, length_s=12.0)
    out, caught = _quiet(folder)
    (gap,) = out.meta["gaps"]["watch"]
    assert gap[1] - gap[0] == pytest.approx(12.0, abs=0.1)
    assert any("watch has 1 gap" in str(w.message) for w in caught)
    seq = align(out, PreprocessConfig(frame_align="none"))
    watch = seq.devices.index("watch")
    inside = (seq.t > gap[0] + 0.2) & (seq.t < gap[1] - 0.2)
    assert inside.sum() > 250 and not seq.mask[watch, inside].any()
    assert not np.any(seq.imu[watch, inside])
    assert seq.mask[watch, seq.t < gap[0] - 0.5].all()


def test_missing_metadata_says_what_to_do_and_platform_option(rec, tmp_path, monkeypatch, capsys):
    folder = write_export(rec, tmp_path / "src" / EXPORT, platform="ios", metadata=False)
    with pytest.raises(FormatError) as err:
        _import_one(folder)
    msg = str(err.value)
    assert "Metadata.csv is missing" in msg and "--platform" in msg
    out, _ = _quiet(folder, platform="ios")
    assert out.meta["platform"] == "ios" and "--platform" in out.meta["platform_from"]
    assert_round_trip(out, rec)
    # the command line: one error line without the option, an import with it
    monkeypatch.setattr(sys, "argv", ["wearnav", "import", "sensorlogger", str(folder), "--out", str(tmp_path / "ds")])
    with pytest.raises(SystemExit) as exit_:
        cli.main()
    assert exit_.value.code == 2 and "--platform" in capsys.readouterr().err
    monkeypatch.setattr(
        sys,
        "argv",
        ["wearnav", "import", "sensorlogger", str(folder), "--out", str(tmp_path / "ds"), "--platform", "ios"],
    )
    cli.main()
    ds = Dataset.open(tmp_path / "ds")
    assert ds.names == [EXPORT]
    assert_round_trip(ds.load(EXPORT), rec)
